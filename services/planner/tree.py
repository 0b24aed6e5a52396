"""The behaviour tree of one intent: the intent is the goal, guards repair what the user left out.

`create_tree(intent, scenes, robot)` builds it (pure: no Zenoh; the robot is anything with
``send(action, object, params) -> Future`` and ``cancel(future)``). The shape is the
postcondition-precondition-action pattern (Colledanchise & Ögren), unrolled once per action::

    [o] put_into(drawer1)                        selector: goal already reached? (pick_up, open,
        --> goal reached?                        close only) else achieve it
        [-] achieve put_into(drawer1)            sequence without memory: re-checked every tick
            [o] drawer1 open                     a guard: its condition, else its repair,
                --> drawer1 open?                repeated until the condition holds
                -^- repair until drawer1 open
                    [-] achieve open(drawer1)    the repair achieves another action, with its
                        ...                      own guards (gripper empty: place first)
            [o] holding the source
                ...
            --> put_into(drawer1) feasible?      every other precondition: no repair -> FAILURE
            --> put_into(drawer1)                `Act`: one primitive on cbgo/robot/act

Rules:
- reactive: sequences have no memory, so each tick re-checks every guard against the scene
  (`SceneSource`); a drawer closed by someone meanwhile is opened again;
- one robot action at a time; the scene is frozen while it runs, and no action is sent in the
  tick in which another one's reply arrived, so the whole tree is re-checked before each send;
- a failed action is retried once (after that re-evaluation), then fails with the robot's error;
- bounded: the structure is finite (repairs name the actions they need, never themselves), and
  at most ``max_repairs`` repair actions are sent per intent; then the tree fails;
- which repairs exist, and which object a fetch takes, is `repair`'s table.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any, Protocol

import py_trees
from py_trees.common import Status

from cbgo.services.planner import repair
from cbgo.services.planner.scenes import SceneSource
from cbgo.world import MOVES, Scene

RETRIES = 1  # a failed robot action is sent once more before the tree fails


class RobotPort(Protocol):
    """What the tree needs of a robot: send one primitive, abandon one."""

    def send(self, action: str, obj: str | None, params: dict) -> Future:
        """Starts one primitive; the future resolves to a ``robot/act`` reply dict."""

    def cancel(self, future: Future) -> None:
        """Abandons a primitive (its reply is ignored; robot/stop stops the motion)."""


@dataclass
class Step:
    """One primitive of the plan, as ``plan/status`` lists it."""

    action: str
    object: str | None
    params: dict
    state: str = "pending"
    goal: bool = False  # the intended action itself, not a repair

    def as_dict(self) -> dict[str, Any]:
        """Returns the contract's step: ``{action, object, params, state}``."""
        return {"action": self.action, "object": self.object, "params": dict(self.params),
                "state": self.state}


@dataclass
class PlanState:
    """What the behaviours of one tree share (a typed blackboard)."""

    intent: dict
    scenes: SceneSource
    robot: RobotPort
    memory: repair.PlanMemory
    max_repairs: int = 8
    repairs_used: int = 0
    steps: list[Step] = field(default_factory=list)
    error: str | None = None
    ticks: int = 0
    last_reply_tick: int = -1

    def scene(self) -> Scene:
        """Returns the scene preconditions are checked against."""
        return self.scenes.scene()

    def fail(self, message: str) -> None:
        """Records why the plan failed (the first reason wins: it is the cause)."""
        if self.error is None:
            self.error = message


@dataclass(frozen=True)
class Target:
    """The object of an action: fixed, or resolved from the scene when the tree needs it."""

    label: str
    resolve: Callable[[PlanState], str | None]

    @classmethod
    def named(cls, name: str | None) -> Target:
        """Returns a fixed target (None for actions without one)."""
        return cls(name or "-", lambda _state: name)


HELD = Target("held", lambda state: state.scene().robot.holding)
NOTHING = Target.named(None)
Test = Callable[[PlanState], "str | None"]


# ==================================================================== behaviours


