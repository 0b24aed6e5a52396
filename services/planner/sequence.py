"""The action sequence an intent leads to, computed on the world model alone.

`predict` runs the very tree the planner executes (`tree.create_tree`) against a
`SymbolicRobot`: a robot that is the world model, executing each primitive at once with
`cbgo.world.apply` and refusing, as a real robot would, what the model forbids. The planner uses
it to list the steps still to come in ``plan/status`` and, before moving, to refuse plans the
world model says cannot succeed; the fast tests use it to check sequences without a simulator.
"""

from __future__ import annotations

import time
from concurrent.futures import Future
from dataclasses import dataclass, field

from py_trees.common import Status

from cbgo import keys
from cbgo.services.planner.repair import PlanMemory
from cbgo.services.planner.scenes import SceneSource
from cbgo.services.planner.tree import create_tree
from cbgo.world import InfeasibleAction, Scene, apply

MAX_TICKS = 400  # each primitive takes two ticks; the repair budget ends a plan long before


class SymbolicRobot:
    """A robot that executes primitives on a `Scene` with the world model, at once.

    Args:
        scene: the world before the first action (copied).
    """

    def __init__(self, scene: Scene):
        self.scene = scene.copy()
        self.log: list[tuple[str, str | None, dict]] = []
        self._seq = 0

    def send(self, action: str, obj: str | None, params: dict) -> Future:
        """Executes the primitive now; the returned future holds the ``robot/act`` reply."""
        self.log.append((action, obj, dict(params)))
        try:
            self.scene = apply(action, obj, params, self.scene)
            ok, error = True, None
        except InfeasibleAction as e:
            ok, error = False, f"refused: {'; '.join(f.message for f in e.failures)}"
        self._seq += 1
        future: Future = Future()
        future.set_result(keys.ROBOT_ACT.reply(ok, error, duration_s=0.0,
                           scene=self.scene.to_message(self._seq, time.time())))
        return future

    def cancel(self, future: Future) -> None:
        """Nothing to abandon: every action has finished when `send` returns."""


@dataclass
class Prediction:
    """What the tree would do on the world model.

    Attributes:
        steps: the primitives sent, in order: (action, object, params).
        ok: the tree succeeded.
        error: why it failed (None on success).
        scene: the world after the last step.
    """

    steps: list[tuple[str, str | None, dict]]
    ok: bool
    error: str | None
    scene: Scene = field(repr=False)


def predict(intent: dict, scene: Scene, memory: PlanMemory | None = None,
            max_repairs: int = 8, max_ticks: int = MAX_TICKS) -> Prediction:
    """Runs the intent's tree on the world model from `scene`.

    Args:
        intent: a ``cbgo/intent`` message.
        scene: the world to start from (not changed).
        memory: the plan's memory (default: as a plan starting in `scene` would have it).
        max_repairs: the repair budget left.
        max_ticks: a safety bound on ticks.
    """
    robot = SymbolicRobot(scene)
    scenes = SceneSource(robot.scene.copy())
    plan = create_tree(intent, scenes, robot, memory=memory, max_repairs=max(0, max_repairs))
    status = Status.RUNNING
    for _ in range(max_ticks):
        status = plan.tick()
        if status != Status.RUNNING:
            break
    ok = status == Status.SUCCESS
    error = None
    if not ok:
        error = plan.state.error or f"the tree did not finish within {max_ticks} ticks"
    return Prediction([(a, o, p) for a, o, p in robot.log], ok, error, robot.scene)
