"""The paper's 57 static-gesture features of one hand, as the real Leap recordings define them.

Rules (the definition is the one in ``cbgo/data/README.md``; the vendored recordings were made
with it, and a classifier trained on them only works on features computed exactly this way):

- For a direction ``d``: ``pitch = asin(-d_y)`` and ``yaw = atan2(d_x, d_z)`` (radians, Leap
  frame, +y up, +z towards the user).
- ``[0:2]`` wrist: angles of ``unit(palm_position - wrist_position)`` minus the angles of the
  hand's ``direction`` (Δpitch, Δyaw).
- ``[2:42]`` bones: for finger f (thumb..pinky) and bone b (metacarpal..distal), the angles of
  the previous direction minus the angles of this bone's direction, at index
  ``2 + 2·(4·f + b)`` (pitch) and ``+1`` (yaw). "Previous" is the hand ``direction`` for the
  metacarpal and the preceding bone otherwise. Yaw differences are NOT unwrapped: a jump of
  ±2π is part of the definition (the recordings have them).
- ``[42:57]`` distances (mm) between every pair of (thumb, index, middle, ring, pinky tips, palm
  centre) in ``itertools.combinations`` order; a tip is the distal bone's ``next_joint``.

Bone directions follow the RECORDING device's convention, which is the bone basis +z axis:
pointing from the bone's tip towards its base, i.e. ``unit(prev_joint - next_joint)`` (the
"next_joint − prev_joint" of the README that came with the data does not match the data, see
``cbgo/data/README.md``). The recordings leave no
doubt about it: in every recorded gesture the hand ``direction`` and ``unit(palm - wrist)``
agree to ~0.15 rad, while the index..pinky metacarpals differ from the hand direction by ~π in
yaw and by about twice the hand's pitch — what an anti-parallel vector gives, and what no real
hand produces with base-to-tip directions. Fitting the hand model to the recordings
(``cbgo train hands``) with base-to-tip directions leaves a residual ~25× larger than with
tip-to-base ones. A contract frame (docs/protocol.md: joints in anatomical order, ``direction``
towards the fingers) therefore has its bone directions reversed here, and only here, so that
one feature space holds for real devices, simulated hands and the recordings alike.

The thumb's metacarpal has zero length (Leap SDK), so its direction is taken from its
``rotation`` (the basis z axis, as for every other bone) when present; without a rotation it
falls back to the thumb proximal's direction. The recordings' own thumb-metacarpal values
(features 2..5, see ``UNTRUSTED_FEATURES``) came from an older device and should not be relied
on.

Sides: yaw is odd under the x mirror, so a hand's yaw differences are the negated ones of its
mirror image (pitch differences and distances are unchanged). The recordings are LEFT hands
(``RECORDED_SIDE``): fitted as right hands, four gestures come out palm up and the thumbs-up
points the thumb down, while as left hands the residual is 3.7× smaller and every pose is the
natural palm-down one. ``to_recorded_side=True`` maps a right hand into the recordings' space
by negating its yaw differences (``mirror_features``), so one classifier serves both hands.
"""

from __future__ import annotations

from itertools import combinations
from typing import Any

import numpy as np

from cbgo.wire import BONE_TYPES, FINGER_TYPES

FEATURE_VERSION = 1
N_FEATURES = 57

_TIP_NAMES = ("thumb", "index", "middle", "ring", "pinky", "palm")
PAIRS = tuple(combinations(range(6), 2))
"""Point index pairs of the distance features, in ``itertools.combinations`` order."""

FEATURE_NAMES: tuple[str, ...] = (
    ("wrist_dpitch", "wrist_dyaw")
    + tuple(f"{f}_{b}_{a}" for f in FINGER_TYPES for b in BONE_TYPES for a in ("dpitch", "dyaw"))
    + tuple(f"dist_{_TIP_NAMES[i]}_{_TIP_NAMES[j]}" for i, j in PAIRS)
)