class Check(py_trees.behaviour.Behaviour):
    """A condition: SUCCESS when `test` returns None, else FAILURE with its reason.

    Args:
        name: shown in the tree, e.g. ``drawer1 open?``.
        state: the plan's shared state.
        test: returns None when the condition holds, else why not (a sentence).
        fatal: a failure ends the plan: ``no repair for: <reason>``.
    """

    def __init__(self, name: str, state: PlanState, test: Test, fatal: bool = False):
        super().__init__(name=name)
        self.plan, self.test, self.fatal = state, test, fatal

    def update(self) -> Status:
        """Called every tick the condition is visited: evaluates it on the current scene."""
        reason = self.test(self.plan)
        if reason is None:
            self.feedback_message = ""
            return Status.SUCCESS
        self.feedback_message = reason
        if self.fatal:
            self.plan.fail(f"no repair for: {reason}")
        return Status.FAILURE


class Act(py_trees.behaviour.Behaviour):
    """One primitive on the robot: initialise sends the goal, update polls, terminate cancels.

    Args:
        name: shown in the tree, e.g. ``open(drawer1)``.
        state: the plan's shared state.
        action: the primitive.
        target: its object.
        params: its metric parameters.
        repair: counts against the plan's repair budget (every action but the intended one).
    """

    def __init__(self, name: str, state: PlanState, action: str, target: Target,
                 params: dict | None = None, repair: bool = True):
        super().__init__(name=name)
        self.plan, self.action, self.target = state, action, target
        self.params, self.repair = dict(params or {}), repair
        self._future: Future | None = None
        self._step: Step | None = None
        self._attempts = 0
        self._error: str | None = None

    def initialise(self) -> None:
        """Called when the tree first reaches this action (again): sends it to the robot."""
        self._future, self._step, self._attempts, self._error = None, None, 0, None
        self._send()

    def update(self) -> Status:
        """Called every tick while the action runs: polls the robot's reply."""
        if self._error is not None:
            self.plan.fail(self._error)
            return Status.FAILURE
        if self._future is None:
            self._send()  # deferred, or a retry: after one re-evaluation of the tree
        if self._future is None or not self._future.done():
            return Status.RUNNING
        return self._on_reply(_reply_of(self._future))

    def terminate(self, new_status: Status) -> None:
        """Called when the action ends or is interrupted: abandons a primitive in flight."""
        if new_status != Status.INVALID:
            return
        if self._future is not None:  # in flight, or its reply not yet taken
            self.plan.robot.cancel(self._future)
            self.plan.scenes.release()
        if self._step is not None and self._step.state == "running":
            self._step.state = "failed"
        self._future = None

    def _send(self) -> None:
        state = self.plan
        if state.last_reply_tick == state.ticks:
            # Another action ended during this tick: the rest of this tick saw a tree that was
            # evaluated before its reply; send only after the next tick has re-checked it all.
            self.feedback_message = "waiting for the tree to re-check"
            return
        if self._step is None:
            if self.repair and state.repairs_used >= state.max_repairs:
                self._error = (f"repair budget exhausted: {state.max_repairs} repair actions "
                               f"sent, {self.name} would be one more")
                return
            state.repairs_used += int(self.repair)
            self._step = Step(self.action, self.target.resolve(state), self.params,
                              goal=not self.repair)
            state.steps.append(self._step)
            self.name = f"{self.action}({self._step.object or '-'})"
        self._attempts += 1
        self._step.state = "running"
        state.scenes.hold()
        self._future = state.robot.send(self.action, self._step.object, dict(self.params))
        self.feedback_message = "sent" if self._attempts == 1 else "sent again"

    def _on_reply(self, reply: dict) -> Status:
        self._future = None
        self.plan.scenes.release(reply.get("scene"))
        self.plan.last_reply_tick = self.plan.ticks
        if reply.get("ok"):
            self._step.state = "done"
            self.feedback_message = "done"
            return Status.SUCCESS
        error = reply.get("error") or "the robot refused without a reason"
        if self._attempts <= RETRIES:
            self.feedback_message = f"failed ({error}); retrying"
            return Status.RUNNING
        self._step.state = "failed"
        self.feedback_message = error
        self.plan.fail(f"{self.name} failed {self._attempts} times: {error}")
        return Status.FAILURE


