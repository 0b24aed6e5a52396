"""Device-independent static-gesture features, derived from the paper's 57.

Why: the 57 features (``cbgo.hands.features``) read parts of the skeleton that every tracker
lays out its own way — the wrist, the metacarpal bases, and the thumb's zero-length metacarpal
(older Leap SDKs give it an orientation, LeapC an identity basis, datasets like the multi-modal
Leap HGR set give no metacarpal at all). A classifier that leans on them learns one device. The
derived features keep only what every Leap-style tracker reports the same way:

- per finger (thumb..pinky), the PROXIMAL bone relative to the hand direction: the metacarpal
  feature plus the proximal feature of the 57, which telescopes to
  ``angles(direction) − angles(proximal)`` whatever the metacarpal was. For the thumb this is
  the extension cue (thumb proximal against the palm) that survives across devices, where
  features 2..5 alone do not;
- per finger, the intermediate and distal bones relative to the preceding bone (unchanged);
- the 15 fingertip / palm distances (mm).

Every yaw difference is wrapped into (−π, π] first (the 57 keep ±2π jumps by definition), so a
hand pointing straight away from the user (yaw ≈ ±π) gives one value, not two. The wrist
features and the metacarpals of index..pinky are left out. 5·3·2 angles + 15 distances = 45.

`augment` adds the variation devices and people bring, on the 57 (so it works on rows that
only exist as features, like the paper's recordings): hand size (every distance scaled
together), joint placement (angle jitter per bone), and palm-centre placement (the palm
distances moved together).
"""

from __future__ import annotations

import numpy as np

from cbgo.hands import features as F
from cbgo.wire import FINGER_TYPES

TRANSFORM = "invariant-1"
"""The name a model's metadata gives this feature set (``"transform"``)."""

_BONES = ("proximal_rel_hand", "intermediate", "distal")
NAMES: tuple[str, ...] = (
    tuple(f"{f}_{b}_{a}" for f in FINGER_TYPES for b in _BONES for a in ("dpitch", "dyaw"))
    + tuple(F.FEATURE_NAMES[i] for i in F.DISTANCE_FEATURES))
N_DERIVED = len(NAMES)
THUMB_PROXIMAL = (0, 1)
"""Derived indices of the thumb proximal relative to the hand direction."""
DISTANCES = np.arange(30, 45)
_PALM_PAIRS = np.array([k for k, (i, j) in enumerate(F.PAIRS) if j == 5])


def wrap(a: np.ndarray) -> np.ndarray:
    """Returns angles wrapped into (−π, π]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def derive(x57: np.ndarray) -> np.ndarray:
    """Returns the 45 derived features of (N, 57) (or (57,)) rows.

    Args:
        x57: the paper's features, on the recorded side.

    Returns:
        float64 (N, 45) (or (45,)).
    """
    x = np.asarray(x57, dtype=np.float64)
    single = x.ndim == 1
    x = np.atleast_2d(x).copy()
    x[:, F.YAW_FEATURES] = wrap(x[:, F.YAW_FEATURES])
    bones = x[:, 2:42].reshape(len(x), 5, 4, 2)
    proximal = bones[:, :, 0] + bones[:, :, 1]
    proximal[..., 1] = wrap(proximal[..., 1])
    angles = np.stack([proximal, bones[:, :, 2], bones[:, :, 3]], 2).reshape(len(x), 30)
    out = np.concatenate([angles, x[:, F.DISTANCE_FEATURES]], 1)
    return out[0] if single else out


def augment(x57: np.ndarray, rng: np.random.Generator, size: tuple[float, float] = (0.85, 1.15),
            angle_sd: float = 0.05, palm_sd_mm: float = 6.0) -> np.ndarray:
    """Returns a copy of (N, 57) rows with device- and person-style variation.

    Args:
        x57: features on the recorded side.
        rng: the random generator.
        size: range of the hand-size factor applied to every distance of a row.
        angle_sd: std (rad) of independent noise on every bone angle (joint placement).
        palm_sd_mm: std of a per-row shift of the five fingertip-to-palm distances (where a
            device puts the palm centre).

    Returns:
        float64 (N, 57).
    """
    x = np.array(x57, dtype=np.float64, copy=True)
    n = len(x)
    x[:, 2:42] += rng.normal(0.0, angle_sd, (n, 40))
    x[:, F.DISTANCE_FEATURES] *= rng.uniform(*size, (n, 1))
    x[:, F.DISTANCE_FEATURES[_PALM_PAIRS]] += rng.normal(0.0, palm_sd_mm, (n, 1))
    x[:, F.DISTANCE_FEATURES] = np.maximum(x[:, F.DISTANCE_FEATURES], 0.0)
    return x
