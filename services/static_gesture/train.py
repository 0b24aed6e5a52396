"""Train the static-gesture ensemble of Bayesian MLPs and write it where the service loads it.

Training data (every row is the paper's 57 features, right hands mirrored into the recordings'
left-hand space):

- the real Leap recordings vendored with cbgo (``cbgo.hands.data``, 4477 frames of the 8
  static gestures) — the evaluation split in ``../shared/eval/`` is never read here;
- simulated hands from the calibrated hand model: ``--per-gesture`` renditions of each gesture,
  each by a NEW simulated person (``HandShape.sample``: size 0.85–1.15, bone lengths ±4 %,
  knuckles ±1.5 mm; left or right hand at random), the gesture's calibrated pose spread scaled by
  0.7–1.3, the palm turned by N(0, 10°) in roll, pitch and yaw and placed anywhere in the middle
  of the sensor's field;
- the no-gesture class ``none`` (``--none`` poses; 0 leaves it out): the relaxed hand
  (``neutral_pose``) with every joint jittered by a 10° correlated spread, 60 % of them blended
  towards a random gesture by 0–40 % — what a hand looks like between gestures and while it
  forms one. It lets the episode service tell "no gesture" from "five";
- simulated poses OUTSIDE the vocabulary, also ``none`` (``--off-vocabulary``): the finger
  patterns no gesture uses (`OFF_VOCABULARY`, `THUMB_OUT_ONLY`) and half-open hands
  (`simulate_off_vocabulary`), so that "not one of mine" is learnt beyond relaxed hands;
- the multi-modal Leap HGR set when its cache exists (`mmhgr`; ``--no-mmhgr`` leaves it out;
  25 other people on another Leap): its gestures under cbgo's names (``mmhgr.POSE_MAP``) and
  its unknown poses (ok, C, L, hang, heavy, thumb down) as ``none``, every ``--mmhgr-stride``-th
  frame, each turned by N(0, 20°) about its palm (``--rotate-deg``; 20° rather than 10°: chosen
  on the person-grouped cross-validation, never on ``../shared/eval``); ``--rotate-shape-deg``
  turns the poses told by shape alone wider (a model for hands held at many angles, at a
  cost on hands held as usual: docs/design/static_gesture.md);
- the user's own gestures recorded by demonstration (``cbgo gestures record NAME --static``),
  stored in ``data_dir()/gestures/static/NAME.npz``: a new name becomes a new class (after the 8
  and before ``none``), a known name adds examples to that class. Few frames of one take are
  augmented to ``USER_MIN_ROWS`` rows by jittering them (half their own spread, at least 0.03 rad
  and 1.5 mm), so that a new class is not a handful of points. A new gesture whose fingers
  are extended and curled as no gesture of the 8's are (horns) takes the ``none`` rows of that
  pattern out of ``none`` (`without_claimed_none`).

The recorded rows (the paper's and the HGR set's) also come once more with device- and
person-style variation (``invariant.augment``: hand size 0.85–1.15, 0.05 rad per bone angle,
palm-centre placement ±6 mm; ``--curl-deg`` also bends their open fingers by up to that many
degrees, 0 by default). Classes are weighted to equal total weight in the likelihood.

Inputs (``--features``), standardised with the training mean/std: by default ``invariant-4``,
the proximal bones and distances of ``invariant-3`` with the other bones read as angles in 3-D
(``invariant.bends``: the same however the hand is held; 49 inputs). ``invariant-3``: the 45
device-independent features derived from the 57 with every proximal bone against the palm's
axis (``invariant.derive_palm``: no thumb-metacarpal convention and no wrist is read, and the
hand's pitch drops out, which the paper's recordings tie to the gesture) with each of their 15
yaw differences as its sine and cosine (``invariant.continuous``: 60 inputs). ``invariant-2``
keeps the yaw differences wrapped into (−π, π], where a curled finger's lands near either end;
``invariant-1`` measures the proximal bones against the hand direction; ``raw`` is the 57 minus
the thumb-metacarpal ones (2..5, ``UNTRUSTED_FEATURES``). docs/design/static_gesture.md says
why the default. The model is an ensemble of ``--members`` networks (3 by default), each
trained from its own seed on its own draw of the simulated hands, augmentations and HGR frames
(`build_datasets`). Each network is the paper's shape, one tanh hidden layer (``--hidden``, 32
by default), with biases, Normal(0, 1) priors on every weight, trained by maximising the ELBO
(``cbgo.bayes``: closed-form KL, local reparameterisation, Adam; batches of 256 at lr 0.01). 60
epochs: on a fold of five held-out people of the HGR set they scored within a few tenths of a
percent of 150 epochs in 40 % of the time, which is what makes the person-grouped cross-validation
of ``cbgo bench static`` affordable. Model choices are made on TRAINING data only (``--validate``:
a grouped fifth of the paper's recordings and unseen simulated people; the cross-validation on
held-out people) — never on ``../shared/eval``.

With a ``none`` class, the model also carries its open-set rule (`openset`: references and
calibration distances of its own training gesture rows in the hidden layer), which the
classifier applies to every prediction: a frame far from every training gesture fades into
``none``.

The model is written atomically (temporary files, then renamed: weights first, metadata last)
with the weights' SHA-256 in the metadata, so a running service that polls the files never
loads half a model.

Examples::

    cbgo train static                       # → data_dir()/models/static-gesture.{pt,json}
    cbgo train static --validate            # also print held-out figures first
    cbgo train static --shipped             # regenerate the default model shipped in the repo
    cbgo train static --no-none --out /tmp/m
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch

import cbgo
from cbgo import bayes
from cbgo.config import data_dir
from cbgo.errors import ConfigError
from cbgo.hands import features as F
from cbgo.hands.data import load_real_features, real_features_sha256
from cbgo.hands.model import HandPose, HandShape, blend, build_hands, clip_to_limits, neutral_pose
from cbgo.hands.poses import correlated_normal, gesture_pose
from cbgo.metrics import expected_calibration_error
from cbgo.services.static_gesture import invariant, mmhgr, openset
from cbgo.services.static_gesture.classifier import (
    KIND,
    NONE,
    Posterior,
    StaticClassifier,
    model_id_of,
    shipped_model_path,
    user_model_path,
    weights_sha256,
)

INPUTS = tuple(j for j in range(F.N_FEATURES) if j not in F.UNTRUSTED_FEATURES)
"""Inputs of a model on the raw 57 features (``features="raw"``)."""
SOURCES = ("real", "simulated", "none", "user", "mmhgr", "mmhgr_none")
USER_MIN_ROWS = 300
NONE_BLEND_MAX = 0.25  # how far a no-gesture hand may be into forming a gesture
_DEG = np.pi / 180.0
# Seed streams: training and validation never draw the same simulated people; the benchmark
# uses its own stream too (``SIM_STREAM_BENCH``); the open set's choice of reference rows another.
SIM_STREAM_TRAIN, SIM_STREAM_VALIDATE, SIM_STREAM_BENCH, SIM_STREAM_OPEN_SET = 1, 2, 3, 4


@dataclass
class TrainOptions:
    """What to train on and how (the defaults are what ships)."""

    per_gesture: int = 400
    none: int = 800
    hidden: list[int] = field(default_factory=lambda: [32])
    epochs: int = 60
    batch_size: int = 256
    lr: float = 0.01
    prior_sigma: float = 1.0
    kl_scale: float = 1.0
    none_weight: float = 1.0
    seed: int = 0
    user_gestures: bool = True
    off_vocabulary: int = 1200
    features: str = invariant.TRANSFORM_BENDS
    mmhgr: bool = True
    mmhgr_stride: int = 6
    augment_copies: int = 1
    rotate_deg: float = 20.0
    rotate_shape_deg: float | None = None
    curl_deg: float = 0.0
    spliced_none: int = 0
    none_turned: int = 0
    members: int = 3
    ok_sign: str = "pinch"

    def __post_init__(self):
        if self.members < 1 or self.epochs < 1:
            raise ValueError(f"members and epochs must be at least 1, got {self.members} and "
                             f"{self.epochs}")
        if self.features not in ("raw", *invariant.TRANSFORMS):
            raise ValueError(f"features must be one of raw, {', '.join(invariant.TRANSFORMS)}; "
                             f"got {self.features!r}")
        mmhgr.pose_map(self.ok_sign)  # raises for an unknown choice


# --------------------------------------------------------------------------- simulated data


def _rng(stream: int, seed: int) -> np.random.Generator:
    return np.random.default_rng([stream, seed])


def _shapes(rng: np.random.Generator, n: int) -> list[HandShape]:
    return [HandShape.sample(rng, side=("left", "right")[int(rng.integers(2))])
            for _ in range(n)]


def _features(rng: np.random.Generator, shapes: list[HandShape], poses: list[HandPose]
              ) -> np.ndarray:
    palms = rng.uniform([-80.0, 150.0, -60.0], [80.0, 300.0, 60.0], size=(len(poses), 3))
    return F.hands_features(build_hands(shapes, poses, palms), to_recorded_side=True)


def _turned(pose: HandPose, rng: np.random.Generator, deg: float | None = 10.0) -> HandPose:
    """Turns the palm by N(0, deg) in roll, pitch and yaw; any way at all when deg is None."""
    if deg is None:
        roll, yaw = rng.uniform(-np.pi, np.pi, 2)
        pitch = np.arcsin(rng.uniform(-1.0, 1.0))  # the fingers' direction uniform on a sphere
        return pose.rotated(roll=roll, pitch=pitch, yaw=yaw)
    roll, pitch, yaw = rng.normal(0.0, deg * _DEG, 3)
    return pose.rotated(roll=roll, pitch=pitch, yaw=yaw)


def simulate_gestures(names: list[str], per_gesture: int, rng: np.random.Generator
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Simulated renditions of static gestures, a new person each.

    Args:
        names: gestures known to the hand model (``STATIC_GESTURES``), label order.
        per_gesture: renditions per gesture.
        rng: the random generator.

    Returns:
        ``(x, y)``: features (N, 57) on the recorded side and labels into ``names``.
    """
    poses, labels = [], []
    for g, name in enumerate(names):
        for _ in range(per_gesture):
            poses.append(_turned(gesture_pose(name, rng, float(rng.uniform(0.7, 1.3))), rng))
            labels.append(g)
    if not poses:
        return np.zeros((0, F.N_FEATURES)), np.zeros(0, dtype=np.int64)
    return _features(rng, _shapes(rng, len(poses)), poses), np.asarray(labels, dtype=np.int64)


