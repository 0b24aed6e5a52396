"""mujoco-sim: the simulated robot cell; executes actions physically and reports the world.

Behaviour (the contract is services/mujoco_sim/README.md):
- at start, loads the world model's random scene of ``--seed`` or the scene in ``--scene``;
- answers ``cbgo/robot/act``: one action at a time, refused without moving when infeasible,
  else executed and verified from the physics; the reply carries the scene after it;
- publishes ``cbgo/scene/state`` at ``--state-rate-hz`` and after every action, and
  ``cbgo/robot/state`` at ``--robot-rate-hz``, both read from the physics; while an action runs,
  they are published from inside its control loop (the event loop is busy with it);
- ``cbgo/robot/stop`` (any payload) sets a flag that the control loop checks every tick: the
  running action ends with ``ok: false, error: "stopped"`` and the arm holds its position;
- answers ``cbgo/sim/reset`` (seed or scene -> settled scene; a scene outside the workspace or
  against the world model's rules is refused, ``cbgo.world.reset_refusal``), ``cbgo/sim/render``
  (PNG) and ``cbgo/sim/info`` (the workspace, ``cbgo.world.workspace_info``);
- after a failed action, loose objects come to rest and the scene is checked
  (``cbgo.world.check_consistent``) before it is published; a contradiction is named in the
  reply's error;
- physics runs as fast as it can, or paced at ``--realtime`` times real time.
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
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.build import CAMERAS
from cbgo.services.mujoco_sim.engine import Sim
from cbgo.services.mujoco_sim.render import Camera, RenderError
from cbgo.services.mujoco_sim.skills import Robot
from cbgo.world import failure_error, read_scene_file, workspace_info


@dataclass
class MujocoSimSettings:
    """Settings of mujoco-sim (flags ``--seed`` ... or env ``CBGO_SEED`` ...)."""

    seed: int = field(default=0, metadata=_help(
        "seed of the world model's random scene loaded at start"))
    scene: str | None = field(default=None, metadata=_help(
        "a scene file (JSON or YAML: {objects: [...], robot: {...}}) to load at start "
        "instead of a random one"))
    state_rate_hz: float = field(default=20.0, metadata=_help(
        "cbgo/scene/state rate, Hz (10-30); also published after every action"))
    robot_rate_hz: float = field(default=50.0, metadata=_help("cbgo/robot/state rate, Hz "
                                                              "(10-100)"))
    realtime: float = field(default=0.0, metadata=_help(
        "pace the physics at this many times real time (1: real time); 0: as fast as it can"))
    camera: str = field(default="overview", metadata=_help(
        f"default camera of cbgo/sim/render: {', '.join(CAMERAS)}"))
    width: int = field(default=640, metadata=_help("default image width, pixels"))
    height: int = field(default=480, metadata=_help("default image height, pixels"))
    shadows: bool = field(default=False, metadata=_help(
        "render shadows and reflections (slow without a GPU)"))

    def __post_init__(self):
        if not 10.0 <= self.state_rate_hz <= 30.0:
            raise ConfigError(f"state_rate_hz={self.state_rate_hz} must be within 10-30 Hz")
        if not 10.0 <= self.robot_rate_hz <= 100.0:
            raise ConfigError(f"robot_rate_hz={self.robot_rate_hz} must be within 10-100 Hz")
        if self.realtime < 0:
            raise ConfigError(f"realtime={self.realtime} must be 0 (as fast as possible) or a "
                              "positive factor, e.g. 1 for real time")
        if self.camera not in CAMERAS:
            raise ConfigError(f"camera {self.camera!r} is not one of {', '.join(CAMERAS)}")
        if self.scene is not None and not Path(self.scene).is_file():
            raise ConfigError(f"scene file {self.scene!r} does not exist")


class MujocoSim(Service):
    """The simulated robot cell."""

    name = "mujoco-sim"
    description = ("The Panda table-top world in MuJoCo: executes cbgo/robot/act physically, "
                   "publishes cbgo/scene/state and cbgo/robot/state, answers sim/reset and "
                   "sim/render.")
    settings_class = MujocoSimSettings

    def __init__(self, settings: MujocoSimSettings):
        super().__init__(settings)
        self.stop = threading.Event()
        self.camera = Camera(shadows=settings.shadows)
        self.sim: Sim | None = None
        self.robot: Robot | None = None
        self.source = ""
        self.seq = {"scene": 0, "robot": 0}
        self.counts = {"actions": 0, "ok": 0, "refused": 0, "stopped": 0, "inconsistent": 0}
        self.last_compile_s = 0.0
        self._due = {"scene": 0.0, "robot": 0.0}
        self._pace: tuple[float, float] | None = None

    def setup(self, ctx) -> None:
        """Loads the start scene, then declares stop, outputs, queryables and state timers."""
        self.ctx = ctx
        s = self.settings
        start = read_scene_file(s.scene) if s.scene else None
        try:
            self.load(start if start is not None else s.seed)
        except scenes.SceneError as e:
            raise ConfigError(f"cannot load the start scene: {e}") from e
        ctx.subscribe(keys.ROBOT_STOP, self.on_stop, immediate=True)
        ctx.publishes(keys.SCENE_STATE, keys.ROBOT_STATE)
        ctx.queryable(keys.ROBOT_ACT, self.on_act)
        ctx.queryable(keys.SIM_RESET, self.on_reset)
        ctx.queryable(keys.SIM_RENDER, self.on_render)
        ctx.queryable(keys.SIM_INFO, self.on_info)
        ctx.every(1.0 / s.state_rate_hz, lambda: [self.scene_output()])
        ctx.every(1.0 / s.robot_rate_hz, lambda: [self.robot_output()])

    def shutdown(self) -> None:
        """Frees the renderer's OpenGL contexts."""
        self.camera.close()

    def status_extra(self) -> dict:
        """Returns the loaded scene's source, compile time and action counts."""
        return {"scene_source": self.source, "compile_s": self.last_compile_s,
                "actions": dict(self.counts)}

    # ------------------------------------------------------------------ world

    def load(self, scene: int | dict) -> list[str]:
        """Loads a scene (a seed or a contract scene body); returns its mismatches.

        Raises:
            SceneError: inconsistent, or the robot fits nowhere.
        """
        symbolic = scenes.scene_for_seed(scene) if isinstance(scene, int) else scene
        loaded = scenes.load(symbolic)
        loaded.sim.stop = self.stop
        loaded.sim.on_tick = self._on_tick
        self.sim, self.robot = loaded.sim, Robot(loaded.sim)
        self.source = f"seed {scene}" if isinstance(scene, int) else "scene"
        self.last_compile_s = loaded.compile_s
        return scenes.mismatches(loaded.sim, loaded.scene)

    def scene_output(self):
        """Returns the ``cbgo/scene/state`` output of the physics now."""
        self.seq["scene"] += 1
        return keys.SCENE_STATE, observe.scene_state(self.sim, self.seq["scene"])

    def robot_output(self):
        """Returns the ``cbgo/robot/state`` output of the physics now."""
        self.seq["robot"] += 1
        return keys.ROBOT_STATE, observe.robot_state(self.sim, self.seq["robot"])

    def _on_tick(self, sim: Sim) -> None:
        """Called after every control tick of an action: state streams and pacing."""
        now = time.monotonic()
        for kind, rate, output in (("scene", self.settings.state_rate_hz, self.scene_output),
                                   ("robot", self.settings.robot_rate_hz, self.robot_output)):
            if now >= self._due[kind]:
                self._due[kind] = now + 1.0 / rate
                self.ctx.publish(*output())
        if self.settings.realtime > 0 and self._pace is not None:
            wall0, sim0 = self._pace
            ahead = (sim.time - sim0) / self.settings.realtime - (now - wall0)
            if ahead > 0:
                time.sleep(ahead)

    # ------------------------------------------------------------------ inputs

    def on_stop(self, _msg: dict) -> None:
        """robot/stop (any payload, on Zenoh's thread): the motion stops at its next tick."""
        self.stop.set()
        self.ctx.log.info("stop received")

    def on_act(self, query: dict) -> dict:
        """robot/act: executes one action and replies with the outcome and the scene after."""
        self.stop.clear()
        self._pace = (time.monotonic(), self.sim.time)
        t0 = time.perf_counter()
        outcome = self.robot.execute(query["action"], query.get("object"), query["params"])
        self._pace = None
        self.counts["actions"] += 1
        self.counts["ok"] += outcome.ok
        self.counts["refused"] += outcome.refused
        self.counts["stopped"] += outcome.error == "stopped"
        topic, scene = self.scene_output()
        error = outcome.error
        if not outcome.ok and not outcome.refused:
            error = self._checked(error, scene)
        self.ctx.publish(topic, scene)
        self.ctx.log.info("%s(%s): %s in %.2f s sim, %.2f s wall", query["action"],
                          query.get("object") or "", error or "ok", outcome.sim_s,
                          time.perf_counter() - t0)
        return {"v": wire.SCHEMA_VERSION, "ok": outcome.ok, "error": error,
                "duration_s": round(outcome.sim_s, 4),
                "wall_s": round(time.perf_counter() - t0, 4), "scene": scene}

    def _checked(self, error: str, scene: dict) -> str:
        """Returns a failure's error, naming every contradiction in the scene read after it.

        The observation is built to be consistent (`observe`); a contradiction left is a gap
        in it, and the planner must hear of it rather than replan on a wrong world.
        """
        checked, problems = failure_error(error, scene)
        if problems:
            self.counts["inconsistent"] += 1
            self.ctx.log.error("inconsistent scene after %s: %s", error, "; ".join(problems))
        return checked

    def on_reset(self, query: dict) -> dict:
        """sim/reset: a random scene from a seed, or exactly the given scene, settled."""
        if "scene" in query:
            target = query["scene"]
        else:
            target = int(query.get("seed", self.settings.seed))
        try:
            problems = self.load(target)
        except scenes.SceneError as e:
            return {"v": wire.SCHEMA_VERSION, "ok": False, "error": str(e), "scene": None}
        topic, scene = self.scene_output()
        self.ctx.publish(topic, scene)
        error = ("after settling: " + "; ".join(problems)) if problems else None
        return {"v": wire.SCHEMA_VERSION, "ok": not problems, "error": error, "scene": scene}

    def on_info(self, _query: dict) -> dict:
        """sim/info: the workspace, as every robot of cbgo answers it."""
        return {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "robot": self.name,
                "workspace": workspace_info()}

    def on_render(self, query: dict) -> dict:
        """sim/render: a PNG of the world from a named camera."""
        s = self.settings
        try:
            png = self.camera.png(self.sim.model, self.sim.data, query.get("camera", s.camera),
                                  int(query.get("width", s.width)),
                                  int(query.get("height", s.height)))
        except RenderError as e:
            raise QueryError(str(e)) from None
        return {"v": wire.SCHEMA_VERSION, "ok": True, "error": None, "png": png}


main = main_for(MujocoSim)

if __name__ == "__main__":
    main()
