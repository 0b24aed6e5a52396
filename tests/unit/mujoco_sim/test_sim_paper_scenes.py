"""The paper's scene distribution in real MuJoCo: a drawer in every column of the grid, cups
from 0.03 m, and the paper's random scenes accepted at reset as they are described."""

import pytest

from cbgo import world
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.world import DEFAULT_GRID, drawer_direction, paper_scene

SMALLEST_CUP = 0.03  # m, the paper's smallest cup


def _scene(objects, tcp=(0.44, 0.0, 0.36), holding=None):
    return {"objects": objects,
            "robot": {"tcp": list(tcp), "gripper_open": holding is None, "holding": holding}}


def _cup(name, column, size=SMALLEST_CUP, **fields):
    x, y = DEFAULT_GRID.column_xy(column)
    return {"name": name, "type": "cup", "position": [x, y, size / 2], "size": size, **fields}


def _act(robot, action, obj=None):
    outcome = robot.execute(action, obj, {})
    scene = observe.scene_state(robot.sim, 0)
    assert outcome.ok, (action, obj, outcome.error)
    assert world.check_consistent(scene) == [], (action, obj)
    return {o["name"]: o for o in scene["objects"]}


@pytest.mark.parametrize("column", list(DEFAULT_GRID.columns()))
def test_a_drawer_in_every_column_is_accepted_opened_filled_with_a_small_cup_and_closed(column):
    x, y = DEFAULT_GRID.column_xy(column)
    way = drawer_direction(x)
    cup_column = (3 - column[0], 3 - column[1])  # another row, clear of the tray
    drawer = {"name": "drawer1", "type": "drawer", "position": [x, y, 0.055], "size": 0.11}
    loaded = scenes.load(_scene([drawer, _cup("cup1", cup_column)]))
    assert scenes.mismatches(loaded.sim, loaded.scene) == []
    robot = Robot(loaded.sim)
    opened = _act(robot, "open", "drawer1")
    item = loaded.sim.items["drawer1"]
    tray_out = loaded.sim.data.xpos[item.body][0] - loaded.sim.data.xpos[item.cabinet][0]
    assert opened["drawer1"]["open"] and way * tray_out > 0.06  # out on the side it opens to
    _act(robot, "pick_up", "cup1")
    filled = _act(robot, "put_into", "drawer1")
    assert filled["cup1"]["inside"] == "drawer1" and filled["drawer1"]["contains"] == ["cup1"]
    closed = _act(robot, "close", "drawer1")
    assert not closed["drawer1"]["open"] and closed["cup1"]["inside"] == "drawer1"
    assert closed["cup1"]["position"][0] == pytest.approx(x, abs=0.03)  # rode in on the tray


def test_the_smallest_cups_are_grasped_poured_from_and_into_stacked_and_placed():
    box = {"name": "box1", "type": "box", "position": [0.56, 0.18, 0.025], "size": 0.05}
    loaded = scenes.load(_scene([_cup("cup1", (1, 0), full=True), _cup("cup2", (2, 1)), box]))
    assert scenes.mismatches(loaded.sim, loaded.scene) == []
    robot = Robot(loaded.sim)
    held = _act(robot, "pick_up", "cup1")
    assert robot.sim.holding == "cup1" and held["cup1"]["full"]
    poured = _act(robot, "pour", "cup2")
    assert poured["cup2"]["full"] and not poured["cup1"]["full"]
    stacked = _act(robot, "put_on", "box1")
    assert stacked["cup1"]["on"] == "box1"
    _act(robot, "pick_up", "cup2")
    placed = _act(robot, "place")
    assert placed["cup2"]["on"] is None and robot.sim.holding is None


@pytest.mark.parametrize("seed", range(24))
def test_the_papers_random_scenes_are_accepted_and_settle_as_described(seed):
    symbolic = paper_scene(seed)
    assert world.reset_refusal(symbolic) is None
    loaded = scenes.load(symbolic)
    assert scenes.mismatches(loaded.sim, loaded.scene) == []
    assert world.check_consistent(observe.scene_state(loaded.sim, 0)) == []
