"""(scene, intent) -> action sequence, on the symbolic world model alone (no network, no physics).

Each row runs the planner's real tree (`create_tree`) against the symbolic robot of
tests/fakes/symbolic_robot.py, which executes with `cbgo.world.apply` and refuses what the world
model forbids; the sequence it received must be the expected one, and `sequence.predict` (what
the planner reports as pending steps) must agree with it.
"""

import pytest
from planner_worlds import FakeRobot, box, cup, drawer, intent, scene
from py_trees.common import Status

from cbgo.services.planner import repair
from cbgo.services.planner.scenes import SceneSource
from cbgo.services.planner.sequence import predict
from cbgo.services.planner.tree import create_tree
from cbgo.world import Scene


def execute(scene_dict, the_intent, robot=None, max_repairs=8, memory=None):
    """Runs the tree to the end; returns (robot log, status, error, final scene)."""
    robot = robot or FakeRobot(scene_dict)
    scenes = SceneSource(robot.scene.copy())
    plan = create_tree(the_intent, scenes, robot, max_repairs=max_repairs, memory=memory)
    status = Status.RUNNING
    for _ in range(400):
        status = plan.tick()
        if status != Status.RUNNING:
            break
    return robot.log, status, plan.state.error, robot.scene


HOLDING_CUP1 = dict(holding="cup1")

