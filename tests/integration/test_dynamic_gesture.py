"""dynamic-gesture through real processes: leap-bridge plays simulated strokes, the right
gesture wins; a still hand gives no gesture; a gesture taught with `cbgo gestures record` is
published after the reload."""

import sys
import time

import numpy as np
import pytest

from cbgo import wire
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


def test_a_hand_held_still_gives_no_gesture(running):
    stack, _ = running
    out = stack.collect("gestures/dynamic")
    time.sleep(0.3)
    time.sleep(play(stack, {"scenario": "still"}) + 1.0)
    assert [winner(m) for m in finals(out.items()) if winner(m) != "none"] == []


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
