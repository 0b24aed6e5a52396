"""franka's pure parts: frames, the safety box, the eleven actions' plans, the tracked world."""

import math

import numpy as np
import pytest

from cbgo.services.franka.frames import (
    TOP_DOWN,
    Mount,
    SafetyBox,
    hand_rotation,
    quaternion_xyzw,
)
from cbgo.services.franka.main import grip_mismatch, seed_scene_in_hand
from cbgo.services.franka.plan import (
    Grasp,
    Gripper,
    Holding,
    Move,
    PlanRefused,
    handle_point,
    plan_action,
    travel_z,
)
from cbgo.services.franka.tracking import TrackedWorld
from cbgo.world import Scene

SCENE = {
    "objects": [
        {"name": "box1", "type": "box", "position": [0.56, -0.06, 0.025], "size": 0.05},
        {"name": "cup1", "type": "cup", "position": [0.44, 0.18, 0.03], "size": 0.06,
         "full": True},
        {"name": "cup2", "type": "cup", "position": [0.56, 0.18, 0.03], "size": 0.06},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11},
    ],
    "robot": {"tcp": [0.56, 0.06, 0.36], "gripper_open": True, "holding": None},
}


def scene(**robot):
    s = Scene.from_dict({**SCENE, "robot": {**SCENE["robot"], **robot}})
    s.settle()
    return s


def test_the_top_down_hand_is_franky_s_quaternion_1_0_0_0():
    assert quaternion_xyzw(TOP_DOWN) == pytest.approx([1, 0, 0, 0])
    turned = Mount(yaw_deg=90).rotation_to_base(TOP_DOWN)
    assert np.allclose(turned @ [0, 1, 0], Mount(yaw_deg=90).rotation.T @ (TOP_DOWN @ [0, 1, 0]))


def test_a_positive_tilt_leans_the_held_object_towards_the_robot():
    up = -hand_rotation(60.0)[:, 2]  # from the fingertips to the wrist
    assert up[0] < 0 and up[2] > 0
    assert math.degrees(math.acos(up[2])) == pytest.approx(60.0)


def test_the_mount_maps_table_points_to_base_points_and_back():
    mount = Mount(0.1, -0.2, 0.05, 30.0)
    p = np.array([0.5, 0.1, 0.2])
    assert mount.to_table(mount.to_base(p)) == pytest.approx(p)
    assert Mount().to_base(p) == pytest.approx(p)
    assert Mount.parse("0.1,-0.2,0.05,30") == mount
    with pytest.raises(ValueError, match="4 comma-separated"):
        Mount.parse("0,0,0")


def test_the_safety_box_refuses_points_outside_it_and_out_of_reach():
    box, mount = SafetyBox(), Mount()
    assert box.refusal((0.5, 0.0, 0.2), mount) is None
    assert "outside the safety box (z 0.600 not in" in box.refusal((0.5, 0.0, 0.6), mount)
    assert "from the robot's base axis" in box.refusal((0.26, 0.0, 0.2), mount)
    assert "from the robot's shoulder" in box.refusal((0.74, 0.29, 0.01), mount)
    assert box.first_refusal([(0.5, 0, 0.2), (0.5, 0, -0.1)], mount).startswith(
        "the TCP target [0.500, 0.000, -0.100]")
    with pytest.raises(ValueError, match="from low to high"):
        SafetyBox.parse("0.7,0.2,-0.3,0.3,0,0.5")


def test_a_move_is_one_motion_to_the_world_model_s_goal_cell():
    plan = plan_action("move_down", None, {}, scene())
    assert plan.steps == [Move((0.56, 0.06, pytest.approx(0.26)))]
    with pytest.raises(PlanRefused, match="leave the workspace grid"):
        plan_action("move_up", None, {}, scene())


def test_pick_up_comes_from_above_and_closes_on_the_object_s_size():
    plan = plan_action("pick_up", "box1", {}, scene())
    kinds = [type(s).__name__ for s in plan.steps]
    assert kinds == ["Gripper", "Move", "Move", "Grasp", "Move", "Holding"]
    assert plan.steps[0] == Gripper(pytest.approx(0.05 + 2 * 0.012))
    down = plan.steps[2]
    assert down.slow and down.position == pytest.approx((0.56, -0.06, 0.03))
    assert plan.steps[3] == Grasp(0.05, "box1")
    assert plan.steps[5] == Holding(0.05, "box1")  # lifted: measured again, it may slip
    assert plan.after.robot.holding == "box1" and plan.touched == ["box1"]
    assert all(p[2] <= travel_z(scene(), None) + 1e-9 for p in plan.points())


