"""Device-independent static-gesture features, derived from the paper's 57.

Why: the 57 features (``cbgo.hands.features``) read parts of the skeleton that every tracker
lays out its own way — the wrist, the metacarpal bases, and the thumb's zero-length metacarpal
(older Leap SDKs give it an orientation, LeapC an identity basis, datasets like the multi-modal
Leap HGR set give no metacarpal at all). A classifier that leans on them learns one device. The
derived features (`derive`) keep only what every Leap-style tracker reports the same way:

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

The feature sets a model can read (`TRANSFORMS`, named in its metadata): ``invariant-1``
(`derive`, 45); ``invariant-2`` (`derive_palm`: the proximal bones against the palm's axis,
45); ``invariant-3`` (`continuous`: those with each yaw difference as its sine and cosine, 60);
``invariant-4``, the trainer's default (the proximal bones and distances of ``invariant-3`` with
the 19 angles between bones of `bends`, 49). docs/design/static_gesture.md says why.

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
TRANSFORM_PALM = "invariant-2"
"""The same features with every proximal bone against the palm's own axis (`derive_palm`)."""
TRANSFORM_CONTINUOUS = "invariant-3"
"""`derive_palm`'s features with every yaw difference as its sine and cosine (`continuous`)."""
TRANSFORM_BENDS = "invariant-4"
"""The proximal bones and distances of `continuous`, and each joint's bend and the fingers'
spread as angles in 3-D (`bends`) in place of the other bones' pitch and yaw differences."""
TRANSFORMS = (TRANSFORM, TRANSFORM_PALM, TRANSFORM_CONTINUOUS, TRANSFORM_BENDS)

_BONES = ("proximal_rel_hand", "intermediate", "distal")
NAMES: tuple[str, ...] = (
    tuple(f"{f}_{b}_{a}" for f in FINGER_TYPES for b in _BONES for a in ("dpitch", "dyaw"))
    + tuple(F.FEATURE_NAMES[i] for i in F.DISTANCE_FEATURES))
N_DERIVED = len(NAMES)
YAWS = np.array([k for k, name in enumerate(NAMES) if name.endswith("_dyaw")])
NAMES_CONTINUOUS: tuple[str, ...] = tuple(
    part for name in NAMES
    for part in ((f"{name}_sin", f"{name}_cos") if name.endswith("_dyaw") else (name,)))
BEND_NAMES: tuple[str, ...] = (
    tuple(f"{f}_{j}_bend" for f in FINGER_TYPES for j in ("proximal", "intermediate", "distal"))
    + ("spread_thumb_index", "spread_index_middle", "spread_middle_ring", "spread_ring_pinky"))
_KEPT = np.array([k for k in range(N_DERIVED) if k not in YAWS])
_BEND_KEPT = np.array([k for k, name in enumerate(NAMES_CONTINUOUS)
                       if "_proximal_" in name or name.startswith("dist_")])
_KEPT_TO = np.array([NAMES_CONTINUOUS.index(NAMES[k]) for k in _KEPT])
_SIN_TO = np.array([NAMES_CONTINUOUS.index(f"{NAMES[k]}_sin") for k in YAWS])
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


def palm_axis(x57: np.ndarray) -> np.ndarray:
    """Returns (N, 2) pitch and yaw differences of the hand direction against its palm axis.

    The palm axis is the mean of the index..pinky metacarpal features. Those bones point from
    the knuckles back to the wrist (the recording convention), so each metacarpal feature is
    about ``angles(d) − angles(−d)``: twice the hand's pitch, and ±π in yaw. Taking it away
    from a proximal feature leaves the finger's bend against the palm, whatever the hand's pitch.
    """
    x = np.atleast_2d(np.asarray(x57, dtype=np.float64))
    meta = x[:, 2:42].reshape(len(x), 5, 4, 2)[:, 1:, 0]
    yaw = np.angle(np.exp(1j * meta[..., 1]).mean(1))  # circular mean: the yaws sit at ±π
    return np.stack([meta[..., 0].mean(1), yaw], 1)


