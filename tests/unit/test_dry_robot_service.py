"""dry-robot through the real runtime dispatch (FakeBus): acts, refusals, reset, render, stop."""

import json
import threading
import time

import pytest

from cbgo import keys, wire
from cbgo.errors import ConfigError
from cbgo.services.dry_robot.main import NO_RENDERER, DryRobot, DryRobotSettings
from cbgo.services.dry_robot.robot import SymbolicRobot
from cbgo.testing import FakeBus
from cbgo.world import Scene, paper_scene, random_scene, workspace_info

PAPER_SCENE = {  # the paper's example: cup1 in the gripper, drawer1 closed
    "objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.2], "size": 0.06,
         "full": False, "on": None, "inside": None},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11,
         "open": False},
    ],
    "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": False, "holding": "cup1"},
}


def act(bus, action, obj=None, **params):
    ok, reply = bus.query(keys.ROBOT_ACT, {"v": 1, "action": action, "object": obj,
                                           "params": params})
    assert ok, reply
    wire.validate(reply, wire.ROBOT_ACT_REPLY, "cbgo/robot/act")
    return reply


def objects(scene):
    return {o["name"]: o for o in scene["objects"]}


def published(bus, topic):
    return [m for t, m in bus.published if t == topic]


@pytest.fixture
def bus():
    bus = FakeBus(DryRobot(DryRobotSettings(action_s=0.0)))
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": PAPER_SCENE})
    assert ok and reply["ok"], reply
    yield bus
    bus.stop()


def test_a_feasible_act_applies_its_effects_and_publishes_the_scene_after(bus):
    before = len(published(bus, "scene/state"))
    reply = act(bus, "place")
    assert (reply["ok"], reply["error"]) == (True, None)
    assert reply["scene"]["robot"]["holding"] is None
    assert objects(reply["scene"])["cup1"]["position"][2] == pytest.approx(0.03)  # on the table
    scenes = published(bus, "scene/state")
    assert len(scenes) == before + 1 and scenes[-1] == reply["scene"]
    assert act(bus, "open", "drawer1")["ok"]
    assert act(bus, "pick_up", "cup1")["ok"]
    reply = act(bus, "put_into", "drawer1")
    assert reply["ok"] and objects(reply["scene"])["cup1"]["inside"] == "drawer1"
    assert objects(reply["scene"])["drawer1"]["contains"] == ["cup1"]
    assert bus.service.status_extra()["actions"] == {"actions": 4, "ok": 4, "refused": 0,
                                                     "stopped": 0, "inconsistent": 0}


def test_an_infeasible_act_is_refused_with_the_world_models_reason_and_counted(bus):
    scene_before = objects(published(bus, "scene/state")[-1])
    reply = act(bus, "put_into", "drawer1")
    assert not reply["ok"]
    assert reply["error"] == "refused: drawer1 is closed"
    assert reply["duration_s"] == 0.0
    assert objects(reply["scene"]) == scene_before  # nothing moved
    reply = act(bus, "open", "cup1")
    assert reply["error"] == "refused: open needs a drawer; cup1 is a cup"
    counts = bus.service.status_extra()["actions"]
    assert (counts["actions"], counts["refused"], counts["ok"]) == (2, 2, 0)
    ok, status = bus.query("status", None)
    assert ok and status["actions"]["refused"] == 2


def test_a_malformed_act_gets_an_error_reply_and_the_service_keeps_answering(bus):
    ok, reason = bus.query(keys.ROBOT_ACT, {"v": 1, "object": "cup1", "params": {}})
    assert not ok and reason.startswith("rejected: ") and "action" in reason
    assert bus.counters.rejected == 1
    assert act(bus, "place")["ok"]


def test_render_is_an_error_reply_that_says_why(bus):
    ok, reason = bus.query(keys.SIM_RENDER, {"v": 1, "camera": "front"})
    assert not ok
    assert reason == NO_RENDERER and reason.startswith("dry-robot has no renderer; ")


