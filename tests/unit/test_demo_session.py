"""The demo's scripted sessions: parsing, goals, fault schedules (no processes)."""

import copy

import pytest

from cbgo.demo.runner import ALL_FAULTS, Fault, parse_faults
from cbgo.demo.session import Expect, goal_failures, load_session, parse_session
from cbgo.errors import ConfigError
from cbgo.world import Scene, apply


def paper_data():
    import yaml

    from cbgo.demo.session import BUNDLED
    return yaml.safe_load((BUNDLED / "paper.yaml").read_text())


def scene_message(scene: Scene) -> dict:
    return scene.to_message(1, 0.0)


def test_the_bundled_session_tells_the_papers_story():
    session = load_session("paper")
    expected = [(s.user, s.expect.status, s.expect.action, s.expect.object)
                for s in session.steps]
    assert expected == [
        ("user1", "accepted", "pick_up", "cup1"), ("user1", "accepted", "pour", "cup2"),
        ("user1", "accepted", "put_into", "drawer1"), ("user1", "accepted", "pick_up", "box1"),
        ("user2", "accepted", "pick_up", "cup2"), ("user2", "accepted", "move_left", None),
        ("user1", "accepted", "move_right", None)]
    # only the grab without a look must be asked back (and answered) first
    assert [s.ask for s in session.steps] == [False, False, False, True, False, False, False]
    drawer = next(o for o in session.scene["objects"] if o["name"] == "drawer1")
    assert drawer["open"] is False  # the tree must open it
    # user2 makes the very gesture user1 makes for the opposite move
    assert session.steps[5].gestures == session.steps[6].gestures == ["swipe_right"]


def test_the_scripted_goals_hold_on_the_world_model_executing_the_story():
    session = load_session("paper")
    world = Scene.from_dict(session.scene)
    world.settle()
    plans = [[("pick_up", "cup1")], [("pour", "cup2")],
             [("place", None), ("open", "drawer1"), ("pick_up", "cup1"),
              ("put_into", "drawer1")], [("pick_up", "box1")],
             [("place", None), ("pick_up", "cup2")], [("move_left", None)],
             [("move_right", None)]]
    for step, plan in zip(session.steps, plans, strict=True):
        before = scene_message(world)
        for action, obj in plan:
            world = apply(action, obj, {}, world)
        assert goal_failures(step.goal, before, scene_message(world)) == [], step.say


def test_goal_failures_name_what_does_not_hold():
    session = load_session("paper")
    world = Scene.from_dict(session.scene)
    world.settle()
    before = scene_message(world)
    after = scene_message(apply("pick_up", "cup2", {}, world))
    assert goal_failures({"holding": "cup1"}, before, after) == [
        "the robot holds 'cup2', expected 'cup1'"]
    assert goal_failures({"unchanged": True}, before, after) == [
        "the world changed, expected nothing to be executed"]
    assert goal_failures({"unchanged": True}, before, before) == []
    assert goal_failures({"full": {"cup1": False}}, before, after) == [
        "cup1.full is True, expected False"]
    moved = goal_failures({"moved": "right"}, before, after)  # it went left, to cup2
    assert len(moved) == 1 and moved[0].startswith("the TCP moved")


def test_expectations_compare_only_what_they_name():
    expect = Expect("accepted", "move_left")
    assert expect.mismatch({"status": "accepted", "action": "move_left", "object": "x"}) is None
    assert expect.mismatch({"status": "low_confidence", "action": None}) == (
        "status is 'low_confidence', expected 'accepted'")
    assert Expect("low_confidence").label() == "low_confidence"


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["steps"][0].update(gesturs=["grab"]), "unknown field(s) ['gesturs']"),
    (lambda d: d["steps"][0].update(user="nobody"), "user 'nobody' is not in users"),
    (lambda d: d["steps"][0]["expect"].update(status="maybe"), "expect.status: 'maybe'"),
    (lambda d: d["steps"][0]["goal"].update(moved="sideways"), "moved: 'sideways'"),
    (lambda d: d["steps"][0].update(gestures=["wave"]), "unknown gesture 'wave'"),
    (lambda d: d["scene"]["objects"].append(dict(d["scene"]["objects"][0])), "scene:"),
    (lambda d: d.update(steps=[]), "non-empty 'steps'"),
])
def test_a_malformed_session_is_refused_with_the_step_and_field(edit, message):
    data = copy.deepcopy(paper_data())
    edit(data)
    with pytest.raises(ConfigError) as info:
        parse_session(data, "s.yaml")
    assert message in str(info.value)


def test_an_unknown_session_name_lists_the_bundled_ones():
    with pytest.raises(ConfigError, match="bundled sessions: paper"):
        load_session("no-such-session")


def test_fault_schedules():
    assert parse_faults("planner@2:plan, router@1:before,episode@3", 7) == [
        Fault(1, "plan", "planner"), Fault(0, "before", "router"), Fault(2, "gesture", "episode")]
    every = parse_faults("all", 7)
    assert sorted(f.target for f in every) == sorted(
        ["router", "leap-bridge", "static-gesture", "dynamic-gesture", "episode", "intent",
         "planner", "robot"])
    assert len(every) == len(ALL_FAULTS)
    assert max(f.step for f in parse_faults("all", 3)) == 2  # clamped to a short session
    with pytest.raises(ValueError, match="STEP in 1..7"):
        parse_faults("planner@9", 7)
    with pytest.raises(ValueError, match="phase must be"):
        parse_faults("planner@1:later", 7)


@pytest.mark.parametrize("ask, expect, problem", [
    ("yes", {"status": "accepted", "action": "pick_up", "object": "box1"},
     "ask: expected true or false"),
    (True, {"status": "low_confidence"}, "a question is answered with the expected intent"),
])
def test_a_step_that_must_be_asked_back_is_checked(ask, expect, problem):
    data = paper_data()
    data["steps"][3] = {**data["steps"][3], "ask": ask, "expect": expect}
    with pytest.raises(ConfigError, match=problem):
        parse_session(data)
