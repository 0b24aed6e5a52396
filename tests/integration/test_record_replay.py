"""`cbgo record` and `cbgo replay` through a real router: same messages, same order, never early.

And a replay cannot drive the robot unless asked to: derived keys need --derived, and a planner
or robot alive needs --yes-drive-robot too; the planner refuses replayed intents anyway.
"""

from __future__ import annotations

import random
import re
import signal
import subprocess
import sys
import threading
import time

from cbgo import keys, wire
from cbgo.examples import example
from cbgo.recording import Recorder, read_recording, recording_info

CLI = [sys.executable, "-m", "cbgo.cli.main"]
SUFFIXES = ["hands/frame", "gaze", "user", "episode/event"]


def start_recorder(stack, path, *flags):
    stack.start_router()
    stack.wait_alive(["router"])
    rec = stack.spawn("record", [*CLI, "record", "-o", str(path), *flags,
                                 "--connect", stack.endpoint])
    rec.wait_for_line("recording ")
    return rec


def publishers(stack, suffixes):
    """One publisher per key, returned once each has a matching subscriber (the recorder)."""
    return {stack.keys.resolve(s): stack.publisher(s, timeout=10) for s in suffixes}


def publish_irregularly(pubs, count, seed=3):
    """Publishes count messages on random keys, 2-18 ms apart; returns [(key, payload)]."""
    rng = random.Random(seed)
    keys = list(pubs)
    sent, deadline = [], time.perf_counter()
    for i in range(count):
        key = rng.choice(keys)
        message = {**example(key.split("/", 1)[1], ts=time.time()), "n": i}
        if "seq" in message:
            message["seq"] = i
        payload = wire.encode(message)
        while time.perf_counter() < deadline:
            pass
        pubs[key].put(payload)
        sent.append((key, payload))
        deadline += rng.uniform(0.002, 0.018)
    return sent


def marked(key, payload):
    """The message `cbgo replay` sends for a recorded payload."""
    message = {**wire.decode(payload), "replayed": True}
    if key == "cbgo/hands/frame":
        message["source"] = "replay"
    return message


def replay(stack, path, *flags, timeout=120):
    """Runs `cbgo replay` against the stack; returns the CompletedProcess."""
    return subprocess.run([*CLI, "replay", str(path), *flags, "--connect", stack.endpoint],
                          capture_output=True, text=True, timeout=timeout, env=stack.env())


def replay_into_subscriber(stack, path, *flags, expect):
    """Runs `cbgo replay` with a subscriber on cbgo/**; returns [(arrival s, key, payload)]."""
    arrivals = []
    sub = stack.session().declare_subscriber(
        "cbgo/**", lambda s: arrivals.append((time.perf_counter(), str(s.key_expr),
                                              s.payload.to_bytes())))
    try:
        done = subprocess.run([*CLI, "replay", str(path), "--wait", "10", *flags,
                               "--connect", stack.endpoint], capture_output=True, text=True,
                              timeout=60, env=stack.env())
        assert done.returncode == 0, done.stderr
        deadline = time.monotonic() + 5
        while len(arrivals) < expect and time.monotonic() < deadline:
            time.sleep(0.01)
    finally:
        sub.undeclare()
    return arrivals, done.stderr


def replay_seconds(stderr):
    """The duration `cbgo replay` reports ("replayed N messages on K keys in S s ...")."""
    return float(re.search(r"replayed \d+ messages? on \d+ keys? in ([0-9.]+) s", stderr)[1])


def test_replay_sends_the_recorded_messages_in_order_and_never_early(stack, tmp_path):
    path = tmp_path / "session.mcap"
    rec = start_recorder(stack, path)
    pubs = publishers(stack, SUFFIXES)
    stack.session().put("cbgo/@ctl/nobody/status", b"\x80")  # control keys are not data
    sent = publish_irregularly(pubs, 200)
    time.sleep(0.3)
    code, seconds = stack.stop("record", signal.SIGINT)
    assert code == 0, rec.log()
    assert seconds < 3.0
    assert "200 messages on 4 keys" in rec.log()

    recorded = list(read_recording(path))
    assert [(m.key, m.payload) for m in recorded] == sent
    info = recording_info(path)
    assert info.counts == {k: sum(1 for s in sent if s[0] == k) for k in info.counts}
    assert set(info.counts) == set(pubs)

    arrivals, stderr = replay_into_subscriber(stack, path, "--derived", expect=len(sent))
    assert [(k, wire.decode(p)) for _t, k, p in arrivals] == [(k, marked(k, p)) for k, p in sent]
    assert "another publisher" not in stderr  # its own hand frames are not a second source
    # Never early, whatever the load: the replay cannot end before the recording's last
    # message was due. How late messages arrive is measured by `cbgo bench replay`, and the
    # schedule itself exactly by tests/unit/shared/test_replay_schedule.py.
    span_s = (recorded[-1].log_time_ns - recorded[0].log_time_ns) / 1e9
    assert span_s > 1.0
    assert replay_seconds(stderr) >= span_s


def test_record_stops_after_count_and_replay_filters_restamps_and_speeds_up(stack, tmp_path):
    path = tmp_path / "five.mcap"
    rec = start_recorder(stack, path, "user", "**", "--count", "6")  # overlapping: kept once
    pubs = publishers(stack, ["user", "gaze"])
    sent = publish_irregularly(pubs, 10, seed=5)
    assert rec.wait(10) == 0, rec.log()
    recorded = list(read_recording(path))
    assert [(m.key, m.payload) for m in recorded] == sent[:6]

    users = [m for m in recorded if m.key == "cbgo/user"]
    before = time.time()
    arrivals, stderr = replay_into_subscriber(stack, path, "--keys", "user", "--restamp",
                                              "--speed", "4", expect=len(users))
    assert f"replayed {len(users)} messages on 1 key in" in stderr
    assert [k for _t, k, _p in arrivals] == ["cbgo/user"] * len(users)
    for (_t, _k, payload), original in zip(arrivals, users, strict=True):
        got, old = wire.decode(payload), original.message
        assert got["ts"] >= before > old["ts"]
        assert {k: v for k, v in got.items() if k != "ts"} == {
            k: v for k, v in old.items() if k != "ts"} | {"replayed": True}
        wire.validate(got, wire.USER, "cbgo/user")


