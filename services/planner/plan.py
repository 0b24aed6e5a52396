"""One intent being executed: its tree, its state, and the ``plan/status`` message about it.

Rules:
- a plan starts from the current scene; with ``check_first`` it is first simulated on the world
  model (`sequence.predict`) and, if that fails, fails at once without moving the robot;
- `tick` ticks the tree once; the plan ends with the root's SUCCESS or FAILURE;
- `abort` interrupts it (robot/stop, shutdown): the primitive in flight is abandoned and the plan
  fails with the given reason;
- the ``sequence`` it reports is what was sent (done, failed or running) followed, while it
  runs, by what the tree would still send, predicted on the world model from the current scene
  (pending); an ended plan lists only what was sent.
"""

from __future__ import annotations

import time
from typing import Any

from py_trees.common import Status

from cbgo import keys
from cbgo.services.planner.repair import PlanMemory
from cbgo.services.planner.scenes import SceneSource
from cbgo.services.planner.sequence import predict
from cbgo.services.planner.tree import RobotPort, create_tree
from cbgo.world import InfeasibleAction, apply


class Plan:
    """Executes one accepted intent.

    Args:
        intent: the ``cbgo/intent`` message.
        scenes: the planner's scene source (it must hold a scene).
        robot: where primitives go.
        max_repairs: repair actions allowed.
        check_first: simulate on the world model first and refuse what cannot succeed.
    """

    def __init__(self, intent: dict, scenes: SceneSource, robot: RobotPort,
                 max_repairs: int = 8, check_first: bool = True):
        self.intent, self.scenes, self.max_repairs = intent, scenes, max_repairs
        self.memory = PlanMemory.at_start(intent, scenes.scene(), scenes.last_held)
        self.tree = create_tree(intent, scenes, robot, memory=self.memory,
                                max_repairs=max_repairs)
        self.state, self.error = "running", None
        self._forecast_key: tuple | None = None
        self._forecast: list[dict] = []
        if check_first:
            first = predict(intent, scenes.scene(), self.memory, max_repairs)
            if not first.ok:
                self._finish("failure", f"{first.error} (found on the world model before "
                                        "moving; nothing was sent to the robot)")

    @property
    def done(self) -> bool:
        """Whether the plan has ended (success or failure)."""
        return self.state != "running"

    def tick(self) -> None:
        """Ticks the tree once (nothing once the plan has ended)."""
        if self.done:
            return
        status = self.tree.tick()
        if status == Status.SUCCESS:
            self._finish("success", None)
        elif status == Status.FAILURE:
            self._finish("failure", self.tree.state.error or "the behaviour tree failed")

    def abort(self, reason: str) -> None:
        """Interrupts a running plan; it fails with `reason`."""
        if self.done:
            return
        self.tree.stop()
        self._finish("failure", reason)

    def _finish(self, state: str, error: str | None) -> None:
        self.state, self.error = state, error
        self._forecast = []  # an ended plan lists what was sent, nothing pending

    def status(self, ts: float | None = None) -> dict[str, Any]:
        """Returns the ``cbgo/plan/status`` message of the plan as it is now."""
        return keys.PLAN_STATUS.message(ts=time.time() if ts is None else ts,
                intent=self.intent, sequence=self.sequence(), state=self.state,
                tree=self.tree.snapshot(), error=self.error)

    def sequence(self) -> list[dict]:
        """Returns the steps sent so far, then the steps still predicted (pending)."""
        steps = [s.as_dict() for s in self.tree.state.steps]
        return steps + self._predicted_rest()

    def _predicted_rest(self) -> list[dict]:
        if self.done:
            return self._forecast
        sent = self.tree.state.steps
        key = (self.scenes.version, len(sent), sent[-1].state if sent else None)
        if key != self._forecast_key:
            self._forecast_key, self._forecast = key, self._forecast_from_now()
        return self._forecast

    def _forecast_from_now(self) -> list[dict]:
        scene = self.scenes.scene()
        sent = self.tree.state.steps
        if sent and sent[-1].goal:
            return []  # the intended action is under way: nothing follows it
        if sent and sent[-1].state == "running":
            last = sent[-1]
            try:
                scene = apply(last.action, last.object, last.params, scene)
            except InfeasibleAction:
                return []
        budget = self.max_repairs - self.tree.state.repairs_used
        rest = predict(self.intent, scene, self.memory, budget)
        return [_pending(a, o, p) for a, o, p in rest.steps]


def _pending(action: str, obj: str | None, params: dict) -> dict:
    return {"action": action, "object": obj, "params": dict(params), "state": "pending"}