# (name, scene, intent, expected sequence of (action, object)); every row ends in SUCCESS
SUCCEEDS = [
    # the paper's example: put into a closed drawer while holding a cup; the gripper must be
    # free to grasp the handle, so the cup is set aside and picked again
    ("paper_put_into_closed_drawer_while_holding",
     scene(cup("cup1", 1, 2), drawer("drawer1", 0), **HOLDING_CUP1),
     intent("put_into", "drawer1"),
     # Expect: place the cup, open, pick it again, put it in
     [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"), ("put_into", "drawer1")]),
    ("put_into_open_drawer_is_one_action",
     scene(cup("cup1", 1, 2), drawer("drawer1", 0, open=True), **HOLDING_CUP1),
     intent("put_into", "drawer1"),
     [("put_into", "drawer1")]),
    ("put_into_with_empty_gripper_fetches_params_source",
     scene(cup("cup1", 1, 2), drawer("drawer1", 0)),
     intent("put_into", "drawer1", params={"source": "cup1"}),
     # Expect: open (gripper free already), fetch the named source, put it in
     [("open", "drawer1"), ("pick_up", "cup1"), ("put_into", "drawer1")]),
    ("pick_up_while_holding_places_first",
     scene(cup("cup1", 1, 2), cup("cup2", 0, 0), **HOLDING_CUP1),
     intent("pick_up", "cup2"),
     [("place", "cup1"), ("pick_up", "cup2")]),
    ("pick_up_a_blocked_box_moves_the_object_off",
     scene(box("box1", 0, 0), cup("cup1", 0, 0, on="box1")),
     intent("pick_up", "box1"),
     [("pick_up", "cup1"), ("place", "cup1"), ("pick_up", "box1")]),
    ("pick_up_under_a_tower_takes_it_apart_top_first",
     scene(box("box1", 0, 0), box("box2", 0, 0, on="box1"), cup("cup1", 0, 0, on="box2")),
     intent("pick_up", "box1"),
     [("pick_up", "cup1"), ("place", "cup1"), ("pick_up", "box2"), ("place", "box2"),
      ("pick_up", "box1")]),
    ("put_on_a_blocked_box_while_holding",
     scene(box("box1", 0, 0), cup("cup1", 0, 0, on="box1"), cup("cup2", 1, 2),
           holding="cup2"),
     intent("put_on", "box1"),
     # Expect: set the payload aside, clear box1, take the payload again, put it on
     [("place", "cup2"), ("pick_up", "cup1"), ("place", "cup1"), ("pick_up", "cup2"),
      ("put_on", "box1")]),
    ("close_with_the_arm_inside_retreats_first",
     scene(drawer("drawer1", 0, open=True), cup("cup1", 2, 0, inside="drawer1"),
           tcp=(0.60, -0.18, 0.04)),
     intent("close", "drawer1"),
     [("move_up", None), ("close", "drawer1")]),
    ("close_while_holding_places_first",
     scene(drawer("drawer1", 0, open=True), cup("cup1", 1, 2), **HOLDING_CUP1),
     intent("close", "drawer1"),
     [("place", "cup1"), ("close", "drawer1")]),
    ("open_while_holding_places_first",
     scene(drawer("drawer1", 0), cup("cup1", 1, 2), **HOLDING_CUP1),
     intent("open", "drawer1"),
     [("place", "cup1"), ("open", "drawer1")]),
    ("pour_with_empty_gripper_picks_the_attended_full_cup",
     scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3), cup("cup3", 0, 3, full=True)),
     intent("pour", "cup2", p_object={"cup2": 0.7, "cup3": 0.2, "cup1": 0.1}),
     # Expect: cup3 (more attention than cup1), then pour
     [("pick_up", "cup3"), ("pour", "cup2")]),
    ("pour_holding_an_empty_cup_swaps_it_for_a_full_one",
     scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3), cup("cup3", 1, 2), holding="cup3"),
     intent("pour", "cup2"),
     [("place", "cup3"), ("pick_up", "cup1"), ("pour", "cup2")]),
    ("pour_into_a_cup_in_a_closed_drawer_opens_it",
     scene(drawer("drawer1", 0), cup("cup2", 2, 0, inside="drawer1"),
           cup("cup1", 1, 2, full=True), **HOLDING_CUP1),
     intent("pour", "cup2"),
     [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"), ("pour", "cup2")]),
    ("goal_already_reached_is_success_without_action",
     scene(drawer("drawer1", 0, open=True)),
     intent("open", "drawer1"),
     []),
    ("pick_up_of_the_held_object_is_already_done",
     scene(cup("cup1", 1, 2), **HOLDING_CUP1),
     intent("pick_up", "cup1"),
     []),
    ("a_move_carries_its_distance",
     scene(cup("cup1", 0, 0)),
     intent("move_down", params={"distance": 0.2}),
     [("move_down", None)]),
    ("place_puts_down_the_held_object",
     scene(cup("cup1", 1, 2), **HOLDING_CUP1),
     intent("place", "cup1"),
     [("place", "cup1")]),
]


@pytest.mark.parametrize("name, scene_dict, the_intent, expected", SUCCEEDS,
                         ids=[row[0] for row in SUCCEEDS])
def test_intent_leads_to_the_expected_sequence(name, scene_dict, the_intent, expected):
    log, status, error, after = execute(scene_dict, the_intent)
    assert (log, status, error) == (expected, Status.SUCCESS, None)
    assert after.problems() == []
    forecast = predict(the_intent, Scene.from_dict(scene_dict))
    assert forecast.ok and [(a, o) for a, o, _ in forecast.steps] == expected


def test_the_paper_example_ends_with_the_cup_in_the_drawer():
    _, _, _, after = execute(SUCCEEDS[0][1], SUCCEEDS[0][2])
    assert after.get("cup1").inside == "drawer1" and after.get("drawer1").open
    assert after.robot.holding is None


def test_metric_parameters_reach_the_robot():
    cases = [(scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3), holding="cup1"),
              intent("pour", "cup2", params={"angle_deg": 60.0, "source": "cup1"}),
              {"action": "pour", "object": "cup2", "params": {"angle_deg": 60.0},
               "state": "done"}),
             (scene(cup("cup1", 0, 0)), intent("move_down", params={"distance": 0.2}),
              {"action": "move_down", "object": None, "params": {"distance": 0.2},
               "state": "done"})]
    for world, the_intent, step in cases:
        robot = FakeRobot(world)
        plan = create_tree(the_intent, SceneSource(robot.scene.copy()), robot)
        while plan.tick() == Status.RUNNING:
            pass
        # Expect: the planner's own params.source is not passed on to the robot
        assert [s.as_dict() for s in plan.state.steps] == [step]


