"""The robot side of the contract, written once: what every robot cell of cbgo does alike.

A robot cell answers ``cbgo/robot/act``, ``cbgo/sim/reset``, ``cbgo/sim/info`` and
``cbgo/sim/render``, obeys ``cbgo/robot/stop``, and publishes ``cbgo/scene/state`` and
``cbgo/robot/state``. `RobotCell` owns that glue, so both robots (mujoco-sim, dry-robot) and any
robot a user writes behave the same at the seams; a robot supplies only:

- `load(target)`: replace its world by a seed's random scene or a contract scene body;
- `execute(action, object, params)`: carry out one action, as an `ActOutcome`, checking
  `stop` while it runs;
- `scene_message()` / `robot_message()`: its world as the next state messages;
- `render(query)`: a PNG, or the base's error reply when it has nothing to render.

What the base does, the same for every robot:

- **act**: one action at a time; a failed action that was not refused before moving has its
  scene checked (`cbgo.world.failure_error`): a contradiction is named in the reply's error and
  counted, so a planner is told rather than misled; the scene after it is published with the
  robot state, and the reply carries that scene;
- **stop**: any payload sets `stop` at once (on Zenoh's thread); it concerns the action under
  way, so it is cleared when the next action starts;
- **reset targets** (`reset_target`): ``{"scene": body}`` exactly that scene,
  ``{"seed": n}`` the world model's random scene of ``n``, ``{}`` the start scene (the
  ``--scene`` file when given, else ``--seed``); a scene the world model or the workspace refuse
  is answered ``ok: false`` with the reason, and the world stays as it was;
- **state** at one cadence convention, rates in Hz: ``--state-rate-hz`` for
  ``cbgo/scene/state`` and ``--robot-rate-hz`` for ``cbgo/robot/state``, and both after every
  action and reset;
- **status**: the scene's source, the action counts, the stops received.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cbgo import keys
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.runtime import Service
from cbgo.world import failure_error, read_scene_file, workspace_info
from cbgo.world.workspace import SceneError

STATE_RATES_HZ = (1.0, 100.0)  # cbgo/scene/state
ROBOT_RATES_HZ = (1.0, 200.0)


@dataclass
class RobotCellSettings:
    """Settings every robot cell has (flags ``--seed`` ... or env ``CBGO_SEED`` ...)."""

    seed: int = field(default=0, metadata=_help(
        "seed of the world model's random scene loaded at start (and by a reset without "
        "seed or scene, unless --scene is given)"))
    scene: str | None = field(default=None, metadata=_help(
        "a scene file (JSON or YAML: {objects: [...], robot: {...}}) to load at start "
        "instead of a random one"))
    state_rate_hz: float = field(default=20.0, metadata=_help(
        "cbgo/scene/state rate, Hz (1-100); also published after every action and reset"))
    robot_rate_hz: float = field(default=50.0, metadata=_help(
        "cbgo/robot/state rate, Hz (1-200); also published after every action and reset"))

    def __post_init__(self):
        if self.seed < 0:
            raise ConfigError(f"seed={self.seed} must be 0 or more")
        if self.scene is not None and not Path(self.scene).is_file():
            raise ConfigError(f"scene file {self.scene!r} does not exist")
        for name, (low, high) in (("state_rate_hz", STATE_RATES_HZ),
                                  ("robot_rate_hz", ROBOT_RATES_HZ)):
            if not low <= getattr(self, name) <= high:
                raise ConfigError(f"{name}={getattr(self, name)} must be within "
                                  f"{low:g}-{high:g} Hz")


@dataclass(frozen=True)
class ActOutcome:
    """How one action ended.

    Attributes:
        ok: the action was done.
        error: why not (``refused: ...`` when refused before moving, ``stopped``, ...).
        refused: refused before moving: the world is unchanged, so it is not checked.
        duration_s: how long the action took (simulated time for a simulator).
        scene: the scene message after it, when the robot built one while acting; else the
            base reads it with `RobotCell.scene_message`.
    """

    ok: bool
    error: str | None = None
    refused: bool = False
    duration_s: float = 0.0
    scene: dict | None = None


class RobotCell(Service):
    """Base of the services that answer ``cbgo/robot/act`` (see the module docstring)."""

    settings_class = RobotCellSettings

    def __init__(self, settings: RobotCellSettings):
        super().__init__(settings)
        self.stop = threading.Event()
        self.start_target: int | dict = settings.seed
        self.source = ""
        self.stops = 0
        self.counts = {"actions": 0, "ok": 0, "refused": 0, "stopped": 0, "inconsistent": 0}
        self._due = {"scene": 0.0, "robot": 0.0}  # when each state stream is next due

    def publish_due_states(self) -> None:
        """Publishes the state streams that are due, at their rates, from inside an action.

        While an action runs the event loop is busy with it, so its state timers cannot fire:
        a robot's control loop calls this between its steps instead.
        """
        now = time.monotonic()
        for kind, rate, topic, message in (
                ("scene", self.settings.state_rate_hz, keys.SCENE_STATE, self.scene_message),
                ("robot", self.settings.robot_rate_hz, keys.ROBOT_STATE, self.robot_message)):
            if now >= self._due[kind]:
                self._due[kind] = now + 1.0 / rate
                self.ctx.publish(topic, message())

    # ------------------------------------------------------------------ what a robot supplies

    def load(self, target: int | dict) -> list[str]:
        """Replaces the world by a seed's random scene or a scene body; returns mismatches.

        A mismatch is where the robot's world settled differently from the scene asked for
        (a reset with mismatches answers ``ok: false`` with them).

        Raises:
            SceneError: the scene is refused; the world must stay as it was.
        """
        raise NotImplementedError

    def execute(self, action: str, obj: str | None, params: dict) -> ActOutcome:
        """Carries out one action (checking `stop` while it runs)."""
        raise NotImplementedError

    def scene_message(self) -> dict:
        """Returns the world as the next ``cbgo/scene/state`` message."""
        raise NotImplementedError

    def robot_message(self) -> dict:
        """Returns the robot as the next ``cbgo/robot/state`` message."""
        raise NotImplementedError

    def render(self, query: dict) -> bytes:
        """Returns a PNG of the world for a ``sim/render`` query.

        Raises:
            QueryError: the robot cannot render (the reply says why).
        """
        raise QueryError(f"{self.name} has no renderer")

    # ------------------------------------------------------------------ lifecycle

    def setup(self, ctx) -> None:
        """Loads the start scene, then declares stop, outputs, queryables and state timers."""
        self.ctx = ctx
        s = self.settings
        self.start_target = read_scene_file(s.scene) if s.scene else s.seed
        try:
            self.reload(self.start_target)
        except SceneError as e:
            raise ConfigError(f"cannot load the start scene: {e}") from e
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.publishes(keys.SCENE_STATE, keys.ROBOT_STATE)
        ctx.queryable(keys.ROBOT_ACT, self.on_act)
        ctx.queryable(keys.SIM_RESET, self.on_reset)
        ctx.queryable(keys.SIM_RENDER, self.on_render)
        ctx.queryable(keys.SIM_INFO, self.on_info)
        ctx.every(1.0 / s.state_rate_hz, lambda: [(keys.SCENE_STATE, self.scene_message())])
        ctx.every(1.0 / s.robot_rate_hz, lambda: [(keys.ROBOT_STATE, self.robot_message())])

    def status_extra(self) -> dict:
        """Returns the loaded scene's source, the action counts and the stops received."""
        return {"scene_source": self.source, "actions": dict(self.counts), "stops": self.stops}

    def reload(self, target: int | dict) -> list[str]:
        """Loads a world (`load`) and remembers where it came from; returns its mismatches."""
        problems = self.load(target)
        self.source = f"seed {target}" if isinstance(target, int) else "scene"
        return problems

    # ------------------------------------------------------------------ inputs

    def on_stop(self, _msg: dict) -> None:
        """robot/stop (any payload, on Zenoh's thread): the action under way ends now."""
        self.stops += 1
        self.stop.set()
        self.ctx.log.info("stop received")

    def on_act(self, query: dict) -> dict:
        """robot/act: executes one action; replies with its outcome and the scene after it."""
        action, obj, params = query["action"], query.get("object"), query["params"]
        self.stop.clear()  # a stop concerns the action under way, not the next one
        t0 = time.perf_counter()
        outcome = self.execute(action, obj, params)
        scene = outcome.scene if outcome.scene is not None else self.scene_message()
        error = outcome.error
        if not outcome.ok and not outcome.refused:
            error = self._checked(error, scene)
        self._count(outcome)
        self.ctx.publish(keys.SCENE_STATE, scene)
        self.ctx.publish(keys.ROBOT_STATE, self.robot_message())
        wall_s = time.perf_counter() - t0
        self.ctx.log.info("%s(%s): %s in %.2f s, %.2f s wall", action, obj or "",
                          error or "ok", outcome.duration_s, wall_s)
        return keys.ROBOT_ACT.reply(outcome.ok, error,
                duration_s=round(max(outcome.duration_s, 0.0), 4),
                wall_s=round(wall_s, 4), scene=scene)

    def _checked(self, error: str | None, scene: dict) -> str | None:
        """Returns a failure's error, naming every contradiction in the scene after it.

        A robot keeps its reported scene consistent; a contradiction left is a fault or a gap
        in its observation, and the planner must hear of it rather than replan on a wrong
        world.
        """
        checked, problems = failure_error(error, scene)
        if problems:
            self.counts["inconsistent"] += 1
            self.ctx.log.error("inconsistent scene after %s: %s", error, "; ".join(problems))
        return checked

    def _count(self, outcome: ActOutcome) -> None:
        self.counts["actions"] += 1
        self.counts["ok"] += outcome.ok
        self.counts["refused"] += outcome.refused
        self.counts["stopped"] += outcome.error == "stopped"

    def reset_target(self, query: dict) -> int | dict:
        """Returns what a ``sim/reset`` query asks for: a scene, a seed, or the start scene."""
        if "scene" in query:
            return query["scene"]
        if "seed" in query:
            return int(query["seed"])
        return self.start_target

    def on_reset(self, query: dict) -> dict:
        """sim/reset: loads the target (`reset_target`); refused scenes keep the world."""
        try:
            problems = self.reload(self.reset_target(query))
        except SceneError as e:
            return keys.SIM_RESET.reply(False, str(e), scene=None)
        scene = self.scene_message()
        self.ctx.publish(keys.SCENE_STATE, scene)
        self.ctx.publish(keys.ROBOT_STATE, self.robot_message())
        error = ("after settling: " + "; ".join(problems)) if problems else None
        return keys.SIM_RESET.reply(not problems, error, scene=scene)

    def on_info(self, _query: dict) -> dict:
        """sim/info: the workspace, as every robot of cbgo answers it."""
        return keys.SIM_INFO.reply(True, None, robot=self.name,
                workspace=workspace_info())

    def on_render(self, query: dict) -> dict:
        """sim/render: a PNG of the world (`render`), or an error reply saying why not."""
        return keys.SIM_RENDER.reply(True, None, png=self.render(query))


def describe_outcome(reply: dict[str, Any]) -> ActOutcome:
    """Returns the `ActOutcome` of a ``robot/act``-shaped reply a robot built itself."""
    error = reply["error"]
    return ActOutcome(ok=reply["ok"], error=error,
                      refused=(error or "").startswith("refused"),
                      duration_s=reply.get("duration_s", 0.0), scene=reply["scene"])