def test_every_action_of_the_paper_story_has_a_plan_inside_the_default_box():
    box, mount = SafetyBox(), Mount()
    world = scene()
    for action, obj in [("move_down", None), ("move_left", None), ("move_right", None),
                        ("move_up", None), ("pick_up", "cup1"), ("pour", "cup2"),
                        ("place", None), ("pick_up", "box1"), ("put_on", "drawer1"),
                        ("open", "drawer1"), ("pick_up", "cup2"), ("put_into", "drawer1"),
                        ("close", "drawer1")]:
        plan = plan_action(action, obj, {}, world)
        assert box.first_refusal(plan.points(), mount) is None, (action, obj)
        world = plan.after
    assert world.get("cup2").inside == "drawer1" and not world.get("drawer1").open


def test_open_pulls_the_handle_by_the_tray_s_travel_and_close_pushes_it_back():
    plan = plan_action("open", "drawer1", {}, scene())
    grasp = next(i for i, s in enumerate(plan.steps) if isinstance(s, Grasp))
    grasp_at, pulled_to = plan.steps[grasp - 1].position, plan.steps[grasp + 1].position
    assert grasp_at == pytest.approx(handle_point(scene(), "drawer1", opened=False))
    assert grasp_at[0] - pulled_to[0] == pytest.approx(0.818 * 0.11)
    assert plan.steps[grasp].what == "the handle of drawer1"
    assert plan.steps[grasp + 2] == Holding(0.02, "the handle of drawer1")  # pulled, not slipped
    back = plan_action("close", "drawer1", {}, plan.after)
    grasp = next(i for i, s in enumerate(back.steps) if isinstance(s, Grasp))
    assert back.steps[grasp - 1].position == pytest.approx(pulled_to)
    assert back.steps[grasp + 1].position == pytest.approx(grasp_at)


def test_refusals_name_the_reason():
    with pytest.raises(PlanRefused, match="the gripper holds nothing"):
        plan_action("place", None, {}, scene())
    held = plan_action("pick_up", "cup1", {}, scene()).after
    with pytest.raises(PlanRefused, match="angle_deg must be a number of degrees in 30..135"):
        plan_action("pour", "cup2", {"angle_deg": 10}, held)
    with pytest.raises(PlanRefused, match="must be empty to grasp a handle"):
        plan_action("open", "drawer1", {}, held)


def test_a_failure_makes_the_handled_objects_unknown_and_refuses_every_action():
    world = TrackedWorld(scene())
    world.scene.get("cup2").on = "box1"
    world.scene.settle()
    world.lose(["box1"], "stopped during pick_up(box1)")
    assert set(world.unknown) == {"box1", "cup2"}  # what stood on it goes with it
    message = world.message()
    assert {o["name"] for o in message["objects"]} == {"cup1", "drawer1"}
    assert [u["name"] for u in message["unknown"]] == ["box1", "cup2"]
    assert message["unknown"][0]["last_position"] == [0.56, -0.06, 0.025]
    assert world.refusal().startswith("the place of box1, cup2 is unknown: box1 (stopped")


def test_a_declared_load_must_match_the_measured_finger_gap():
    held = scene(holding="cup1", gripper_open=False)
    assert grip_mismatch(held, 0.0595) is None
    assert "the fingers are 0.080 m apart" in grip_mismatch(held, 0.08)
    assert grip_mismatch(scene(), 0.08) is None


def test_a_seeds_scene_drops_a_load_the_fingers_do_not_hold():
    invented = scene(tcp=[0.44, 0.18, 0.26], gripper_open=False, holding="cup1")
    kept = seed_scene_in_hand(invented, 0.06)  # the fingers hold something of cup1's size
    assert kept.robot.holding == "cup1"
    empty = seed_scene_in_hand(invented, 0.08)  # wide open: cup1 is not there
    assert empty.robot.holding is None and not empty.has("cup1")
    assert {o.name for o in empty.objects} == {"box1", "cup2", "drawer1"}
