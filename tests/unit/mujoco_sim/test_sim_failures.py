"""Failure injection in the real simulation: a slipped grasp, an obstacle in the way, a stop
mid-motion. Every scene the robot reports, during the action and after it, is consistent
(`check_consistent`), and it is the physical truth: a dropped cup is not held and is reported
where it comes to rest; a held object is between both fingers; an object reported on the table
touches it. The planner's next decision on the reported world is one the robot can execute."""

import time

import mujoco
import numpy as np
import pytest

from cbgo import world
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.services.planner.sequence import predict
from cbgo.world import Scene

FALLING_SPEED = 0.02  # m/s: above it an object reported in mid-air may truly be falling
TOUCH_GAP = 0.003  # m: an object at rest this close to its support stands on it


def _intent(action, obj=None, params=None):
    return {"v": 1, "ts": time.time(), "episode": "ep-1", "action": action, "object": obj,
            "params": params or {}, "p_action": {action: 0.9},
            "p_object": {obj: 0.9} if obj else {}, "confidence": 0.9, "status": "accepted",
            "reason": "", "model": "test"}


class Injector:
    """Calls `fault(sim)` once, at the first control tick of the next action where
    `when(sim, tick)` holds (an int: that tick), and `after(sim)` on every tick after it;
    checks the scene of every tick."""

    def __init__(self, sim, when, fault, after=None):
        self.when = (lambda _s, n: n == when) if isinstance(when, int) else when
        self.fault, self.after, self.ticks, self.fired, self.problems = fault, after, 0, None, []
        sim.on_tick = self

    def __call__(self, sim):
        self.ticks += 1
        if self.fired is None and self.when(sim, self.ticks):
            self.fired = self.ticks
            self.fault(sim)
        elif self.fired is not None and self.after is not None:
            self.after(sim)
        # what mujoco-sim publishes from inside the control loop
        self.problems += [(self.ticks, p) for p in _mid_motion_problems(sim)]


def _speed(sim, name):
    return float(np.linalg.norm(sim.data.cvel[sim.items[name].body][3:]))


def _mid_motion_problems(sim):
    """check_consistent, except an object reported in mid-air while it does fall."""
    falling = [n for n, it in sim.items.items() if it.type != "drawer"
               and _speed(sim, n) > FALLING_SPEED]
    return [p for p in world.check_consistent(observe.scene_state(sim, 0))
            if not any(p.startswith(f"{n} is reported on the table, but") for n in falling)]


def _untrue(sim, scene):
    """Returns where a reported scene differs from the physics (objects at rest only)."""
    out = []
    held = scene["robot"]["holding"]
    if held is not None and not all(sim.finger_contacts(sim.items[held].geoms)):
        out.append(f"{held} is reported held but not between both fingers")
    for obj in scene["objects"]:
        name, item = obj["name"], sim.items[obj["name"]]
        if item.type == "drawer" or name == held or _speed(sim, name) > FALLING_SPEED:
            continue
        if obj["on"] is not None:
            base = sim.items[obj["on"]]
            surface = ([sim.model.geom(f"{base.name}/cab_top").id] if base.type == "drawer"
                       else base.geoms)
            if _gap(sim, item.geoms, surface) > TOUCH_GAP:
                out.append(f"{name} is reported on {base.name} but does not touch it")
        if obj["on"] is None and obj["inside"] is None \
                and _gap(sim, item.geoms, [sim.built.table_geom]) > TOUCH_GAP:
            out.append(f"{name} is reported on the table but does not touch it")
    return out


def _gap(sim, geoms_a, geoms_b):
    """The smallest distance between two sets of geoms (m; negative: they penetrate)."""
    fromto = np.zeros(6)
    return min(mujoco.mj_geomDistance(sim.model, sim.data, a, b, 0.1, fromto)
               for a in geoms_a for b in geoms_b)


def _after(sim, injector):
    """The scene after the action: consistent, true, and every tick's scene consistent."""
    sim.on_tick = None
    scene = observe.scene_state(sim, 0)
    assert world.check_consistent(scene) == []
    assert injector.problems == []
    assert _untrue(sim, scene) == []
    return scene


def _fits(robot, scene, intent):
    """The planner's plan on the reported scene; its first step succeeds in the physics."""
    forecast = predict(intent, Scene.from_dict(scene))
    assert forecast.ok, forecast.error
    action, obj, params = forecast.steps[0]
    assert world.feasible(action, obj, Scene.from_dict(scene), params)
    outcome = robot.execute(action, obj, params)
    assert outcome.ok, f"{action}({obj}): {outcome.error}"
    return [(a, o) for a, o, _ in forecast.steps]


@pytest.fixture
def world_with(fixed_scene):
    """Returns a function: the fixed scene loaded, these actions done -> (sim, robot)."""
    def make(*steps):
        sim = scenes.load(fixed_scene).sim
        robot = Robot(sim)
        for action, obj in steps:
            assert robot.execute(action, obj, {}).ok
        return sim, robot
    return make


def _drop(sim):
    sim.detach()
    sim.set_fingers(0.04)