# (name, scene, intent, expected sequence before failing, words of the error)
FAILS = [
    ("drawer_full_has_no_repair",
     scene(drawer("drawer1", 0, open=True), cup("cup2", 2, 0, inside="drawer1"),
           cup("cup1", 1, 2), **HOLDING_CUP1),
     intent("put_into", "drawer1"),
     [], "no repair for: drawer1 is full (cup2 inside)"),
    ("pour_into_a_full_cup_has_no_repair",
     scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3, full=True), **HOLDING_CUP1),
     intent("pour", "cup2"),
     [], "no repair for: cup2 is already full"),
    ("pick_up_from_inside_a_drawer_has_no_repair",
     scene(drawer("drawer1", 0, open=True), cup("cup1", 2, 0, inside="drawer1")),
     intent("pick_up", "cup1"),
     [], "no repair for: cup1 is inside drawer1"),
    ("move_out_of_the_grid_has_no_repair",
     scene(cup("cup1", 0, 0), tcp=(0.44, 0.06, 0.36)),
     intent("move_up"),
     [], "no repair for: the TCP cannot move up by 1 cell(s)"),
    ("put_on_with_nothing_to_put_has_no_repair",
     scene(box("box1", 0, 0)),
     intent("put_on", "box1"),
     [], "no repair for: the gripper holds nothing and there is no object to put on box1"),
    ("pour_without_any_full_cup_has_no_repair",
     scene(cup("cup1", 0, 0), cup("cup2", 1, 3)),
     intent("pour", "cup2"),
     [], "there is no full cup to pour from"),
    ("unknown_object",
     scene(cup("cup1", 0, 0)),
     intent("pick_up", "cup9"),
     [], "no repair for: there is no cup9 in the scene"),
    ("intent_without_action",
     scene(cup("cup1", 0, 0)),
     intent(None),
     [], "no repair for: the intent names no action"),
]


@pytest.mark.parametrize("name, scene_dict, the_intent, expected, error", FAILS,
                         ids=[row[0] for row in FAILS])
def test_intent_without_repair_fails_with_a_clear_reason(name, scene_dict, the_intent, expected,
                                                         error):
    log, status, got, _ = execute(scene_dict, the_intent)
    assert (log, status) == (expected, Status.FAILURE)
    assert error in got
    forecast = predict(the_intent, Scene.from_dict(scene_dict))
    assert not forecast.ok and error in forecast.error


def test_repairs_are_bounded_by_the_budget():
    tower = scene(box("box1", 0, 0), box("box2", 0, 0, on="box1"), cup("cup1", 0, 0, on="box2"))
    log, status, error, _ = execute(tower, intent("pick_up", "box1"), max_repairs=2)
    # Expect: two repairs sent, the third refused by the budget, the intended one never sent
    assert log == [("pick_up", "cup1"), ("place", "cup1")]
    assert status == Status.FAILURE
    assert error.startswith("repair budget exhausted: 2 repair actions sent")


def test_a_drawer_closed_meanwhile_is_opened_again():
    closed_once = []

    def someone_closes_it(action, world):
        if action == "pick_up" and not closed_once:
            closed_once.append(True)
            world = world.copy()
            world.get("drawer1").open = False
        return world

    robot = FakeRobot(SUCCEEDS[0][1], after=someone_closes_it)
    log, status, error, _ = execute(None, intent("put_into", "drawer1"), robot=robot)
    # Expect: the tree notices after pick_up, sets the cup aside again and reopens
    assert log == [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"),
                   ("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"),
                   ("put_into", "drawer1")]
    assert (status, error) == (Status.SUCCESS, None)


def test_a_failed_action_is_retried_once():
    robot = FakeRobot(SUCCEEDS[0][1], refuse={"pick_up": 1})
    log, status, _, _ = execute(None, intent("put_into", "drawer1"), robot=robot)
    assert log == [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"),
                   ("pick_up", "cup1"), ("put_into", "drawer1")]
    assert status == Status.SUCCESS


def test_an_action_failing_twice_fails_the_tree_with_the_robots_reason():
    robot = FakeRobot(SUCCEEDS[0][1], refuse={"open": 2}, error="drawer1 opened only 40 %")
    log, status, error, _ = execute(None, intent("put_into", "drawer1"), robot=robot)
    assert log == [("place", "cup1"), ("open", "drawer1"), ("open", "drawer1")]
    assert status == Status.FAILURE
    assert error == "open(drawer1) failed 2 times: drawer1 opened only 40 %"


def test_fetch_falls_back_to_the_object_held_last():
    world = scene(cup("cup1", 1, 2), drawer("drawer1", 0, open=True))
    memory = repair.PlanMemory(last_held="cup1")
    log, status, _, _ = execute(world, intent("put_into", "drawer1"), memory=memory)
    assert (log, status) == ([("pick_up", "cup1"), ("put_into", "drawer1")], Status.SUCCESS)


def test_the_tree_snapshot_names_guards_and_actions():
    robot = FakeRobot(SUCCEEDS[0][1])
    plan = create_tree(intent("put_into", "drawer1"), SceneSource(robot.scene), robot)
    plan.tick()
    text = plan.snapshot()
    for words in ("achieve put_into(drawer1)", "drawer1 open?", "repair until drawer1 open",
                  "gripper empty?", "place(cup1)", "holding the source"):
        assert words in text, text
