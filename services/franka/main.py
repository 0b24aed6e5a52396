"""franka: the robot cell on a Franka Research 3, driven through franky-control.

Behaviour (the contract is services/franka/README.md):
- at start, connects to the arm and hand at ``--robot-ip`` and moves nothing; the world is the
  user's declaration (``--scene`` file, ``cbgo/sim/reset {scene}``, or the world model's random
  scene of a seed, for franky-sim), with the TCP and finger gap as measured;
- answers ``cbgo/robot/act``: one action at a time, planned as Cartesian motions and gripper
  commands (`plan`), every point checked against the safety box (`frames.SafetyBox`) before
  anything is sent; refused with the reason, without moving, when the world model forbids it,
  a point is outside the box, an object's place is unknown or the connection is down;
- a done action's effects are the world model's, at the measured TCP; a failed one (a grasp
  that closed on nothing, a reflex, a stop, a lost connection) makes the objects it was handling
  *unknown* (`tracking`): they leave ``objects`` and are listed under ``unknown``, and every
  action is refused until the scene is declared again;
- ``cbgo/robot/stop`` (any payload) stops the arm or the gripper at once (``robot.stop()``,
  ``gripper.stop()``); the action ends with ``ok: false, error: "stopped"``;
- a lost connection is reported (the act reply, ``robot/state``'s ``connected: false``, the
  status) and nothing is retried: ``cbgo/sim/reset`` reconnects, with a new declaration;
- ``--dry-run`` plans and checks every action without connecting or moving.

All of that but the arm is `cbgo.robot_cell.RobotCell`, shared with mujoco-sim and dry-robot.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from cbgo import keys
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError
from cbgo.robot_cell import ActOutcome, RobotCell, RobotCellSettings
from cbgo.runtime import main_for
from cbgo.services.franka.arm import (
    GRASP_FORCE_MAX,
    GRASP_TOLERANCE,
    ArmFault,
    ArmState,
    DryArm,
    FrankyArm,
    Stopped,
)
from cbgo.services.franka.frames import Mount, SafetyBox, hand_rotation, quaternion_xyzw
from cbgo.services.franka.plan import (
    Grasp,
    Gripper,
    Holding,
    Move,
    Pause,
    Plan,
    PlanRefused,
    plan_action,
)
from cbgo.services.franka.tracking import TrackedWorld
from cbgo.world import Scene, random_scene, workspace_info
from cbgo.world.workspace import SceneError, startable_scene

# the highest --dynamics accepted: half of the arm's limits, for a shared table
DYNAMICS_MAX = 0.5
NO_RENDERER = ("franka has no renderer: it drives a real arm; read the world on "
               "cbgo/scene/state, or run mujoco-sim for images")


@dataclass
class FrankaSettings(RobotCellSettings):
    """Settings of franka (flags ``--robot-ip`` ... or env ``CBGO_ROBOT_IP`` ...)."""

    robot_ip: str = field(default="", metadata=_help(
        "the robot's FCI address (a Franka Research 3, or franky-sim's 127.0.0.x); empty: a "
        "dry run (nothing connects, nothing moves)"))
    base_in_table: str = field(default="0,0,0,0", metadata=_help(
        "where the robot base stands in the table frame the scene is declared in: "
        "x,y,z (m),yaw (degrees about the vertical)"))
    dynamics: float = field(default=0.1, metadata=_help(
        f"the arm's speed: franky's relative dynamics factor for every motion (velocity, "
        f"acceleration and jerk as a fraction of the arm's limits), 0.01-{DYNAMICS_MAX:g}; "
        "slow steps near objects take half"))
    box: str = field(default="0.25,0.75,-0.30,0.30,0.005,0.55", metadata=_help(
        "the safety box the TCP must stay in, table frame: x0,x1,y0,y1,z0,z1 (m); targets "
        "outside are refused before anything moves"))
    grasp_force: float = field(default=20.0, metadata=_help(
        f"N the fingers press with when grasping (1-{GRASP_FORCE_MAX:g})"))
    dry_run: bool = field(default=False, metadata=_help(
        "plan and check every action without connecting to a robot or moving anything"))

    def __post_init__(self):
        super().__post_init__()
        self.dry_run = self.dry_run or not self.robot_ip.strip()  # no address: nothing moves
        if not 0.01 <= self.dynamics <= DYNAMICS_MAX:
            raise ConfigError(f"dynamics={self.dynamics} must be within 0.01-{DYNAMICS_MAX:g} (a "
                              "fraction of the arm's velocity, acceleration and jerk limits)")
        if not 1.0 <= self.grasp_force <= GRASP_FORCE_MAX:
            raise ConfigError(f"grasp_force={self.grasp_force} must be within "
                              f"1-{GRASP_FORCE_MAX:g} N")
        try:
            self.mount = Mount.parse(self.base_in_table)
            self.safety_box = SafetyBox.parse(self.box)
        except ValueError as e:
            raise ConfigError(str(e)) from None


class Franka(RobotCell):
    """The robot cell on a Franka arm (the glue is `cbgo.robot_cell.RobotCell`'s)."""

    name = "franka"
    description = ("A Franka Research 3 driven through franky-control on mujoco-sim's keys: "
                   "answers cbgo/robot/act with real motions and the real gripper (safety box "
                   "checked first), tracks the user-declared scene through its own actions, "
                   "obeys cbgo/robot/stop at once. --dry-run plans without a robot.")
    settings_class = FrankaSettings

    def __init__(self, settings: FrankaSettings):
        super().__init__(settings)
        self.mount, self.box = settings.mount, settings.safety_box
        self.arm = (DryArm((0.44, 0.0, 0.36), hand_rotation()) if settings.dry_run
                    else FrankyArm(settings.robot_ip, settings.dynamics, settings.grasp_force))
        self.world: TrackedWorld | None = None
        self.last: ArmState | None = None
        self.action: str | None = None
        self.state_seq = 0
        self.connects = 0

    def setup(self, ctx) -> None:
        """Connects (a dry run does not), declares the start scene, then the robot cell's keys."""
        if self.settings.dry_run:
            ctx.log.warning("dry run%s: actions are planned and checked, nothing moves",
                            "" if self.settings.robot_ip.strip() else " (no --robot-ip)")
        super().setup(ctx)

    # ------------------------------------------------------------------ world

    def load(self, target: int | dict) -> list[str]:
        """Declares the world (a seed's random scene or a scene body) at the measured arm.

        Reconnects first when the connection is down (the one place that does).

        Raises:
            SceneError: the scene is refused, the robot cannot be reached, or the gripper
                contradicts what the scene says it holds.
        """
        scene = random_scene(target) if isinstance(target, int) else startable_scene(target)
        if isinstance(self.arm, DryArm):
            self._declare_dry(scene)
        state = self._measured()
        if isinstance(target, int):
            scene = seed_scene_in_hand(scene, state.width)
        mismatch = grip_mismatch(scene, state.width)
        if mismatch is not None:
            raise SceneError(mismatch)
        scene.robot.tcp = tuple(float(v) for v in self.mount.to_table(state.tcp))
        seq = self.world.seq if self.world is not None else 0
        self.world = TrackedWorld(scene, seq=seq)
        self.world.scene.settle()
        return []

    def _declare_dry(self, scene: Scene) -> None:
        """A dry run's arm starts where the declared scene puts the TCP and fingers."""
        held = scene.robot.holding
        self.arm.tcp = tuple(float(v) for v in self.mount.to_base(scene.robot.tcp))
        self.arm.width = scene.get(held).size if held else 0.08

    def _measured(self) -> ArmState:
        """Returns the measured arm, connecting first if needed.

        Raises:
            SceneError: the robot cannot be reached.
        """
        if not self.arm.connected:
            try:
                self.arm.connect()
                self.connects += 1
            except ArmFault as e:
                raise SceneError(f"cannot reach the robot at {self.settings.robot_ip}: {e}; "
                                 "check that it is on, in FCI mode and that no other client "
                                 "is connected") from None
        try:
            self.last = self.arm.read()
        except ArmFault as e:
            raise SceneError(f"cannot read the robot's state: {e}") from None
        return self.last

    def scene_message(self) -> dict:
        """Returns the tracked world as the next ``cbgo/scene/state`` message."""
        return self.world.message()

    def robot_message(self) -> dict:
        """Returns the measured arm as the next ``cbgo/robot/state`` message.

        With the connection down, the last measured values with ``connected: false``.
        """
        try:
            if self.arm.connected:
                self.last = self.arm.read()
        except ArmFault as e:
            self.ctx.log.error("robot state: %s", e)
        state = self.last
        self.state_seq += 1
        tcp = self.mount.to_table(state.tcp) if state else self.world.scene.robot.tcp
        return keys.ROBOT_STATE.message(
            ts=time.time(), seq=self.state_seq,
            joints=list(state.joints) if state else [0.0] * 7,
            gripper_width=max(0.0, state.width) if state else 0.0,
            tcp=[round(float(v), 5) for v in tcp], moving=self.action is not None,
            action=self.action, kinematics=bool(state and state.kinematics),
            connected=self.arm.connected, dry_run=self.settings.dry_run)

    def status_extra(self) -> dict:
        """Adds the connection, the safety settings and what is unknown to the status."""
        return {**super().status_extra(), "robot_ip": self.settings.robot_ip,
                "connected": self.arm.connected, "lost": self.arm.lost,
                "connects": self.connects, "dry_run": self.settings.dry_run,
                "dynamics": self.settings.dynamics, "box": self.box.describe(),
                "unknown": sorted(self.world.unknown) if self.world else []}

    def on_info(self, _query: dict) -> dict:
        """sim/info: the contract's workspace, plus the safety box the TCP is held to."""
        b = self.box
        return keys.SIM_INFO.reply(True, None, robot=self.name, workspace=workspace_info(),
                                   safety_box={"x": list(b.x), "y": list(b.y), "z": list(b.z)})

    def render(self, _query: dict) -> bytes:
        """sim/render: an error reply, always."""
        raise QueryError(NO_RENDERER)

    # ------------------------------------------------------------------ actions

    def execute(self, action: str, obj: str | None, params: dict) -> ActOutcome:
        """Plans, checks, then runs one action; see the module docstring."""
        refusal, plan = self._checked_plan(action, obj, params)
        if refusal is not None:
            return ActOutcome(False, f"refused: {refusal}", refused=True)
        self.action = action
        t0 = time.monotonic()
        try:
            error = self._run(plan, action, obj)
        finally:
            self.action = None
        return ActOutcome(error is None, error, duration_s=time.monotonic() - t0,
                          scene=self.world.message())

    def _checked_plan(self, action: str, obj: str | None,
                      params: dict) -> tuple[str | None, Plan | None]:
        """Returns (why the action is refused, None) or (None, its plan); nothing moves."""
        if not self.arm.connected:
            return (f"not connected to the robot at {self.settings.robot_ip} ({self.arm.lost}); "
                    "nothing was sent: check the robot, then declare the scene again with "
                    "cbgo/sim/reset, which reconnects"), None
        refusal = self.world.refusal()
        if refusal is not None:
            return refusal, None
        try:
            state = self.arm.read()
        except ArmFault as e:
            return f"{e}; nothing was sent", None
        self.last = state
        self.world.scene.robot.tcp = tuple(float(v) for v in self.mount.to_table(state.tcp))
        try:
            plan = plan_action(action, obj, params, self.world.scene)
        except PlanRefused as e:
            return str(e), None
        reason = self.box.first_refusal(plan.points(), self.mount)
        return (reason, None) if reason is not None else (None, plan)

    def _run(self, plan: Plan, action: str, obj: str | None) -> str | None:
        """Runs a plan's steps; returns None when done, else the error (world updated)."""
        held_before = self.world.scene.robot.holding
        near = False  # whether the hand has started down towards what it handles
        what = f"{action}({obj})" if obj else action
        try:
            for step in plan.steps:
                near = near or (isinstance(step, Move) and step.slow) or isinstance(step, Grasp)
                failure = self._step(step)
                if failure is not None:
                    self._retreat()
                    self._after_failure(plan.touched, held_before, f"{failure} during {what}")
                    return failure
        except Stopped:
            touched = plan.touched if near else []
            self._after_failure(touched, held_before, f"stopped during {what}")
            return "stopped"
        except ArmFault as e:
            touched = plan.touched if near or e.kind == "connection" else []
            self._after_failure(touched, held_before, f"{e.kind} during {what}")
            return f"{e.kind}: {e}"
        self.world.done(plan.after, self.mount.to_table(self._read_or_last().tcp))
        return None

    def _step(self, step) -> str | None:
        """Runs one step; returns a failure sentence (a grasp that did not hold), or None."""
        stop, tick = self.stop, self._tick
        if isinstance(step, Move):
            rot = self.mount.rotation_to_base(hand_rotation(step.tilt_deg))
            self.arm.move(self.mount.to_base(step.position), quaternion_xyzw(rot), step.slow,
                          stop, tick)
        elif isinstance(step, Grasp):
            held, width = self.arm.grasp(step.width, stop, tick)
            if not held:
                return (f"the grasp of {step.what} failed: the fingers closed to {width:.4f} m, "
                        f"expected {step.width:.4f} ± {GRASP_TOLERANCE:.3f} m")
        elif isinstance(step, Holding):
            width = self.arm.read().width
            if abs(width - step.width) > GRASP_TOLERANCE:
                return (f"{step.what} slipped out of the fingers: they are {width:.4f} m apart, "
                        f"expected {step.width:.4f} ± {GRASP_TOLERANCE:.3f} m")
        elif isinstance(step, Gripper):
            self.arm.open_to(step.width, stop, tick)
        elif isinstance(step, Pause):
            end = time.monotonic() + step.seconds
            while time.monotonic() < end:
                if stop.wait(0.02):
                    raise Stopped()
                tick()
        return None

    def _retreat(self) -> None:
        """After a failed grasp: opens the fingers and goes straight up to travel height."""
        state = self._read_or_last()
        if state is None:
            return
        up = self.mount.to_table(state.tcp)
        up[2] = max(float(up[2]), float(self.box.z[0]))
        target = (float(up[0]), float(up[1]), min(float(up[2]) + 0.1, self.box.z[1]))
        if self.box.refusal(target, self.mount) is not None:
            return
        try:
            self.arm.open_to(0.08, self.stop, self._tick)
            self._step(Move(target, slow=True))
        except (Stopped, ArmFault) as e:
            self.ctx.log.warning("retreat after a failed grasp ended: %s", e)

    def _after_failure(self, touched: list[str], held_before: str | None, why: str) -> None:
        """Marks what may have moved unknown; the TCP and fingers as measured (if readable)."""
        state = self._read_or_last(fresh=True)
        lost = list(touched)
        if held_before is not None:
            size = self.world.scene.get(held_before).size if self.world.scene.has(
                held_before) else None
            still = (state is not None and self.arm.connected and size is not None
                     and abs(state.width - size) <= GRASP_TOLERANCE)
            if not still:
                lost.append(held_before)
            elif held_before in lost:
                lost.remove(held_before)
        self.world.lose(lost, why)
        if state is not None and self.arm.connected:
            holding = self.world.scene.robot.holding
            self.world.release_grip(self.mount.to_table(state.tcp), gripper_open=holding is None)
            self.world.scene.settle()
        for name in lost:
            self.ctx.log.warning("%s: place unknown (%s)", name, why)

    def _read_or_last(self, fresh: bool = True) -> ArmState | None:
        if fresh and self.arm.connected:
            try:
                self.last = self.arm.read()
            except ArmFault as e:
                self.ctx.log.error("%s", e)
        return self.last

    def _tick(self) -> None:
        """Between two waits of a motion: the state streams at their rates.

        The event loop is busy with the action, so its timers cannot fire.
        """
        self.publish_due_states()


def seed_scene_in_hand(scene: Scene, width: float) -> Scene:
    """Returns a seed's random scene without the load the measured fingers do not hold.

    A seed's scene is the world model's invention, not the user's declaration: where it puts a
    load in the gripper and the fingers are apart otherwise, the load (and what stands on it)
    is left out and the gripper declared empty, so that a robot started without ``--scene``
    comes up rather than refusing the world it invented.
    """
    if grip_mismatch(scene, width) is None:
        return scene
    held = scene.robot.holding
    gone = {held, *scene.tower_above(held)}
    body = scene.to_dict()
    body["objects"] = [o for o in body["objects"] if o["name"] not in gone]
    body["robot"] = {**body["robot"], "holding": None, "gripper_open": True}
    return startable_scene(body)


def grip_mismatch(scene: Scene, width: float) -> str | None:
    """Returns why a declared scene contradicts the measured finger gap, or None."""
    held = scene.robot.holding
    if held is None or not scene.has(held):
        return None
    size = scene.get(held).size
    if abs(width - size) <= GRASP_TOLERANCE:
        return None
    return (f"the scene says the gripper holds {held} ({size:.3f} m), but the fingers are "
            f"{width:.3f} m apart: declare what the gripper really holds")


main = main_for(Franka)

if __name__ == "__main__":
    main()