def test_reset_with_an_inconsistent_scene_is_refused_and_keeps_the_world(bus):
    bad = {"objects": [dict(PAPER_SCENE["objects"][0], on="drawer9")],
           "robot": {"holding": None}}
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": bad})
    assert ok and reply["ok"] is False and reply["scene"] is None
    assert reply["error"].startswith("inconsistent scene: ") and "drawer9" in reply["error"]
    assert objects(published(bus, "scene/state")[-1]).keys() == {"cup1", "drawer1"}
    assert act(bus, "place")["ok"]  # still the paper scene: cup1 is held


def test_reset_with_a_seed_loads_the_world_models_random_scene(bus):
    seq_before = published(bus, "scene/state")[-1]["seq"]
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "seed": 5})
    assert ok and reply["ok"]
    assert reply["scene"]["seq"] > seq_before  # one publisher, one counter
    assert reply["scene"]["objects"] == random_scene(5).to_dict()["objects"]
    assert published(bus, "scene/state")[-1] == reply["scene"]
    assert bus.service.status_extra()["scene_source"] == "seed 5"


def test_a_reset_without_seed_or_scene_goes_back_to_the_start_scene(tmp_path):
    path = tmp_path / "paper.json"
    path.write_text(json.dumps(PAPER_SCENE))
    bus = FakeBus(DryRobot(DryRobotSettings(action_s=0.0, scene=str(path))))
    assert act(bus, "place")["ok"]
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1})
    assert ok and reply["ok"] and reply["scene"]["robot"]["holding"] == "cup1"


def test_the_timer_publishes_both_states_valid_and_the_robot_state_says_it_is_symbolic(bus):
    out = bus.tick(1.0)
    topics = [t for t, _ in out]
    assert topics.count("scene/state") >= 1 and topics.count("robot/state") >= 1
    for topic, message in out:
        wire.validate(message, wire.SCHEMAS[topic], topic)
    state = next(m for t, m in out if t == "robot/state")
    assert state["tcp"] == PAPER_SCENE["robot"]["tcp"] and state["moving"] is False
    assert state["kinematics"] is False
    assert state["gripper_width"] == pytest.approx(0.06)  # closed on cup1


def _place_in_flight(bus):
    """Resets to the paper scene and starts ``place`` on a thread; returns once it moves."""
    bus.query(keys.SIM_RESET, {"v": 1, "scene": PAPER_SCENE})
    replies = []
    worker = threading.Thread(target=lambda: replies.append(bus.query(
        keys.ROBOT_ACT, {"v": 1, "action": "place", "object": None, "params": {}})))
    worker.start()
    deadline = time.monotonic() + 10  # a bound on waiting, not a measurement
    while not any(m["moving"] for m in published(bus, "robot/state")):
        assert time.monotonic() < deadline, "the action never started"
        time.sleep(0.01)
    return worker, replies


def test_stop_aborts_the_action_in_flight_without_effect():
    bus = FakeBus(DryRobot(DryRobotSettings(action_s=60.0)))
    worker, replies = _place_in_flight(bus)
    assert published(bus, "robot/state")[-1]["action"] == "place"
    bus.feed_raw(keys.ROBOT_STOP, b"not even msgpack")  # any payload stops
    worker.join(10)
    assert not worker.is_alive(), "the 60 s action was not aborted"
    (ok, reply), = replies
    assert ok and (reply["ok"], reply["error"]) == (False, "stopped")
    assert reply["scene"]["robot"]["holding"] == "cup1"  # the place never happened
    assert published(bus, "robot/state")[-1]["moving"] is False
    extra = bus.service.status_extra()
    assert extra["stops"] == 1 and extra["actions"]["stopped"] == 1


def test_a_stop_between_actions_does_not_stop_the_next_one(bus):
    bus.feed_raw(keys.ROBOT_STOP, wire.encode({"v": 1, "ts": time.time(), "reason": "x"}))
    assert act(bus, "place")["ok"]


def test_settings_refuse_what_cannot_work(tmp_path):
    with pytest.raises(ConfigError, match="action_s"):
        DryRobotSettings(action_s=-1)
    with pytest.raises(ConfigError, match="state_rate_hz"):
        DryRobotSettings(state_rate_hz=0)
    with pytest.raises(ConfigError, match="does not exist"):
        DryRobotSettings(scene=str(tmp_path / "missing.json"))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"objects": [dict(PAPER_SCENE["objects"][0], inside="cup1")]}))
    with pytest.raises(ConfigError, match="cannot load the start scene"):
        FakeBus(DryRobot(DryRobotSettings(scene=str(bad))))


