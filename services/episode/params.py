"""Auxiliary metric parameters from the hand's geometry during an episode.

The paper extracts metric features from the hands to parametrise actions ("distances can easily
be demonstrated as the distance between the thumb and the index finger"). Per frame and hand
the episode keeps a small `HandSample` (computed once, when the frame arrives); at the end of
the episode these functions turn the samples into the summary's ``params``:

- ``distance`` (m): the thumb–index tip distance, median over the frames the static classifier
  labelled ``pinch`` (the gesture for showing a size); without pinch frames, over the frames
  labelled with any static gesture (a held pose); without static labels it is left out.
- ``angle_deg``: the palm roll of a ``rotate`` stroke (the most confident one, see
  `EpisodeBuilder._window_for`): over the frames of the rotate window, the
  roll (signed angle of the palm normal about the hand direction, relative to the window's
  first frame) of largest magnitude. Positive raises the thumb side, on either hand (a right
  hand rolling anticlockwise as its owner sees it from behind).
- ``move_distance`` (m): the length of a swipe stroke: the farthest the palm got from where the
  swipe window started.

Lengths come in Leap millimetres; the frames' ``to_base`` carries the scale to metres (its
rotation part is R/1000), which is used when present (else 1/1000, the contract's units).
Angles do not depend on the frame. Pure numpy, no Zenoh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cbgo.transform import leap_to_base

MM_TO_M = 1e-3


@dataclass
class HandSample:
    """What the episode keeps of one hand in one frame.

    Attributes:
        ts: the frame's time.
        seq: the frame's seq.
        side: ``left`` or ``right``.
        aperture_m: thumb tip to index tip distance, m.
        palm_m: palm position, m (base frame with to_base, else the Leap frame scaled to m).
        normal: palm normal (Leap frame, unit).
        direction: hand direction (Leap frame, unit).
        ray: (origin, direction) of the index finger in the base frame (m), or None without
            to_base.
    """

    ts: float
    seq: int
    side: str
    aperture_m: float
    palm_m: np.ndarray
    normal: np.ndarray
    direction: np.ndarray
    ray: tuple[np.ndarray, np.ndarray] | None


def scale_of(to_base: np.ndarray | None) -> float:
    """Returns the metres per Leap millimetre of a to_base transform (1/1000 without one)."""
    if to_base is None:
        return MM_TO_M
    return float(np.cbrt(abs(np.linalg.det(to_base[:3, :3]))))


def _tip(hand: dict, finger: int) -> np.ndarray:
    return np.asarray(hand["fingers"][finger]["bones"][3]["next_joint"], dtype=float)


def index_ray_leap(hand: dict) -> tuple[np.ndarray, np.ndarray]:
    """Returns the pointing ray (origin, direction) in the Leap frame: knuckle → index tip."""
    bones = hand["fingers"][1]["bones"]
    knuckle = np.asarray(bones[1]["prev_joint"], dtype=float)
    return knuckle, _tip(hand, 1) - knuckle


def hand_sample(ts: float, seq: int, hand: dict, to_base: np.ndarray | None) -> HandSample:
    """Returns the sample of one hand of one frame.

    Args:
        ts: the frame's time.
        seq: the frame's seq.
        hand: a contract hand (Leap frame, mm).
        to_base: the frame's Leap(mm)→base(m) transform, or None.
    """
    scale = scale_of(to_base)
    palm = np.asarray(hand["palm_position"], dtype=float)
    ray = None
    if to_base is not None:
        origin, direction = index_ray_leap(hand)
        ray = (leap_to_base(to_base, origin), to_base[:3, :3] @ direction / scale)
        palm_m = leap_to_base(to_base, palm)
    else:
        palm_m = palm * scale
    return HandSample(ts, seq, hand["side"], float(np.linalg.norm(_tip(hand, 0) - _tip(hand, 1)))
                      * scale, palm_m, _unit(hand["palm_normal"]), _unit(hand["direction"]), ray)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


def aperture(samples: list[HandSample]) -> float | None:
    """Returns the median thumb–index distance (m) of samples, or None if there are none."""
    return float(np.median([s.aperture_m for s in samples])) if samples else None


def roll_deg(samples: list[HandSample]) -> np.ndarray:
    """Returns each sample's palm roll relative to the first, degrees (thumb side up > 0)."""
    if not samples:
        return np.zeros(0)
    normals = np.array([s.normal for s in samples])
    axes = np.array([s.direction for s in samples])
    ref = normals[0]
    # Project the reference and each normal onto the plane across the current hand direction.
    a = ref[None, :] - np.sum(ref[None, :] * axes, axis=1, keepdims=True) * axes
    b = normals - np.sum(normals * axes, axis=1, keepdims=True) * axes
    signed = np.degrees(np.arctan2(np.sum(np.cross(a, b) * axes, axis=1), np.sum(a * b, axis=1)))
    # About the direction, a right hand's thumb side rises for a negative angle, a left's for
    # a positive one (mirror images).
    mirror = np.array([-1.0 if s.side == "right" else 1.0 for s in samples])
    return signed * mirror


def rotate_angle(samples: list[HandSample]) -> float | None:
    """Returns the roll of largest magnitude in a rotate window (degrees), or None."""
    if len(samples) < 2:
        return None
    rolls = roll_deg(samples)
    return float(rolls[int(np.argmax(np.abs(rolls)))])


def stroke_length(samples: list[HandSample]) -> float | None:
    """Returns how far (m) the palm got from its position at the first sample, or None."""
    if len(samples) < 2:
        return None
    palms = np.array([s.palm_m for s in samples])
    return float(np.max(np.linalg.norm(palms - palms[0], axis=1)))
