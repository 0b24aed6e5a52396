"""The planner's repairs carried out in the real physics, an object in every column.

A closed drawer in any column the workspace accepts: ``put_into(drawer1)`` of a cup standing in
the farthest column is repaired to open, pick_up, put_into, and each step succeeds in MuJoCo
with a consistent scene after it; a drawer the workspace does not accept is refused at reset
with the reason. A box in every column: ``put_on(box1)`` of that cup is repaired to pick_up,
put_on.
"""

import time

import pytest

from cbgo import world
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.services.planner.sequence import predict
from cbgo.world import Scene
from cbgo.world.grid import DEFAULT_GRID

COLUMNS = list(DEFAULT_GRID.columns())
ROBOT = {"tcp": [0.5, 0.0, 0.3], "gripper_open": True, "holding": None}


def _intent(action, obj, source):
    return {"v": 1, "ts": time.time(), "episode": "ep-1", "action": action, "object": obj,
            "params": {"source": source}, "p_action": {action: 0.9}, "p_object": {obj: 0.9},
            "confidence": 0.9, "status": "accepted", "reason": "", "model": "test"}


def _scene_with(target: dict, column) -> dict:
    """`target` in `column`, an empty cup in the column farthest from it."""
    x, y = DEFAULT_GRID.column_xy(column)
    fx, fy = DEFAULT_GRID.column_xy(max(COLUMNS, key=lambda c: (
        (DEFAULT_GRID.column_xy(c)[0] - x) ** 2 + (DEFAULT_GRID.column_xy(c)[1] - y) ** 2)))
    cup = {"name": "cup1", "type": "cup", "size": 0.06, "position": [fx, fy, 0.03],
           "full": False}
    return {"objects": [{**target, "position": [x, y, target["size"] / 2]}, cup],
            "robot": dict(ROBOT)}


def _carry_out(scene: dict, action: str, obj: str) -> list[str]:
    """Plans the intent on the world model and executes every step in the physics."""
    forecast = predict(_intent(action, obj, "cup1"), Scene.from_dict(scene))
    assert forecast.ok, forecast.error
    sim = scenes.load(scene).sim
    robot = Robot(sim)
    for step, target, params in forecast.steps:
        outcome = robot.execute(step, target, params)
        assert outcome.ok, f"{step}({target}): {outcome.error}"
        assert world.check_consistent(observe.scene_state(sim, 0)) == []
    return [step for step, _, _ in forecast.steps]


@pytest.mark.parametrize("column", COLUMNS, ids=str)
def test_a_closed_drawer_in_any_column_is_opened_and_filled_or_refused_at_reset(column):
    drawer = {"name": "drawer1", "type": "drawer", "size": 0.11, "open": False}
    scene = _scene_with(drawer, column)
    refusal = world.reset_refusal(Scene.from_dict(scene))
    if refusal is not None:
        assert "drawer1" in refusal and "workspace" in refusal
        return
    assert _carry_out(scene, "put_into", "drawer1") == ["open", "pick_up", "put_into"]


@pytest.mark.parametrize("column", COLUMNS, ids=str)
def test_a_cup_is_put_on_a_box_in_any_column(column):
    box = {"name": "box1", "type": "box", "size": 0.05}
    scene = _scene_with(box, column)
    assert world.reset_refusal(Scene.from_dict(scene)) is None
    assert _carry_out(scene, "put_on", "box1") == ["pick_up", "put_on"]


def test_drawers_are_accepted_in_most_columns():
    accepted = [c for c in COLUMNS if world.reset_refusal(Scene.from_dict(_scene_with(
        {"name": "drawer1", "type": "drawer", "size": 0.11, "open": False}, c))) is None]
    # all but the row nearest the robot (its tray would open out of reach) and the middle two
    # of the next (their handle would come nearer than the arm reaches)
    assert len(accepted) >= 10
