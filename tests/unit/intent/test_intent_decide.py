"""The decision picks the most probable FEASIBLE pair under the joint, or says why not."""

import numpy as np
import pytest

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig, decide, decide_arrays
from cbgo.wire import ACTIONS
from cbgo.world import DEFAULT_GRID, Robot, Scene, SceneObject


def scene_holding_box() -> Scene:
    """cup1 on the table, drawer1 closed, drawer2 open and empty; the robot holds box1."""
    def at(name, kind, column, size, **kw):
        x, y = DEFAULT_GRID.column_xy(column)
        return SceneObject(name, kind, (x, y, size / 2), size, **kw)

    scene = Scene([at("cup1", "cup", (0, 0), 0.06), at("drawer1", "drawer", (3, 0), 0.11),
                   at("box1", "box", (1, 1), 0.05), at("drawer2", "drawer", (3, 3), 0.11,
                                                       open=True)],
                  Robot(DEFAULT_GRID.position((1, 1, 2)), False, "box1"))
    scene.settle()
    assert scene.problems() == []
    return scene


def joint_of(scene: Scene, entries: dict, rest: float = 0.0) -> np.ndarray:
    joint = np.full((len(scene.objects), len(ACTIONS)), rest)
    for (action, obj), p in entries.items():
        joint[scene.names.index(obj), ACTIONS.index(action)] = p
    return joint / joint.sum()


def test_the_best_feasible_pair_wins_over_a_more_probable_infeasible_one():
    scene = scene_holding_box()
    joint = joint_of(scene, {("put_into", "drawer1"): 0.4, ("put_into", "drawer2"): 0.35,
                             ("pick_up", "cup1"): 0.25})
    d = decide(joint, scene.names, scene, DecisionConfig(min_confidence=0.3,
                                                        accept_repairable=False, clarify=False))
    assert (d.status, d.action, d.object) == ("accepted", "put_into", "drawer2")
    assert d.confidence == pytest.approx(0.35)
    assert abs(sum(d.p_action.values()) - 1) < 1e-9 and abs(sum(d.p_object.values()) - 1) < 1e-9


def test_a_confident_infeasible_request_is_infeasible_with_the_unmet_precondition():
    scene = scene_holding_box()
    joint = joint_of(scene, {("put_into", "drawer1"): 0.8, ("put_into", "drawer2"): 0.2})
    d = decide(joint, scene.names, scene, DecisionConfig(min_confidence=0.5,
                                                        accept_repairable=False))
    assert (d.status, d.action, d.object) == ("infeasible", None, None)
    assert "put_into(drawer1)" in d.reason and "drawer1 is closed" in d.reason
    repaired = decide(joint, scene.names, scene, DecisionConfig(0.5, accept_repairable=True,
                                                                clarify=False))
    assert (repaired.status, repaired.action, repaired.object) == ("accepted", "put_into",
                                                                   "drawer1")
    assert "planner repairs" in repaired.reason


def test_moves_and_place_are_scored_by_their_marginal_and_ignore_the_object():
    scene = scene_holding_box()
    joint = joint_of(scene, {("move_left", "cup1"): 0.2, ("move_left", "drawer1"): 0.2,
                             ("move_left", "drawer2"): 0.2, ("put_on", "drawer2"): 0.4})
    d = decide(joint, scene.names, scene, DecisionConfig(clarify=False))
    assert (d.status, d.action, d.object) == ("accepted", "move_left", None)
    assert d.confidence == pytest.approx(0.6) and d.p_action["move_left"] == pytest.approx(0.6)
    # by default an intent below --ask-below is asked back, the same one offered first
    asked = decide(joint, scene.names, scene)
    assert (asked.status, asked.action) == ("clarify", None)
    assert (asked.candidates[0].action, asked.candidates[0].object) == ("move_left", None)


def test_an_uncertain_posterior_is_low_confidence_and_takes_no_action():
    scene = scene_holding_box()
    d = decide(np.full((4, len(ACTIONS)), 1.0), scene.names, scene)
    assert (d.status, d.action, d.object, d.params) == ("low_confidence", None, None, {})
    assert "< 0.5" in d.reason and 0 < d.confidence < 0.5


def test_nothing_feasible_is_infeasible_with_a_reason():
    empty = Scene([], Robot(DEFAULT_GRID.position((1, 1, 1))))
    d = decide(np.zeros((0, len(ACTIONS))), [], empty, params={"distance": 1.0})
    assert d.status == "infeasible" and d.reason.startswith("no feasible intent")
    assert d.action is None and d.confidence == 0.0


def test_params_pour_gets_its_angle_moves_their_distance_others_nothing():
    scene = scene_holding_box()
    scene.robot.holding = None
    scene.robot.gripper_open = True
    scene.get("box1").position = (0.44, -0.06, 0.025)
    move = decide(joint_of(scene, {("move_up", "cup1"): 1.0}), scene.names, scene,
                  params={"distance": 0.1, "angle_deg": 30})
    assert move.params == {"distance": 0.1}
    grab = decide(joint_of(scene, {("pick_up", "cup1"): 1.0}), scene.names, scene,
                  params={"distance": 0.1})
    assert grab.params == {}
    pouring = scene_with_full_cup()
    pour = decide(joint_of(pouring, {("pour", "cup2"): 1.0}), pouring.names, pouring)
    assert (pour.action, pour.params) == ("pour", {"angle_deg": 90.0})
    pour = decide(joint_of(pouring, {("pour", "cup2"): 1.0}), pouring.names, pouring,
                  DecisionConfig(pour_angle_deg=80.0), params={"angle_deg": 45})
    assert pour.params == {"angle_deg": 45.0}


def scene_with_full_cup() -> Scene:
    scene = Scene([SceneObject("cup1", "cup", (0.44, 0.06, 0.26), 0.06, full=True),
                   SceneObject("cup2", "cup", (0.32, -0.18, 0.03), 0.06)],
                  Robot((0.44, 0.06, 0.26), False, "cup1"))
    assert scene.problems() == []
    return scene


def test_the_batch_decision_agrees_with_the_one_by_one_decision():
    rng = np.random.default_rng(0)
    items = list(datasets.samples("D4", 40, seed=30))
    ds = datasets.to_dataset(items)
    joint = rng.dirichlet(np.full(7 * len(ACTIONS), 0.3), size=40).reshape(40, 7, len(ACTIONS))
    mask = ds.obj_type >= 0
    joint = joint * mask[..., None]
    joint /= joint.sum((1, 2), keepdims=True)
    action, slot, confidence = decide_arrays(joint, ds.feasible, mask)
    for i, s in enumerate(items):
        n = len(s.scene.objects)
        d = decide(joint[i, :n], s.scene.names, s.scene, DecisionConfig(min_confidence=0.0,
                                                                         clarify=False))
        assert d.action == ACTIONS[action[i]]
        assert d.object == (s.scene.names[slot[i]] if slot[i] >= 0 else None)
        assert d.confidence == pytest.approx(confidence[i])
