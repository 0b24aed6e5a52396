"""Preconditions (with their failure codes and repairs) and effects of all eleven actions."""

import pytest
from world_scenes import obj, world

from cbgo import wire
from cbgo.world import (
    DEFAULT_GRID,
    OBJECT_AGNOSTIC,
    InfeasibleAction,
    apply,
    candidates,
    check,
    failures,
    feasible,
    gripper_room,
)
from cbgo.world.actions import reserved_columns
from cbgo.world.scene import DRAWER_TRAY_OFFSET


def codes(action, target, scene, params=None):
    return [f.code for f in failures(action, target, scene, params)]


def table_scene(**kw):
    """A box with a cup on it, a free full cup, an open drawer with a box inside, a closed one."""
    return world(obj("cup1", "cup", (0, 0), full=True), obj("box1", "box", (1, 2)),
                 obj("cup2", "cup", on="box1"), obj("drawer1", "drawer", (3, 0), open=True),
                 obj("box2", "box", inside="drawer1"), obj("drawer2", "drawer", (3, 3)), **kw)


# ------------------------------------------------------------------ moves


@pytest.mark.parametrize("action, axis, sign", [
    ("move_up", 2, 1), ("move_down", 2, -1), ("move_left", 1, -1), ("move_right", 1, 1)])
def test_a_move_shifts_the_tcp_one_cell_and_left_is_minus_y(action, axis, sign):
    scene = table_scene(tcp_cell=(1, 1, 2))
    after = apply(action, None, {}, scene)
    delta = [a - b for a, b in zip(after.robot.tcp, scene.robot.tcp, strict=True)]
    assert delta[axis] == pytest.approx(sign * DEFAULT_GRID.step[axis])
    assert sum(abs(d) for i, d in enumerate(delta) if i != axis) == pytest.approx(0.0)
    assert scene.robot.tcp == DEFAULT_GRID.position((1, 1, 2))  # the input is unchanged


def test_a_move_whose_goal_leaves_the_gripper_no_room_is_infeasible():
    # (1, 1, 0) is 0.12 m beside box1 with cup2 on it (top 0.11 m): the hand, 0.105 m either
    # side of the TCP along y and 0.045 m above it, would sit on cup2
    scene = table_scene(tcp_cell=(1, 1, 1))
    assert failures("move_down", None, scene)[0].message == (
        "the gripper does not fit at the goal cell [1, 1, 0]: cup2 is there")
    assert codes("move_down", None, table_scene(tcp_cell=(1, 0, 1))) == []
    # the fingers on a cup: straight down onto cup1 at (0, 0) from level 1
    assert codes("move_down", None, table_scene(tcp_cell=(0, 0, 1))) == ["no_room"]
    # a held 0.06 m cup hangs 0.04 m under the TCP: at level 1 (0.16) it clears cup2 on box1
    # (top 0.11), and at level 0 it would stand in it
    assert codes("move_left", None, table_scene(tcp_cell=(1, 3, 1), holding="cup1")) == []
    assert codes("move_left", None, table_scene(tcp_cell=(1, 3, 0), holding="cup1")) == [
        "no_room"]
    # an open drawer's tray and handle are in the way in front of it, a closed one's are not
    assert codes("move_down", None, table_scene(tcp_cell=(2, 0, 1))) == ["no_room"]


def test_a_move_that_leaves_the_grid_is_out_of_reach():
    scene = table_scene(tcp_cell=(0, 0, 3))
    assert codes("move_up", None, scene) == ["out_of_reach"]
    assert codes("move_left", None, scene) == ["out_of_reach"]
    assert "cannot move up" in check("move_up", None, scene)
    assert feasible("move_down", "cup1", scene)  # moves ignore the object


def test_a_move_distance_becomes_whole_cells_and_carries_the_held_object():
    scene = world(obj("cup1", "cup", (0, 0)), holding="cup1", tcp_cell=(0, 0, 1))
    after = apply("move_right", None, {"distance": 0.25}, scene)
    assert DEFAULT_GRID.cell_of(after.robot.tcp) == (0, 2, 1)
    assert after.get("cup1").position == after.robot.tcp
    assert codes("move_right", None, scene, {"distance": 0.5}) == ["out_of_reach"]
    assert codes("move_right", None, scene, {"distance": "far"}) == ["bad_param"]


# ------------------------------------------------------------------ pick_up and place


def test_pick_up_takes_a_free_cup_to_the_gripper():
    scene = table_scene()
    after = apply("pick_up", "cup2", {}, scene)
    assert after.robot.holding == "cup2" and not after.robot.gripper_open
    assert after.get("cup2").on is None and after.get("cup2").position == after.robot.tcp
    assert after.robot.tcp == scene.get("cup2").position
    assert after.is_free("box1") and after.problems() == []


