"""Frames and the safety box: where the robot base stands on the table, and where the TCP may go.

The contract states the scene in the *table frame* (metres, +z up, the table top at z = 0, the
person across the table at +x; docs/protocol.md "Frames and units"). franky commands and reports
the end effector in the *robot base frame*. `Mount` is the one transform between them, given by
the user (``--base-in-table x,y,z,yaw_deg``: where the base stands on the table and how it is
turned about the vertical); a real cell measures it once.

Orientations: the hand points straight down with its fingers closing along the table's y axis
(the world model's gripper at yaw 0, `cbgo.world.actions`); a pour turns it about that closing
axis. franky's quaternions are (x, y, z, w).

`SafetyBox` is checked for every point of a plan before anything is sent to the arm: the TCP
stays inside an axis-aligned box in the table frame, no nearer to the base axis than the arm
folds top-down (`MIN_REACH`) and no farther from the shoulder than it reaches (`MAX_REACH`).
franky-sim drives the arm below the floor, and keeps it broken, when a target is out of reach,
and a real arm stops with a reflex: neither may be left to find out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from cbgo.world.workspace import MIN_REACH

SHOULDER_Z = 0.333  # m, the FR3's second joint above its base (Franka's datasheet)
# m from the shoulder that the TCP reaches with a top-down hand: the FR3's 0.855 m reach is the
# flange's, and a top-down hand costs about its length (0.107 m to the fingertips)
MAX_REACH = 0.75


def rot_x(angle: float) -> np.ndarray:
    """Returns the rotation matrix about x by `angle` rad."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Returns the rotation matrix about y by `angle` rad."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Returns the rotation matrix about z by `angle` rad."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# the hand pointing down, fingers closing along the table's y axis: franky's pose at
# quaternion (1, 0, 0, 0) for a base aligned with the table
TOP_DOWN = rot_x(math.pi)


def hand_rotation(tilt_deg: float = 0.0) -> np.ndarray:
    """Returns the hand's rotation in the table frame, tilted about the fingers' closing axis.

    A positive tilt turns what the hand holds so that its top leans towards −x (the robot).
    """
    return rot_y(-math.radians(tilt_deg)) @ TOP_DOWN


def quaternion_xyzw(rot: np.ndarray) -> np.ndarray:
    """Returns the unit quaternion (x, y, z, w) of a rotation matrix."""
    m = np.asarray(rot, float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def parse_numbers(text: str, count: int, what: str) -> tuple[float, ...]:
    """Returns `count` comma-separated finite numbers from `text`.

    Raises:
        ValueError: another count, or not numbers (the message names `what`).
    """
    try:
        values = tuple(float(v) for v in str(text).split(","))
    except ValueError:
        raise ValueError(f"{what} must be {count} comma-separated numbers, got {text!r}") from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be {count} comma-separated finite numbers, got {text!r}")
    return values


@dataclass(frozen=True)
class Mount:
    """Where the robot base stands in the table frame.

    Attributes:
        x, y, z: the base origin in the table frame (m).
        yaw_deg: the base's turn about the vertical, degrees (0: its x axis along the table's).
    """

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw_deg: float = 0.0

    @classmethod
    def parse(cls, text: str) -> Mount:
        """Returns the mount of ``x,y,z,yaw_deg``.

        Raises:
            ValueError: not four finite numbers.
        """
        return cls(*parse_numbers(text, 4, "--base-in-table (x,y,z in m, yaw in degrees)"))

    @property
    def rotation(self) -> np.ndarray:
        """The base's rotation in the table frame."""
        return rot_z(math.radians(self.yaw_deg))

    @property
    def origin(self) -> np.ndarray:
        """The base origin in the table frame (m)."""
        return np.array([self.x, self.y, self.z])

    def to_base(self, point: Sequence[float]) -> np.ndarray:
        """Returns a table-frame point in the base frame."""
        return self.rotation.T @ (np.asarray(point, float) - self.origin)

    def to_table(self, point: Sequence[float]) -> np.ndarray:
        """Returns a base-frame point in the table frame."""
        return self.rotation @ np.asarray(point, float) + self.origin

    def rotation_to_base(self, rot: np.ndarray) -> np.ndarray:
        """Returns a table-frame orientation in the base frame."""
        return self.rotation.T @ rot


@dataclass(frozen=True)
class SafetyBox:
    """Where the TCP may be commanded to, in the table frame (m)."""

    x: tuple[float, float] = (0.25, 0.75)
    y: tuple[float, float] = (-0.30, 0.30)
    z: tuple[float, float] = (0.005, 0.55)

    @classmethod
    def parse(cls, text: str) -> SafetyBox:
        """Returns the box of ``x0,x1,y0,y1,z0,z1``.

        Raises:
            ValueError: not six finite numbers, or a range that is empty.
        """
        x0, x1, y0, y1, z0, z1 = parse_numbers(text, 6, "--box (x0,x1,y0,y1,z0,z1 in m)")
        if not (x0 < x1 and y0 < y1 and z0 < z1):
            raise ValueError(f"--box {text!r}: each range must go from low to high")
        return cls((x0, x1), (y0, y1), (z0, z1))

    def describe(self) -> str:
        """Returns the box as text."""
        return (f"x {self.x[0]:.3f}..{self.x[1]:.3f}, y {self.y[0]:.3f}..{self.y[1]:.3f}, "
                f"z {self.z[0]:.3f}..{self.z[1]:.3f} m")

    def refusal(self, point: Sequence[float], mount: Mount) -> str | None:
        """Returns why the TCP may not go to a table-frame point, or None."""
        p = np.asarray(point, float)
        where = f"[{p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}]"
        for axis, (low, high), v in zip("xyz", (self.x, self.y, self.z), p, strict=True):
            if not low <= v <= high:
                return (f"the TCP target {where} is outside the safety box ({axis} {v:.3f} not in "
                        f"{low:.3f}..{high:.3f}; box {self.describe()}, --box)")
        base = mount.to_base(p)
        axis_distance = math.hypot(base[0], base[1])
        if axis_distance < MIN_REACH:
            return (f"the TCP target {where} is {axis_distance:.3f} m from the robot's base axis; "
                    f"the arm reaches top-down no nearer than {MIN_REACH:.2f} m")
        shoulder = math.dist(base, (0.0, 0.0, SHOULDER_Z))
        if shoulder > MAX_REACH:
            return (f"the TCP target {where} is {shoulder:.3f} m from the robot's shoulder; the "
                    f"arm reaches no farther than {MAX_REACH:.2f} m top-down")
        return None

    def first_refusal(self, points: Iterable[Sequence[float]], mount: Mount) -> str | None:
        """Returns why the first refused point is refused, or None when all may be reached."""
        for point in points:
            reason = self.refusal(point, mount)
            if reason is not None:
                return reason
        return None