ANGLE_FEATURES = np.arange(0, 42)
YAW_FEATURES = np.arange(1, 42, 2)
DISTANCE_FEATURES = np.arange(42, 57)
RECORDED_SIDE = "left"
"""The side of the hands in the real recordings (their yaw differences have its sign)."""
UNTRUSTED_FEATURES = (2, 3, 4, 5)
"""Thumb metacarpal (2, 3) and thumb proximal (4, 5, whose "previous" is that metacarpal)."""

_EPS_MM = 1e-6


def pitch_yaw(xp: Any, d: Any) -> tuple[Any, Any]:
    """Returns (pitch, yaw) of unit vectors ``d`` (..., 3) with numpy or torch as ``xp``."""
    # Rounding can push |d_y| a hair above 1; torch also needs to stay off ±1, where the
    # derivative of asin is infinite.
    limit = 1.0 if xp is np else 1.0 - 1e-7
    return xp.arcsin(xp.clip(-d[..., 1], -limit, limit)), xp.arctan2(d[..., 0], d[..., 2])


def direction_of(xp: Any, pitch: Any, yaw: Any) -> Any:
    """Returns the unit vectors (..., 3) whose `pitch_yaw` is (pitch, yaw)."""
    return xp.stack([xp.cos(pitch) * xp.sin(yaw), -xp.sin(pitch),
                     xp.cos(pitch) * xp.cos(yaw)], -1)


def unit(xp: Any, v: Any) -> Any:
    """Returns ``v`` (..., 3) divided by its norm (zero vectors stay zero)."""
    norm = xp.sqrt((v * v).sum(-1, keepdims=True))
    return v / xp.clip(norm, _EPS_MM, None)


def palm_basis(xp: Any, direction: Any, normal: Any) -> Any:
    """Returns (..., 3, 3) rows: hand direction, palm normal made orthogonal, their cross.

    The hand's own frame, for numpy arrays (``xp.cross``).
    """
    d = unit(xp, direction)
    n = unit(xp, normal - (normal * d).sum(-1, keepdims=True) * d)
    return xp.stack([d, n, xp.cross(d, n)], -2)


def hand_basis(hand: dict) -> np.ndarray:
    """Returns a `cbgo/hands/frame` hand's own frame (`palm_basis`): direction, normal, side."""
    return palm_basis(np, np.asarray(hand["direction"], dtype=np.float64),
                      np.asarray(hand["palm_normal"], dtype=np.float64))


def features_from_geometry(xp: Any, palm: Any, wrist: Any, direction: Any, bone_dirs: Any,
                           tips: Any) -> Any:
    """Computes the features from stacked geometry; shared by numpy and the torch calibration.

    Args:
        xp: the array module, ``numpy`` or ``torch``.
        palm: palm centres (..., 3), mm.
        wrist: wrist positions (..., 3), mm.
        direction: hand directions (..., 3), unit.
        bone_dirs: bone directions in the recording convention (tip to base), unit,
            (..., 5, 4, 3), fingers thumb..pinky, bones metacarpal..distal.
        tips: fingertip positions (..., 5, 3), mm.

    Returns:
        The features (..., 57).
    """
    hand_pitch, hand_yaw = pitch_yaw(xp, direction)
    wrist_pitch, wrist_yaw = pitch_yaw(xp, unit(xp, palm - wrist))
    bone_pitch, bone_yaw = pitch_yaw(xp, bone_dirs)
    prev_pitch = xp.concatenate(
        [xp.stack([hand_pitch] * 5, -1)[..., None], bone_pitch[..., :3]], -1)
    prev_yaw = xp.concatenate([xp.stack([hand_yaw] * 5, -1)[..., None], bone_yaw[..., :3]], -1)
    bones = xp.stack([prev_pitch - bone_pitch, prev_yaw - bone_yaw], -1)
    points = xp.concatenate([tips, palm[..., None, :]], -2)
    first = points[..., [i for i, _ in PAIRS], :]
    second = points[..., [j for _, j in PAIRS], :]
    dist = xp.sqrt(((first - second) ** 2).sum(-1))
    wrist_part = xp.stack([wrist_pitch - hand_pitch, wrist_yaw - hand_yaw], -1)
    flat_bones = bones.reshape(*bones.shape[:-3], 40)
    return xp.concatenate([wrist_part, flat_bones, dist], -1)