def simulate_none(count: int, gestures: list[str], rng: np.random.Generator,
                  turn_deg: float | None = 10.0) -> np.ndarray:
    """Simulated no-gesture poses: relaxed hands, and hands part-way into a gesture.

    Args:
        count: how many.
        gestures: the gestures a hand may be forming (blended by 0–40 %).
        rng: the random generator.
        turn_deg: the palm's turn (`_turned`; None: any way).

    Returns:
        Features (count, 57) on the recorded side.
    """
    if count <= 0:
        return np.zeros((0, F.N_FEATURES))
    relaxed = neutral_pose().to_vector()
    jitter = np.r_[np.full(21, 10.0 * _DEG), np.zeros(3)]
    poses = []
    for _ in range(count):
        pose = HandPose.from_vector(relaxed + correlated_normal(rng) * jitter)
        if rng.random() < 0.6:
            target = gesture_pose(gestures[int(rng.integers(len(gestures)))], rng)
            pose = blend(pose, target, float(rng.uniform(0.0, NONE_BLEND_MAX)))
        poses.append(_turned(pose, rng, turn_deg))
    return _features(rng, _shapes(rng, count), poses)


# Finger patterns (index, middle, ring, pinky extended = 1) of the vocabulary, whatever the
# thumb does: grab/thumbsup 0000, point 1000, two 1100, three 1110 (either way of counting),
# four/five 1111, pinch 0111 (thumb on index, the others open). Every other pattern is a pose
# outside the vocabulary.
VOCABULARY_PATTERNS = ((0, 0, 0, 0), (1, 0, 0, 0), (1, 1, 0, 0), (1, 1, 1, 0), (1, 1, 1, 1),
                       (0, 1, 1, 1))
