"""The arm and gripper behind one small interface: a Franka through franky, or a dry run.

`FrankyArm` talks to a Franka Research 3 (or franky-sim, which speaks the same network protocol)
with franky-control. Everything it sends is asynchronous, so that a stop is obeyed at once: a
motion is started with ``asynchronous=True`` and waited for in short slices
(`WAIT_SLICE_S`); between slices the caller's stop event is checked, and a set event calls
``robot.stop()`` (the robot decelerates on its own and the motion ends with a "preempted"
ControlException, which is the expected end of a stop) or ``gripper.stop()``. The caller's
`tick` runs between slices too (the service publishes ``cbgo/robot/state`` from it while the
arm moves).

What can go wrong, and how it is told apart (`ArmFault.kind`):

- ``reflex``: a ControlException the arm raised on its own (a collision, a limit): the arm has
  stopped; `recover_from_errors` is called and its result reported;
- ``planner``: a RuntimeError from franky's motion planner (a target it cannot reach): nothing
  may have moved, or part of the way;
- ``connection``: a NetworkException, or a state that cannot be read: the connection is lost.
  The arm is marked disconnected and nothing is retried: the next action is refused until the
  user reconnects (``cbgo/sim/reset``).

`DryArm` plans and checks like the real one but moves nothing: its TCP and fingers are where
the last command put them, and its grasps always hold (it cannot feel).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

WAIT_SLICE_S = 0.01  # s between two checks of the stop event while the arm or gripper moves
SLOW_FACTOR = 0.5  # of the configured speed, for the slow steps near objects
GRIPPER_SPEED = 0.05  # m/s the fingers move (the Franka Hand's maximum)
GRASP_FORCE_MAX = 70.0  # N, the Franka Hand's continuous force
# m the fingers may stop short of or beyond the expected width and still count as holding it:
# franky-sim closes within 1.5 mm of a 0.05 m box (the measurement); the real hand on
# a cup squeezes it a few mm
GRASP_TOLERANCE = 0.006
# m inside the expected width that a grasp aims: the real hand closes on the object with force
# and stops there; franky-sim drives the fingers to the commanded width, so only a command
# inside the object presses on it, and an empty grasp ends this far short of the object's width
# (and is told apart from a held one)
GRASP_SQUEEZE = 0.012
GRIPPER_TIMEOUT_S = 10.0  # s a gripper command may take before it counts as failed
MOTION_TIMEOUT_S = 60.0  # s one Cartesian motion may take at the slowest speed
# Both are counted on the robot's own clock (`RobotClock`): a simulator runs slower than the wall
# clock on a busy machine (franky-sim's 90 s pour), and its motions last as long in its time.
CLOCK_STALL_S = 10.0  # s of wall time the robot's clock may stand still before it counts as lost
CONNECT_TIMEOUT_S = 10.0  # s to open the connection (franky-sim blocks a second client forever)
READY_JOINTS = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)  # rad, the Franka's ready posture


class Stopped(Exception):  # noqa: N818 - an outcome, not an error
    """The motion was ended by a stop request."""


class ArmFault(Exception):
    """The arm or gripper failed: `kind` is reflex, planner, connection or gripper."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class ArmState:
    """The arm as measured: joints (rad), TCP in the base frame (m), finger gap (m)."""

    joints: tuple[float, ...]
    tcp: tuple[float, float, float]
    rotation: np.ndarray
    width: float
    kinematics: bool = True


Tick = Callable[[], None]


