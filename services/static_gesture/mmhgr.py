"""The "Multi-modal Leap Motion dataset for HGR": converter, loader and vocabulary mapping.

The dataset (Mantecón et al.; 25 people, 16 static poses, Leap Motion SDK v2 frames as OpenCV
XML, about 1.25 GB) is copied in the GitHub repository ``sluyters/QuantumLeap``, folder
``backend/src/datasets/static/multi_mod_hand_gest_recog/``. It comes with no licence file, so
cbgo ships none of it: this module converts a local copy into one compact cache file OUTSIDE
the repository, and the bench and the trainer use that file when it is present.

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

    python -m cbgo.services.static_gesture.mmhgr convert SRC          # → default cache
    python -m cbgo.services.static_gesture.mmhgr convert SRC --out F  # elsewhere
    python -m cbgo.services.static_gesture.mmhgr info                 # what the cache holds

SRC is the ``multi_mod_hand_gest_recog`` folder, e.g. from
``git archive HEAD backend/src/datasets/static/multi_mod_hand_gest_recog | tar -x``.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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
"""What the set's ok signs can be trained as (`pose_map`): the paper's ``pinch`` (the default,
above), or ``none``, an unknown pose, as issue 15 reads an ok sign. The README's section "The
ok sign is `pinch`" measures both."""
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
_FINGER_TAGS = ("Thumb", "Index", "Middle", "Ring", "Pinky")
_POINT_TAGS = ("mcpPosition", "pipPosition", "dipPosition", "TipPosition")
_NUM = r"([-+0-9.eE]+)"
_VEC = re.compile(r"<(\w+) type_id=\"opencv-matrix\">.*?<data>\s*" + r"\s+".join([_NUM] * 3)
                  + r"\s*</data>", re.S)
_SCALAR = re.compile(r"<(Confidence|PinchStrength|GrabStrength|isExtended)>\s*([-+0-9.eE]+)\s*<")
METACARPAL_MM = 50.0  # length of the stand-in metacarpals of index..pinky (only its axis counts)
_FILE = re.compile(r"user_(\d+)/(train_pose|test_pose)/(\w+)/frame_(\d+)\.xml$")


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
    """Returns the cache file: ``$XDG_CACHE_HOME/cbgo/mmhgr.npz`` (``~/.cache`` by default).

    It sits outside the repository and the data directory on purpose (unlicensed data).
    """
    import os  # noqa: PLC0415 - only here, for XDG_CACHE_HOME

    root = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(root) / "cbgo" / "mmhgr.npz"


def parse_frame(text: str) -> dict | None:
    """Parses one frame file; returns its first hand, or None when the frame has no hand.

    Returns:
        ``{side, palm, normal, direction, joints (5, 4, 3), extended (5,), confidence, grab,
        pinch}``.
    """
    start = text.find("<Hands>")
    end = text.find("</Hands>", start)
    if start < 0 or end < 0:
        return None
    block = text[start:end]
    side = re.search(r"<(Right|Left)>", block)
    if side is None:
        return None
    vectors: dict[str, list] = {}
    finger = None
    for m in re.finditer(r"<(Thumb|Index|Middle|Ring|Pinky)>|" + _VEC.pattern, block, re.S):
        if m.group(1):
            finger = m.group(1)
            continue
        tag = m.group(2)
        vectors[f"{finger}.{tag}" if finger and tag in _POINT_TAGS else tag] = [
            float(m.group(i)) for i in (3, 4, 5)]
    scalars: dict[str, list] = {}
    for m in _SCALAR.finditer(block):
        scalars.setdefault(m.group(1), []).append(float(m.group(2)))
    try:
        joints = [[vectors[f"{f}.{p}"] for p in _POINT_TAGS] for f in _FINGER_TAGS]
        return {"side": side.group(1).lower(), "palm": vectors["Center"],
                "normal": vectors["Normal"], "direction": vectors["Direction"],
                "joints": joints, "extended": scalars["isExtended"][:5],
                "confidence": scalars["Confidence"][0], "grab": scalars["GrabStrength"][0],
                "pinch": scalars["PinchStrength"][0]}
    except (KeyError, IndexError):
        return None


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