OFF_VOCABULARY = tuple(p for p in np.ndindex(2, 2, 2, 2) if p not in VOCABULARY_PATTERNS)
THUMB_OUT_ONLY = ((1, 0, 0, 0),)
"""Patterns outside the vocabulary only with the thumb out: the index alone with the thumb
spread wide is an L, not ``point`` (whose thumb is tucked)."""
SPLICE_PATTERNS = np.array([(thumb, *p) for p in OFF_VOCABULARY for thumb in (0, 1)], dtype=bool)
"""The HGR hands spliced from a person's fist and open hand (`mmhgr.splice_fingers`): the
finger patterns no gesture uses, thumb in or out."""


def simulate_off_vocabulary(count: int, rng: np.random.Generator,
                            turn_deg: float | None = 10.0) -> np.ndarray:
    """Simulated poses outside the vocabulary: the finger patterns no gesture uses.

    Each pose takes one of `OFF_VOCABULARY`'s patterns (thumb out or in at random) or of
    `THUMB_OUT_ONLY`'s (thumb out): an extended
    finger has ``five``'s angles, a curled one ``grab``'s, each moved 0–20 % towards the other;
    every third pose is instead the half-open hand (all four fingers 35–65 % curled, ±8 %);
    then every joint jittered by an 8° correlated spread, the palm held like a random gesture
    of the vocabulary and turned by N(0, 10°). They teach the ``none`` class what "not one of
    mine" looks like beyond relaxed hands, without using any real unknown pose.

    Args:
        count: how many.
        rng: the random generator.
        turn_deg: the palm's turn (`_turned`; None: any way).

    Returns:
        Features (count, 57) on the recorded side.
    """
    if count <= 0:
        return np.zeros((0, F.N_FEATURES))
    from cbgo.hands.poses import STATIC_GESTURES, gesture_mean  # noqa: PLC0415

    open_, curled = gesture_mean("five").to_vector(), gesture_mean("grab").to_vector()
    jitter = np.r_[np.full(21, 8.0 * _DEG), np.zeros(3)]
    poses = []
    patterns = OFF_VOCABULARY + THUMB_OUT_ONLY
    for n in range(count):
        pattern = patterns[int(rng.integers(len(patterns)))]
        thumb_bent = int(rng.integers(2)) == 0 and pattern not in THUMB_OUT_ONLY
        # curl per finger (0 open .. 1 curled): thumb, index, middle, ring, pinky
        curl = [float(rng.uniform(0.8, 1.0) if bent else rng.uniform(0.0, 0.2))
                for bent in [thumb_bent, *[not e for e in pattern]]]
        if n % 3 == 2:  # the half-open hand: every finger half curled, the thumb anywhere
            middle = float(rng.uniform(0.35, 0.65))
            curl[1:] = list(np.clip(middle + rng.normal(0.0, 0.08, 4), 0.25, 0.75))
        v = open_.copy()
        for f, t in enumerate(curl):
            block = slice(0, 5) if f == 0 else slice(5 + 4 * (f - 1), 9 + 4 * (f - 1))
            v[block] = (1 - t) * open_[block] + t * curled[block]
        held = gesture_mean(STATIC_GESTURES[int(rng.integers(len(STATIC_GESTURES)))])
        v[21:] = held.to_vector()[21:]
        pose = HandPose.from_vector(clip_to_limits(v + correlated_normal(rng) * jitter))
        poses.append(_turned(pose, rng, turn_deg))
    return _features(rng, _shapes(rng, count), poses)


CURLED_BEND = np.radians(90.0)  # a finger whose three joints bend more than this is curled


def finger_patterns(x57: np.ndarray) -> np.ndarray:
    """Returns (N, 4) whether index..pinky are extended (1), as `VOCABULARY_PATTERNS` reads."""
    bends = invariant.bends(x57)[:, :15].reshape(-1, 5, 3)
    return (bends[:, 1:].sum(-1) <= CURLED_BEND).astype(np.int64)


def without_claimed_none(data: Dataset, user: list[UserGesture], new: list[str]) -> Dataset:
    """Returns the data without the ``none`` rows whose finger pattern a new gesture claims.

    A recorded gesture of a new name whose pattern (`finger_patterns`, most of its rows) is
    none of the vocabulary's claims it: the simulated off-vocabulary hands and the HGR set's
    unknown poses of that pattern (its "heavy" is horns) would otherwise teach the same hand
    as no gesture, and renditions of the taught gesture other than the recorded ones would be
    read as ``none`` (`tests/integration/test_static_gesture.py` teaches horns and checks
    fresh renditions live).
    """
    if NONE not in data.names:
        return data
    claimed = set()
    for g in user:
        if g.name in new:
            patterns, counts = np.unique(finger_patterns(g.x), axis=0, return_counts=True)
            pattern = tuple(int(v) for v in patterns[counts.argmax()])
            if pattern not in VOCABULARY_PATTERNS:
                claimed.add(pattern)
    if not claimed:
        return data
    none = data.y == data.names.index(NONE)
    keep = ~(none & np.isin(_pattern_codes(finger_patterns(data.x)),
                            _pattern_codes(np.array(sorted(claimed)))))
    return replace(data, x=data.x[keep], y=data.y[keep], source=data.source[keep])


def _pattern_codes(patterns: np.ndarray) -> np.ndarray:
    return patterns @ np.array([8, 4, 2, 1])


# --------------------------------------------------------------------------- user gestures


def gestures_dir(env=None) -> Path:
    """Returns where recorded static gestures live: ``data_dir()/gestures/static``."""
    return data_dir(env) / "gestures" / "static"


@dataclass
class UserGesture:
    """One recorded gesture: its name, feature rows and who recorded it when."""

    name: str
    x: np.ndarray
    takes: list[dict]
    path: Path | None = None


