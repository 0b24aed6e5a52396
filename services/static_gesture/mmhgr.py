"""The "Multi-modal Leap Motion dataset for HGR": loader and vocabulary mapping.

The dataset (Mantecón et al.; 25 people, 16 static poses, Leap Motion SDK v2 frames as OpenCV
XML, about 1.25 GB) is copied in the GitHub repository ``sluyters/QuantumLeap``, folder
``backend/src/datasets/static/multi_mod_hand_gest_recog/``. It comes with no licence file, so
cbgo ships none of it: ``cbgo data convert mmhgr SRC`` (`cbgo_tools.data.mmhgr`) converts a local
copy into one compact cache file OUTSIDE the repository, and the trainer and the bench use that
file when it is present.

Rules:

- Source layout: ``<root>/user_NN/{train_pose,test_pose}/<pose>/frame_<id>.xml``. Each file
  holds one frame with one hand (the same hand under ``RigthImage`` and ``LeftImage``; the
  first one is read): palm ``Center``, ``Normal``, ``Direction``, ``Confidence``, grab/pinch
  strength, and per finger (thumb..pinky) ``mcpPosition``, ``pipPosition``, ``dipPosition``,
  ``TipPosition`` and ``isExtended``, in the Leap frame (mm, +y up, +z towards the user). There
  is no wrist, no arm and no metacarpal base.
- The four points of a finger are the joints of its last three bones: proximal.prev (``mcp``),
  intermediate.prev (``pip``), distal.prev (``dip``), distal.next (``tip``). For the thumb too:
  its metacarpal has zero length in the Leap model, so ``mcp`` is where its proximal starts.
- `hand_dicts` turns rows into contract hands (``docs/protocol.md``) with stand-in
  metacarpals and no rotation: the thumb's has ZERO LENGTH at ``mcp`` (as in the Leap model),
  the other fingers' end at ``mcp`` and lie along the hand direction (`METACARPAL_MM` long).
  The device-independent features of ``cbgo.services.static_gesture.invariant`` read those
  four only through their mean, as the palm's axis (the real ones fan out a little about it);
  nothing reads the thumb's metacarpal or the wrist (put 60 mm behind the palm to keep the
  dict complete).
- `POSE_MAP` maps the dataset's poses to cbgo's static vocabulary (``STATIC_GESTURES``):
  ``fist_moved`` → grab, ``index`` → point, ``two``, ``three``, ``four``, ``five`` → the same,
  ``up`` (thumb up, fist) → thumbsup. Every other pose is unknown to cbgo (`UNKNOWN_POSES`).
  The flat open hands ``palm``, ``palm_m`` and ``palm_u`` are left out of both (`AMBIGUOUS`):
  fingers together or apart, an open hand is what a user means by ``five``, so neither a
  gesture label nor a "none" label would be honest.

Examples::

    cbgo data fetch mmhgr             # a copy of the source folder, into the cache
    cbgo data convert mmhgr SRC       # SRC (that copy) → the cache file the trainer reads
    cbgo data convert mmhgr --info    # what the cache file holds
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.wire import BONE_TYPES, FINGER_TYPES

POSES = ("C", "L", "down", "fist_moved", "five", "four", "hang", "heavy", "index", "ok",
         "palm", "palm_m", "palm_u", "three", "two", "up")
POSE_MAP = {"fist_moved": "grab", "index": "point", "two": "two", "three": "three",
            "four": "four", "five": "five", "up": "thumbsup", "ok": "pinch"}
"""The set's poses that are cbgo gestures. ``ok`` is ``pinch``: the paper's authors define
their pinch as "grip between finger and thumb, while last three fingers are open"
(imitrob/teleop_gesture_toolbox, include/custom_settings/gestures.yaml), an ok sign's shape,
and their recorded pinches are one (thumb and index tips 18 ± 13 mm apart, the other three
fingers straight; the set's ok signs 29 ± 20 mm)."""
OK_SIGNS = ("pinch", "none")
"""What the set's ok signs can be trained as (`pose_map`, ``cbgo train static --ok-sign``): the
paper's ``pinch`` (the default, above), or ``none``, an unknown pose. What each does to the ok
signs of unseen people and of the Leap Motion Controller 2: docs/design/static_gesture.md, "The
ok sign is `pinch`"."""
POSE_FINGERS = {"fist_moved": (0, 0, 0, 0), "up": (0, 0, 0, 0), "index": (1, 0, 0, 0),
                "two": (1, 1, 0, 0), "three": (1, 1, 1, 0), "four": (1, 1, 1, 1),
                "five": (1, 1, 1, 1), "ok": (0, 1, 1, 1)}
"""Which of index, middle, ring and pinky each gesture pose holds out (the thumb left aside:
the tracker flags it extended in a quarter of the set's fists)."""
POSE_THUMB = {"fist_moved": False, "up": True, "four": False, "five": True}
"""Whether the gesture poses that fix the thumb hold it out: a grab's and a four's are in, a
thumbs-up's and a five's out (the others may hold it either way)."""
AMBIGUOUS = ("palm", "palm_m", "palm_u")
ORIENTED_POSES = ("up", "down")
"""Poses that differ by orientation alone: the same fist with the thumb out, held palm up
(``up``) or palm down (``down``); every other pose is told by its shape."""
UNKNOWN_POSES = tuple(p for p in POSES if p not in POSE_MAP and p not in AMBIGUOUS)
SESSIONS = ("train_pose", "test_pose")
METACARPAL_MM = 50.0  # length of the stand-in metacarpals of index..pinky (only its axis counts)


def pose_map(ok_sign: str = "pinch") -> dict[str, str]:
    """Returns `POSE_MAP` with the ok signs as ``ok_sign`` says (`OK_SIGNS`).

    Raises:
        ValueError: for an ``ok_sign`` not in `OK_SIGNS`.
    """
    if ok_sign not in OK_SIGNS:
        raise ValueError(f"ok_sign must be one of {', '.join(OK_SIGNS)}, got {ok_sign!r}")
    return POSE_MAP if ok_sign == "pinch" else {p: g for p, g in POSE_MAP.items() if p != "ok"}


def unknown_poses(ok_sign: str = "pinch", base: tuple[str, ...] = UNKNOWN_POSES
                  ) -> tuple[str, ...]:
    """Returns the set's poses that are no cbgo gesture.

    ``base`` (by default `UNKNOWN_POSES`), and the ok sign too if ``ok_sign`` is ``"none"``.
    """
    return tuple(base) + (("ok",) if "ok" not in pose_map(ok_sign) else ())


def default_cache() -> Path:
    """Returns the converted cache file, ``mmhgr.npz`` in `cbgo.config.cache_dir`.

    It sits outside the repository and the data directory on purpose (unlicensed data).
    """
    return cache_dir() / "mmhgr.npz"


@dataclass
class Frames:
    """Converted frames, one row each (see the module docstring for the fields)."""

    joints: np.ndarray      # (N, 5, 4, 3) mcp, pip, dip, tip per finger, mm
    palm: np.ndarray        # (N, 3)
    normal: np.ndarray      # (N, 3)
    direction: np.ndarray   # (N, 3)
    side: np.ndarray        # (N,) "left" / "right"
    confidence: np.ndarray  # (N,)
    extended: np.ndarray    # (N, 5) bool
    user: np.ndarray        # (N,) int, 1..25
    session: np.ndarray     # (N,) index into SESSIONS
    pose: np.ndarray        # (N,) str, the dataset's pose name
    frame: np.ndarray       # (N,) int, the frame id

    def __len__(self) -> int:
        return len(self.pose)

    def subset(self, mask: np.ndarray) -> Frames:
        """Returns the rows selected by a boolean mask or index array."""
        return Frames(**{k: getattr(self, k)[mask] for k in self.__dataclass_fields__})

    def labels(self, ok_sign: str = "pinch") -> np.ndarray:
        """Returns each row's cbgo gesture name, ``""`` for unknown and ambiguous poses.

        ``ok_sign``: what the ok signs are (`OK_SIGNS`); ``"none"`` makes them unknown.
        """
        names = pose_map(ok_sign)
        return np.array([names.get(p, "") for p in self.pose])

    def tracker_agrees(self) -> np.ndarray:
        """Returns per row whether the tracker's own finger flags show its pose's fingers.

        The Leap software flags each finger it tracked as extended or not. Where its index..
        pinky flags differ from what the pose holds out (`POSE_FINGERS`), the skeleton it
        reported shows another pose: a tracking error, or a loosely made pose. False for the
        poses outside `POSE_FINGERS`.
        """
        agrees = np.zeros(len(self), dtype=bool)
        for pose, fingers in POSE_FINGERS.items():
            rows = self.pose == pose
            agrees[rows] = (self.extended[rows][:, 1:] == np.array(fingers, dtype=bool)).all(1)
        return agrees

    def thumb_agrees(self) -> np.ndarray:
        """Returns per row whether the tracker's thumb flag shows its pose's thumb.

        True where the pose does not fix the thumb (`POSE_THUMB`). Where it does and the flag
        differs, the skeleton shows the other gesture of the pair (a four as a five, a grab as
        a thumbs-up), whatever the person held.
        """
        agrees = np.ones(len(self), dtype=bool)
        for pose, out in POSE_THUMB.items():
            rows = self.pose == pose
            agrees[rows] = self.extended[rows][:, 0] == out
        return agrees


def load(path: Path | None = None) -> Frames | None:
    """Loads the cache file; None when it does not exist (the data are optional)."""
    path = default_cache() if path is None else Path(path)
    if not path.is_file():
        return None
    with np.load(path, allow_pickle=False) as d:
        return Frames(**{k: d[k] for k in Frames.__dataclass_fields__})


def hand_dicts(frames: Frames, joints: np.ndarray | None = None,
               palm: np.ndarray | None = None, normal: np.ndarray | None = None,
               direction: np.ndarray | None = None) -> list[dict]:
    """Returns contract hands of the rows (geometry overridable, e.g. by an augmentation).

    The thumb gets a zero-length metacarpal at ``mcp``, the other fingers one of
    `METACARPAL_MM` ending at ``mcp`` along the hand direction (see the module docstring).
    """
    joints = frames.joints if joints is None else joints
    palm = frames.palm if palm is None else palm
    normal = frames.normal if normal is None else normal
    direction = frames.direction if direction is None else direction
    hands = []
    for n in range(len(joints)):
        j = np.asarray(joints[n], dtype=np.float64).tolist()
        d = np.asarray(direction[n], dtype=np.float64)
        p = np.asarray(palm[n], dtype=np.float64)
        fingers = []
        for f, ftype in enumerate(FINGER_TYPES):
            base = j[f][0] if f == 0 else (np.asarray(j[f][0]) - METACARPAL_MM * d).tolist()
            points = [base, *j[f]]
            fingers.append({"type": ftype, "bones": [
                {"type": b, "prev_joint": points[k], "next_joint": points[k + 1], "width": 15.0}
                for k, b in enumerate(BONE_TYPES)]})
        hands.append({"id": n, "side": str(frames.side[n]), "confidence": float(
            frames.confidence[n]), "palm_position": p.tolist(), "palm_velocity": [0.0] * 3,
            "palm_normal": np.asarray(normal[n], dtype=np.float64).tolist(),
            "direction": d.tolist(), "wrist_position": (p - 60.0 * d).tolist(),
            "palm_width": 80.0, "grab_strength": 0.0, "pinch_strength": 0.0,
            "fingers": fingers})
    return hands


def features57(frames: Frames, rotation: np.ndarray | None = None) -> np.ndarray:
    """Returns the paper's 57 features of the rows, on the recorded side, vectorised.

    The same numbers as ``cbgo.hands.features.hands_features(hand_dicts(frames), True)``
    (a unit test holds the two together), without building dicts.

    Args:
        frames: the rows.
        rotation: optional (N, 3, 3) rotations applied to each hand about its palm centre (an
            augmentation: the hand held at another angle).
    """
    from cbgo.hands import features as F  # noqa: PLC0415 - keeps `convert` light

    joints = frames.joints.astype(np.float64)
    palm = frames.palm.astype(np.float64)
    direction = F.unit(np, frames.direction.astype(np.float64))
    if rotation is not None:
        joints = np.einsum("nij,nfkj->nfki", rotation, joints - palm[:, None, None]) \
            + palm[:, None, None]
        direction = np.einsum("nij,nj->ni", rotation, direction)
    mcp, pip, dip, tip = (joints[:, :, k] for k in range(4))
    proximal = F.unit(np, mcp - pip)  # recording convention: tip to base
    # The stand-in metacarpals (`hand_dicts`): the thumb's has zero length and borrows its
    # proximal; the others lie along the hand direction, so tip to base is −direction.
    metacarpal = np.concatenate([proximal[:, :1], np.repeat(-direction[:, None], 4, 1)], 1)
    bone_dirs = np.stack([metacarpal, proximal, F.unit(np, pip - dip), F.unit(np, dip - tip)],
                         2)
    x = F.features_from_geometry(np, palm, palm - 60.0 * direction, direction, bone_dirs, tip)
    other = frames.side != F.RECORDED_SIDE
    x[other] = F.mirror_features(x[other])
    return x


SPLICE_OPEN, SPLICE_CLOSED = "five", "fist_moved"


def palm_basis(frames: Frames) -> np.ndarray:
    """Returns (N, 3, 3) rows: each frame's hand direction, palm normal and their cross."""
    from cbgo.hands import features as F  # noqa: PLC0415 - keeps `convert` light

    return F.palm_basis(np, frames.direction.astype(np.float64),
                        frames.normal.astype(np.float64))


def splice_fingers(frames: Frames, patterns: np.ndarray, count: int,
                   rng: np.random.Generator) -> Frames:
    """Real-looking hands of poses nobody recorded, each finger taken from one person's real frames.

    Why: a `none` class learnt from simulated poses outside the vocabulary teaches the model
    what a simulated hand looks like, not what an unknown real pose looks like. Each spliced
    hand is one person's fist (`SPLICE_CLOSED`, same side), with the fingers that `patterns`
    holds out taken from one of their open hands (`SPLICE_OPEN`): each such finger is moved
    from the open hand's palm frame (direction, normal) into the fist's. Curls, knuckle
    placement and tracker noise are that person's and that device's.

    Args:
        frames: the frames to splice from (only the people one trains on).
        patterns: (K, 5) bools per pose, thumb..pinky: True takes the open hand's finger.
        count: how many hands.
        rng: the random generator.

    Returns:
        Frames of pose ``"spliced"``, the fist's fields otherwise, ``extended`` the pattern.
    """
    groups = []
    for user in np.unique(frames.user):
        for side in ("left", "right"):
            own = (frames.user == user) & (frames.side == side)
            group = (np.flatnonzero(own & (frames.pose == SPLICE_OPEN)),
                     np.flatnonzero(own & (frames.pose == SPLICE_CLOSED)))
            if len(group[0]) and len(group[1]):
                groups.append(group)
    if count <= 0 or not groups or not len(patterns):
        return frames.subset(np.zeros(0, dtype=np.int64))
    pick = rng.integers(len(groups), size=count)
    open_rows = np.array([rng.choice(groups[g][0]) for g in pick])
    closed_rows = np.array([rng.choice(groups[g][1]) for g in pick])
    pattern = np.asarray(patterns, dtype=bool)[rng.integers(len(patterns), size=count)]
    opened, closed = frames.subset(open_rows), frames.subset(closed_rows)
    local = np.einsum("nij,nfkj->nfki", palm_basis(opened),
                      opened.joints - opened.palm[:, None, None])
    moved = np.einsum("nji,nfkj->nfki", palm_basis(closed), local) + closed.palm[:, None, None]
    out = closed.subset(np.arange(count))
    out.joints = np.where(pattern[:, :, None, None], moved, closed.joints).astype(
        closed.joints.dtype)
    out.extended = pattern
    out.pose = np.full(count, "spliced")
    return out


def random_rotations(rng: np.random.Generator, n: int, deg: float | np.ndarray) -> np.ndarray:
    """Returns (n, 3, 3) rotations by roll, pitch, yaw each drawn from N(0, deg).

    ``deg`` is one spread for all, or (n, 1) spreads, one per rotation.
    """
    a = np.deg2rad(rng.normal(0.0, deg, (n, 3)))
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones(n), np.zeros(n)
    rz = np.stack([c[:, 0], -s[:, 0], zero, s[:, 0], c[:, 0], zero, zero, zero, one], 1)
    rx = np.stack([one, zero, zero, zero, c[:, 1], -s[:, 1], zero, s[:, 1], c[:, 1]], 1)
    ry = np.stack([c[:, 2], zero, s[:, 2], zero, one, zero, -s[:, 2], zero, c[:, 2]], 1)
    return (ry.reshape(n, 3, 3) @ rx.reshape(n, 3, 3)) @ rz.reshape(n, 3, 3)