def convert(src: Path, out: Path, progress: bool = True) -> int:
    """Converts every frame file under ``src`` into the cache file ``out`` (atomically).

    Returns:
        The number of frames written (files without a hand are skipped).

    Raises:
        FileNotFoundError: ``src`` holds no ``user_NN/<session>/<pose>/frame_*.xml`` file.
    """
    files = sorted(p for p in Path(src).rglob("frame_*.xml") if _FILE.search(p.as_posix()))
    if not files:
        raise FileNotFoundError(f"no user_NN/<session>/<pose>/frame_*.xml under {src}")
    rows, meta = [], []
    t0 = time.monotonic()
    for n, path in enumerate(files):
        hand = parse_frame(path.read_text(errors="replace"))
        if hand is not None:
            rows.append(hand)
            meta.append(_FILE.search(path.as_posix()).groups())
        if progress and n % 5000 == 0:
            print(f"  {n}/{len(files)} files, {time.monotonic() - t0:.0f} s", file=sys.stderr)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"tmp-{out.name}")
    np.savez_compressed(
        tmp, joints=np.array([r["joints"] for r in rows], dtype=np.float32),
        palm=np.array([r["palm"] for r in rows], dtype=np.float32),
        normal=np.array([r["normal"] for r in rows], dtype=np.float32),
        direction=np.array([r["direction"] for r in rows], dtype=np.float32),
        side=np.array([r["side"] for r in rows]),
        confidence=np.array([r["confidence"] for r in rows], dtype=np.float32),
        extended=np.array([r["extended"] for r in rows], dtype=bool),
        user=np.array([int(m[0]) for m in meta], dtype=np.int16),
        session=np.array([SESSIONS.index(m[1]) for m in meta], dtype=np.int8),
        pose=np.array([m[2] for m in meta]), frame=np.array([int(m[3]) for m in meta]))
    tmp.replace(out)
    return len(rows)


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


def _info(frames: Frames) -> None:
    print(f"{len(frames)} frames, {len(np.unique(frames.user))} people, sides "
          f"{dict(zip(*np.unique(frames.side, return_counts=True), strict=True))}")
    for pose in POSES:
        sel = frames.pose == pose
        ext = frames.extended[sel].mean(0)
        role = POSE_MAP.get(pose, "(ambiguous)" if pose in AMBIGUOUS else "(unknown)")
        print(f"  {pose:10s} → {role:12s} {int(sel.sum()):5d} frames; extended T I M R P "
              + " ".join(f"{e:.2f}" for e in ext)
              + f"; confidence {np.median(frames.confidence[sel]):.2f}")
    print("median tracking confidence per person: " + ", ".join(
        f"{u}: {np.median(frames.confidence[frames.user == u]):.2f}"
        for u in np.unique(frames.user)))


def main(argv: list[str] | None = None) -> int:
    """Command line: ``convert SRC [--out FILE]`` or ``info [--file FILE]``."""
    parser = argparse.ArgumentParser(prog="python -m cbgo.services.static_gesture.mmhgr",
                                     description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="verb", required=True)
    conv = sub.add_parser("convert", help="XML folder → cache file")
    conv.add_argument("src", type=Path)
    conv.add_argument("--out", type=Path, default=None, help=f"[{default_cache()}]")
    info = sub.add_parser("info", help="what the cache file holds")
    info.add_argument("--file", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.verb == "convert":
        out = args.out or default_cache()
        try:
            n = convert(args.src, out)
        except (OSError, ValueError) as exc:  # no copy there, or an unreadable frame
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"wrote {n} frames to {out}")
        return 0
    frames = load(args.file)
    if frames is None:
        print(f"no cache file at {args.file or default_cache()}; run `convert` first")
        return 1
    _info(frames)
    return 0


if __name__ == "__main__":  # pragma: no cover - command line
    sys.exit(main())


__all__ = ["AMBIGUOUS", "OK_SIGNS", "POSES", "POSE_MAP", "UNKNOWN_POSES", "Frames", "convert",
           "default_cache", "hand_dicts", "load", "parse_frame", "pose_map", "unknown_poses"]


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
