"""The symbolic robot: the world model (`cbgo.world`) acting as a robot, without physics.

`SymbolicRobot` holds a `Scene` and executes a primitive by applying its symbolic effects
(`cbgo.world.apply`) after checking its preconditions (`cbgo.world.failures`); what the model
forbids is refused with the model's reason. It answers in the contract's shapes: `act` returns
a ``cbgo/robot/act`` reply, `message` a ``cbgo/scene/state`` message, `state_message` a
``cbgo/robot/state`` message. It keeps no clock and never waits: the service decides how long
an action "takes" and whether it was stopped (the world model has no half-done actions, so a
stopped action simply has no effect).

The robot state is symbolic too: the TCP, the gripper and what it holds are the scene's;
there is no kinematics, so ``joints`` is always the Panda's ready posture, and the message
says so with the extra field ``kinematics: false``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

from cbgo import keys
from cbgo.world import DEFAULT_GRID, Grid, InfeasibleAction, Scene, apply, failures

READY_JOINTS = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)  # the Panda's ready posture, rad
GRIPPER_MAX_WIDTH = 0.08  # m between the Panda's fingers when open


class SymbolicRobot:
    """A robot that is the world model.

    Args:
        scene: the world (a `Scene` or a contract scene body; copied, settled).
        grid: the TCP grid moves and place are checked against.
    """

    def __init__(self, scene: Scene | Mapping[str, Any], grid: Grid = DEFAULT_GRID):
        self.scene = Scene.from_dict(dict(scene)) if isinstance(scene, Mapping) else scene.copy()
        self.scene.settle()
        self.grid = grid
        self.seq = 0
        self.state_seq = 0

    def refusal(self, action: str, obj: str | None, params: Mapping[str, Any] | None) -> str | None:
        """Returns why the world model forbids the action (``refused: ...``), or None."""
        found = failures(action, obj, self.scene, params, self.grid)
        return "refused: " + "; ".join(f.message for f in found) if found else None

    def act(self, action: str, obj: str | None, params: Mapping[str, Any] | None = None,
            duration_s: float = 0.0) -> dict:
        """Executes one primitive at once; returns the ``robot/act`` reply.

        Args:
            action: the primitive.
            obj: its target object (None for moves and place).
            params: its metric parameters.
            duration_s: the duration to report for a done action.
        """
        try:
            self.scene = apply(action, obj, params or {}, self.scene, self.grid)
        except InfeasibleAction as e:
            return self.act_reply(False, "refused: " + "; ".join(f.message for f in e.failures))
        return self.act_reply(True, None, duration_s)

    def act_reply(self, ok: bool, error: str | None, duration_s: float = 0.0) -> dict:
        """Returns a ``robot/act`` reply carrying the scene as it is now."""
        return keys.ROBOT_ACT.reply(ok, error,
                duration_s=round(max(duration_s, 0.0), 4), scene=self.message())

    def message(self) -> dict:
        """Returns the world as the next ``cbgo/scene/state`` message."""
        self.seq += 1
        return self.scene.to_message(self.seq, time.time())

    def state_message(self, action: str | None = None) -> dict:
        """Returns the next ``cbgo/robot/state`` message; `action` is the primitive under way."""
        self.state_seq += 1
        return keys.ROBOT_STATE.message(ts=time.time(), seq=self.state_seq,
                joints=list(READY_JOINTS), gripper_width=self.gripper_width(),
                tcp=[float(v) for v in self.scene.robot.tcp], moving=action is not None,
                action=action, kinematics=False)

    def gripper_width(self) -> float:
        """Returns the finger gap: fully open, closed on the held object's size, or shut."""
        robot = self.scene.robot
        if robot.gripper_open:
            return GRIPPER_MAX_WIDTH
        if robot.holding is not None and self.scene.has(robot.holding):
            return min(float(self.scene.get(robot.holding).size), GRIPPER_MAX_WIDTH)
        return 0.0
