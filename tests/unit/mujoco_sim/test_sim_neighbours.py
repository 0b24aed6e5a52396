"""Drawers and grasps beside tall neighbours: layouts `cbgo bench sim` found failing."""

import numpy as np

from cbgo import world
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.world import Robot as RobotState
from cbgo.world import Scene, SceneObject


def _scene(*objects, tcp=(0.56, 0.18, 0.36), on=None) -> Scene:
    scene = Scene([SceneObject(n, t, (x, y, s / 2), s, open=o) for n, t, x, y, s, o in objects],
                  RobotState(tcp, gripper_open=True, holding=None))
    for top, support in (on or {}).items():
        scene.get(top).on = support
    scene.settle()
    assert world.reset_refusal(scene) is None
    return scene


def _run(scene: Scene, action: str, obj: str):
    sim = scenes.load(scene).sim
    outcome = Robot(sim).execute(action, obj, {})
    assert world.check_consistent(observe.scene_state(sim, 0)) == []
    return sim, outcome


def test_a_drawer_closes_beside_a_taller_cabinet():
    # level with the knob, the hand's underside (0.107 m) grazed the neighbour's top (0.108 m)
    # and the drawer stayed 8 % open
    scene = _scene(("drawer1", "drawer", 0.562, -0.182, 0.108, False),
                   ("drawer2", "drawer", 0.562, -0.058, 0.097, True))
    _, outcome = _run(scene, "close", "drawer2")
    assert outcome.ok, outcome.error


def test_a_drawer_opens_beside_a_tower():
    scene = _scene(("drawer1", "drawer", 0.554, -0.173, 0.1, False),
                   ("box1", "box", 0.459, -0.067, 0.046, False),
                   ("cup1", "cup", 0.459, -0.067, 0.066, False), tcp=(0.68, -0.18, 0.26),
                   on={"cup1": "box1"})
    _, outcome = _run(scene, "open", "drawer1")
    assert outcome.ok, outcome.error


def test_a_cup_cornered_by_two_cabinets_is_refused_and_nothing_moves():
    # the hand's underside is 25 mm above the cup's top, under both cabinets' tops, at every yaw
    scene = _scene(("drawer1", "drawer", 0.561, 0.062, 0.102, True),
                   ("drawer2", "drawer", 0.682, -0.056, 0.092, True),
                   ("cup1", "cup", 0.66, 0.037, 0.051, False), tcp=(0.68, 0.18, 0.26))
    sim = scenes.load(scene).sim
    before, tcp = sim.pose("cup1")[0].copy(), sim.tcp()[0].copy()
    outcome = Robot(sim).execute("pick_up", "cup1", {})
    assert outcome.refused and "no room to grasp cup1" in outcome.error
    assert np.linalg.norm(sim.pose("cup1")[0] - before) < 1e-3
    assert np.linalg.norm(sim.tcp()[0] - tcp) < 1e-3


def test_the_world_model_and_the_simulator_agree_on_room_at_a_moves_goal():
    # move_down from (2, 3, 1) to (2, 3, 0): beside drawer1, whose top is above the hand there
    scene = _scene(("drawer1", "drawer", 0.56, 0.06, 0.11, False),
                   ("cup1", "cup", 0.44, 0.18, 0.06, False), tcp=(0.56, 0.18, 0.16))
    assert world.failures("move_down", None, scene)[0].code == "no_room"
    sim, outcome = _run(scene, "move_down", None)
    assert outcome.refused and "drawer1 is there" in outcome.error
    assert world.failures("move_up", None, scene) == []