def derive_palm(x57: np.ndarray) -> np.ndarray:
    """Returns the 45 features of `derive` with the proximal bones against the palm axis.

    Why: in `derive` a proximal feature is about "twice the hand's pitch + the finger's bend",
    so it carries how the hand is held: the paper's recordings hold each gesture at its own
    pitch (grab ~45° up, thumbs-up ~7°), and a model learns the pitch with the pose. Measured
    against `palm_axis` instead, the ten proximal features are bends alone. Devices without
    metacarpals (the HGR set) stand one in along the hand direction (`mmhgr.features57`).
    """
    x = np.atleast_2d(np.asarray(x57, dtype=np.float64))
    out = derive(x)
    axis = palm_axis(x)
    for f in range(5):
        out[:, 6 * f:6 * f + 2] -= axis
        out[:, 6 * f + 1] = wrap(out[:, 6 * f + 1])
    return out[0] if np.ndim(x57) == 1 else out


def continuous(derived: np.ndarray) -> np.ndarray:
    """Returns (N, 45) derived rows with each yaw difference as its sine and cosine (N, 60).

    Why: a curled finger's bones point down and back, where the yaw of a direction flips by
    π with a little noise, so its yaw difference to the bone before lands near +π or near −π:
    the same curl as two values far apart (in the paper's recordings, 69 % of the grabs and
    58 % of the threes have one beyond ±2.5 rad; in the HGR set 71 % of the thumb-down poses).
    The sine and cosine are the same there. Pitch differences never wrap and stay as they are.
    """
    x = np.atleast_2d(np.asarray(derived, dtype=np.float64))
    out = np.empty((len(x), len(NAMES_CONTINUOUS)))
    out[:, _KEPT_TO] = x[:, _KEPT]
    out[:, _SIN_TO] = np.sin(x[:, YAWS])
    out[:, _SIN_TO + 1] = np.cos(x[:, YAWS])
    return out


def bends(x57: np.ndarray) -> np.ndarray:
    """Returns (N, 19) angles between bones in 3-D: each joint's bend and the fingers' spread.

    Why: the 57 are pitch and yaw differences in the sensor's frame, so the same bend reads
    otherwise when the whole hand turns (and a yaw means nothing for a bone pointing up); the
    angle between two bones is the same however the hand is held. The 57 hold every bone's
    pitch and yaw against the one before, and the metacarpals (tip to base, so about twice the
    hand's pitch) give the hand's own pitch: that fixes every bone's direction up to a turn
    about the vertical, which no angle between bones sees.

    Returns:
        per finger thumb..pinky, the proximal bone against the palm's axis (the mean of the
        index..pinky metacarpals), the intermediate against the proximal, the distal against
        the intermediate; then thumb–index, index–middle, middle–ring and ring–pinky proximals
        (rad, 0 = straight / together).
    """
    x = np.atleast_2d(np.asarray(x57, dtype=np.float64))
    steps = x[:, 2:42].reshape(len(x), 5, 4, 2)
    hand = np.stack([steps[:, 1:, 0, 0].mean(1) / 2.0, np.zeros(len(x))], -1)  # pitch, yaw
    angles = hand[:, None, None, :] - np.cumsum(steps, axis=2)  # (N, 5, 4, 2) per bone
    dirs = F.direction_of(np, angles[..., 0], angles[..., 1])  # tip to base (N, 5, 4, 3)
    axis = dirs[:, 1:, 0].sum(1)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)

    def between(a, b):
        return np.arccos(np.clip(np.sum(a * b, -1), -1.0, 1.0))

    # each finger's chain from the palm's axis: joint k bends bone k against the one before
    # (one call for all 15 joints: the service computes this for every hand of every frame)
    chain = np.concatenate([np.broadcast_to(axis[:, None, None], (len(x), 5, 1, 3)),
                            dirs[:, :, 1:]], 2)
    bent = between(chain[:, :, :-1], chain[:, :, 1:]).reshape(len(x), 15)
    spread = between(dirs[:, :-1, 1], dirs[:, 1:, 1])
    return np.concatenate([bent, spread], 1)