class UntilHolds(py_trees.decorators.SuccessIsRunning):
    """Runs a repair whose success reads as RUNNING.

    So the guard above re-checks its condition on the next tick, and runs the repair again
    (restarted) while the condition still fails.
    """

    def update(self) -> Status:
        """Called every tick after the repair was ticked: success becomes "check again"."""
        if self.decorated.status == Status.SUCCESS:
            self.feedback_message = "repaired; checking again"
            return Status.RUNNING
        self.feedback_message = ""
        return self.decorated.status


def _reply_of(future: Future) -> dict:
    if future.cancelled():
        return {"ok": False, "error": "cancelled", "scene": None}
    error = future.exception()
    if error is not None:
        return {"ok": False, "error": f"robot/act failed: {type(error).__name__}: {error}",
                "scene": None}
    return future.result()


# ==================================================================== tests (conditions)


def _lacks(action: str, target: Target, codes: frozenset[str],
           params: dict | None = None) -> Test:
    """Returns a test that holds while `action` on `target` reports none of `codes`."""

    def test(state: PlanState) -> str | None:
        found = repair.all_failures(action, target.resolve(state), state.scene(), params)
        return next((f.message for f in found if f.code in codes), None)

    return test


def _feasible(action: str, target: Target, params: dict) -> Test:
    def test(state: PlanState) -> str | None:
        found = repair.all_failures(action, target.resolve(state), state.scene(), params)
        return "; ".join(f.message for f in found) or None

    return test


def _goal_reached(action: str, target: Target) -> Test:
    def test(state: PlanState) -> str | None:
        found = repair.all_failures(action, target.resolve(state), state.scene())
        return None if repair.GOAL_CODES[action] in repair.codes(found) else "not reached yet"

    return test


def _source(action: str, target: Target) -> Target:
    def resolve(state: PlanState) -> str | None:
        return repair.choose_source(action, target.resolve(state), state.scene(), state.memory)

    return Target("source", resolve)


def _holds(source: Target, action: str, target: Target) -> Test:
    def test(state: PlanState) -> str | None:
        name = source.resolve(state)
        if name is None:
            return repair.no_source_reason(action, target.resolve(state))
        held = state.scene().robot.holding
        if held == name:
            return None
        return f"{name} is not in the gripper" + (f" ({held} is)" if held else "")

    return test


def _known(source: Target, action: str, target: Target) -> Test:
    def test(state: PlanState) -> str | None:
        if source.resolve(state) is None:
            return repair.no_source_reason(action, target.resolve(state))
        return None

    return test


# ==================================================================== tree construction


def _guard(state: PlanState, name: str, test: Test, fix: py_trees.behaviour.Behaviour):
    """Returns ``name``: SUCCESS if `test` holds, else `fix`, repeated until it holds."""
    return py_trees.composites.Selector(name, memory=False, children=[
        Check(f"{name}?", state, test),
        UntilHolds(f"repair until {name}", fix),
    ])


def _place(state: PlanState) -> py_trees.behaviour.Behaviour:
    return achieve(state, "place", HELD)


def _clear(state: PlanState, target: Target) -> py_trees.behaviour.Behaviour:
    """Takes the top object off the tower on `target` and places it on the table."""
    top = Target(f"top of {target.label}",
                 lambda s: repair.top_of(s.scene(), target.resolve(s)))
    return py_trees.composites.Sequence(f"take the top off {target.label}", memory=True,
                                        children=[achieve(state, "pick_up", top, clearing=True),
                                                  _place(state)])


def _fetch(state: PlanState, action: str, target: Target) -> py_trees.behaviour.Behaviour:
    """Picks the source object of put_into/put_on/pour (placing what else is held first)."""
    source = _source(action, target)
    return py_trees.composites.Sequence(f"fetch the source for {action}", memory=False, children=[
        Check("source known?", state, _known(source, action, target), fatal=True),
        achieve(state, "pick_up", source),
    ])


