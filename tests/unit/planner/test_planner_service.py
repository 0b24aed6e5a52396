"""The planner service through FakeBus: intents in, robot/act queries out, plan/status reported."""

import threading
import time

from planner_worlds import FakeRobot, cup, drawer, intent, scene

from cbgo import keys, wire
from cbgo.services.planner.main import Planner, PlannerSettings
from cbgo.testing import FakeBus

PAPER = scene(cup("cup1", 1, 2), drawer("drawer1", 0), holding="cup1")
PAPER_SEQUENCE = [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"),
                  ("put_into", "drawer1")]


def planner(robot=None, inline=True, **settings):
    """A planner on a FakeBus, answering robot/act with `robot`, fed its first scene."""
    bus = FakeBus(Planner(PlannerSettings(**settings), inline_queries=inline))
    if robot is not None:
        bus.answer(keys.ROBOT_ACT, robot.reply)
        bus.feed(keys.SCENE_STATE, robot.message())
    return bus


def statuses(out):
    return [m for suffix, m in out if suffix == "plan/status"]


def run(bus, ticks=200):
    """Ticks until a plan ends; returns every plan/status published meanwhile."""
    got = []
    for _ in range(ticks):
        got += statuses(bus.tick(0.05))
        if got and got[-1]["state"] != "running":
            return got
    raise AssertionError(f"no plan ended within {ticks} ticks: {got[-1:] or 'no status'}")


def steps(status):
    return [(s["action"], s["object"], s["state"]) for s in status["sequence"]]


def test_an_accepted_intent_runs_to_success_and_reports_each_change():
    robot = FakeRobot(PAPER)
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))
    got = run(bus)
    assert robot.log == PAPER_SEQUENCE
    # Expect: the first status already lists the whole predicted sequence (the robot here
    # answers at once, so the first action is done within the first tick)
    assert steps(got[0]) == [("place", "cup1", "done"), ("open", "drawer1", "pending"),
                             ("pick_up", "cup1", "pending"), ("put_into", "drawer1", "pending")]
    assert steps(got[-1]) == [(a, o, "done") for a, o in PAPER_SEQUENCE]
    assert (got[-1]["state"], got[-1]["error"]) == ("success", None)
    assert [m["state"] for m in got[:-1]] == ["running"] * (len(got) - 1)
    for message in got:
        wire.validate(message, wire.PLAN_STATUS, "cbgo/plan/status")
        assert message["intent"]["action"] == "put_into"
    assert "put_into(drawer1)" in got[-1]["tree"] and "drawer1 open?" in got[-1]["tree"]
    assert bus.counters.errors == 0
    # nothing changes any more: nothing more is published
    assert statuses(bus.tick(0.05) + bus.tick(0.05)) == []


def test_only_accepted_intents_are_executed():
    robot = FakeRobot(PAPER)
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("put_into", "drawer1", status="low_confidence"))
    bus.feed(keys.INTENT, intent("open", "drawer1", status="infeasible"))
    out = []
    for _ in range(10):
        out += bus.tick(0.05)
    assert statuses(out) == [] and robot.queries == []
    ok, status = bus.query("status", None)
    assert ok and status["plans"]["ignored"] == 2 and status["plans"]["accepted"] == 0


def test_a_refused_action_is_retried_once_then_the_plan_fails_with_the_robots_reason():
    robot = FakeRobot(PAPER, refuse={"open": 5}, error="could not grasp the handle of drawer1")
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))
    last = run(bus)[-1]
    assert robot.log == [("place", "cup1"), ("open", "drawer1"), ("open", "drawer1")]
    assert last["state"] == "failure"
    assert last["error"] == ("open(drawer1) failed 2 times: could not grasp the handle of "
                             "drawer1")
    assert steps(last) == [("place", "cup1", "done"), ("open", "drawer1", "failed")]


def test_robot_stop_aborts_the_plan_and_nothing_more_is_sent():
    robot = FakeRobot(PAPER)
    bus = planner(robot)

    def reply_then_stop(query):
        reply = robot.reply(query)
        if query["action"] == "open":
            bus.feed_raw(keys.ROBOT_STOP, b"\xc1 not msgpack: any payload stops")
        return reply

    bus.answer(keys.ROBOT_ACT, reply_then_stop)
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))
    last = run(bus)[-1]
    assert (last["state"], last["error"]) == ("failure", "stopped")
    for _ in range(10):
        bus.tick(0.05)
    assert robot.log == [("place", "cup1"), ("open", "drawer1")]