def thumb_elevation(x57: np.ndarray) -> np.ndarray:
    """Returns (N,) how far each hand's thumb distal bone points above level, degrees (< 0: down).

    Why: a thumbs-down is a thumbs-up rolled over; every angle between bones is the same, so
    only the thumb's direction against the vertical tells them apart. The 57 give each bone's
    pitch, which is that elevation, by the same chain from the hand's pitch as `bends`
    (through the thumb's metacarpal, which the paper's recordings got from an older device).
    The hand's pitch is read from the index..pinky metacarpals, so the figure is within a few
    degrees of the bone's own (Ultraleap's thumbs-ups: 3° at most).
    """
    x = np.atleast_2d(np.asarray(x57, dtype=np.float64))
    steps = x[:, 2:42].reshape(len(x), 5, 4, 2)
    hand_pitch = steps[:, 1:, 0, 0].mean(1) / 2.0
    return np.degrees(hand_pitch - steps[:, 0, :, 0].sum(1))


def finger_change(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Returns how far the fingers moved between two `bends` rows (..., 19) rad: degrees.

    The root mean square change of the 19 angles: one number per hand that reads the same
    however the hand is turned, and that a held pose keeps near 0.
    """
    return np.degrees(np.sqrt(((np.asarray(after) - np.asarray(before)) ** 2).mean(-1)))

def names_of(name: str) -> tuple[str, ...]:
    """Returns the feature names of a feature set named in `TRANSFORMS`."""
    if name == TRANSFORM_BENDS:
        return tuple(NAMES_CONTINUOUS[k] for k in _BEND_KEPT) + BEND_NAMES
    return NAMES_CONTINUOUS if name == TRANSFORM_CONTINUOUS else NAMES


def transform(x57: np.ndarray, name: str, bent: np.ndarray | None = None) -> np.ndarray:
    """Returns the derived features of a feature set named in `TRANSFORMS`.

    ``bent``: the rows' `bends` where the caller has them already (the service measures
    finger motion with them), so that they are not computed twice.
    """
    if name == TRANSFORM_CONTINUOUS:
        return continuous(derive_palm(x57))
    if name == TRANSFORM_BENDS:
        return np.concatenate([continuous(derive_palm(x57))[:, _BEND_KEPT],
                               bends(x57) if bent is None else bent], 1)
    return derive_palm(x57) if name == TRANSFORM_PALM else derive(x57)


def augment(x57: np.ndarray, rng: np.random.Generator, size: tuple[float, float] = (0.85, 1.15),
            angle_sd: float = 0.05, palm_sd_mm: float = 6.0, curl_deg: float = 0.0) -> np.ndarray:
    """Returns a copy of (N, 57) rows with device- and person-style variation.

    Args:
        x57: features on the recorded side.
        rng: the random generator.
        size: range of the hand-size factor applied to every distance of a row.
        angle_sd: std (rad) of independent noise on every bone angle (joint placement).
        palm_sd_mm: std of a per-row shift of the five fingertip-to-palm distances (where a
            device puts the palm centre).
        curl_deg: the index..pinky intermediate and distal bones of a row bent by one U(0,
            this) more (degrees): how far a device or a person lets open fingers curl (the
            paper's fives bend them 3 ± 1°, the HGR set's 9 ± 9°).

    Returns:
        float64 (N, 57).
    """
    x = np.array(x57, dtype=np.float64, copy=True)
    n = len(x)
    x[:, 2:42] += rng.normal(0.0, angle_sd, (n, 40))
    if curl_deg > 0.0:
        bones = x[:, 2:42].reshape(n, 5, 4, 2)  # a view: pitch differences of later bones
        bones[:, 1:, 2:, 0] += np.deg2rad(rng.uniform(0.0, curl_deg, (n, 1, 1)))
    x[:, F.DISTANCE_FEATURES] *= rng.uniform(*size, (n, 1))
    x[:, F.DISTANCE_FEATURES[_PALM_PAIRS]] += rng.normal(0.0, palm_sd_mm, (n, 1))
    x[:, F.DISTANCE_FEATURES] = np.maximum(x[:, F.DISTANCE_FEATURES], 0.0)
    return x
