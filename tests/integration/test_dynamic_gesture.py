"""dynamic-gesture through real processes: leap-bridge plays simulated strokes, the right
gesture wins; a still hand gives no gesture; a gesture taught with `cbgo gestures record` is
published after the reload."""

import sys
import time

import numpy as np
import pytest

from cbgo import wire
from cbgo.hands.model import HandShape, build_hand, neutral_pose
from cbgo.simuser.scenario import load_scenario
from cbgo.testing import Stack

CLI = [sys.executable, "-m", "cbgo.cli.main"]


@pytest.fixture(scope="module")
def running(tmp_path_factory):
    """Router, leap-bridge (idle simulated user) and dynamic-gesture, shared by the tests."""
    tmp = tmp_path_factory.mktemp("dynamic")
    with Stack(tmp) as stack:
        stack.start_router()
        stack.start_service("leap-bridge")
        stack.start_service("dynamic-gesture", env={"CBGO_DATA_DIR": str(tmp / "data")})
        stack.wait_alive(["router", "leap-bridge", "dynamic-gesture"], timeout=60)
        yield stack, tmp / "data"


def play(stack, scenario):
    (ok, reply), = stack.query("cbgo/@ctl/leap-bridge/play", scenario, timeout=10)
    assert ok, reply
    return reply["duration_s"]


def finals(messages):
    """The last window of each stroke (windows of one stroke share their start)."""
    last = {}
    for msg in messages:
        last[(msg["hand_id"], msg["window"][0])] = msg
    return list(last.values())


def winner(msg):
    return msg["names"][int(np.argmax(msg["probs"]))]


def test_each_simulated_stroke_is_published_with_its_gesture_winning(running):
    stack, _ = running
    out = stack.collect("gestures/dynamic")
    time.sleep(0.3)
    time.sleep(play(stack, {"scenario": "dynamic-all"}) + 1.5)
    messages = out.items()
    for msg in messages:
        wire.validate(msg, wire.GESTURES_DYNAMIC, "cbgo/gestures/dynamic")
    expected = [s.gesture for e in load_scenario("dynamic-all").episodes for s in e.gestures]
    won = [winner(m) for m in finals(messages) if winner(m) != "none"]
    assert won == expected, [(winner(m), m["window"]) for m in finals(messages)]
    # a final message answers for its stroke: never less sure than one published before it
    for last in (m for m in messages if m.get("final")):
        stroke = [m for m in messages if m["hand_id"] == last["hand_id"]
                  and m["window"][0] == last["window"][0] and not m.get("final")]
        assert all(gesture_p(last) >= gesture_p(m) for m in stroke), (last, stroke)


def gesture_p(msg):
    """The probability of the message's most probable gesture (`none` left out)."""
    return max(p for n, p in zip(msg["names"], msg["probs"], strict=True)
               if n != wire.NO_GESTURE)


def test_a_hand_held_still_gives_no_gesture(running):
    stack, _ = running
    out = stack.collect("gestures/dynamic")
    time.sleep(0.3)
    time.sleep(play(stack, {"scenario": "still"}) + 1.0)
    assert [winner(m) for m in finals(out.items()) if winner(m) != "none"] == []


def stroke_frames(segments, start, rate=60.0):
    """Palm positions (mm) of a palm-down hand: ('hold', s) or ('move', s, dxyz), min jerk."""
    pos, out = np.asarray(start, float), []
    for seg in segments:
        n = max(1, int(seg[1] * rate))
        delta = np.asarray(seg[2], float) if seg[0] == "move" else np.zeros(3)
        for i in range(1, n + 1):
            s = i / n
            out.append(pos + (s**3 * (10 - 15 * s + 6 * s**2)) * delta)
        pos = pos + delta
    return out


@pytest.fixture(scope="module")
def alone(tmp_path_factory):
    """Router and dynamic-gesture only: the test is the one source of hand frames."""
    tmp = tmp_path_factory.mktemp("dynamic-alone")
    with Stack(tmp) as stack:
        stack.start_router()
        stack.start_service("dynamic-gesture", env={"CBGO_DATA_DIR": str(tmp / "data")})
        stack.wait_alive(["router", "dynamic-gesture"], timeout=60)
        yield stack


def test_a_swipe_from_off_centre_is_heard_and_its_return_is_not(alone):
    stack = alone
    out = stack.collect("gestures/dynamic")
    pub = stack.publisher("hands/frame")
    shape = HandShape.default()
    # Far from the centre, no rest: a swipe right, straight back a little more slowly, a
    # pause, then a swipe up (its last window tells that everything before was handled).
    palms = stroke_frames([("hold", 0.15), ("move", 0.45, (180, 0, 0)), ("move", 0.6, (-180, 0, 0)),
                           ("hold", 0.6), ("move", 0.45, (0, 170, 0)), ("hold", 0.6)],
                          start=(-140.0, 300.0, 60.0))
    t0 = time.time()
    for i, palm in enumerate(palms):
        time.sleep(max(0.0, t0 + i / 60.0 - time.time()))
        hand = build_hand(shape, neutral_pose(), palm, hand_id=7)
        pub.put(wire.encode({"v": wire.SCHEMA_VERSION, "ts": time.time(), "seq": i,
                         "source": "replay", "device": "test", "hands": [hand]}))
    up = out.first(lambda m: m["hand_id"] == 7 and winner(m) == "swipe_up"
                   and m["window"][1] - m["window"][0] > 0.3, timeout=20)
    heard = [winner(m) for m in finals(out.items())
             if m["hand_id"] == 7 and m["window"][0] < up["window"][0] and winner(m) != "none"]
    assert heard == ["swipe_right"], heard


def test_a_gesture_taught_with_cbgo_gestures_record_is_published_after_the_reload(running):
    stack, data = running
    recorder = stack.spawn("record", [*CLI, "gestures", "record", "lift", "--dynamic",
                                      "--takes", "3", "--user", "tester", "--timeout", "60"],
                           env={"CBGO_DATA_DIR": str(data)})
    recorder.wait_for_line("recording 3 take", timeout=30)  # subscribed: takes can start
    play(stack, {"episodes": [{"gestures": ["swipe_up"], "pause_s": 0.3}] * 3, "seed": 5})
    assert recorder.wait(60) == 0, recorder.log()
    assert "dynamic-gesture reloaded" in recorder.log()
    assert (data / "gestures" / "dynamic" / "lift.json").exists()
    out = stack.collect("gestures/dynamic")
    time.sleep(0.3)
    time.sleep(play(stack, {"episodes": [{"gestures": ["swipe_up"], "pause_s": 0.3}]}) + 1.0)
    last = finals(out.items())
    assert last and all("lift" in m["names"] for m in last)
    won = [winner(m) for m in last if winner(m) != "none"]
    assert len(won) == 1 and won[0] in ("lift", "swipe_up"), [winner(m) for m in last]
    status = stack.status("dynamic-gesture")
    assert "lift" in [g["name"] for g in status["gestures"]]
