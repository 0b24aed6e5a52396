"""Scenes: built from the world model, they match their symbolic description after settling;
observing and loading again gives the same scene."""

import numpy as np
import pytest

from cbgo import wire
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.world import Scene, random_scene


@pytest.mark.parametrize("seed", range(8))
def test_a_random_scene_matches_its_symbolic_description_after_settling(seed):
    symbolic = random_scene(seed)
    loaded = scenes.load(symbolic)
    assert scenes.mismatches(loaded.sim, symbolic) == []
    message = observe.scene_state(loaded.sim, 1)
    wire.validate(message, wire.SCENE_STATE, "cbgo/scene/state")
    seen = Scene.from_dict(message)
    assert seen.problems() == []
    assert seen.robot.holding == symbolic.robot.holding


def test_the_fixed_scene_settles_as_described(fixed_scene):
    loaded = scenes.load(fixed_scene)
    objects = {o["name"]: o for o in observe.observe_objects(loaded.sim)}
    assert objects["cup1"]["full"] and not objects["cup2"]["full"]
    assert not objects["drawer1"]["open"] and objects["drawer1"]["opening"] == 0.0
    for spec in fixed_scene["objects"]:
        got = objects[spec["name"]]["position"]
        assert np.linalg.norm(np.subtract(got, spec["position"])) < 0.005, spec["name"]
    assert loaded.compile_s < 5.0


def test_stacks_drawers_and_the_gripper_are_observed_from_the_physics(scene_file):
    scene = scene_file("fixed")
    names = {o["name"]: o for o in scene["objects"]}
    names["box1"]["on"] = "box2"
    names["cup2"]["inside"] = "drawer1"
    names["drawer1"]["open"] = True
    scene["robot"] = {"tcp": [0.44, -0.06, 0.3], "gripper_open": False, "holding": "cup1"}
    loaded = scenes.load(scene)
    got = {o["name"]: o for o in observe.observe_objects(loaded.sim)}
    assert got["box1"]["on"] == "box2"
    assert got["cup2"]["inside"] == "drawer1" and got["drawer1"]["contains"] == ["cup2"]
    assert got["drawer1"]["open"] and got["drawer1"]["opening"] > 0.95
    robot = observe.observe_robot(loaded.sim)
    assert robot["holding"] == "cup1" and not robot["gripper_open"]
    assert np.linalg.norm(np.subtract(robot["tcp"], [0.44, -0.06, 0.3])) < 0.005


@pytest.mark.parametrize("seed", [3, 11])
def test_observing_and_loading_again_round_trips(seed):
    first = scenes.load(random_scene(seed))
    body = observe.scene_state(first.sim, 1)
    second = scenes.load({"objects": body["objects"], "robot": body["robot"]})
    again = observe.scene_state(second.sim, 2)
    for a, b in zip(body["objects"], again["objects"], strict=True):
        assert a["name"] == b["name"]
        for key in ("on", "inside", "full", "open", "contains"):
            assert a.get(key) == b.get(key), (a["name"], key)
        assert np.linalg.norm(np.subtract(a["position"], b["position"])) < 0.02, a["name"]
    assert body["robot"]["holding"] == again["robot"]["holding"]


def test_an_inconsistent_scene_is_refused_with_the_broken_rule(fixed_scene):
    fixed_scene["objects"][0]["on"] = "cup2"  # nothing can stand on a cup
    with pytest.raises(scenes.SceneError, match="only boxes and drawers carry objects"):
        scenes.load(fixed_scene)