def quaternion_z_axis(q: np.ndarray) -> np.ndarray:
    """Returns the basis z axis (..., 3) of quaternions ``[qx, qy, qz, qw]`` (..., 4)."""
    q = q / np.clip(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12, None)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], -1)


def _stack(hands: list[dict]) -> dict[str, np.ndarray]:
    """Stacks contract hands into arrays: joints (N,5,4,2,3), rotations (N,5,4,4) + a mask."""
    joints = np.array([[[[b["prev_joint"], b["next_joint"]] for b in f["bones"]]
                        for f in h["fingers"]] for h in hands], dtype=np.float64)
    rotation = np.zeros(joints.shape[:3] + (4,))
    has_rotation = np.zeros(joints.shape[:3], dtype=bool)
    for n, h in enumerate(hands):
        for f, finger in enumerate(h["fingers"]):
            for b, bone in enumerate(finger["bones"]):
                if bone.get("rotation") is not None:
                    rotation[n, f, b], has_rotation[n, f, b] = bone["rotation"], True
    return {
        "joints": joints.reshape(len(hands), 5, 4, 2, 3), "rotation": rotation,
        "has_rotation": has_rotation,
        "palm": np.array([h["palm_position"] for h in hands], dtype=np.float64),
        "wrist": np.array([h["wrist_position"] for h in hands], dtype=np.float64),
        "direction": np.array([h["direction"] for h in hands], dtype=np.float64),
        "side": np.array([h["side"] for h in hands]),
    }


def _bone_directions(stacked: dict[str, np.ndarray]) -> np.ndarray:
    """Returns recording-convention bone directions (tip to base), with the zero-length rules."""
    prev, nxt = stacked["joints"][..., 0, :], stacked["joints"][..., 1, :]
    vec = prev - nxt
    length = np.linalg.norm(vec, axis=-1)
    dirs = vec / np.clip(length, _EPS_MM, None)[..., None]
    short = length < _EPS_MM
    from_rotation = short & stacked["has_rotation"]
    dirs[from_rotation] = unit(np, quaternion_z_axis(stacked["rotation"][from_rotation]))
    # A zero-length bone without orientation borrows the next bone's direction: for the thumb
    # metacarpal that is the proximal, the bone that actually carries the thumb's base.
    for b in (2, 1, 0):
        borrow = short[..., b] & ~stacked["has_rotation"][..., b]
        dirs[..., b, :][borrow] = dirs[..., b + 1, :][borrow]
    return dirs


def mirror_features(x: np.ndarray) -> np.ndarray:
    """Returns features (..., 57) of the mirror-image hands: the yaw differences negated."""
    out = np.array(x, dtype=np.float64, copy=True)
    out[..., YAW_FEATURES] *= -1.0
    return out


def hands_features(hands: list[dict], to_recorded_side: bool = False) -> np.ndarray:
    """Computes the 57 features of several contract hands at once.

    Args:
        hands: hand dicts as in a ``cbgo/hands/frame`` message.
        to_recorded_side: mirror the features of hands not on ``RECORDED_SIDE`` (negate their
            yaw differences), mapping every hand into the recordings' feature space.

    Returns:
        float64 array (N, 57); (0, 57) for an empty list.
    """
    if not hands:
        return np.zeros((0, N_FEATURES))
    stacked = _stack(hands)
    feats = features_from_geometry(
        np, stacked["palm"], stacked["wrist"], unit(np, stacked["direction"]),
        _bone_directions(stacked), stacked["joints"][:, :, 3, 1, :])
    if to_recorded_side:
        other = stacked["side"] != RECORDED_SIDE
        feats[other] = mirror_features(feats[other])
    return feats


def hand_features(hand: dict, to_recorded_side: bool = False) -> np.ndarray:
    """Computes the 57 features of one contract hand.

    Args:
        hand: a hand dict as in a ``cbgo/hands/frame`` message.
        to_recorded_side: mirror the features if the hand is not on ``RECORDED_SIDE``.

    Returns:
        float64 array (57,).
    """
    return hands_features([hand], to_recorded_side=to_recorded_side)[0]
