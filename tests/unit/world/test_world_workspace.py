"""The workspace: its machine-readable description, and the scenes a robot refuses at reset."""

import math

import pytest
from world_scenes import obj, world

from cbgo import wire
from cbgo.examples import example
from cbgo.world import (
    DEFAULT_GRID,
    Grid,
    drawer_direction,
    paper_scene,
    random_scene,
    reset_refusal,
    table_area,
    workspace_info,
    workspace_problems,
)
from cbgo.world.scene import DRAWER_OPENS_AWAY_BELOW_X, DRAWER_TRAY_OFFSET
from cbgo.world.workspace import MIN_REACH, open_handle_x


def _moved(scene, name, x, y):
    scene.get(name).position = (x, y, scene.get(name).position[2])
    return scene


def test_the_table_area_is_the_grid_columns_with_the_margin():
    area = table_area()
    assert area.x == (0.30, 0.70) and area.y == (-0.20, 0.20)
    small = table_area(Grid(shape=(2, 3, 2), origin=(0.4, 0.0, 0.1), step=(0.1, 0.1, 0.1)))
    assert small.x == (0.38, 0.52) and small.y == (-0.02, 0.22)


def test_the_info_describes_the_grid_and_validates_as_a_sim_info_reply():
    info = workspace_info()
    assert info["columns_x"] == [0.32, 0.44, 0.56, 0.68]
    assert info["columns_y"] == [-0.18, -0.06, 0.06, 0.18]
    assert info["levels_z"] == [0.06, 0.16, 0.26, 0.36]
    assert info["grid"] == {"shape": [4, 4, 4], "origin": list(DEFAULT_GRID.origin),
                            "step": list(DEFAULT_GRID.step)}
    reply = example("sim/info", "reply", workspace=info)
    wire.validate(reply, wire.SIM_INFO_REPLY, "sim/info")


@pytest.mark.parametrize("seed", range(300))
def test_every_random_scene_of_the_world_model_fits_in_the_workspace(seed):
    assert workspace_problems(random_scene(seed)) == []
    assert workspace_problems(paper_scene(seed)) == []


def test_an_object_beyond_the_outer_columns_is_refused_with_where_it_is_and_the_area():
    scene = _moved(world(obj("cup1", "cup"), obj("drawer1", "drawer", (3, 3))), "drawer1",
                   0.6, 0.3)
    problems = workspace_problems(scene)
    assert len(problems) == 1
    assert problems[0].startswith("drawer1 at (0.60, 0.30) is outside the workspace: objects "
                                  "on the table stand within x 0.30..0.70, y -0.20..0.20")


def test_positions_between_columns_and_within_the_margin_are_accepted():
    scene = _moved(world(obj("cup1", "cup")), "cup1", 0.70, -0.20)
    assert workspace_problems(scene) == []
    assert workspace_problems(_moved(scene, "cup1", 0.50, 0.01)) == []
    assert workspace_problems(_moved(scene, "cup1", 0.71, 0.0)) != []


@pytest.mark.parametrize("column", list(DEFAULT_GRID.columns()))
@pytest.mark.parametrize("size", [0.09, 0.11])
def test_a_drawer_fits_in_every_column_opening_towards_the_middle_of_the_table(column, size):
    scene = world(obj("drawer1", "drawer", column, open=True))
    drawer = scene.get("drawer1")
    drawer.size = size
    assert workspace_problems(scene) == []
    way = drawer_direction(drawer.position[0])
    assert way == (1 if column[0] < 2 else -1)  # away from the robot in the near half
    handle = open_handle_x(drawer)
    assert handle == pytest.approx(drawer.position[0] + way * (size / 2 + 0.818 * size + 0.018))
    assert MIN_REACH <= math.hypot(handle, drawer.position[1]) <= 0.70
    assert table_area().contains(drawer.position[0] + way * DRAWER_TRAY_OFFSET,
                                 drawer.position[1])


def test_drawers_open_away_from_the_robot_below_the_split_and_towards_it_from_there_on():
    split = workspace_info()["drawer_opens_away_below_x"]
    assert split == DRAWER_OPENS_AWAY_BELOW_X == 0.50
    assert drawer_direction(split - 0.001) == 1 and drawer_direction(split) == -1


