"""The tree's plumbing: which scene it sees, and what an interrupted action leaves behind."""

from concurrent.futures import Future

from planner_worlds import FakeRobot, cup, drawer, intent, scene
from py_trees.common import Status

from cbgo.services.planner import repair
from cbgo.services.planner.scenes import SceneSource
from cbgo.services.planner.tree import create_tree
from cbgo.world import Scene

PAPER = scene(cup("cup1", 1, 2), drawer("drawer1", 0), holding="cup1")


def message(ts, holding=None, drawer_open=False):
    body = scene(cup("cup1", 1, 2), drawer("drawer1", 0, open=drawer_open), holding=holding)
    return {"v": 1, "ts": ts, "seq": 0, **body}


def test_the_newest_scene_wins_by_its_timestamp():
    scenes = SceneSource()
    assert not scenes.ready
    assert scenes.observe(message(10.0, holding="cup1"))
    assert not scenes.observe(message(9.0))  # taken before the one we have
    assert scenes.scene().robot.holding == "cup1" and scenes.last_held == "cup1"


def test_observations_wait_while_an_action_runs():
    scenes = SceneSource()
    scenes.observe(message(10.0))
    scenes.hold()
    assert not scenes.observe(message(11.0, drawer_open=True))  # half-open: our own action
    assert not scenes.scene().get("drawer1").open
    scenes.release(message(12.0, drawer_open=True))  # the reply: the scene after the action
    assert scenes.scene().get("drawer1").open
    scenes.hold()
    scenes.observe(message(14.0))  # someone closed it after our reply
    scenes.release(message(13.0, drawer_open=True))
    assert not scenes.scene().get("drawer1").open


class PendingRobot:
    """A robot whose replies the test delivers by hand."""

    def __init__(self):
        self.futures, self.cancelled = [], []

    def send(self, action, obj, params):
        self.futures.append(((action, obj), Future()))
        return self.futures[-1][1]

    def cancel(self, future):
        self.cancelled.append(future)


def test_an_interrupted_action_is_abandoned_and_the_scene_released():
    robot = PendingRobot()
    scenes = SceneSource(Scene.from_dict(PAPER))
    plan = create_tree(intent("put_into", "drawer1"), scenes, robot)
    assert plan.tick() == Status.RUNNING and scenes.busy
    (sent, future), = robot.futures
    assert sent == ("place", "cup1")
    future.set_result(FakeRobot(PAPER).act("place", "cup1"))  # the reply arrives, untaken
    plan.stop()
    assert robot.cancelled == [future] and not scenes.busy
    assert [s.state for s in plan.state.steps] == ["failed"]


def test_a_pending_action_is_polled_until_its_reply():
    robot = PendingRobot()
    scenes = SceneSource(Scene.from_dict(PAPER))
    plan = create_tree(intent("open", "drawer1"), scenes, robot)
    for _ in range(3):
        assert plan.tick() == Status.RUNNING
    assert len(robot.futures) == 1
    fake = FakeRobot(PAPER)
    robot.futures[0][1].set_result(fake.act("place", "cup1"))
    assert plan.tick() == Status.RUNNING  # the reply is taken; no new action in this tick
    assert len(robot.futures) == 1
    assert plan.tick() == Status.RUNNING and robot.futures[-1][0] == ("open", "drawer1")
    robot.futures[-1][1].set_result(fake.act("open", "drawer1"))
    assert plan.tick() == Status.SUCCESS


def test_arm_inside_needs_an_open_drawer_and_the_tcp_over_its_tray_below_its_top():
    world = Scene.from_dict(scene(drawer("drawer1", 0, open=True), tcp=(0.60, -0.18, 0.05)))
    assert repair.arm_inside(world, "drawer1")
    world.robot.tcp = (0.60, -0.18, 0.16)
    assert not repair.arm_inside(world, "drawer1")
    world.robot.tcp = (0.60, -0.18, 0.05)
    world.get("drawer1").open = False
    assert not repair.arm_inside(world, "drawer1")


def test_the_source_rule_takes_the_named_then_the_held_then_the_last_held_object():
    world = Scene.from_dict(scene(cup("cup1", 0, 0, full=True), cup("cup2", 1, 3),
                                  cup("cup3", 0, 3), drawer("drawer1", 0, open=True)))
    memory = repair.PlanMemory(source_hint="cup2", payload="cup3", last_held="cup1")
    assert repair.choose_source("put_into", "drawer1", world, memory) == "cup2"
    memory = repair.PlanMemory(payload="cup3", last_held="cup1")
    assert repair.choose_source("put_into", "drawer1", world, memory) == "cup3"
    memory = repair.PlanMemory(last_held="cup1")
    assert repair.choose_source("put_into", "drawer1", world, memory) == "cup1"
    # pour takes only full cups: the payload cup3 is empty
    memory = repair.PlanMemory(payload="cup3", attention=("cup2", "cup3"))
    assert repair.choose_source("pour", "cup2", world, memory) == "cup1"
    assert repair.choose_source("put_into", "drawer1", world, repair.PlanMemory()) is None
