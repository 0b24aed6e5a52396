"""Palm trajectories of a simulated person: where the hand is, how it is turned, when it is seen.

A `TimelineBuilder` appends movement segments (enter, move, hold, roll, leave) sampled at the
frame rate; the result is a `Timeline` of per-frame arrays plus pose keyframes. The hand's
finger pose is opaque here (any object, blended by a function the caller gives), so this module
is pure numpy and knows nothing about the hand model.

Rules of the simulated motion, after how people gesture at a Leap Motion:
- point-to-point moves follow a minimum-jerk profile (bell-shaped speed), with an optional
  sideways bow (stroke curvature);
- physiological tremor (8–12 Hz) and slow drift are added to every visible frame;
- the sensor sees the hand only inside its field (`FIELD_BOX`); a hand entering or leaving
  appears or disappears at the field's border, as with a real sensor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# The sensor's usable field (mm, Leap frame): |x| and |z| bounds, y range.
FIELD_BOX = {"x": 240.0, "y": (60.0, 520.0), "z": 200.0}
CENTRE_MM = np.array([0.0, 230.0, 0.0])  # where strokes start: the centre of the field
ENTRY_MM = np.array([40.0, 190.0, 300.0])  # hands come in from the user's side (+z)
EXIT_MM = np.array([60.0, 320.0, 300.0])


def min_jerk(s: np.ndarray) -> np.ndarray:
    """Returns the minimum-jerk position profile for normalised time s in [0, 1]."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2)


