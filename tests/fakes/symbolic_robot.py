"""dry-robot with scripted faults, for planner tests (never imported by cbgo).

The robot logic is dry-robot's (`cbgo.services.dry_robot`): `FakeRobot` is its
`SymbolicRobot` (each primitive executed at once with `cbgo.world.apply`, refused with the world
model's reason when the model forbids it) plus scripting hooks that make it misbehave on
purpose:

- ``refuse={"pick_up": 1}``: refuse the first pick_up (``{"pick_up": 9}``: every one) with
  ``error`` ("could not grasp: only one finger touched it");
- ``after=fn(action, scene) -> scene``: change the world after an action, as someone else would
  (close a drawer the planner has just opened).

It answers like a ``cbgo/robot/act`` queryable (`reply`, for `FakeBus.answer`) or like the
planner's robot port (`send`, a completed future), and logs what it was asked to do.

Run as a script, it is the dry-robot service under the name ``symbolic-robot`` with
``--refuse ACTION`` (always refused with "refused: the target is out of reach") and
``--delay-s`` (the same as ``--action-s``, default 0); its status adds ``log``::

    python tests/fakes/symbolic_robot.py --delay-s 0.5
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass, field

from cbgo.config import described
from cbgo.runtime import run
from cbgo.services.dry_robot.main import DryRobot, DryRobotSettings
from cbgo.services.dry_robot.robot import SymbolicRobot
from cbgo.world import Scene

ALWAYS = 10**9  # a refusal count that never runs out


class FakeRobot(SymbolicRobot):
    """dry-robot's symbolic robot with scripted faults.

    Args:
        scene: the world (a Scene or a contract scene dict).
        refuse: action -> how many of its next requests to refuse.
        error: the refusal's reason.
        after: called after each successful action; returns the world as it is then.
    """

    def __init__(self, scene: Scene | dict, refuse: dict[str, int] | None = None,
                 error: str = "could not grasp: only one finger touched it",
                 after: Callable[[str, Scene], Scene] | None = None):
        super().__init__(scene)
        self.refuse = dict(refuse or {})
        self.error, self.after = error, after
        self.log: list[tuple[str, str | None]] = []
        self.queries: list[dict] = []

    def act(self, action: str, obj: str | None, params: dict | None = None,
            duration_s: float = 0.1) -> dict:
        """Executes one primitive (or refuses it as scripted); returns the ``robot/act`` reply."""
        self.log.append((action, obj))
        if self.refuse.get(action, 0) > 0:
            self.refuse[action] -= 1
            return self.act_reply(False, self.error)
        reply = super().act(action, obj, params, duration_s)
        if reply["ok"] and self.after is not None:
            self.scene = self.after(action, self.scene)
            reply["scene"] = self.message()
        return reply

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
class SymbolicRobotSettings(DryRobotSettings):
    action_s: float = field(default=0.0, metadata=described("seconds each action takes"))
    delay_s: float = field(default=0.0, metadata=described("the same as --action-s"))
    refuse: list[str] = field(default_factory=list, metadata=described(
        "actions always refused (with 'refused: the target is out of reach')"))

    def __post_init__(self):
        super().__post_init__()
        self.action_s = max(self.action_s, self.delay_s)


class SymbolicRobotService(DryRobot):
    name = "symbolic-robot"
    description = "dry-robot with scripted refusals, for planner tests."
    settings_class = SymbolicRobotSettings

    def new_robot(self, scene: Scene) -> FakeRobot:
        return FakeRobot(scene, refuse={a: ALWAYS for a in self.settings.refuse},
                         error="refused: the target is out of reach")

    def status_extra(self) -> dict:
        return {**super().status_extra(), "log": [list(x) for x in self.robot.log]}


if __name__ == "__main__":
    sys.exit(run(SymbolicRobotService, sys.argv[1:]))
