"""The arm drawn from its joints: the Panda/FR3 kinematics, and the Foxglove robot entity."""

from __future__ import annotations

import jsonschema
import pytest

from cbgo import keys
from cbgo.examples import example
from cbgo.foxglove import scene as fx
from cbgo.foxglove.arm import link_points
from cbgo.foxglove.channels import foxglove_schema
from cbgo.foxglove.derive import DERIVED_TOPICS, SCENE_TOPIC, Deriver
from cbgo.registry import by_name

READY = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)


def test_the_ready_posture_puts_the_tcp_where_franka_reports_it():
    # libfranka's O_T_EE in the ready posture, the Franka Hand set as end effector
    assert link_points(READY)[-1] == pytest.approx((0.307, 0.0, 0.487), abs=0.002)
    stretched = link_points([0.0] * 7)  # upright, the hand pointing down from joint 7
    assert stretched[-2] == pytest.approx((0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107))
    assert stretched[-1] == pytest.approx((0.088, 0.0, 0.926 - 0.1034))
    with pytest.raises(ValueError, match="expected 7 joint angles"):
        link_points(READY[:6])


@pytest.mark.skipif(not by_name("mujoco-sim").exists(), reason="mujoco-sim is not installed")
def test_the_links_drawn_from_mujoco_sims_joints_end_at_the_tcp_it_reports():
    from cbgo.services.mujoco_sim.main import MujocoSim, MujocoSimSettings
    from cbgo.testing import FakeBus

    bus = FakeBus(MujocoSim(MujocoSimSettings(seed=1)))
    ok, reply = bus.query(keys.ROBOT_ACT, {"v": 1, "action": "move_down", "object": None,
                                           "params": {}})
    assert ok and reply["ok"], reply
    state = next(m for t, m in reversed(bus.tick(1.0)) if t == "robot/state")
    bus.stop()
    assert link_points(state["joints"])[-1] == pytest.approx(state["tcp"], abs=0.005)


def robot_of(deriver, suffix, message):
    return next(e for d in deriver.feed(suffix, message) if d.topic == SCENE_TOPIC
                for e in d.message["entities"] if e["id"] == "robot")


def test_the_robot_entity_draws_the_links_posed_by_the_last_robot_state():
    deriver = Deriver()
    bare = robot_of(deriver, "scene/state", example("scene/state", ts=1.0))
    assert len(bare["lines"][0]["points"]) == 2  # no joints yet: base to TCP
    state = {**example("robot/state", ts=2.0), "joints": list(READY), "tcp": [0.307, 0, 0.487]}
    robot = robot_of(deriver, "robot/state", state)
    points = [(p["x"], p["y"], p["z"]) for p in robot["lines"][0]["points"]]
    assert len(points) == 2 * 9 and points[-1] == pytest.approx((0.307, 0.0, 0.487), abs=0.002)
    assert robot["lines"][0]["scale_invariant"] is False  # links in metres, not pixels
    assert {"key": "joints", "value": "measured"} in robot["metadata"]
    again = robot_of(deriver, "scene/state", example("scene/state", ts=3.0))
    assert again["lines"] == robot["lines"]  # a scene update keeps the measured arm
    for entity in (bare, robot, again):
        jsonschema.validate({"deletions": [], "entities": [entity]},
                            foxglove_schema(DERIVED_TOPICS[SCENE_TOPIC]))


def test_a_robot_without_kinematics_is_drawn_faded_and_labelled_nominal():
    state = {**example("robot/state", ts=2.0), "joints": list(READY), "kinematics": False}
    robot = robot_of(Deriver(), "robot/state", state)
    assert robot["lines"][0]["color"] == fx.colour(fx.ARM_NOMINAL)
    assert any("nominal pose" in t["text"] for t in robot["texts"])
    assert {"key": "joints", "value": "nominal"} in robot["metadata"]
