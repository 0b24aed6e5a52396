"""The planner refuses what `cbgo replay` sends (``replayed: true``) unless told to accept it."""

from planner_worlds import FakeRobot, cup, drawer, intent, scene

from cbgo import keys
from cbgo.services.planner.main import Planner, PlannerSettings
from cbgo.testing import FakeBus

WORLD = scene(cup("cup1", 1, 2), drawer("drawer1", 0), holding="cup1")


def planner(robot, **settings):
    bus = FakeBus(Planner(PlannerSettings(**settings), inline_queries=True))
    bus.answer(keys.ROBOT_ACT, robot.reply)
    bus.feed(keys.SCENE_STATE, robot.message())
    return bus


def tick(bus, n=40):
    out = []
    for _ in range(n):
        out += bus.tick(0.05)
    return out


def test_a_replayed_intent_moves_nothing_and_is_counted_and_logged(caplog):
    robot = FakeRobot(WORLD)
    bus = planner(robot)
    bus.feed(keys.INTENT, {**intent("put_into", "drawer1"), "replayed": True})
    out = tick(bus)
    assert robot.queries == [] and out == []
    ok, status = bus.query("status", None)
    assert ok and status["plans"]["refused_replayed"] == 1
    assert status["plans"]["accepted"] == 0 and status["robot_acts_sent"] == 0
    assert "refused a replayed intent put_into(drawer1)" in caplog.text
    assert "--accept-replayed" in caplog.text


def test_a_replayed_scene_is_not_planned_on():
    robot = FakeRobot(WORLD)
    bus = planner(robot)
    bus.feed(keys.SCENE_STATE, {**robot.message(), "objects": [], "replayed": True})
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))  # a live intent: planned on live scenes
    tick(bus, 200)
    assert robot.log[-1] == ("put_into", "drawer1")
    ok, status = bus.query("status", None)
    assert status["plans"] == {**status["plans"], "refused_replayed": 1, "succeeded": 1}


def test_with_accept_replayed_a_replayed_intent_runs():
    robot = FakeRobot(WORLD)
    bus = planner(robot, accept_replayed=True)
    bus.feed(keys.INTENT, {**intent("put_into", "drawer1"), "replayed": True})
    tick(bus, 200)
    assert robot.log[-1] == ("put_into", "drawer1")
    ok, status = bus.query("status", None)
    assert status["plans"]["refused_replayed"] == 0 and status["plans"]["succeeded"] == 1