def _guards(state: PlanState, action: str, target: Target,
            clearing: bool) -> list[py_trees.behaviour.Behaviour]:
    """Returns the guards of `action`, in the order they are checked (see `repair`)."""
    t = target.label
    out = []
    if action in ("pick_up", "put_on") and not clearing:
        out.append(_guard(state, f"{t} free", _lacks(action, target, repair.NOT_FREE),
                          _clear(state, target)))
    if action in ("pick_up", "open", "close"):
        out.append(_guard(state, "gripper empty", _lacks(action, target, repair.HAND_BUSY),
                          _place(state)))
    if action == "close":
        out.append(_guard(state, f"gripper out of {t}", _lacks(action, target, repair.ARM_INSIDE),
                          achieve(state, "move_up", NOTHING)))
    if action == "put_into":
        out.append(_guard(state, f"{t} open", _lacks(action, target, repair.DRAWER_CLOSED),
                          achieve(state, "open", target)))
    if action == "pour":
        drawer = Target(f"drawer of {t}", lambda s: repair.drawer_of(s.scene(), target.resolve(s)))
        out.append(_guard(state, f"{t} out of closed drawers",
                          _lacks(action, target, repair.DRAWER_CLOSED),
                          achieve(state, "open", drawer)))
    if action in repair.FETCH_ACTIONS:
        source = _source(action, target)
        what = "a full cup" if action == "pour" else "the source"
        out.append(_guard(state, f"holding {what}", _holds(source, action, target),
                          _fetch(state, action, target)))
    return out


def achieve(state: PlanState, action: str, target: Target, params: dict | None = None, *,
            repair_action: bool = True, clearing: bool = False) -> py_trees.behaviour.Behaviour:
    """Returns the subtree that performs `action` on `target`, repairing its preconditions.

    Args:
        state: the plan's shared state.
        action: the primitive.
        target: its object.
        params: its metric parameters.
        repair_action: the action is a repair (counts against the budget).
        clearing: the target is the top of a tower being taken apart (it is free by
            construction, so no guard for it; this keeps the structure finite).
    """
    params = dict(params or {})
    label = f"{action}({target.label})"
    return py_trees.composites.Sequence(f"achieve {label}", memory=False, children=[
        *_guards(state, action, target, clearing),
        Check(f"{label} feasible?", state, _feasible(action, target, params), fatal=True),
        Act(label, state, action, target, params, repair=repair_action),
    ])


@dataclass
class PlanTree:
    """A built tree and the state its behaviours share."""

    root: py_trees.behaviour.Behaviour
    state: PlanState

    def tick(self) -> Status:
        """Ticks the tree once; returns the root's status."""
        self.state.ticks += 1
        self.root.tick_once()
        return self.root.status

    def stop(self) -> None:
        """Interrupts the tree: a primitive in flight is abandoned."""
        if self.root.status == Status.RUNNING:
            self.root.stop(Status.INVALID)

    def snapshot(self) -> str:
        """Returns the ASCII drawing of the tree with each behaviour's status."""
        return py_trees.display.ascii_tree(self.root, show_status=True)


def intent_target(intent: dict) -> Target:
    """Returns the target of the intended action: its object, the held one (place), or none."""
    action = intent.get("action")
    if action == "place":
        return HELD
    if action in MOVES:
        return NOTHING
    return Target.named(intent.get("object"))


def create_tree(intent: dict, scenes: SceneSource, robot: RobotPort, *,
                memory: repair.PlanMemory | None = None, max_repairs: int = 8) -> PlanTree:
    """Returns the behaviour tree that executes one intent.

    Args:
        intent: a ``cbgo/intent`` message (its action, object and params are the goal).
        scenes: where the tree reads the scene (it must hold one).
        robot: where it sends primitives.
        memory: what the fetch rule may use (default: from the intent and the current scene).
        max_repairs: repair actions the tree may send before it fails.
    """
    if memory is None:
        memory = repair.PlanMemory.at_start(intent, scenes.scene(), scenes.last_held)
    state = PlanState(intent, scenes, robot, memory, max_repairs)
    action = intent.get("action")
    if action is None:
        return PlanTree(Check("intent has an action?", state, lambda _s: "the intent names no "
                              "action", fatal=True), state)
    target = intent_target(intent)
    params = {k: v for k, v in (intent.get("params") or {}).items() if k != "source"}
    body = achieve(state, action, target, params, repair_action=False)
    if action not in repair.GOAL_CODES:
        return PlanTree(body, state)
    root = py_trees.composites.Selector(f"{action}({target.label})", memory=False, children=[
        Check("goal reached?", state, _goal_reached(action, target)), body])
    return PlanTree(root, state)