@pytest.mark.parametrize("target, code, repair", [
    ("box1", "not_free", ("pick_up", "cup2")),
    ("box2", "inside_drawer", None),
    ("drawer1", "wrong_type", None),
    ("plate", "unknown_object", None),
    (None, "needs_object", None),
])
def test_pick_up_refuses_what_is_not_a_free_cup_or_box(target, code, repair):
    found = failures("pick_up", target, table_scene())
    assert found[0].code == code and found[0].repair == repair


def test_pick_up_with_a_full_gripper_asks_to_place_first():
    scene = table_scene()
    holding = apply("pick_up", "cup1", {}, scene)
    found = failures("pick_up", "cup2", holding)
    assert [(f.code, f.repair) for f in found] == [("holding", ("place", None))]
    assert codes("pick_up", "cup1", holding) == ["is_held"]


def test_place_puts_the_held_object_on_the_table_below_the_tcp():
    scene = apply("pick_up", "cup1", {}, table_scene())
    scene.robot.tcp = DEFAULT_GRID.position((1, 1, 2))
    after = apply("place", "anything", {}, scene)
    cup = after.get("cup1")
    assert after.robot.holding is None and after.robot.gripper_open
    assert DEFAULT_GRID.column_of(cup.position) == (1, 1) and cup.position[2] == cup.size / 2


def test_place_avoids_taken_columns_and_the_drawer_tray():
    scene = apply("pick_up", "cup1", {}, table_scene())
    scene.robot.tcp = DEFAULT_GRID.position((2, 0, 2))  # in front of drawer1: its tray's place
    after = apply("place", None, {}, scene)
    assert DEFAULT_GRID.column_of(after.get("cup1").position) not in {(2, 0), (3, 0), (1, 2)}
    assert codes("place", None, scene, {"position": [0.44, 0.06, 0.0]}) == ["place_taken"]
    wanted = apply("place", None, {"position": [0.32, 0.18, 0.0]}, scene)
    assert DEFAULT_GRID.column_of(wanted.get("cup1").position) == (0, 3)


def test_a_drawer_near_the_robot_opens_away_from_it_its_tray_column_and_room_follow():
    scene = world(obj("drawer1", "drawer", (0, 1), open=True), obj("cup1", "cup", (3, 3)),
                  holding="cup1", tcp_cell=(0, 1, 3))
    assert reserved_columns(scene)[(1, 1)] == "drawer1"  # behind it, away from the robot
    after = apply("put_into", "drawer1", {}, scene)
    drawer, cup = after.get("drawer1"), after.get("cup1")
    assert cup.position[0] == pytest.approx(drawer.position[0] + DRAWER_TRAY_OFFSET)
    assert apply("close", "drawer1", {}, after).get("cup1").position[0] == pytest.approx(
        drawer.position[0])
    # the open tray and handle stand behind the cabinet: no room for the fingers there
    assert gripper_room(after, (0.50, -0.06, 0.06)) == "drawer1"
    assert gripper_room(after, (0.20, -0.06, 0.06)) is None


def test_place_needs_a_held_object_and_a_free_column():
    assert codes("place", None, table_scene()) == ["not_holding"]
    boxes = [obj(f"box{i}", "box", column) for i, column in enumerate(DEFAULT_GRID.columns())]
    full = world(*boxes, obj("cup1", "cup", on="box0"))
    full = apply("pick_up", "cup1", {}, full)
    assert codes("place", None, full) == ["no_free_place"]


# ------------------------------------------------------------------ put_on and put_into


def test_put_on_stacks_the_held_object_on_a_free_box_or_drawer():
    scene = apply("pick_up", "cup1", {}, table_scene())
    on_drawer = apply("put_on", "drawer2", {}, scene)
    cup, drawer = on_drawer.get("cup1"), on_drawer.get("drawer2")
    assert cup.on == "drawer2" and on_drawer.robot.holding is None
    assert cup.position[2] == pytest.approx(drawer.position[2] + drawer.size / 2 + cup.size / 2)
    assert on_drawer.problems() == []


@pytest.mark.parametrize("target, code", [
    ("box1", "not_free"), ("cup2", "wrong_type"), ("box2", "inside_drawer"),
    ("cup1", "wrong_type")])
def test_put_on_refuses_blocked_and_wrong_targets(target, code):
    scene = apply("pick_up", "cup1", {}, table_scene())
    assert code in codes("put_on", target, scene)


def test_put_on_keeps_towers_within_four_objects_and_needs_a_held_object():
    scene = world(obj("drawer1", "drawer", (3, 1)), obj("box1", "box", on="drawer1"),
                  obj("box2", "box", on="box1"), obj("box3", "box", on="box2"),
                  obj("cup1", "cup", (0, 0)), holding="cup1")
    assert codes("put_on", "box3", scene) == ["stack_too_high"]
    assert codes("put_on", "box1", table_scene()) == ["not_holding", "not_free"]


