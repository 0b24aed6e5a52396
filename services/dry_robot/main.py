"""dry-robot: the robot side of the contract on the symbolic world model, without physics.

Behaviour (the contract is services/dry_robot/README.md):
- at start, loads the world model's random scene of ``--seed`` or the scene in ``--scene``;
- answers ``cbgo/robot/act``: one action at a time; an action the world model forbids is
  refused at once with the model's reason; a feasible one "takes" ``--action-s`` seconds,
  then its symbolic effects are applied; the reply carries the scene after it;
- ``cbgo/robot/stop`` (any payload) ends the action under way at once with
  ``ok: false, error: "stopped"`` and no effect (the world model has no half-done actions);
- publishes ``cbgo/scene/state`` at ``--state-rate-hz`` and ``cbgo/robot/state`` at
  ``--robot-rate-hz``, and both after every change (robot/state also when an action starts);
- answers ``cbgo/sim/reset`` (seed or scene; a scene the world model's rules or the workspace
  refuse, `cbgo.world.reset_refusal`, is answered ``ok: false`` with the reason and the world
  stays), ``cbgo/sim/info`` (the workspace, `cbgo.world.workspace_info`, as mujoco-sim answers
  it), and refuses ``cbgo/sim/render`` with an error reply: there is nothing to render;
- after a failed action the scene is checked (`cbgo.world.check_consistent`) before it is
  published; a contradiction is named in the reply's error and counted.

All of that but the symbolic execution is `cbgo.robot_cell.RobotCell`, shared with mujoco-sim.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from cbgo import keys
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.robot_cell import ActOutcome, RobotCell, RobotCellSettings, describe_outcome
from cbgo.runtime import main_for
from cbgo.services.dry_robot.robot import SymbolicRobot
from cbgo.world import Scene, random_scene
from cbgo.world.workspace import startable_scene

NO_RENDERER = ("dry-robot has no renderer; it is the symbolic world model without physics or "
               "images: run mujoco-sim for cbgo/sim/render, or read the world on "
               "cbgo/scene/state")


@dataclass
class DryRobotSettings(RobotCellSettings):
    """Settings of dry-robot (flags ``--action-s`` ... or env ``CBGO_ACTION_S`` ...)."""

    action_s: float = field(default=0.3, metadata=_help(
        "seconds each feasible action takes (so that plans can be watched); 0: at once, for "
        "fast plan checks"))

    def __post_init__(self):
        super().__post_init__()
        if self.action_s < 0:
            raise ConfigError(f"action_s={self.action_s} must be 0 (at once) or more seconds")


class DryRobot(RobotCell):
    """The symbolic robot cell (the glue is `cbgo.robot_cell.RobotCell`'s)."""

    name = "dry-robot"
    description = ("The robot side of the contract on the symbolic world model, without "
                   "physics: answers cbgo/robot/act (preconditions checked, effects applied), "
                   "sim/reset and sim/render (an error: no renderer); publishes "
                   "cbgo/scene/state and cbgo/robot/state. For users without MuJoCo and for "
                   "fast plan checks (--action-s 0).")
    settings_class = DryRobotSettings

    def __init__(self, settings: DryRobotSettings):
        super().__init__(settings)
        self.robot: SymbolicRobot | None = None

    def load(self, target: int | dict) -> list[str]:
        """Replaces the world with a seed's random scene or a contract scene body.

        Raises:
            SceneError: the scene breaks the world model's rules.
        """
        scene = random_scene(target) if isinstance(target, int) else startable_scene(target)
        previous, self.robot = self.robot, self.new_robot(scene)
        if previous is not None:  # seq counts per publisher, across resets
            self.robot.seq, self.robot.state_seq = previous.seq, previous.state_seq
        return []  # the world model settles exactly as asked

    def new_robot(self, scene: Scene) -> SymbolicRobot:
        """Returns the robot acting in `scene` (tests subclass it to script faults)."""
        return SymbolicRobot(scene)

    def scene_message(self) -> dict:
        """Returns the world as the next ``cbgo/scene/state`` message."""
        return self.robot.message()

    def robot_message(self, action: str | None = None) -> dict:
        """Returns the next ``cbgo/robot/state``; `action` is the primitive under way."""
        return self.robot.state_message(action)

    def execute(self, action: str, obj: str | None, params: dict) -> ActOutcome:
        """Refuses at once, or "takes" ``--action-s`` (a stop ends it without effect)."""
        reason = self.robot.refusal(action, obj, params)
        if reason is not None:
            return describe_outcome(self.robot.act_reply(False, reason))  # without moving
        self.ctx.publish(keys.ROBOT_STATE, self.robot_message(action))
        t0 = time.monotonic()
        if self.stop.wait(self.settings.action_s):
            return describe_outcome(self.robot.act_reply(False, "stopped",
                                                         time.monotonic() - t0))
        return describe_outcome(self.robot.act(action, obj, params, self.settings.action_s))

    def render(self, _query: dict) -> bytes:
        """sim/render: an error reply, always."""
        raise QueryError(NO_RENDERER)


main = main_for(DryRobot)

if __name__ == "__main__":
    main()