def test_a_cup_dropped_mid_move_is_reported_not_held_and_where_it_comes_to_rest(world_with):
    sim, robot = world_with(("pick_up", "cup1"))
    injector = Injector(sim, 5, _drop)
    outcome = robot.execute("move_right", None, {})
    assert not outcome.ok and not outcome.refused and "dropped" in outcome.error
    scene = _after(sim, injector)
    cup = next(o for o in scene["objects"] if o["name"] == "cup1")
    assert scene["robot"]["holding"] is None and (cup["on"], cup["inside"]) == (None, None)
    assert cup["full"] is False  # it spilled as it fell
    sim.settle(2.0)  # where it lies: nothing moves on after the report
    assert np.linalg.norm(np.subtract(sim.pose("cup1")[0], cup["position"])) < 0.01
    # the planner, asked to pour from it, reports why not; asked to put it away, replans
    assert not predict(_intent("pour", "cup2"), Scene.from_dict(scene)).ok
    steps = _fits(robot, scene, _intent("put_into", "drawer1", {"source": "cup1"}))
    assert steps == [("open", "drawer1"), ("pick_up", "cup1"), ("put_into", "drawer1")]


def _held_for(name, ticks):
    """A condition: `name` has been held for this many control ticks."""
    since = {}

    def when(sim, n):
        if sim.holding == name:
            since.setdefault("tick", n)
        return "tick" in since and n == since["tick"] + ticks
    return when


class Slip:
    """A slipped grasp: the weld goes and the cup's grip on the pads is lost (friction 0)
    until it has left the fingers; then it has its friction back, to land as cups do."""

    def __init__(self, sim, name):
        self.geoms = list(sim.items[name].geoms)
        self.friction = sim.model.geom_friction[self.geoms].copy()

    def fault(self, sim):
        sim.model.geom_friction[self.geoms] = 0.0
        sim.model.geom_priority[self.geoms] = 10  # its friction, not the pads', rules
        sim.detach()

    def after(self, sim):
        if not any(sim.finger_contacts(self.geoms)):
            sim.model.geom_friction[self.geoms] = self.friction


def test_a_cup_slipping_out_of_the_fingers_while_lifted_is_reported_where_it_landed(world_with):
    sim, robot = world_with()
    slip = Slip(sim, "cup1")
    injector = Injector(sim, _held_for("cup1", 5), slip.fault, slip.after)
    outcome = robot.execute("pick_up", "cup1", {})
    assert injector.fired is not None, "the grasp was never made: nothing was injected"
    assert not outcome.ok and "not held" in outcome.error
    scene = _after(sim, injector)
    cup = next(o for o in scene["objects"] if o["name"] == "cup1")
    assert scene["robot"]["holding"] is None and cup["inside"] is None
    sim.settle(2.0)
    assert np.linalg.norm(np.subtract(sim.pose("cup1")[0], cup["position"])) < 0.01


def _box_under_the_tcp(sim):
    tcp, item = sim.tcp()[0], sim.items["box2"]
    sim.data.qpos[item.qpos:item.qpos + 7] = [tcp[0], tcp[1], item.dims.half_height + 0.0005,
                                              1, 0, 0, 0]
    dof = sim.model.body_dofadr[item.body]
    sim.data.qvel[dof:dof + 6] = 0.0


def test_an_obstacle_in_the_way_down_fails_the_move_and_the_scene_says_where_things_are(
        world_with):
    sim, robot = world_with(("pick_up", "cup1"), ("move_down", None))
    injector = Injector(sim, 1, _box_under_the_tcp)  # after the plan checked the way
    outcome = robot.execute("move_down", None, {})
    assert not outcome.ok and not outcome.refused and "did not reach" in outcome.error
    scene = _after(sim, injector)
    box = next(o for o in scene["objects"] if o["name"] == "box2")
    assert scene["robot"]["holding"] == "cup1"
    assert np.linalg.norm(np.subtract(box["position"][:2], sim.tcp()[0][:2])) < 0.03
    assert _fits(robot, scene, _intent("place"))[0][0] == "place"


@pytest.mark.parametrize("action, obj, before, at", [
    ("pick_up", "cup1", (), 30),       # on the way down to the cup
    ("pick_up", "cup1", (), 66),       # lifting it
    ("place", None, (("pick_up", "cup1"),), 10),  # carrying it
    ("place", None, (("pick_up", "cup1"),), 46),  # letting go
    ("open", "drawer1", (), 50),       # pulling the handle
    ("move_left", None, (("pick_up", "cup2"),), 8),
])
def test_a_stop_mid_motion_leaves_a_true_consistent_scene(world_with, action, obj, before, at):
    sim, robot = world_with(*before)
    injector = Injector(sim, at, lambda s: s.stop.set())
    outcome = robot.execute(action, obj, {})
    assert outcome.error == "stopped" and injector.ticks == at
    scene = _after(sim, injector)
    assert sim.grasped_drawer() is None  # no hidden weld to a handle outlives the stop
    sim.stop.clear()
    goal = _intent("place") if scene["robot"]["holding"] else _intent("pick_up", "cup1")
    _fits(robot, scene, goal)