def test_put_into_puts_the_held_object_on_the_open_drawers_tray():
    scene = apply("pick_up", "cup1", {}, table_scene())
    scene = apply("open", "drawer2", {}, scene)
    after = apply("put_into", "drawer2", {}, scene)
    cup, drawer = after.get("cup1"), after.get("drawer2")
    assert cup.inside == "drawer2" and after.contents("drawer2") == ["cup1"]
    assert cup.position[0] == pytest.approx(drawer.position[0] - DRAWER_TRAY_OFFSET)
    assert after.robot.holding is None and after.problems() == []


def test_put_into_a_closed_or_full_drawer_says_why_and_how_to_repair():
    scene = apply("pick_up", "cup1", {}, table_scene())
    closed = failures("put_into", "drawer2", scene)
    assert [(f.code, f.repair) for f in closed] == [("drawer_closed", ("open", "drawer2"))]
    assert check("put_into", "drawer2", scene) == "drawer2 is closed"
    assert codes("put_into", "drawer1", scene) == ["drawer_full"]
    assert codes("put_into", "box1", scene) == ["wrong_type"]
    assert codes("put_into", "drawer2", table_scene()) == ["not_holding", "drawer_closed"]


# ------------------------------------------------------------------ pour, open, close


def test_pour_fills_an_empty_cup_from_the_held_full_one():
    scene = apply("pick_up", "cup1", {}, table_scene())
    after = apply("pour", "cup2", {"angle_deg": 120}, scene)
    assert after.get("cup2").full and not after.get("cup1").full


def test_pour_needs_a_held_full_cup_and_an_empty_reachable_target():
    holding_full = apply("pick_up", "cup1", {}, table_scene())
    assert codes("pour", "cup1", holding_full) == ["is_held"]
    assert codes("pour", "box1", holding_full) == ["wrong_type"]
    filled = apply("pour", "cup2", {}, holding_full)
    assert codes("pour", "cup2", filled) == ["held_empty", "cup_full"]
    assert codes("pour", "cup2", table_scene()) == ["not_holding"]
    holding_box = world(obj("box1", "box", (0, 0)), obj("cup1", "cup", (1, 1)), holding="box1")
    assert codes("pour", "cup1", holding_box) == ["held_not_cup"]
    hidden = world(obj("drawer1", "drawer", (3, 0)), obj("cup1", "cup", inside="drawer1"),
                   obj("cup2", "cup", (0, 0), full=True), holding="cup2")
    found = failures("pour", "cup1", hidden)
    assert [(f.code, f.repair) for f in found] == [("drawer_closed", ("open", "drawer1"))]


def test_open_and_close_switch_a_drawer_and_its_contents_ride_on_the_tray():
    scene = table_scene()
    closed = apply("close", "drawer1", {}, scene)
    assert not closed.get("drawer1").open and closed.is_hidden("box2")
    assert closed.get("box2").position[0] == pytest.approx(scene.get("box2").position[0]
                                                           + DRAWER_TRAY_OFFSET)
    assert closed.robot.tcp == scene.robot.tcp
    reopened = apply("open", "drawer1", {}, closed)
    assert reopened.get("box2").position == pytest.approx(scene.get("box2").position)
    assert codes("open", "drawer1", scene) == ["already_open"]
    assert codes("close", "drawer2", scene) == ["already_closed"]
    assert codes("open", "cup1", scene) == ["wrong_type"]


# ------------------------------------------------------------------ the API around them


def test_apply_refuses_an_infeasible_action_with_every_reason():
    scene = table_scene()
    with pytest.raises(InfeasibleAction) as caught:
        apply("put_into", "drawer2", {}, scene)
    assert [f.code for f in caught.value.failures] == ["not_holding", "drawer_closed"]
    assert "put_into(drawer2): the gripper holds nothing; drawer2 is closed" == str(caught.value)
    assert codes("fly", None, scene) == ["unknown_action"]


def test_candidates_list_moves_and_place_once_without_an_object():
    scene = table_scene(tcp_cell=(1, 1, 2))
    pairs = candidates(scene)
    assert ("pick_up", "cup1") in pairs and ("pick_up", "cup2") in pairs
    assert ("pick_up", "box1") not in pairs and ("close", "drawer1") in pairs
    agnostic = [p for p in pairs if p[0] in OBJECT_AGNOSTIC]
    assert sorted(agnostic) == sorted((a, None) for a in ("move_up", "move_down", "move_left",
                                                          "move_right"))
    assert all(feasible(a, o, scene) for a, o in pairs)
    assert {a for a, _ in pairs} <= set(wire.ACTIONS)


def test_a_sequence_of_actions_keeps_the_scene_consistent():
    scene = table_scene()
    for action, target in [("pick_up", "cup2"), ("put_on", "drawer2"), ("pick_up", "cup1"),
                           ("pour", "cup2"), ("move_right", None), ("place", None),
                           ("close", "drawer1"), ("open", "drawer1"), ("pick_up", "box1")]:
        scene = apply(action, target, {}, scene)
        assert scene.problems() == [], (action, target, scene.problems())
    assert scene.get("cup2").full and scene.robot.holding == "box1"