def test_a_drawer_whose_tray_or_handle_would_leave_the_reach_is_refused():
    # grids other than the contract's: one column near the far edge, one at the robot's base
    far = Grid(shape=(1, 1, 1), origin=(0.4, 0.0, 0.06), step=(0.1, 0.1, 0.1))
    scene = _moved(world(obj("drawer1", "drawer")), "drawer1", 0.4, 0.0)
    assert workspace_problems(scene, far) == [
        "drawer1 at (0.40, 0.00) would open its tray away from the robot to x 0.48, out of "
        "the arm's reach (x 0.38..0.42, y -0.02..0.02)"]
    near = Grid(shape=(2, 1, 1), origin=(0.06, 0.0, 0.06), step=(0.12, 0.1, 0.1))
    problems = workspace_problems(_moved(scene, "drawer1", 0.06, 0.0), near)
    assert problems == [
        "drawer1 at (0.060, 0.00) would open its handle to (0.223, 0.00), 0.222 m from the "
        "robot's base axis: the arm reaches top-down no nearer than 0.29 m (see cbgo/sim/info)"]
    assert workspace_info()["min_reach"] == 0.29


def test_a_held_stacked_or_contained_object_is_judged_by_its_support_not_its_position():
    scene = world(obj("drawer1", "drawer", (3, 0), open=True), obj("cup1", "cup", (3, 0),
                                                                   inside="drawer1"),
                  obj("box1", "box", (2, 3)), obj("cup2", "cup", (2, 3), on="box1"),
                  obj("box2", "box", (0, 0)), holding="box2", tcp_cell=(0, 3, 2))
    for name in ("cup1", "cup2", "box2"):
        scene.get(name).position = (2.0, 2.0, 2.0)
    assert workspace_problems(scene) == []


def test_sizes_outside_what_the_gripper_and_a_cell_take_are_refused():
    scene = world(obj("cup1", "cup"), obj("drawer1", "drawer", (3, 3)))
    scene.get("drawer1").size = 0.3
    scene.get("cup1").size = 0.08
    problems = workspace_problems(scene)
    assert problems[0] == ("cup1 is a cup of size 0.080 m; the workspace takes cups of "
                           "0.030..0.070 m (see cbgo/sim/info)")
    scene.get("cup1").size = 0.03  # the paper's smallest cup
    assert len(workspace_problems(scene)) == 1
    assert problems[1].startswith("drawer1 is a drawer of size 0.300 m")


def test_overlapping_footprints_and_objects_in_a_trays_way_are_refused():
    scene = world(obj("cup1", "cup", (1, 1)), obj("box1", "box", (0, 0)),
                  obj("drawer1", "drawer", (3, 3)))
    assert workspace_problems(_moved(scene, "box1", 0.47, -0.05)) == [
        "cup1 at (0.44, -0.06) and box1 at (0.47, -0.05) overlap on the table (footprints "
        "of 0.06 and 0.05 m)"]
    _moved(scene, "box1", 0.32, -0.18)
    assert workspace_problems(_moved(scene, "cup1", 0.58, 0.18)) == [
        "cup1 at (0.58, 0.18) stands where the tray of drawer1 at (0.68, 0.18) slides out "
        "(0.08 m towards the robot)"]


def test_two_trays_sliding_out_into_the_same_column_are_refused():
    scene = world(obj("drawer1", "drawer", (0, 2)), obj("drawer2", "drawer", (2, 2)))
    assert workspace_problems(scene) == [
        "the trays of drawer1 at (0.32, 0.06) and drawer2 at (0.56, 0.06) slide out into the "
        "same place"]
    _moved(scene, "drawer2", 0.68, 0.06)
    assert workspace_problems(scene) == []


def test_the_reset_refusal_names_broken_rules_first_then_the_workspace():
    scene = world(obj("cup1", "cup"), obj("box1", "box", (2, 2)))
    assert reset_refusal(scene) is None
    scene.get("cup1").on = "cup1"
    assert reset_refusal(scene).startswith("inconsistent scene: cup1 stands on 'cup1'")
    scene.get("cup1").on = None
    _moved(scene, "box1", 0.9, 0.0)
    assert reset_refusal(scene).startswith("outside the workspace: box1 at (0.90, 0.00)")
