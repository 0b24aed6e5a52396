"""Every action on the fixed scene succeeds and its outcome shows in the physics; refusals and
stop leave the robot where it was."""

import numpy as np
import pytest

from cbgo import wire
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.world import DEFAULT_GRID


def _objects(scene):
    return {o["name"]: o for o in scene["objects"]}


def _step(run, index):
    (action, obj, _), outcome, scene, before, after = run[index]
    assert outcome.ok, f"{action}({obj}): {outcome.error}"
    assert outcome.error is None and not outcome.refused and outcome.sim_s > 0
    wire.validate(scene, wire.SCENE_STATE, "cbgo/scene/state")
    return _objects(scene), scene["robot"], np.array(before), np.array(after)


def test_every_action_of_the_sequence_succeeds(sequence_run, sequence):
    failed = [f"{a}({o}): {out.error}" for (a, o, _), out, *_ in sequence_run if not out.ok]
    assert not failed
    assert {a for a, _, _ in sequence} == set(wire.ACTIONS)


def test_open_pulls_the_drawer_out_beyond_three_quarters(sequence_run):
    objects, robot, *_ = _step(sequence_run, 0)
    assert objects["drawer1"]["open"] and objects["drawer1"]["opening"] >= 0.75
    assert robot["holding"] is None


def test_pick_up_lifts_the_cup_between_both_fingers(sequence_run):
    objects, robot, *_ = _step(sequence_run, 1)
    assert robot["holding"] == "cup1" and not robot["gripper_open"]
    assert objects["cup1"]["position"][2] > 0.03 + 0.04


@pytest.mark.parametrize("index,delta", [(2, (0, 0, 1)), (3, (0, 1, 0)), (4, (0, 0, -1)),
                                         (5, (0, -1, 0))])
def test_moves_carry_the_cup_one_grid_cell(sequence_run, index, delta):
    objects, robot, before, after = _step(sequence_run, index)
    cell = DEFAULT_GRID.cell_of(before)  # a move goes to the neighbour of the nearest cell
    goal = np.array(DEFAULT_GRID.position(np.add(cell, delta)))
    assert np.linalg.norm(after - goal) < 0.01
    assert np.dot(after - before, delta) > 0.05
    assert robot["holding"] == "cup1"
    assert np.linalg.norm(np.subtract(objects["cup1"]["position"], after)) < 0.03


def test_pour_empties_the_held_cup_into_the_other(sequence_run):
    objects, robot, *_ = _step(sequence_run, 6)
    assert objects["cup1"]["full"] is False and objects["cup2"]["full"] is True
    assert robot["holding"] == "cup1"


def test_put_into_leaves_the_cup_on_the_drawers_floor(sequence_run):
    objects, robot, *_ = _step(sequence_run, 7)
    assert objects["cup1"]["inside"] == "drawer1" and objects["drawer1"]["contains"] == ["cup1"]
    assert robot["holding"] is None


def test_close_pushes_the_drawer_in_with_the_cup(sequence_run):
    objects, *_ = _step(sequence_run, 8)
    assert not objects["drawer1"]["open"] and objects["drawer1"]["opening"] <= 0.05
    assert objects["cup1"]["inside"] == "drawer1"


def test_put_on_stacks_the_box_centred_on_the_other(sequence_run):
    _step(sequence_run, 9)
    objects, robot, *_ = _step(sequence_run, 10)
    assert objects["box1"]["on"] == "box2" and robot["holding"] is None
    off = np.subtract(objects["box1"]["position"][:2], objects["box2"]["position"][:2])
    assert np.linalg.norm(off) < 0.01


def test_place_puts_the_cup_down_on_a_free_cell(sequence_run):
    _step(sequence_run, 11)
    objects, robot, *_ = _step(sequence_run, 12)
    cup = objects["cup2"]
    assert cup["on"] is None and cup["inside"] is None and robot["holding"] is None
    column = DEFAULT_GRID.column_of(cup["position"])
    assert np.linalg.norm(np.subtract(cup["position"][:2], DEFAULT_GRID.column_xy(column))) < 0.02


def test_an_infeasible_action_is_refused_without_moving(fixed_scene):
    loaded = scenes.load(fixed_scene)
    robot = Robot(loaded.sim)
    q, t = loaded.sim.q.copy(), loaded.sim.time
    outcome = robot.execute("put_into", "drawer1", {})
    assert not outcome.ok and outcome.refused
    assert outcome.error.startswith("refused: ") and "the gripper holds nothing" in outcome.error
    assert loaded.sim.time == t and np.array_equal(loaded.sim.q, q)
    outcome = robot.execute("fly", "cup1", {})
    assert outcome.refused and "unknown action 'fly'" in outcome.error


def test_a_move_into_an_occupied_cell_is_refused_with_what_is_there(fixed_scene):
    scene = fixed_scene  # the robot holds cup2 one cell above cup1
    scene["robot"] = {"tcp": list(DEFAULT_GRID.position((1, 0, 1))), "gripper_open": False,
                      "holding": "cup2"}
    loaded = scenes.load(scene)
    q = loaded.sim.q.copy()
    outcome = Robot(loaded.sim).execute("move_down", None, {})
    assert outcome.refused
    assert outcome.error == ("refused: the gripper does not fit at the goal cell [1, 0, 0]: "
                             "cup1 is there")
    assert np.array_equal(loaded.sim.q, q)


def test_stop_ends_the_action_at_once_and_the_arm_holds_its_position(fixed_scene):
    loaded = scenes.load(fixed_scene)
    sim = loaded.sim
    ticks = []

    def on_tick(s):
        ticks.append(s.time)
        if len(ticks) == 15:
            s.stop.set()  # what cbgo/robot/stop does from Zenoh's thread

    sim.on_tick = on_tick
    outcome = Robot(sim).execute("pick_up", "cup1", {})
    assert not outcome.ok and outcome.error == "stopped"
    assert len(ticks) == 15  # not a single control tick after the stop
    held = sim.q.copy()
    sim.settle(0.5)
    assert np.abs(sim.q - held).max() < 0.01
    assert np.abs(sim.q_cmd - held).max() < 1e-9
    assert observe.observe_robot(sim)["holding"] is None


def test_the_liquid_stays_in_a_cup_that_is_not_tilted(fixed_scene):
    loaded = scenes.load(fixed_scene)
    loaded.sim.settle(1.0)
    assert loaded.sim.full == {"cup1": True, "cup2": False} and not loaded.sim.pours