def store_gesture(name: str, x: np.ndarray, take: dict, directory: Path | None = None,
                  replace: bool = False) -> Path:
    """Adds a take to ``<directory>/<name>.npz`` (written atomically).

    Args:
        name: the gesture name.
        x: features (N, 57) on the recorded side.
        take: attribution of the take: user, ts, time, count, device.
        directory: defaults to `gestures_dir`.
        replace: drop earlier takes of this name instead of adding to them.

    Returns:
        The file written.
    """
    directory = gestures_dir() if directory is None else Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.npz"
    rows, takes = np.asarray(x, dtype=np.float64), [take]
    if path.is_file() and not replace:
        old = read_gesture(path)
        rows, takes = np.concatenate([old.x, rows]), old.takes + takes
    meta = {"name": name, "feature_version": F.FEATURE_VERSION, "count": len(rows),
            "takes": takes}
    tmp = directory / f"tmp-{os.getpid()}-{name}.npz"
    np.savez(tmp, X=rows, meta=np.array(json.dumps(meta)))
    os.replace(tmp, path)
    return path


def read_gesture(path: Path) -> UserGesture:
    """Reads one recorded gesture file.

    Raises:
        ValueError: not a gesture file of this feature version.
    """
    with np.load(path, allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        x = data["X"].astype(np.float64)
    if meta.get("feature_version") != F.FEATURE_VERSION or x.ndim != 2 or x.shape[1] != 57:
        raise ValueError(f"{path}: feature version {meta.get('feature_version')} / shape "
                         f"{x.shape}; record it again")
    return UserGesture(meta["name"], x, meta.get("takes", []), path)


def load_user_gestures(directory: Path | None = None, user: str | None = None
                       ) -> list[UserGesture]:
    """Returns every readable recorded gesture, by name (unreadable files are reported).

    With ``user``, only that person's takes (a gesture none of whose takes are theirs is left
    out): what a personal model is trained on. Without, every take but the personal ones
    (recorded with ``--personal``: that person's model only).
    """
    directory = gestures_dir() if directory is None else Path(directory)
    out = []
    for path in sorted(directory.glob("*.npz")) if directory.is_dir() else []:
        if path.name.startswith("tmp-"):
            continue
        try:
            gesture = read_gesture(path)
        except (ValueError, KeyError, OSError) as e:
            print(f"skipping recorded gesture {path}: {e}")
            continue
        gesture = takes_of(gesture, (lambda t: t.get("user") == user) if user is not None
                           else (lambda t: not t.get("personal", False)))
        if gesture is not None:
            out.append(gesture)
    return out


def takes_of(gesture: UserGesture, keep: Callable[[dict], bool]) -> UserGesture | None:
    """Returns the gesture with only the takes ``keep`` accepts (their rows), None if none.

    The rows are the takes' rows in order, each take's ``count`` of them; a file whose takes do
    not account for its rows (recorded before takes were counted) is kept whole.
    """
    ends = np.cumsum([int(t.get("count", 0)) for t in gesture.takes])
    if not len(ends) or ends[-1] != len(gesture.x):
        return gesture if all(keep(t) for t in gesture.takes) else None
    kept = [(t, slice(int(end) - int(t.get("count", 0)), int(end)))
            for t, end in zip(gesture.takes, ends, strict=True) if keep(t)]
    if not kept:
        return None
    if len(kept) == len(gesture.takes):
        return gesture
    return UserGesture(gesture.name, np.concatenate([gesture.x[rows] for _, rows in kept]),
                       [t for t, _ in kept], gesture.path)


def augment(x: np.ndarray, rows: int, rng: np.random.Generator) -> np.ndarray:
    """Returns ``x`` plus jittered copies up to ``rows`` rows (see the module docstring)."""
    if len(x) >= rows:
        return x
    floor = np.where(np.arange(F.N_FEATURES) < 42, 0.03, 1.5)
    scale = np.maximum(0.5 * x.std(0), floor)
    extra = x[rng.integers(len(x), size=rows - len(x))]
    return np.concatenate([x, extra + rng.normal(0.0, 1.0, extra.shape) * scale])


# --------------------------------------------------------------------------- data set


@dataclass
class Dataset:
    """Training rows with their labels and where each came from."""

    x: np.ndarray
    y: np.ndarray
    names: list[str]
    source: np.ndarray  # "real", "simulated", "none", "user"
    user_gestures: list[dict] = field(default_factory=list)

    def summary(self) -> dict:
        """Rows per class and per source."""
        per_source = {s: int((self.source == s).sum()) for s in SOURCES}
        return {"rows": len(self.y),
                "per_class": {n: int((self.y == i).sum()) for i, n in enumerate(self.names)},
                "per_source": {s: c for s, c in per_source.items()
                               if c or s in ("real", "simulated", "none", "user")}}


def mmhgr_rows(frames: mmhgr.Frames, names: list[str], options: TrainOptions,
               rng: np.random.Generator, unknown: tuple[str, ...] = mmhgr.UNKNOWN_POSES
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of the multi-modal Leap HGR set: its gestures, and unknown poses as ``none``.

    Every ``mmhgr_stride``-th frame of a pose is kept (neighbouring frames are near-identical),
    turned by N(0, ``rotate_deg``) in roll, pitch and yaw about its palm (a hand held at
    another angle, a sensor mounted another way); with ``rotate_shape_deg``, the poses told by
    their shape alone (all but `mmhgr.ORIENTED_POSES`) by N(0, ``rotate_shape_deg``) instead:
    wider turns teach the model those poses at more orientations, while the thumb poses keep
    the orientation that tells them apart.

    Args:
        frames: the converted frames (`mmhgr.load`), only of the people to train on.
        names: the model's classes (``none`` among them for the unknown poses to count).
        options: stride, rotation and seed.
        rng: the random generator.
        unknown: the dataset poses to train as ``none`` (the ok signs too when
            ``options.ok_sign`` is ``"none"``).

    Returns:
        ``(x, y, source)``: features (N, 57), labels into ``names``, "mmhgr" / "mmhgr_none".
    """
    labels = frames.labels(options.ok_sign)
    unknown = mmhgr.unknown_poses(options.ok_sign, unknown)
    keep = np.zeros(len(frames), dtype=bool)
    keep[:: max(1, options.mmhgr_stride)] = True
    known = keep & np.isin(labels, names)
    none = keep & np.isin(frames.pose, unknown) & (NONE in names)
    sel = np.flatnonzero(known | none)
    sub = frames.subset(sel)
    deg = np.full(len(sel), float(options.rotate_deg))
    if options.rotate_shape_deg is not None:
        deg[~np.isin(sub.pose, mmhgr.ORIENTED_POSES)] = options.rotate_shape_deg
    rot = mmhgr.random_rotations(rng, len(sel), deg[:, None]) if deg.any() else None
    x = mmhgr.features57(sub, rot)
    y = np.array([names.index(lab) if lab in names else names.index(NONE)
                  for lab in labels[sel]], dtype=np.int64)
    source = np.where(known[sel], "mmhgr", "mmhgr_none")
    if options.spliced_none > 0 and NONE in names:
        spliced = mmhgr.splice_fingers(frames, SPLICE_PATTERNS, options.spliced_none, rng)
        turn = mmhgr.random_rotations(rng, len(spliced), options.rotate_deg)
        x = np.concatenate([x, mmhgr.features57(spliced, turn)])
        y = np.concatenate([y, np.full(len(spliced), names.index(NONE), dtype=np.int64)])
        source = np.concatenate([source, np.full(len(spliced), "mmhgr_none")])
    return x, y, source


def build_dataset(options: TrainOptions, real: tuple | None = None,
                  user: list[UserGesture] | None = None, stream: int = SIM_STREAM_TRAIN,
                  frames: mmhgr.Frames | None = None,
                  unknown: tuple[str, ...] = mmhgr.UNKNOWN_POSES) -> Dataset:
    """Assembles the training set: real + simulated + none + MMHGR + the user's gestures.

    Args:
        options: counts and seed.
        real: ``(x, y, names)`` of real recordings (default: all vendored ones).
        user: recorded gestures (default: the user's, if ``options.user_gestures``).
        stream: the simulation seed stream.
        frames: multi-modal Leap HGR frames to train on; by default the whole cache
            (`mmhgr.load`) when ``options.mmhgr`` and ``real`` is the default, else none.
        unknown: which of its unknown poses train ``none``.
    """
    if frames is None and real is None and options.mmhgr:
        frames = mmhgr.load()
    x_real, y_real, base = real if real is not None else load_real_features()
    if user is None:
        user = load_user_gestures() if options.user_gestures else []
    new = sorted({g.name for g in user} - set(base) - {NONE})
    names = [*base, *new] + ([NONE] if options.none > 0 else [])
    rng = _rng(stream, options.seed)
    x_sim, y_sim = simulate_gestures(list(base), options.per_gesture, rng)
    parts = [(x_real, y_real, "real"), (x_sim, y_sim, "simulated")]
    if options.none > 0:
        turned = options.none_turned
        x_none = np.concatenate([simulate_none(options.none, list(base), rng),
                                 simulate_off_vocabulary(options.off_vocabulary, rng),
                                 simulate_none(turned - turned // 2, list(base), rng, None),
                                 simulate_off_vocabulary(turned // 2, rng, None)])
        parts.append((x_none, np.full(len(x_none), names.index(NONE)), "none"))
    if frames is not None and len(frames):
        x_m, y_m, s_m = mmhgr_rows(frames, names, options, rng, unknown)
        parts.append((x_m, y_m, s_m))
    for g in user:
        label = names.index(NONE if g.name == NONE else g.name)
        rows = augment(g.x, USER_MIN_ROWS, rng)
        parts.append((rows, np.full(len(rows), label), "user"))
    if options.features != "raw":
        # Device- and person-style copies of the recorded rows (real, MMHGR): the simulated
        # ones already vary in size, placement and angle.
        for x, y, src in [p for p in parts if p[2] is not None and _recorded(p[2])]:
            for _ in range(options.augment_copies):
                parts.append((invariant.augment(x, rng, curl_deg=options.curl_deg), y, src))
    return without_claimed_none(Dataset(
        x=np.concatenate([p[0] for p in parts]), y=np.concatenate([p[1] for p in parts]),
        names=names, source=np.concatenate([np.broadcast_to(p[2], len(p[1])) for p in parts]),
        user_gestures=[{"name": g.name, "rows": len(g.x), "takes": g.takes} for g in user]),
        user, new)


def _recorded(source) -> bool:
    first = source if isinstance(source, str) else (source[0] if len(source) else "")
    return str(first) in ("real", "mmhgr", "mmhgr_none")


# --------------------------------------------------------------------------- training


def model_inputs(x57: np.ndarray, features: str) -> tuple[np.ndarray, list[int], list[str]]:
    """Returns (rows the network reads, their feature indices, names) for a feature set."""
    if features == "raw":
        return x57[:, list(INPUTS)], list(INPUTS), [F.FEATURE_NAMES[i] for i in INPUTS]
    names = invariant.names_of(features)
    return invariant.transform(x57, features), list(range(len(names))), list(names)



MEMBER_SEED_STEP = 1000
"""Member i of an ensemble builds its data and trains with seed ``seed + i·MEMBER_SEED_STEP``
(member 0 with the seed itself); far apart, so that the seeds of nearby runs (crossval's folds
add their index) never meet."""


def member_seed(seed: int, member: int) -> int:
    """Returns the seed member ``member`` of an ensemble trained with ``seed`` uses."""
    return seed + member * MEMBER_SEED_STEP


def build_datasets(options: TrainOptions, *args, **kwargs) -> list[Dataset]:
    """Returns one `build_dataset` per ensemble member, each from its own seed.

    The members see the same recordings but their own simulated hands, augmentations and HGR
    frame choices: that, with their own initialisation, is what makes them disagree where the
    data do not decide (on the person-grouped cross-validation, three members differing by
    seed alone gained less than three on their own draws of the data).
    """
    return [build_dataset(replace(options, seed=member_seed(options.seed, i)), *args, **kwargs)
            for i in range(options.members)]


@dataclass
class Trained:
    """A trained ensemble with its metadata (not yet saved) and how training went.

    ``history`` is the members' mean negative ELBO per row, epoch by epoch.
    """

    model: bayes.BayesEnsemble
    metadata: dict
    history: list[float]
    seconds: float


def fit(datasets: Dataset | list[Dataset], options: TrainOptions,
        progress: bool | str = False) -> Trained:
    """Trains one Bayesian MLP per data set (`build_datasets`); returns the ensemble.

    All members read the same features through one standardizer (fitted on all their rows), so
    the model keeps one ``inputs`` and ``standardizer``; each has its own open-set rule.

    Args:
        datasets: the members' training rows (one data set: one network).
        options: network size, epochs, learning rate, prior, seed.
        progress: show a progress bar (or its description).
    """
    t0 = time.perf_counter()
    datasets = [datasets] if isinstance(datasets, Dataset) else list(datasets)
    data = datasets[0]
    if any(d.names != data.names for d in datasets):
        raise ValueError("ensemble members must be trained on the same classes")
    prepared = [model_inputs(d.x, options.features) for d in datasets]
    _, inputs, input_names = prepared[0]
    standardizer = bayes.Standardizer.fit(np.concatenate([x for x, _, _ in prepared]))
    arch = bayes.Architecture(len(inputs), list(options.hidden), len(data.names), "tanh",
                              options.prior_sigma)
    networks, open_sets, histories = [], [], []
    for i, (d, (x, _, _)) in enumerate(zip(datasets, prepared, strict=True)):
        seed = member_seed(options.seed, i)
        label = progress if not isinstance(progress, str) or len(datasets) == 1 \
            else f"{progress} ({i + 1}/{len(datasets)})"
        inputs_z = standardizer(x)
        network, history = _fit_network(inputs_z, d, arch, replace(options, seed=seed), label)
        networks.append(network)
        histories.append(history)
        open_sets.append(fit_open_set(network, inputs_z, d, seed))
    config = bayes.TrainConfig(options.epochs, options.batch_size, options.lr, options.seed,
                               options.kl_scale)
    history = np.mean(histories, axis=0).tolist()
    metadata = {
        "kind": KIND, "names": data.names, "none_class": NONE if NONE in data.names else None,
        "members": len(networks),
        "inputs": inputs, "feature_version": F.FEATURE_VERSION,
        "transform": None if options.features == "raw" else options.features,
        "feature_names": input_names,
        "standardizer": standardizer,
        "data_hash": bayes.data_hash(*[a for d in datasets for a in (d.x, d.y)]),
        "real_data_sha256": real_features_sha256(), "train": config,
        "options": asdict(replace(options, members=len(networks))), "dataset": data.summary(),
        "user_gestures": data.user_gestures,
        "trained_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "final_neg_elbo": history[-1], "cbgo_version": cbgo.__version__,
        "torch_version": torch.__version__,
        "open_set": None if open_sets[0] is None else [o.to_dict() for o in open_sets],
    }
    return Trained(bayes.BayesEnsemble.of(networks), metadata, history,
                   time.perf_counter() - t0)


def _fit_network(x: np.ndarray, data: Dataset, arch: bayes.Architecture,
                 options: TrainOptions, progress: bool | str) -> tuple[bayes.BayesMLP, list]:
    """Trains one member on standardised inputs ``x``; returns it and its -ELBO history."""
    counts = np.bincount(data.y, minlength=len(data.names)).astype(np.float64)
    share = np.ones(len(data.names))
    if NONE in data.names:
        share[data.names.index(NONE)] = options.none_weight
    weights = (share * len(data.y) / (share.sum() * np.maximum(counts, 1.0)))[data.y]
    torch.manual_seed(options.seed)
    model = bayes.BayesMLP(arch)
    config = bayes.TrainConfig(options.epochs, options.batch_size, options.lr, options.seed,
                               options.kl_scale)
    threads = torch.get_num_threads()
    # One thread: batches of 256 × 53 are far too small to share, and on a busy machine
    # torch's worker threads spin against each other (measured 25× slower with 2 threads).
    torch.set_num_threads(1)
    try:
        history = bayes.train(model, x, data.y, config, progress=progress, weights=weights)
    finally:
        torch.set_num_threads(threads)
    model.eval()
    return model, history


def fit_open_set(model: bayes.BayesMLP, inputs: np.ndarray, data: Dataset, seed: int
                 ) -> openset.OpenSet | None:
    """Calibrates the model's open-set rule on its training gesture rows (None: no ``none``)."""
    if NONE not in data.names:
        return None
    hidden = Posterior.draw(model, 1, seed).embed(inputs)[0]
    gestures = [i for i, n in enumerate(data.names) if n != NONE]
    return openset.OpenSet.fit(hidden, data.y, gestures, _rng(SIM_STREAM_OPEN_SET, seed))


def save_model(base: str | Path, trained: Trained) -> tuple[Path, Path, str]:
    """Writes ``<base>.pt`` and ``<base>.json`` atomically; returns (pt, json, model id).

    Both go to temporary files first; the weights' SHA-256 is added to the metadata; then the
    weights are renamed into place and the metadata last, so that a reader either sees the old
    pair, or a new ``.pt`` its ``.json`` does not vouch for (refused, tried again later).
    """
    base = Path(base)
    if base.suffix in (".pt", ".json"):
        base = base.with_suffix("")
    base.parent.mkdir(parents=True, exist_ok=True)
    tmp = base.parent / f"tmp-{os.getpid()}-{base.name}"
    pt_tmp, js_tmp = bayes.save(tmp, trained.model, trained.metadata)
    sha = weights_sha256(trained.model.state_dict())
    meta = json.loads(js_tmp.read_text())
    meta.update(weights_sha256=sha, model_id=model_id_of(sha))
    js_tmp.write_text(json.dumps(meta, indent=1) + "\n")
    pt, js = base.with_suffix(".pt"), base.with_suffix(".json")
    os.replace(pt_tmp, pt)
    os.replace(js_tmp, js)
    trained.metadata.update(weights_sha256=sha, model_id=model_id_of(sha))
    return pt, js, model_id_of(sha)


def classifier_of(trained: Trained, samples: int = 32) -> StaticClassifier:
    """Returns a classifier for a freshly trained (maybe unsaved) model."""
    meta = json.loads(json.dumps(trained.metadata, default=_plain))
    meta["weights_sha256"] = weights_sha256(trained.model.state_dict())
    return StaticClassifier.from_model(trained.model, meta, samples)


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if hasattr(value, "__dataclass_fields__"):
        return asdict(value)
    raise TypeError(f"cannot store {type(value).__name__} in model metadata")


# --------------------------------------------------------------------------- validation


def grouped_split(x: np.ndarray, y: np.ndarray, fraction: float, seed: int,
                  clusters: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Splits real frames into (held-out, training) indices, holding out whole clusters.

    The recordings are ~30 takes × 26 frames per gesture with the frames shuffled and no take
    id; consecutive frames of a take are near-duplicates, so a random split leaks. Per gesture,
    k-means (on standardised inputs) finds ``clusters`` groups of near-identical frames and a
    ``fraction`` of the groups is held out whole.
    """
    rng = np.random.default_rng(seed)
    z = x[:, list(INPUTS)]
    z = (z - z.mean(0)) / np.maximum(z.std(0), 1e-6)
    held = np.zeros(len(y), dtype=bool)
    for g in np.unique(y):
        idx = np.flatnonzero(y == g)
        labels = _kmeans(z[idx], min(clusters, len(idx)), rng)
        out = rng.choice(labels.max() + 1, max(1, round(fraction * (labels.max() + 1))),
                         replace=False)
        held[idx[np.isin(labels, out)]] = True
    return np.flatnonzero(held), np.flatnonzero(~held)


def _kmeans(z: np.ndarray, k: int, rng: np.random.Generator, iterations: int = 20
            ) -> np.ndarray:
    centres = z[rng.choice(len(z), k, replace=False)]
    for _ in range(iterations):
        labels = ((z[:, None] - centres[None]) ** 2).sum(-1).argmin(1)
        centres = np.stack([z[labels == i].mean(0) if (labels == i).any() else centres[i]
                            for i in range(k)])
    return np.unique(labels, return_inverse=True)[1]


def evaluate(clf: StaticClassifier, x: np.ndarray, y_names: list[str]) -> dict:
    """Balanced accuracy, ECE and confusion of a classifier on labelled feature rows.

    Args:
        clf: the classifier.
        x: features (N, 57) on the recorded side.
        y_names: the true gesture name of each row (a name the model lacks counts as wrong).

    Returns:
        ``{balanced_accuracy, accuracy, ece, n, classes, confusion, predicted}`` where rows of
        ``confusion`` are the true classes present (``classes``) and columns the model's names.
    """
    probs = clf.predict_features(x)
    names = clf.names
    classes = sorted(set(y_names), key=lambda n: (names.index(n) if n in names else len(names),
                                                  n))
    truth_cols = np.array([names.index(n) if n in names else -1 for n in y_names])
    pred = probs.argmax(1)
    rows = np.array([classes.index(n) for n in y_names])
    confusion = np.zeros((len(classes), len(names)), dtype=np.int64)
    np.add.at(confusion, (rows, pred), 1)
    correct = pred == truth_cols
    recall = [float(correct[rows == i].mean()) for i in range(len(classes))]
    ece = expected_calibration_error(np.c_[probs, np.zeros(len(probs))],
                                     np.where(truth_cols >= 0, truth_cols, len(names)))
    return {"balanced_accuracy": float(np.mean(recall)), "accuracy": float(correct.mean()),
            "ece": ece, "n": len(y_names), "classes": classes, "recall": recall,
            "confusion": confusion.tolist(), "names": list(names)}


def validate(options: TrainOptions, progress: bool | str = False) -> dict:
    """Trains on a split of the training data and returns held-out figures.

    Held out: a grouped fifth of the real recordings (`grouped_split`), and simulated people
    from another seed stream (gestures and, if trained, no-gesture poses).
    """
    x_real, y_real, names = load_real_features()
    held, kept = grouped_split(x_real, y_real, 0.2, options.seed)
    data = build_datasets(options, (x_real[kept], y_real[kept], names), user=[])
    trained = fit(data, options, progress)
    clf = classifier_of(trained)
    rng = _rng(SIM_STREAM_VALIDATE, options.seed)
    x_sim, y_sim = simulate_gestures(list(names), 150, rng)
    out = {"real": evaluate(clf, x_real[held], [names[i] for i in y_real[held]]),
           "simulated": evaluate(clf, x_sim, [names[i] for i in y_sim]),
           "seconds": trained.seconds}
    if options.none > 0:
        out["none"] = evaluate(clf, simulate_none(300, list(names), rng), [NONE] * 300)
    return out


# --------------------------------------------------------------------------- CLI


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer's flags."""
    d = TrainOptions()
    parser.add_argument("--out", type=Path, default=None,
                        help="model base path (.pt/.json) [data_dir()/models/static-gesture]")
    parser.add_argument("--shipped", action="store_true",
                        help="write the default model shipped in the package (no user gestures)")
    parser.add_argument("--per-gesture", type=int, default=d.per_gesture,
                        help=f"simulated renditions per gesture [{d.per_gesture}]")
    parser.add_argument("--none", type=int, default=d.none,
                        help=f"simulated no-gesture poses [{d.none}]")
    parser.add_argument("--no-none", action="store_true", help="no no-gesture class")
    parser.add_argument("--hidden", type=int, nargs="+", default=d.hidden,
                        help=f"hidden layer sizes {d.hidden}")
    parser.add_argument("--epochs", type=int, default=d.epochs, help=f"[{d.epochs}]")
    parser.add_argument("--lr", type=float, default=d.lr, help=f"Adam learning rate [{d.lr}]")
    parser.add_argument("--prior-sigma", type=float, default=d.prior_sigma,
                        help=f"std of the Normal prior of every weight [{d.prior_sigma}]")
    parser.add_argument("--seed", type=int, default=d.seed, help=f"[{d.seed}]")
    parser.add_argument("--members", type=int, default=d.members,
                        help="networks in the ensemble, each trained on its own draw of the "
                             "data: 3 read unseen people about 1 point better than one and "
                             "reject 3 points more unknown poses, at 3 times the training time "
                             f"(docs/design/static_gesture.md) [{d.members}]")
    parser.add_argument("--off-vocabulary", type=int, default=d.off_vocabulary,
                        help=f"simulated poses outside the vocabulary, as none "
                             f"[{d.off_vocabulary}]")
    parser.add_argument("--features", choices=("raw", *invariant.TRANSFORMS), default=d.features,
                        help=f"the network's inputs [{d.features}]")
    parser.add_argument("--no-mmhgr", action="store_true",
                        help="leave out the multi-modal Leap HGR frames even if their cache "
                             f"exists ({mmhgr.default_cache()})")
    parser.add_argument("--mmhgr-stride", type=int, default=d.mmhgr_stride,
                        help=f"keep every Nth frame of that set [{d.mmhgr_stride}]")
    parser.add_argument("--rotate-deg", type=float, default=d.rotate_deg,
                        help="turn each HGR frame about its palm by N(0, this) degrees in roll, "
                             f"pitch and yaw [{d.rotate_deg:g}]")
    parser.add_argument("--rotate-shape-deg", type=float, default=d.rotate_shape_deg,
                        help="turn the HGR poses told by shape alone (all but the palm-up and "
                             "palm-down thumb poses) by N(0, this) instead: a model for hands "
                             "held at many angles (head-mounted sensors), at a cost on hands "
                             "held as usual (docs/design/static_gesture.md) [as --rotate-deg]")
    parser.add_argument("--curl-deg", type=float, default=d.curl_deg,
                        help="bend the recorded rows' open fingers by up to this many degrees "
                             "in their device- and person-style copies (devices and people "
                             f"curl open fingers differently) [{d.curl_deg:g}]")
    parser.add_argument("--spliced-none", type=int, default=d.spliced_none,
                        help="train this many `none` hands spliced from HGR people's own fist "
                             "and open hand (the finger patterns no gesture uses): horns and "
                             "hang loose rejected more often, but C, L and thumb down less often "
                             f"(docs/design/static_gesture.md) [{d.spliced_none}]")
    parser.add_argument("--none-turned", type=int, default=d.none_turned,
                        help="this many more simulated `none` hands (relaxed, forming, outside "
                             "the vocabulary) turned any way at all: a hand held palm up or "
                             "fingers down is no gesture by its orientation alone "
                             f"[{d.none_turned}]")
    parser.add_argument("--ok-sign", choices=mmhgr.OK_SIGNS, default=d.ok_sign,
                        help="what the HGR set's ok signs are trained as: pinch (the paper's "
                             "recorded pinches are ok signs) or none (an unknown pose). The "
                             "paper's pinches stay pinch either way, and the Leap Motion "
                             "Controller 2's ok sign (Ultraleap's Gemini pose) still reads "
                             "pinch as held, 0.59 with none (docs/design/static_gesture.md: "
                             f"\"The ok sign is `pinch`\") [{d.ok_sign}]")
    parser.add_argument("--no-user-gestures", action="store_true",
                        help="leave out the gestures recorded by demonstration")
    parser.add_argument("--validate", action="store_true",
                        help="first train on a split of the training data and print held-out "
                             "figures")


def options_from(args: argparse.Namespace) -> TrainOptions:
    """Returns the training options of parsed flags.

    Raises:
        ConfigError: flags no training can run with (naming them).
    """
    try:
        return _options_of(args)
    except ValueError as e:
        raise ConfigError(str(e)) from None


def _options_of(args: argparse.Namespace) -> TrainOptions:
    return TrainOptions(per_gesture=args.per_gesture, none=0 if args.no_none else args.none,
                        hidden=list(args.hidden), epochs=args.epochs, lr=args.lr,
                        prior_sigma=args.prior_sigma, seed=args.seed, members=args.members,
                        off_vocabulary=args.off_vocabulary, features=args.features,
                        mmhgr=not args.no_mmhgr, mmhgr_stride=args.mmhgr_stride,
                        rotate_deg=args.rotate_deg, rotate_shape_deg=args.rotate_shape_deg,
                        curl_deg=args.curl_deg, spliced_none=args.spliced_none,
                        none_turned=args.none_turned, ok_sign=args.ok_sign,
                        user_gestures=not (args.no_user_gestures or args.shipped))


def train_and_save(options: TrainOptions, out: Path, progress: bool | str = True,
                   user: list[UserGesture] | None = None) -> tuple[Trained, str]:
    """Builds the data set, trains, writes the model; returns it and its id.

    ``user``: the recorded gestures to train on (default: every one in the data directory).
    """
    trained = fit(build_datasets(options, user=user), options, progress)
    _, _, model_id = save_model(out, trained)
    return trained, model_id


def _print_eval(title: str, fig: dict) -> None:
    print(f"  {title}: balanced accuracy {fig['balanced_accuracy']:.2%}, ECE {fig['ece']:.4f} "
          f"(n={fig['n']})")


def run(args: argparse.Namespace) -> int:
    """Trains (optionally validates first) and writes the model; prints a summary."""
    options = options_from(args)
    out = args.out or (shipped_model_path() if args.shipped else user_model_path())
    if args.validate:
        print("validation on held-out training data (grouped real fifth, unseen simulated "
              "people):")
        fig = validate(options, progress="validation training")
        _print_eval("real, held-out groups", fig["real"])
        _print_eval("simulated, unseen people", fig["simulated"])
        if "none" in fig:
            _print_eval("no-gesture poses", fig["none"])
    t0 = time.perf_counter()
    trained, model_id = train_and_save(options, out, progress="training static-gesture")
    summary = trained.metadata["dataset"]
    print(f"trained {model_id}, {len(trained.model.members)} networks, on {summary['rows']} "
          "rows each "
          f"({', '.join(f'{k} {v}' for k, v in summary['per_source'].items() if v)}); "
          f"classes: {', '.join(trained.metadata['names'])}")
    print(f"network {len(trained.metadata['inputs'])} → {' → '.join(map(str, options.hidden))} → "
          f"{len(trained.metadata['names'])}, {options.epochs} epochs, final -ELBO/row "
          f"{trained.history[-1]:.4f}; {time.perf_counter() - t0:.1f} s in all "
          f"({trained.seconds:.1f} s training)")
    print(f"wrote {Path(out).with_suffix('.pt')} and .json")
    return 0
