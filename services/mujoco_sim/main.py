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
- answers ``cbgo/sim/reset`` (seed, scene, or neither: the start scene -> settled scene; a
  scene outside the workspace or against the world model's rules is refused,
  ``cbgo.world.reset_refusal``), ``cbgo/sim/render`` (PNG) and ``cbgo/sim/info`` (the
  workspace, ``cbgo.world.workspace_info``);
- after a failed action, loose objects come to rest and the scene is checked
  (``cbgo.world.check_consistent``) before it is published; a contradiction is named in the
  reply's error;
- physics runs as fast as it can, or paced at ``--realtime`` times real time.

All of that but the physics is `cbgo.robot_cell.RobotCell`, shared with dry-robot.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.robot_cell import ActOutcome, RobotCell, RobotCellSettings
from cbgo.runtime import main_for
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.build import CAMERAS
from cbgo.services.mujoco_sim.engine import Sim
from cbgo.services.mujoco_sim.render import Camera, RenderError
from cbgo.services.mujoco_sim.skills import Robot


@dataclass
class MujocoSimSettings(RobotCellSettings):
    """Settings of mujoco-sim (flags ``--seed`` ... or env ``CBGO_SEED`` ...)."""

    realtime: float = field(default=0.0, metadata=_help(
        "pace the physics at this many times real time (1: real time); 0: as fast as it can"))
    camera: str = field(default="overview", metadata=_help(
        f"default camera of cbgo/sim/render: {', '.join(CAMERAS)}"))
    width: int = field(default=640, metadata=_help("default image width, pixels"))
    height: int = field(default=480, metadata=_help("default image height, pixels"))
    shadows: bool = field(default=False, metadata=_help(
        "render shadows and reflections (slow without a GPU)"))

    def __post_init__(self):
        super().__post_init__()
        if self.realtime < 0:
            raise ConfigError(f"realtime={self.realtime} must be 0 (as fast as possible) or a "
                              "positive factor, e.g. 1 for real time")
        if self.camera not in CAMERAS:
            raise ConfigError(f"camera {self.camera!r} is not one of {', '.join(CAMERAS)}")


class MujocoSim(RobotCell):
    """The simulated robot cell (the glue is `cbgo.robot_cell.RobotCell`'s)."""

    name = "mujoco-sim"
    description = ("The Panda table-top world in MuJoCo: executes cbgo/robot/act physically, "
                   "publishes cbgo/scene/state and cbgo/robot/state, answers sim/reset and "
                   "sim/render.")
    settings_class = MujocoSimSettings

    def __init__(self, settings: MujocoSimSettings):
        super().__init__(settings)
        self.camera = Camera(shadows=settings.shadows)
        self.sim: Sim | None = None
        self.robot: Robot | None = None
        self.seq = {"scene": 0, "robot": 0}
        self.last_compile_s = 0.0
        self._pace: tuple[float, float] | None = None

    def shutdown(self) -> None:
        """Frees the renderer's OpenGL contexts."""
        self.camera.close()

    def status_extra(self) -> dict:
        """Adds the last scene's compile time to the robot cell's status."""
        return {**super().status_extra(), "compile_s": self.last_compile_s}

    # ------------------------------------------------------------------ world

    def load(self, target: int | dict) -> list[str]:
        """Loads a scene (a seed or a contract scene body); returns its mismatches.

        Raises:
            SceneError: inconsistent, or the robot fits nowhere.
        """
        symbolic = scenes.scene_for_seed(target) if isinstance(target, int) else target
        loaded = scenes.load(symbolic)
        loaded.sim.stop = self.stop
        loaded.sim.on_tick = self._on_tick
        self.sim, self.robot = loaded.sim, Robot(loaded.sim)
        self.last_compile_s = loaded.compile_s
        return scenes.mismatches(loaded.sim, loaded.scene)

    def scene_message(self) -> dict:
        """Returns the ``cbgo/scene/state`` message of the physics now."""
        self.seq["scene"] += 1
        return observe.scene_state(self.sim, self.seq["scene"])

    def robot_message(self) -> dict:
        """Returns the ``cbgo/robot/state`` message of the physics now."""
        self.seq["robot"] += 1
        return observe.robot_state(self.sim, self.seq["robot"])

    def _on_tick(self, sim: Sim) -> None:
        """Called after every control tick of an action: state streams and pacing.

        While an action runs the event loop is busy with it, so the state timers cannot fire:
        the control loop publishes at the same rates instead.
        """
        self.publish_due_states()
        if self.settings.realtime > 0 and self._pace is not None:
            wall0, sim0 = self._pace
            ahead = (sim.time - sim0) / self.settings.realtime - (time.monotonic() - wall0)
            if ahead > 0:
                time.sleep(ahead)

    # ------------------------------------------------------------------ actions, images

    def execute(self, action: str, obj: str | None, params: dict) -> ActOutcome:
        """Executes one action in the physics, verified from it; `stop` ends it at a tick."""
        self._pace = (time.monotonic(), self.sim.time)
        try:
            outcome = self.robot.execute(action, obj, params)
        finally:
            self._pace = None
        return ActOutcome(ok=outcome.ok, error=outcome.error, refused=outcome.refused,
                          duration_s=outcome.sim_s)

    def render(self, query: dict) -> bytes:
        """sim/render: a PNG of the world from a named camera."""
        s = self.settings
        try:
            return self.camera.png(self.sim.model, self.sim.data, query.get("camera", s.camera),
                                   int(query.get("width", s.width)),
                                   int(query.get("height", s.height)))
        except RenderError as e:
            raise QueryError(str(e)) from None


main = main_for(MujocoSim)

if __name__ == "__main__":
    main()
