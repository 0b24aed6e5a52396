"""A robot made of the world model, for planner tests (never imported by cbgo).

`FakeRobot` executes each primitive at once with `cbgo.world.apply` and refuses, with the
world model's reason, what it forbids. Scripting hooks make it misbehave on purpose:

- ``refuse={"pick_up": 1}``: refuse the first pick_up (``{"pick_up": 9}``: every one) with
  ``error`` ("could not grasp: only one finger touched it");
- ``after=fn(action, scene) -> scene``: change the world after an action, as someone else would
  (close a drawer the planner has just opened).

It answers like a ``cbgo/robot/act`` queryable (`reply`, for `FakeBus.answer`) or like the
planner's robot port (`send`, a completed future). Run as a script, it is a service named
``symbolic-robot``: it answers ``cbgo/robot/act`` and ``cbgo/sim/reset`` (``scene`` or
``seed``), publishes ``cbgo/scene/state`` after each change and every ``--period-s``, and honours
``cbgo/robot/stop`` during its ``--delay-s`` per action::

    python tests/fakes/symbolic_robot.py --delay-s 0.5
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field

from cbgo import keys, wire
from cbgo.errors import QueryError
from cbgo.runtime import Service, run
from cbgo.world import InfeasibleAction, Scene, apply, random_scene


class FakeRobot:
    """A symbolic robot with scripted faults.

    Args:
        scene: the world (a Scene or a contract scene dict).
        refuse: action -> how many of its next requests to refuse.
        error: the refusal's reason.
        after: called after each successful action; returns the world as it is then.
    """

    def __init__(self, scene: Scene | dict, refuse: dict[str, int] | None = None,
                 error: str = "could not grasp: only one finger touched it",
                 after: Callable[[str, Scene], Scene] | None = None):
        self.scene = Scene.from_dict(scene) if isinstance(scene, dict) else scene.copy()
        self.refuse = dict(refuse or {})
        self.error, self.after = error, after
        self.log: list[tuple[str, str | None]] = []
        self.queries: list[dict] = []
        self.seq = 0

    def message(self) -> dict:
        """Returns the world as a ``cbgo/scene/state`` message."""
        self.seq += 1
        return self.scene.to_message(self.seq, time.time())

    def act(self, action: str, obj: str | None, params: dict | None = None) -> dict:
        """Executes one primitive; returns the ``robot/act`` reply."""
        self.log.append((action, obj))
        if self.refuse.get(action, 0) > 0:
            self.refuse[action] -= 1
            return {"v": 1, "ok": False, "error": self.error, "duration_s": 0.0,
                    "scene": self.message()}
        try:
            self.scene = apply(action, obj, params or {}, self.scene)
        except InfeasibleAction as e:
            return {"v": 1, "ok": False, "error": f"refused: {e}", "duration_s": 0.0,
                    "scene": self.message()}
        if self.after is not None:
            self.scene = self.after(action, self.scene)
        return {"v": 1, "ok": True, "error": None, "duration_s": 0.1, "scene": self.message()}

    def reply(self, query: dict) -> dict:
        """Answers a ``robot/act`` query (for `cbgo.testing.FakeBus.answer`)."""
        self.queries.append(query)
        return self.act(query["action"], query["object"], query["params"])

    def send(self, action: str, obj: str | None, params: dict) -> Future:
        """The planner's robot port: executes at once, returns a completed future."""
        future: Future = Future()
        future.set_result(self.act(action, obj, params))
        return future

    def cancel(self, future: Future) -> None:
        """Nothing to cancel: every action ends inside `send`."""


# ============================================================================ as a service


@dataclass
class SymbolicRobotSettings:
    delay_s: float = field(default=0.0, metadata={"help": "seconds each action takes"})
    period_s: float = field(default=0.5, metadata={"help": "scene/state period, s"})
    refuse: list[str] = field(default_factory=list, metadata={
        "help": "actions always refused (with 'the target is out of reach')"})


class SymbolicRobotService(Service):
    name = "symbolic-robot"
    description = "A robot made of the world model, for planner tests."
    settings_class = SymbolicRobotSettings

    def setup(self, ctx):
        self.ctx = ctx
        self.robot = FakeRobot(random_scene(0))
        self.stopped = threading.Event()
        self.stops = 0
        ctx.queryable(keys.ROBOT_ACT, self.on_act)
        ctx.queryable(keys.SIM_RESET, self.on_reset)
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.publishes(keys.SCENE_STATE)
        ctx.every(self.settings.period_s, lambda: [(keys.SCENE_STATE, self.robot.message())])

    def on_act(self, query):
        self.stopped.clear()
        if self.stopped.wait(self.settings.delay_s):
            return {"v": 1, "ok": False, "error": "stopped", "duration_s": 0.0,
                    "scene": self.robot.message()}
        if query["action"] in self.settings.refuse:
            self.robot.log.append((query["action"], query["object"]))
            return {"v": 1, "ok": False, "error": "refused: the target is out of reach",
                    "duration_s": 0.0, "scene": self.robot.message()}
        reply = self.robot.reply(query)
        self.ctx.publish(keys.SCENE_STATE, reply["scene"])
        return reply

    def on_reset(self, query):
        if "scene" in query:
            scene = Scene.from_dict(query["scene"])
            problems = scene.problems()
            if problems:
                raise QueryError("; ".join(problems))
            scene.settle()
        else:
            scene = random_scene(query.get("seed", 0))
        self.robot = FakeRobot(scene)
        message = self.robot.message()
        self.ctx.publish(keys.SCENE_STATE, message)
        return {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "scene": message}

    def on_stop(self, _msg):
        self.stops += 1
        self.stopped.set()

    def status_extra(self):
        return {"log": [list(x) for x in self.robot.log], "stops": self.stops}


if __name__ == "__main__":
    sys.exit(run(SymbolicRobotService, sys.argv[1:]))