def in_field(points: np.ndarray) -> np.ndarray:
    """Returns, per point (N,3 mm), whether the sensor can see a hand there."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    return (np.abs(x) <= FIELD_BOX["x"]) & (y >= FIELD_BOX["y"][0]) & (
        y <= FIELD_BOX["y"][1]) & (np.abs(z) <= FIELD_BOX["z"])


def tremor(n: int, rate_hz: float, rms_mm: float, rng: np.random.Generator) -> np.ndarray:
    """Returns (n,3) tremor: a few 8–12 Hz sinusoids per axis plus a slow drift."""
    t = np.arange(n) / rate_hz
    out = np.zeros((n, 3))
    for axis in range(3):
        for _ in range(3):
            freq = rng.uniform(8.0, 12.0)
            out[:, axis] += np.sin(2 * np.pi * freq * t + rng.uniform(0, 2 * np.pi))
        out[:, axis] *= rms_mm * np.sqrt(2.0 / 3.0)
        out[:, axis] += 2.0 * rms_mm * np.sin(2 * np.pi * rng.uniform(0.2, 0.6) * t
                                              + rng.uniform(0, 2 * np.pi))
    return out


@dataclass
class Timeline:
    """Per-frame samples of one episode.

    Attributes:
        rate_hz: frame rate.
        palm: (N,3) palm centre, mm, Leap frame (tremor included).
        roll: (N,) extra palm roll, radians (rotate strokes).
        visible: (N,) whether the sensor sees the hand.
        label: per frame, the gesture being performed (None between gestures).
        phase: per frame: 'hidden', 'enter', 'prepare', 'pose', 'stroke', 'return', 'leave'.
        keyframes: (frame index, pose) pairs; the pose between two keyframes is blended.
    """

    rate_hz: float
    palm: np.ndarray
    roll: np.ndarray
    visible: np.ndarray
    label: list[str | None]
    phase: list[str]
    keyframes: list[tuple[int, Any]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.palm)

    def velocity(self) -> np.ndarray:
        """Returns (N,3) palm velocity in mm/s (central differences)."""
        if len(self.palm) < 2:
            return np.zeros_like(self.palm)
        return np.gradient(self.palm, 1.0 / self.rate_hz, axis=0)

    def next_pose(self, index: int) -> Any:
        """Returns the pose of the first keyframe after `index` (the last one if none)."""
        after = [p for i, p in self.keyframes if i > index]
        return after[0] if after else self.keyframes[-1][1]

    def pose_at(self, index: int, blend: Callable[[Any, Any, float], Any]) -> Any:
        """Returns the finger pose at a frame, blending the surrounding keyframes."""
        before = [k for k in self.keyframes if k[0] <= index]
        after = [k for k in self.keyframes if k[0] > index]
        if not before:
            return self.keyframes[0][1]
        (i0, p0) = before[-1]
        if not after:
            return p0
        (i1, p1) = after[0]
        return blend(p0, p1, (index - i0) / (i1 - i0))


class TimelineBuilder:
    """Appends segments to an episode timeline at a fixed frame rate.

    Args:
        rate_hz: frame rate.
        start: palm position (mm) before the first segment.
        pose: the finger pose at the start.
    """

    def __init__(self, rate_hz: float, start: np.ndarray, pose: Any):
        self.rate_hz = rate_hz
        self.position = np.asarray(start, dtype=float)
        self.roll_angle = 0.0
        self._palm: list[np.ndarray] = []
        self._roll: list[float] = []
        self._label: list[str | None] = []
        self._phase: list[str] = []
        self._force_hidden: list[bool] = []
        self.keyframes: list[tuple[int, Any]] = [(0, pose)]

    def _frames(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.rate_hz)))

    def _append(self, palm: np.ndarray, roll: np.ndarray, label, phase, hidden=False):
        self._palm.extend(palm)
        self._roll.extend(roll)
        self._label.extend([label] * len(palm))
        self._phase.extend([phase] * len(palm))
        self._force_hidden.extend([hidden] * len(palm))
        self.position = palm[-1].copy()
        self.roll_angle = float(roll[-1])

    def hidden(self, seconds: float) -> None:
        """No hand in view for `seconds` (it stays where it is, unseen)."""
        n = self._frames(seconds)
        self._append(np.repeat(self.position[None], n, 0), np.full(n, self.roll_angle),
                     None, "hidden", hidden=True)

    def move_to(self, target, seconds: float, phase: str, label: str | None = None,
                bow: np.ndarray | None = None, roll_to: float | None = None) -> None:
        """Minimum-jerk move to target (mm), optionally bowed sideways by `bow` (mm).

        With `roll_to` (rad) the palm rolls to that angle on the way, on the same profile.
        """
        n = self._frames(seconds)
        s = min_jerk(np.arange(1, n + 1) / n)[:, None]
        start, target = self.position.copy(), np.asarray(target, dtype=float)
        path = start + s * (target - start)
        if bow is not None:
            path += np.sin(np.pi * s) * np.asarray(bow, dtype=float)
        end_roll = self.roll_angle if roll_to is None else roll_to
        self._append(path, self.roll_angle + s[:, 0] * (end_roll - self.roll_angle), label,
                     phase)

    def hold(self, seconds: float, phase: str, label: str | None = None) -> None:
        """Stays put (tremor is added later)."""
        n = self._frames(seconds)
        self._append(np.repeat(self.position[None], n, 0), np.full(n, self.roll_angle), label,
                     phase)

    def roll_to(self, angle_rad: float, seconds: float, phase: str, label: str | None = None,
                drift=None) -> None:
        """Minimum-jerk palm roll to an absolute angle, in place or drifting by `drift` (mm)."""
        n = self._frames(seconds)
        s = min_jerk(np.arange(1, n + 1) / n)
        rolls = self.roll_angle + s * (angle_rad - self.roll_angle)
        way = np.zeros(3) if drift is None else np.asarray(drift, dtype=float)
        self._append(self.position[None] + s[:, None] * way[None], rolls, label, phase)

    def key_pose(self, pose: Any) -> None:
        """Sets the finger pose reached at the current frame."""
        self.keyframes.append((len(self._palm), pose))

    @property
    def frames(self) -> int:
        """Number of frames so far."""
        return len(self._palm)

    def hide_frames(self, start: int, count: int) -> None:
        """Makes frames [start, start+count) invisible (a tracking dropout)."""
        for i in range(start, min(start + count, len(self._force_hidden))):
            self._force_hidden[i] = True

    def build(self, tremor_mm: float, rng: np.random.Generator) -> Timeline:
        """Returns the timeline, tremor added, visibility from the field and dropouts."""
        palm = np.asarray(self._palm) + tremor(len(self._palm), self.rate_hz, tremor_mm, rng)
        visible = in_field(palm) & ~np.asarray(self._force_hidden)
        keyframes = sorted(self.keyframes, key=lambda k: k[0])
        return Timeline(self.rate_hz, palm, np.asarray(self._roll), visible, self._label,
                        self._phase, keyframes)
