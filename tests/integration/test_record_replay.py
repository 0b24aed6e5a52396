"""`cbgo record` and `cbgo replay` through a real router: same messages, same order, never early."""

from __future__ import annotations

import random
import re
import signal
import subprocess
import sys
import time

from cbgo import wire
from cbgo.examples import example
from cbgo.recording import read_recording, recording_info

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

    arrivals, stderr = replay_into_subscriber(stack, path, expect=len(sent))
    assert [(k, p) for _t, k, p in arrivals] == sent
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
            k: v for k, v in old.items() if k != "ts"}
        wire.validate(got, wire.USER, "cbgo/user")
