"""dry-robot: the robot side of the contract on the symbolic world model, without physics.

Behaviour (the contract is services/dry_robot/README.md):
- at start, loads the world model's random scene of ``--seed`` or the scene in ``--scene``;
- answers ``cbgo/robot/act``: one action at a time; an action the world model forbids is
  refused at once with the model's reason; a feasible one "takes" ``--action-s`` seconds,
  then its symbolic effects are applied; the reply carries the scene after it;
- ``cbgo/robot/stop`` (any payload) ends the action under way at once with
  ``ok: false, error: "stopped"`` and no effect (the world model has no half-done actions);
- publishes ``cbgo/scene/state`` and ``cbgo/robot/state`` every ``--period-s`` and after every
  change (robot/state also when an action starts);
- answers ``cbgo/sim/reset`` (seed or scene; a scene the world model's rules or the workspace
  refuse, `cbgo.world.reset_refusal`, is answered ``ok: false`` with the reason and the world
  stays), ``cbgo/sim/info`` (the workspace, `cbgo.world.workspace_info`, as mujoco-sim answers
  it), and refuses ``cbgo/sim/render`` with an error reply: there is nothing to render;
- after a failed action the scene is checked (`cbgo.world.check_consistent`) before it is
  published; a contradiction is named in the reply's error and counted.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from cbgo import keys, wire
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.runtime import Service, main_for
from cbgo.services.dry_robot.robot import SymbolicRobot
from cbgo.world import (
    Scene,
    failure_error,
    random_scene,
    read_scene_file,
    reset_refusal,
    workspace_info,
)

NO_RENDERER = ("dry-robot has no renderer; it is the symbolic world model without physics or "
               "images: run mujoco-sim for cbgo/sim/render, or read the world on "
               "cbgo/scene/state")


@dataclass
class DryRobotSettings:
    """Settings of dry-robot (flags ``--action-s`` ... or env ``CBGO_ACTION_S`` ...)."""

    action_s: float = field(default=0.3, metadata=_help(
        "seconds each feasible action takes (so that plans can be watched); 0: at once, for "
        "fast plan checks"))
    period_s: float = field(default=0.05, metadata=_help(
        "cbgo/scene/state and cbgo/robot/state period, s; both are also published after "
        "every change"))
    seed: int = field(default=0, metadata=_help(
        "seed of the world model's random scene loaded at start"))
    scene: str | None = field(default=None, metadata=_help(
        "a scene file (JSON or YAML: {objects: [...], robot: {...}}) to load at start "
        "instead of a random one"))

    def __post_init__(self):
        if self.action_s < 0:
            raise ConfigError(f"action_s={self.action_s} must be 0 (at once) or more seconds")
        if self.period_s <= 0:
            raise ConfigError(f"period_s={self.period_s} must be a positive number of seconds")
        if self.seed < 0:
            raise ConfigError(f"seed={self.seed} must be 0 or more")
        if self.scene is not None and not Path(self.scene).is_file():
            raise ConfigError(f"scene file {self.scene!r} does not exist")


class SceneError(ValueError):
    """A scene the world model cannot start from (its rules broken)."""


def consistent_scene(body: dict) -> Scene:
    """Returns the scene of a contract scene body, settled.

    Raises:
        SceneError: the scene breaks the world model's rules or does not fit in the
            workspace (every problem listed, `cbgo.world.reset_refusal`).
    """
    try:
        scene = Scene.from_dict(body)
    except (KeyError, TypeError, ValueError) as e:
        raise SceneError(f"not a scene: {type(e).__name__}: {e}") from None
    reason = reset_refusal(scene)
    if reason is not None:
        raise SceneError(reason)
    scene.settle()
    return scene


class DryRobot(Service):
    """The symbolic robot cell."""

    name = "dry-robot"
    description = ("The robot side of the contract on the symbolic world model, without "
                   "physics: answers cbgo/robot/act (preconditions checked, effects applied), "
                   "sim/reset and sim/render (an error: no renderer); publishes "
                   "cbgo/scene/state and cbgo/robot/state. For users without MuJoCo and for "
                   "fast plan checks (--action-s 0).")
    settings_class = DryRobotSettings

    def __init__(self, settings: DryRobotSettings):
        super().__init__(settings)
        self.stop = threading.Event()
        self.robot: SymbolicRobot | None = None
        self.start_scene: int | dict = settings.seed
        self.source = ""
        self.stops = 0
        self.counts = {"actions": 0, "ok": 0, "refused": 0, "stopped": 0, "inconsistent": 0}

    def setup(self, ctx) -> None:
        """Loads the start scene, then declares stop, outputs, queryables and the state timer."""
        self.ctx = ctx
        s = self.settings
        self.start_scene = read_scene_file(s.scene) if s.scene else s.seed
        try:
            self.load(self.start_scene)
        except SceneError as e:
            raise ConfigError(f"cannot load the start scene: {e}") from e
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.publishes(keys.SCENE_STATE, keys.ROBOT_STATE)
        ctx.queryable(keys.ROBOT_ACT, self.on_act)
        ctx.queryable(keys.SIM_RESET, self.on_reset)
        ctx.queryable(keys.SIM_RENDER, self.on_render)
        ctx.queryable(keys.SIM_INFO, self.on_info)
        ctx.every(self.settings.period_s, self.state_outputs)

    def status_extra(self) -> dict:
        """Returns the loaded scene's source, the action counts and the stops received."""
        return {"scene_source": self.source, "actions": dict(self.counts), "stops": self.stops}

    # ------------------------------------------------------------------ world

    def load(self, target: int | dict) -> None:
        """Replaces the world with a seed's random scene or a contract scene body.

        Raises:
            SceneError: the scene breaks the world model's rules.
        """
        scene = random_scene(target) if isinstance(target, int) else consistent_scene(target)
        previous, self.robot = self.robot, self.new_robot(scene)
        if previous is not None:  # seq counts per publisher, across resets
            self.robot.seq, self.robot.state_seq = previous.seq, previous.state_seq
        self.source = f"seed {target}" if isinstance(target, int) else "scene"

    def new_robot(self, scene: Scene) -> SymbolicRobot:
        """Returns the robot acting in `scene` (tests subclass it to script faults)."""
        return SymbolicRobot(scene)

    def state_outputs(self) -> list:
        """Returns the periodic outputs: the scene and the robot as they are now."""
        return [(keys.SCENE_STATE, self.robot.message()),
                (keys.ROBOT_STATE, self.robot.state_message())]

    # ------------------------------------------------------------------ inputs

    def on_stop(self, _msg: dict) -> None:
        """robot/stop (any payload, on Zenoh's thread): the action under way ends now."""
        self.stops += 1
        self.stop.set()
        self.ctx.log.info("stop received")

    def on_act(self, query: dict) -> dict:
        """robot/act: refuses, or takes ``--action-s`` and applies the effects; replies."""
        action, obj, params = query["action"], query.get("object"), query["params"]
        self.stop.clear()  # a stop concerns the action under way, not the next one
        t0 = time.perf_counter()
        reply = self._execute(action, obj, params)
        if not reply["ok"]:
            reply = self._checked(reply)
        self._count(reply)
        self.ctx.publish(keys.SCENE_STATE, reply["scene"])
        self.ctx.publish(keys.ROBOT_STATE, self.robot.state_message())
        self.ctx.log.info("%s(%s): %s", action, obj or "", reply["error"] or "ok")
        return {**reply, "wall_s": round(time.perf_counter() - t0, 4)}

    def _execute(self, action: str, obj: str | None, params: dict) -> dict:
        reason = self.robot.refusal(action, obj, params)
        if reason is not None:
            return self.robot.act_reply(False, reason)  # refused without moving
        self.ctx.publish(keys.ROBOT_STATE, self.robot.state_message(action))
        t0 = time.monotonic()
        if self.stop.wait(self.settings.action_s):
            return self.robot.act_reply(False, "stopped", time.monotonic() - t0)
        return self.robot.act(action, obj, params, self.settings.action_s)

    def _checked(self, reply: dict) -> dict:
        """Returns a failure's reply, its error naming any contradiction in the scene after it.

        The world model keeps its scene consistent, so this finds nothing unless a fault (or a
        test's scripted robot) broke it; then the planner is told, rather than misled.
        """
        error, problems = failure_error(reply["error"], reply["scene"])
        if not problems:
            return reply
        self.counts["inconsistent"] += 1
        self.ctx.log.error("inconsistent scene after %s: %s", reply["error"], "; ".join(problems))
        return {**reply, "error": error}

    def _count(self, reply: dict) -> None:
        self.counts["actions"] += 1
        self.counts["ok"] += reply["ok"]
        self.counts["stopped"] += reply["error"] == "stopped"
        self.counts["refused"] += (reply["error"] or "").startswith("refused")

    def on_reset(self, query: dict) -> dict:
        """sim/reset: a seed's random scene, exactly the given scene, or the start scene."""
        if "scene" in query:
            target = query["scene"]
        elif "seed" in query:
            target = int(query["seed"])
        else:
            target = self.start_scene  # the --scene file's body, or --seed
        try:
            self.load(target)
        except SceneError as e:
            return {"v": wire.SCHEMA_VERSION, "ok": False, "error": str(e), "scene": None}
        scene = self.robot.message()
        self.ctx.publish(keys.SCENE_STATE, scene)
        self.ctx.publish(keys.ROBOT_STATE, self.robot.state_message())
        return {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "scene": scene}

    def on_info(self, _query: dict) -> dict:
        """sim/info: the workspace, as every robot of cbgo answers it."""
        return {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "robot": self.name,
                "workspace": workspace_info()}

    def on_render(self, _query: dict) -> dict:
        """sim/render: an error reply, always."""
        raise QueryError(NO_RENDERER)


main = main_for(DryRobot)

if __name__ == "__main__":
    main()
