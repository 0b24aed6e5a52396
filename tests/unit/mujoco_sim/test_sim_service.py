"""The mujoco-sim service through the real runtime dispatch (FakeBus): queries, streams, stop."""

import threading
import time

import pytest

from cbgo import keys, wire
from cbgo.services.mujoco_sim.main import MujocoSim, MujocoSimSettings
from cbgo.testing import FakeBus


@pytest.fixture
def bus():
    bus = FakeBus(MujocoSim(MujocoSimSettings(seed=1)))
    yield bus
    bus.stop()


def _reset(bus, scene):
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": scene})
    assert ok and reply["ok"], reply
    return reply


def test_reset_with_a_seed_replies_and_publishes_the_settled_scene(bus):
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "seed": 4})
    assert ok and reply["ok"] and reply["error"] is None
    published = [m for topic, m in bus.published if topic == "scene/state"]
    assert published and published[-1]["objects"] == reply["scene"]["objects"]
    assert bus.service.status_extra()["scene_source"] == "seed 4"


def test_an_act_replies_with_the_outcome_and_the_scene_after(bus, fixed_scene):
    _reset(bus, fixed_scene)
    ok, reply = bus.query(keys.ROBOT_ACT, {"v": 1, "action": "pick_up", "object": "cup1",
                                           "params": {}})
    assert ok and reply["ok"] and reply["error"] is None and reply["duration_s"] > 1.0
    assert reply["scene"]["robot"]["holding"] == "cup1"
    ok, reply = bus.query(keys.ROBOT_ACT, {"v": 1, "action": "open", "object": "box1",
                                           "params": {}})
    assert ok and not reply["ok"]
    assert reply["error"] == "refused: open needs a drawer; box1 is a box"
    assert reply["duration_s"] == 0.0


def test_a_malformed_act_gets_an_error_reply(bus):
    ok, reason = bus.query(keys.ROBOT_ACT, {"v": 1, "object": "cup1", "params": {}})
    assert not ok and reason.startswith("rejected: ") and "action" in reason
    assert bus.counters.rejected == 1


def test_state_streams_come_from_the_timers(bus):
    out = bus.tick(1.0)
    topics = {topic for topic, _ in out}
    assert {"scene/state", "robot/state"} <= topics
    for topic, message in out:
        wire.validate(message, wire.SCHEMAS[topic], topic)


def test_stop_halts_the_running_action(fixed_scene):
    bus = FakeBus(MujocoSim(MujocoSimSettings(realtime=1.0)))  # paced: the action takes seconds
    _reset(bus, fixed_scene)
    replies = []
    worker = threading.Thread(target=lambda: replies.append(bus.query(
        keys.ROBOT_ACT, {"v": 1, "action": "pick_up", "object": "cup1", "params": {}})))
    t0 = time.monotonic()
    worker.start()
    time.sleep(0.5)
    bus.feed_raw(keys.ROBOT_STOP, b"not even msgpack")  # any payload stops
    worker.join(10)
    assert time.monotonic() - t0 < 2.0
    (ok, reply), = replies
    assert ok and not reply["ok"] and reply["error"] == "stopped"
    robot_states = [m for t, m in bus.published if t == "robot/state"]
    assert any(m["action"] == "pick_up" for m in robot_states)  # announced while it ran
    assert robot_states[-1]["moving"] is False  # and after the stop, the arm holds still
    bus.stop()


def test_render_replies_a_png_or_says_why_not(bus):
    ok, reply = bus.query(keys.SIM_RENDER, {"v": 1, "camera": "nowhere"})
    assert not ok and "unknown camera 'nowhere'" in reply
    ok, reply = bus.query(keys.SIM_RENDER, {"v": 1, "width": 64, "height": 48})
    if not ok and "cannot render" in reply:
        pytest.skip(f"no headless OpenGL here: {reply}")
    assert ok and reply["ok"] and reply["png"].startswith(b"\x89PNG\r\n\x1a\n")