# ---------------------------------------------------------------- a replay cannot drive the robot

PAPER_SCENE = {
    "objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.2], "size": 0.06,
         "full": False, "on": None, "inside": None},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11,
         "open": False},
    ],
    "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": False, "holding": "cup1"},
}


def accepted_intent(action, obj):
    return {"v": 1, "ts": time.time(), "episode": "ep-rec", "action": action, "object": obj,
            "params": {}, "p_action": {action: 0.9}, "p_object": {obj: 0.9},
            "confidence": 0.9, "status": "accepted", "reason": "", "model": "test"}


def robot_acts(stack):
    """(robot/act queries the dry-robot answered, robot/act queries the planner sent)."""
    return (stack.status("dry-robot")["actions"]["actions"],
            stack.status("planner")["robot_acts_sent"])


def record_the_planner_acting(stack, path):
    """Records a session in which a person's frames and an accepted intent moved dry-robot."""
    replies = stack.query(stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": PAPER_SCENE},
                          timeout=30)
    assert replies and replies[0][0] and replies[0][1]["ok"], replies
    rec = stack.spawn("record", [*CLI, "record", "-o", str(path), "--connect", stack.endpoint])
    rec.wait_for_line("recording ")
    plans = stack.collect("plan/status")
    for suffix in ("user", "gaze", "hands/frame"):
        stack.put(suffix, example(suffix, ts=time.time()), timeout=10)
    stack.put("intent", accepted_intent("put_into", "drawer1"), timeout=10)
    end = plans.first(lambda m: m["state"] != "running", timeout=60)
    assert end["state"] == "success", (end, stack.logs(["planner", "dry-robot"]))
    time.sleep(0.5)  # the last scene and robot states reach the recorder
    code, _seconds = stack.stop("record", signal.SIGINT)
    assert code == 0, rec.log()
    return recording_info(path).counts


def test_a_replay_of_the_planner_acting_moves_nothing_on_a_live_system(stack, tmp_path):
    path = tmp_path / "acted.mcap"
    stack.start_router()
    stack.start_service("dry-robot")
    stack.start_service("planner")
    stack.wait_alive(["router", "dry-robot", "planner"], timeout=60)
    counts = record_the_planner_acting(stack, path)
    for key in ("intent", "plan/status", "scene/state", "robot/state", "hands/frame"):
        assert counts.get(f"cbgo/{key}"), (key, counts)
    before = robot_acts(stack)
    assert before[0] >= 4 and before[1] >= 4  # the recorded session did move the robot

    # By default only the person's keys go out; the planner and the robot see nothing to do.
    default = replay(stack, path, "--speed", "4")
    assert default.returncode == 0, default.stderr
    assert "not replaying derived and command keys" in default.stderr
    assert "intent" in default.stderr and "--derived" in default.stderr

    # Derived keys with a planner and a robot alive: refused, naming the flag that confirms.
    derived = replay(stack, path, "--derived", "--speed", "4")
    assert derived.returncode == 2, derived.stderr
    assert "--yes-drive-robot" in derived.stderr
    assert "dry-robot, planner are alive" in derived.stderr
    assert "Traceback" not in derived.stderr

    # Confirmed: everything goes out, marked replayed, and the planner refuses the intent.
    forced = replay(stack, path, "--derived", "--yes-drive-robot", "--speed", "4")
    assert forced.returncode == 0, forced.stderr
    deadline = time.monotonic() + 10
    while stack.status("planner")["plans"]["refused_replayed"] < 1:
        assert time.monotonic() < deadline, stack.logs(["planner"])
        time.sleep(0.1)
    time.sleep(1.0)  # a tick or twenty: time for a robot/act, were one coming
    assert robot_acts(stack) == before, stack.logs(["planner", "dry-robot"])
    assert "refused a replayed intent put_into(drawer1)" in stack.procs["planner"].log()


def test_hand_frames_from_another_publisher_during_a_replay_are_reported(stack, tmp_path):
    path, t0 = tmp_path / "hands.mcap", time.time()
    with Recorder(path) as rec:
        for i in range(60):
            frame = {**example("hands/frame", ts=t0 + i * 0.02), "seq": i}
            rec.write("cbgo/hands/frame", wire.encode(frame), int((t0 + i * 0.02) * 1e9))
    stack.start_router()
    stack.wait_alive(["router"])
    frames = stack.collect("hands/frame")  # a subscriber, so that the replay starts at once
    live, stop = stack.session().declare_publisher("cbgo/hands/frame"), threading.Event()

    def live_user():
        seq = 0
        while not stop.wait(0.02):
            live.put(wire.encode({**example("hands/frame", ts=time.time()), "seq": seq}))
            seq += 1

    talker = threading.Thread(target=live_user, daemon=True)
    talker.start()
    try:
        done = replay(stack, path, "--wait", "10")
    finally:
        stop.set()
        talker.join(2)
    assert done.returncode == 0, done.stderr
    assert "hand frames from another publisher are arriving on cbgo/hands/frame" in done.stderr
    assert re.search(r"\d+ hand frames? from another publisher arrived", done.stderr)
    replayed = [m for m in frames.items() if m.get("replayed")]
    assert replayed and all(m["source"] == "replay" for m in replayed)