def test_robot_stop_does_not_wait_for_the_action_in_flight():
    robot = FakeRobot(PAPER)
    started, release = threading.Event(), threading.Event()

    def slow(query):
        started.set()
        release.wait(10)
        return robot.reply(query)

    bus = planner(robot, inline=False)
    bus.answer(keys.ROBOT_ACT, slow)
    try:
        bus.feed(keys.INTENT, intent("put_into", "drawer1"))
        for _ in range(40):  # the planner may wait for a scene newer than the intent
            started_plan = statuses(bus.tick(0.05))
            if started_plan:
                break
        (first,) = started_plan
        assert steps(first)[0] == ("place", "cup1", "running") and len(steps(first)) == 4
        assert started.wait(5)
        bus.feed(keys.ROBOT_STOP, {"v": 1, "ts": 1.0, "reason": "user pressed stop"})
        last = statuses(bus.tick(0.05))[-1]
        assert (last["state"], last["error"]) == ("failure", "stopped: user pressed stop")
        assert steps(last) == [("place", "cup1", "failed")]
    finally:
        release.set()
    deadline = time.monotonic() + 5
    while not robot.log and time.monotonic() < deadline:
        time.sleep(0.01)  # the abandoned query still ends on the worker thread
    for _ in range(5):
        bus.tick(0.05)
    assert robot.log == [("place", "cup1")]
    bus.service.shutdown()


def test_a_new_intent_waits_until_the_running_one_ends():
    robot = FakeRobot(scene(cup("cup1", 1, 2), drawer("drawer1", 0), holding="cup1"))
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("open", "drawer1"))
    got = statuses(bus.tick(0.05))
    bus.feed(keys.INTENT, intent("close", "drawer1"))
    got += run(bus)
    got += run(bus)
    ends = [(m["intent"]["action"], m["state"]) for m in got if m["state"] != "running"]
    assert ends == [("open", "success"), ("close", "success")]
    assert robot.log == [("place", "cup1"), ("open", "drawer1"), ("close", "drawer1")]


def test_a_full_queue_drops_the_oldest_waiting_intent():
    robot = FakeRobot(PAPER)
    bus = planner(robot, queue_size=1)
    bus.feed(keys.INTENT, intent("open", "drawer1"))
    out = bus.feed(keys.INTENT, intent("pick_up", "cup1"))
    (dropped,) = statuses(out)
    assert dropped["intent"]["action"] == "open" and dropped["state"] == "failure"
    assert dropped["error"].startswith("dropped:")
    last = run(bus)[-1]
    assert (last["intent"]["action"], last["state"], last["sequence"]) == ("pick_up", "success",
                                                                           [])


def test_a_plan_the_world_model_rejects_fails_without_moving():
    robot = FakeRobot(scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3, full=True),
                            holding="cup1"))
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("pour", "cup2"))
    last = run(bus)[-1]
    assert last["state"] == "failure" and robot.queries == []
    assert last["error"].startswith("no repair for: cup2 is already full")
    assert "nothing was sent to the robot" in last["error"]


def test_an_intent_fails_when_no_scene_arrives():
    bus = planner(scene_timeout_s=0.2)
    bus.feed(keys.INTENT, intent("open", "drawer1"))
    last = run(bus)[-1]
    assert last["state"] == "failure" and "no cbgo/scene/state within 0.2 s" in last["error"]


def test_a_robot_that_does_not_answer_fails_the_plan_with_that_reason():
    robot = FakeRobot(PAPER)
    bus = planner(robot)
    del bus.transport.responders[bus.keys.of(keys.ROBOT_ACT)]
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))
    last = run(bus)[-1]
    assert last["state"] == "failure"
    assert last["error"].startswith("place(cup1) failed 2 times: no reply on cbgo/robot/act")


def test_status_counts_plans():
    robot = FakeRobot(PAPER)
    bus = planner(robot)
    bus.feed(keys.INTENT, intent("put_into", "drawer1"))
    run(bus)
    ok, status = bus.query("status", None)
    wire.validate(status, wire.SERVICE_STATUS)
    assert status["plans"]["succeeded"] == 1 and status["robot_acts_sent"] == 4
    assert status["current"] is None and status["waiting"] == 0