def test_the_robot_class_executes_at_once_and_never_mutates_the_scene_it_was_given():
    scene = Scene.from_dict(PAPER_SCENE)
    robot = SymbolicRobot(scene)
    reply = robot.act("place", None, {}, duration_s=0.3)
    assert reply["ok"] and reply["duration_s"] == 0.3
    assert robot.scene.robot.holding is None and scene.robot.holding == "cup1"
    assert robot.refusal("place", None, {}) == "refused: the gripper holds nothing"
    assert robot.gripper_width() == 0.08  # open after letting go


def test_reset_with_an_object_off_the_table_area_is_refused_with_where_it_is_and_the_workspace(
        bus):
    far = {"objects": [PAPER_SCENE["objects"][0],
                       dict(PAPER_SCENE["objects"][1], position=[0.6, 0.3, 0.055])],
           "robot": PAPER_SCENE["robot"]}
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": far})
    assert ok and reply["ok"] is False and reply["scene"] is None
    assert reply["error"].startswith("outside the workspace: drawer1 at (0.60, 0.30)")
    assert "x 0.30..0.70, y -0.20..0.20" in reply["error"]
    assert act(bus, "place")["ok"]  # the world stayed the paper scene: cup1 is held


def test_reset_takes_a_drawer_in_the_nearest_row_and_the_papers_smallest_cup(bus):
    near = {"objects": [dict(PAPER_SCENE["objects"][0], size=0.03),
                        dict(PAPER_SCENE["objects"][1], position=[0.32, -0.06, 0.055])],
            "robot": PAPER_SCENE["robot"]}
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": near})
    assert ok and reply["ok"], reply
    assert act(bus, "open", "drawer1")["ok"]
    reply = act(bus, "put_into", "drawer1")
    assert reply["ok"], reply
    cup = objects(reply["scene"])["cup1"]
    # it opens away from the robot (+x): its tray, and the cup on it, come out behind it
    assert cup["inside"] == "drawer1" and cup["position"][0] == pytest.approx(0.32 + 0.08)


@pytest.mark.parametrize("seed", range(40))
def test_reset_takes_every_scene_of_the_papers_distribution(bus, seed):
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": paper_scene(seed).to_dict()})
    assert ok and reply["ok"], reply


def test_info_answers_the_workspace_of_the_world_model(bus):
    ok, reply = bus.query(keys.SIM_INFO, {"v": 1})
    assert ok, reply
    wire.validate(reply, wire.SIM_INFO_REPLY, "cbgo/sim/info")
    assert reply["robot"] == "dry-robot" and reply["workspace"] == workspace_info()
    assert reply["workspace"]["table_area"] == {"x": [0.3, 0.7], "y": [-0.2, 0.2]}


class _Contradicting(SymbolicRobot):
    """A scripted fault: a stopped place leaves cup1 held and inside drawer1 at once."""

    def act_reply(self, ok, error, duration_s=0.0):
        if error == "stopped":
            self.scene.get("cup1").inside = "drawer1"
        return super().act_reply(ok, error, duration_s)


class _FaultyDryRobot(DryRobot):
    def new_robot(self, scene):
        return _Contradicting(scene)


def test_a_failure_that_leaves_a_contradiction_names_it_in_the_reply_and_counts_it():
    bus = FakeBus(_FaultyDryRobot(DryRobotSettings(action_s=60.0)))
    worker, replies = _place_in_flight(bus)
    bus.feed_raw(keys.ROBOT_STOP, b"")
    worker.join(10)
    (ok, reply), = replies
    assert ok and reply["ok"] is False
    assert reply["error"].startswith("stopped; the scene after it is inconsistent: ")
    assert "the robot holds cup1, which also rests on or inside another object" in reply["error"]
    assert bus.service.status_extra()["actions"]["inconsistent"] == 1