def _run_with_timeout(fn: Callable[[], object], timeout_s: float, what: str):
    """Runs a blocking call on a helper thread; raises ArmFault on timeout or error."""
    box: dict[str, object] = {}

    def target():
        try:
            box["value"] = fn()
        except Exception as e:  # noqa: BLE001 - handed to the caller below
            box["error"] = e

    thread = threading.Thread(target=target, name=f"franka-{what}", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if thread.is_alive():
        raise ArmFault("connection", f"{what} did not answer within {timeout_s:g} s (is another "
                                     "client connected to the robot?)")
    if "error" in box:
        e = box["error"]
        raise ArmFault("connection", f"{what} failed: {type(e).__name__}: {e}")
    return box.get("value")


class RobotClock:
    """How long a command has run by the robot's own clock, and whether that clock still runs.

    The robot stamps every state with its time (`RobotState.time`): a real arm's runs with the
    wall clock, a simulator's as fast as it steps. A command is overdue after ``limit_s`` of
    robot time; a clock that stands still for `CLOCK_STALL_S` of wall time is a lost robot.

    Args:
        now: reads the robot's time (s).
        limit_s: the command's time limit in robot time.
        overdue: the `ArmFault.kind` of an overdue command.
    """

    def __init__(self, now: Callable[[], float], limit_s: float, overdue: str = "planner"):
        self.now, self.limit_s, self.overdue = now, limit_s, overdue
        self.start = self.last = now()
        self.last_change = time.monotonic()

    def check(self, what: str) -> None:
        """Raises ArmFault when the command is overdue (`overdue`) or the clock stopped."""
        t = self.now()
        if t != self.last:
            self.last, self.last_change = t, time.monotonic()
        elif time.monotonic() - self.last_change > CLOCK_STALL_S:
            raise ArmFault("connection", f"the robot's clock has not moved for "
                                         f"{CLOCK_STALL_S:g} s during {what}")
        if t - self.start > self.limit_s:
            raise ArmFault(self.overdue, f"{what} did not end within {self.limit_s:g} s of the "
                                         "robot's time")


class FrankyArm:
    """A Franka arm and hand through franky-control (see the module docstring).

    Args:
        ip: the robot's (FCI) address.
        speed: franky's relative dynamics factor for every motion (velocity, acceleration
            and jerk), 0 < speed <= 1.
        grasp_force: N the fingers press with when grasping.
    """

    def __init__(self, ip: str, speed: float, grasp_force: float):
        self.ip, self.speed, self.grasp_force = ip, speed, grasp_force
        self.robot = None
        self.gripper = None
        self.lost: str | None = "not connected yet"

    @property
    def connected(self) -> bool:
        """Whether the last connection is up (as far as the service has seen)."""
        return self.lost is None

    def connect(self) -> None:
        """Opens the connection to the arm and the hand; moves nothing.

        Raises:
            ArmFault: (``connection``) the robot does not answer.
        """
        import franky  # the optional extra `franka`: imported only where it is used

        self.robot = self.gripper = None
        robot = _run_with_timeout(lambda: franky.Robot(
            self.ip, realtime_config=franky.RealtimeConfig.Ignore), CONNECT_TIMEOUT_S,
            f"connecting to the robot at {self.ip}")
        robot.relative_dynamics_factor = franky.RelativeDynamicsFactor(self.speed)
        gripper = _run_with_timeout(lambda: franky.Gripper(self.ip), CONNECT_TIMEOUT_S,
                                    f"connecting to the gripper at {self.ip}")
        if robot.has_errors and not robot.recover_from_errors():
            raise ArmFault("reflex", f"the robot at {self.ip} reports errors that automatic "
                                     "recovery cannot clear: clear them in Desk")
        self.robot, self.gripper, self.lost = robot, gripper, None

    def mark_lost(self, why: str) -> None:
        """Records that the connection is gone; nothing is sent any more."""
        self.lost = why

    def read(self) -> ArmState:
        """Returns the measured state.

        Raises:
            ArmFault: (``connection``) the state cannot be read.
        """
        if self.lost is not None:
            raise ArmFault("connection", f"not connected to the robot at {self.ip} ({self.lost})")
        try:
            state = self.robot.state
            pose = state.O_T_EE
            width = float(self.gripper.width)
        except Exception as e:  # noqa: BLE001 - franky raises RuntimeError("Net Exception")
            self.mark_lost(f"{type(e).__name__}: {e}")
            raise ArmFault("connection", f"the connection to the robot at {self.ip} is lost: "
                                         f"{type(e).__name__}: {e}") from None
        matrix = np.asarray(pose.matrix, float)
        return ArmState(tuple(float(v) for v in state.q),
                        tuple(float(v) for v in matrix[:3, 3]), matrix[:3, :3], width)

    def move(self, position: Sequence[float], quaternion: Sequence[float], slow: bool,
             stop: threading.Event, tick: Tick) -> None:
        """Moves the TCP to a base-frame pose; returns when it is there.

        Raises:
            Stopped: the stop event was set; the arm has been stopped.
            ArmFault: a reflex, the planner, or the connection.
        """
        import franky

        target = franky.Affine(np.asarray(position, float), np.asarray(quaternion, float))
        factor = franky.RelativeDynamicsFactor(SLOW_FACTOR if slow else 1.0)
        motion = franky.CartesianMotion(target, franky.ReferenceType.Absolute, factor)
        clock = RobotClock(self._robot_time, MOTION_TIMEOUT_S)
        self._send(lambda: self.robot.move(motion, asynchronous=True))
        while True:
            if stop.is_set():
                self._halt()
                raise Stopped()
            if self._joined():
                return
            tick()
            try:
                clock.check("the motion")
            except ArmFault:
                self._halt()
                raise

    def _robot_time(self) -> float:
        """Returns the robot's clock (s), from its latest state.

        Raises:
            ArmFault: (``connection``) the state cannot be read.
        """
        try:
            return float(self.robot.state.time.to_sec())
        except Exception as e:  # noqa: BLE001 - franky raises RuntimeError("Net Exception")
            self.mark_lost(f"{type(e).__name__}: {e}")
            raise ArmFault("connection", f"the connection to the robot at {self.ip} is lost: "
                                         f"{type(e).__name__}: {e}") from None

    def _send(self, fn: Callable[[], object]) -> None:
        import franky

        try:
            fn()
        except franky.NetworkException as e:
            self.mark_lost(str(e))
            raise ArmFault("connection", f"the connection to the robot is lost: {e}") from None
        except franky.ControlException as e:
            raise self._reflex(e) from None
        except RuntimeError as e:
            raise ArmFault("planner", f"franky refused the motion: {e}") from None

    def _joined(self) -> bool:
        import franky

        try:
            return bool(self.robot.join_motion(WAIT_SLICE_S))
        except franky.NetworkException as e:
            self.mark_lost(str(e))
            raise ArmFault("connection", f"the connection to the robot was lost during the "
                                         f"motion: {e}") from None
        except franky.ControlException as e:
            raise self._reflex(e) from None
        except RuntimeError as e:
            raise ArmFault("planner", f"franky's motion failed: {e}") from None

    def _reflex(self, error: Exception) -> ArmFault:
        """Recovers from a reflex; returns the fault that reports it."""
        try:
            recovered = bool(self.robot.recover_from_errors())
        except Exception as e:  # noqa: BLE001 - reported, not raised
            recovered, error = False, f"{error}; recovery failed: {e}"
        tail = "recovered" if recovered else "automatic recovery failed: clear the error in Desk"
        return ArmFault("reflex", f"the arm stopped with a reflex ({error}); {tail}")

    def _halt(self) -> None:
        """Stops the arm now (the robot decelerates) and clears the expected preemption."""
        import franky

        try:
            self.robot.stop()
            self.robot.join_motion(1.0)
        except franky.ControlException:
            pass  # "Move command preempted": how a stopped motion ends
        except franky.NetworkException as e:
            self.mark_lost(str(e))
            return
        try:
            if self.robot.has_errors:
                self.robot.recover_from_errors()
        except Exception:  # noqa: BLE001 - the next state read reports a lost connection
            return

    def open_to(self, width: float, stop: threading.Event, tick: Tick) -> None:
        """Moves the fingers to `width` (m) without force.

        Raises:
            Stopped, ArmFault: as `move`.
        """
        self._wait_gripper(lambda: self.gripper.move_async(width, GRIPPER_SPEED), stop, tick,
                           f"opening the gripper to {width:.3f} m")

    def grasp(self, width: float, stop: threading.Event, tick: Tick) -> tuple[bool, float]:
        """Closes on an object `width` m wide; returns (holding it, the measured gap).

        Holding it: the hand says so and the gap is within `GRASP_TOLERANCE` of `width` (a
        grasp aims `GRASP_SQUEEZE` inside it).

        Raises:
            Stopped, ArmFault: as `move`.
        """
        aim = max(0.0, width - GRASP_SQUEEZE)
        held = self._wait_gripper(lambda: self.gripper.grasp_async(
            aim, GRIPPER_SPEED, self.grasp_force, GRASP_TOLERANCE, GRASP_SQUEEZE + GRASP_TOLERANCE),
            stop, tick, f"grasping {width:.3f} m")
        measured = self.read().width
        return bool(held) and abs(measured - width) <= GRASP_TOLERANCE, measured

    def _wait_gripper(self, start: Callable[[], object], stop: threading.Event, tick: Tick,
                      what: str) -> bool:
        import franky

        try:
            clock = RobotClock(self._robot_time, GRIPPER_TIMEOUT_S, overdue="gripper")
            future = start()
            while not future.wait(WAIT_SLICE_S):
                if stop.is_set():
                    self.gripper.stop()
                    raise Stopped()
                tick()
                clock.check(what)
            return bool(future.get())
        except franky.NetworkException as e:
            self.mark_lost(str(e))
            raise ArmFault("connection", f"the connection to the gripper is lost: {e}") from None
        except (franky.GripperException, franky.CommandException) as e:
            raise ArmFault("gripper", f"{what} failed: {e}") from None


class DryArm:
    """An arm that moves nothing: it remembers the last command (``--dry-run``)."""

    connected = True
    lost = None

    def __init__(self, tcp: Sequence[float], rotation: np.ndarray, width: float = 0.08):
        self.tcp = tuple(float(v) for v in tcp)
        self.rotation = rotation
        self.width = width

    def connect(self) -> None:
        """Nothing to connect to."""

    def mark_lost(self, why: str) -> None:
        """A dry run cannot lose its connection."""

    def read(self) -> ArmState:
        """Returns where the last command put the arm; no kinematics."""
        return ArmState(READY_JOINTS, self.tcp, self.rotation, self.width, kinematics=False)

    def move(self, position, quaternion, slow: bool, stop: threading.Event, tick: Tick) -> None:
        """Jumps to the target (after checking the stop)."""
        if stop.is_set():
            raise Stopped()
        self.tcp = tuple(float(v) for v in position)
        self.rotation = _rotation_of(quaternion)

    def open_to(self, width: float, stop: threading.Event, tick: Tick) -> None:
        """Sets the finger gap."""
        if stop.is_set():
            raise Stopped()
        self.width = width

    def grasp(self, width: float, stop: threading.Event, tick: Tick) -> tuple[bool, float]:
        """Closes on the expected width: a dry run cannot feel, so it always holds."""
        if stop.is_set():
            raise Stopped()
        self.width = width
        return True, width


def _rotation_of(q: Sequence[float]) -> np.ndarray:
    """Returns the rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
