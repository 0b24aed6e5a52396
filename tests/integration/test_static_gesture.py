"""static-gesture through real processes: every static gesture from leap-bridge, and a gesture
recorded by demonstration that the running service picks up."""

import subprocess
import sys
import time
from collections import Counter, defaultdict

import numpy as np

from cbgo import wire
from cbgo.hands.model import HandPose, HandShape, build_hand
from cbgo.hands.poses import gesture_mean
from cbgo.simuser.scenario import load_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.wire import STATIC_GESTURES

CLI = [sys.executable, "-m", "cbgo.cli.main"]


def winner(message):
    return message["names"][int(np.argmax(message["probs"]))]


def test_every_static_gesture_streamed_by_leap_bridge_wins_the_frames_where_it_is_held(stack):
    rate, speed = 30.0, 3.0
    scenario = load_scenario("static-all")
    simulated = [f for f in SimulatedUser(scenario, rate).frames() if f.hands]
    label_of = {tuple(f.hands[0]["palm_position"]): f.label for f in simulated}
    last_palm = simulated[-1].hands[0]["palm_position"]
    stack.start_router()
    stack.wait_alive(["router"])
    frames, gestures = stack.collect("hands/frame"), stack.collect("gestures/static")
    stack.start_service("static-gesture")
    stack.wait_alive(["static-gesture"], timeout=60)
    stack.start_service("leap-bridge", "--scenario", "static-all", "--rate-hz", str(rate),
                        "--speed", str(speed), "--wait-for", "static-gesture")
    duration = SimulatedUser(scenario, rate).duration() / speed
    frames.wait(lambda m: m["hands"] and m["hands"][0]["palm_position"] == last_palm,
                timeout=duration + 60)
    time.sleep(1.0)  # the last gestures are on their way
    labels = {m["seq"]: label_of.get(tuple(m["hands"][0]["palm_position"]))
              for m in frames.items() if m["hands"]}
    by_hand = defaultdict(list)  # each episode's hand enters with a new id
    for m in gestures.items():
        by_hand[m["hand_id"]].append(m)
    assert len(by_hand) == len(STATIC_GESTURES), sorted(by_hand)
    for gesture, hand_id in zip(STATIC_GESTURES, sorted(by_hand), strict=True):
        episode = by_hand[hand_id]
        held = [winner(m) for m in episode if labels.get(m["seq"]) == gesture]
        assert len(held) >= 10, f"{gesture}: only {len(held)} held frames classified"
        assert held.count(gesture) > len(held) / 2, f"{gesture}: {Counter(held)}"
        # Over the whole episode, the held gesture is also what wins when anything does.
        poses = Counter(w for w in map(winner, episode) if w != "none")
        assert poses.most_common(1)[0][0] == gesture, f"{gesture}: {poses}"
        assert all(m["model"].startswith("static-bnn-") for m in episode)
    status = stack.status("static-gesture")
    assert status["counters"]["rejected"] == 0 and status["counters"]["errors"] == 0


def horns_frames(n=120, seed=0):
    """Hands showing the 'horns' sign (index and little finger up), which no model knows."""
    rng = np.random.default_rng(seed)
    base = gesture_mean("grab").to_vector()
    fist = HandPose.from_vector(base)
    shape = HandShape.default(side="right")
    hands = []
    for _ in range(n):
        straight = [0.0, 0.0, 0.0, 0.0]
        mcp, pip, dip = list(fist.mcp), list(fist.pip), list(fist.dip)
        for finger in (0, 3):  # index, pinky
            mcp[finger], pip[finger], dip[finger] = straight[:3]
        pose = HandPose(thumb=fist.thumb, mcp=tuple(mcp), spread=fist.spread, pip=tuple(pip),
                        dip=tuple(dip), roll=fist.roll, pitch=fist.pitch, yaw=fist.yaw)
        pose = HandPose.from_vector(pose.to_vector() + rng.normal(0, np.radians(3), 24))
        hands.append(build_hand(shape, pose, [0.0, 220.0, 0.0] + rng.normal(0, 2, 3)))
    return hands


def write_replay(path, hands, rate=60.0):
    from cbgo.recording import Recorder

    with Recorder(path) as recorder:
        for i, hand in enumerate(hands):
            t = 1000.0 + i / rate
            message = {"v": 1, "ts": t, "seq": i, "source": "simulated", "device": "horns",
                       "hands": [hand]}
            recorder.write("cbgo/hands/frame", wire.encode(message), int(t * 1e9))


def test_a_gesture_recorded_by_demonstration_is_served_without_a_code_change(stack, tmp_path):
    data = tmp_path / "data"
    env = {"CBGO_DATA_DIR": str(data)}
    replay = tmp_path / "horns.mcap"
    write_replay(replay, horns_frames())
    stack.start_router()
    # Polling off: the new model must arrive through the reload query of `cbgo gestures`.
    stack.start_service("static-gesture", "--watch-s", "0", env=env)
    stack.wait_alive(["router", "static-gesture"], timeout=60)
    stack.start_service("leap-bridge", "--source", "replay", str(replay), "--loop", env=env)
    stack.wait_alive(["leap-bridge"], timeout=60)
    before = stack.status("static-gesture")["model"]
    assert "horns" not in before["names"]
    result = subprocess.run(
        [*CLI, "gestures", "record", "horns", "--static", "--frames", "40", "--epochs", "30",
         "--timeout", "30", "--user", "tester"],
        env={**stack.env(), **env}, capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "static-gesture now serves static-bnn-" in result.stdout, result.stdout
    gestures = stack.collect("gestures/static")
    gestures.wait(lambda m: "horns" in m["names"], timeout=20)
    time.sleep(1.0)
    served = [m for m in gestures.items() if "horns" in m["names"]]
    wins = Counter(map(winner, served))
    assert wins["horns"] > 0.8 * len(served), wins
    status = stack.status("static-gesture")["model"]
    assert status["model"] != before["model"] and status["names"][-2:] == ["horns", "none"]
    recorded = list((data / "gestures" / "static").glob("*.npz"))
    assert [p.name for p in recorded] == ["horns.npz"]
    assert (data / "models" / "static-gesture.pt").is_file()
    listing = subprocess.run([*CLI, "gestures", "list"], env={**stack.env(), **env},
                             capture_output=True, text=True, timeout=60)
    assert "horns" in listing.stdout and "tester" in listing.stdout
