"""CollaborICE's Leap Motion Controller 2 frames (LeapC, Gemini tracking): reader and a score.

Why: the static-gesture model should hold on the Leap Motion Controller 2, and this is a public
set of LMC2 frames of several people held in static poses, beside Ultraleap's single frames
(`cbgo_tools.data.ultraleap`). The set: ``gesture_recognizer_creator/data/train`` of the
GitHub repository ``univr-GRAIL/CollaborICE_Leap_Gesture_Recognition`` (University of Verona),
one folder per person, one file per pose. It has no licence file: nothing of it is in this
repository; ``cbgo data fetch collaborice`` copies that folder into the cache. The
repository's ``data/test`` folder is reserved: nothing here fetches or reads it.

How a line becomes a contract hand (``docs/protocol.md``, hands/frame). The recorder
(``dataset_creator.py`` with ``lib_gest_recon_leap.create_data`` in that repository) took
each tracking event of Ultraleap's Python bindings for LeapC in Desktop tracking mode, kept its
RIGHT hands only and frames with at least one, and wrote one JSON object a line:
``{frame_id, tracking_frame_id, timestamp, hands: [{hand_type, hand_id, confidence,
hand_keypoints}]}``. Every vector there is the LeapC vector divided by 1000 and nothing else
(``convert_vector_to_list``): metres, LeapC's own axes (+y up, +z towards the user), no
ROS or other transform; quaternions are LeapC's ``(x, y, z, w)``. So:

- positions: × 1000 → mm, axes as they are (LeapC Desktop mode is the contract's Leap frame).
  The project also ran a second sensor above a screen (ScreenTop mode); the recorder sets
  Desktop mode, and the frames agree with a sensor on the desk: the forearm runs from the wrist
  towards the user and the right (+z, +x), level within about 10° (+y 0.1–0.2);
- each hand is laid out as the bindings' ``Hand`` (`as_leap_hand`) and mapped by the live
  sensor's own code, ``services/leap_bridge/leap_device.hand_from_leap``: ``id`` ←
  ``hand_id``, ``side`` ← ``hand_type``, ``confidence``, ``palm_position``, ``wrist_position``
  ← ``arm.next_joint``, each bone's joints and rotation; the thumb's zero-length metacarpal
  (LeapC's placeholder: its joints equal, here with a rotation that is no orientation either)
  loses its ``rotation`` there, as on a live sensor, so the features borrow the proximal's
  direction for it;
- ``palm_normal`` and ``direction`` ← the palm ``orientation`` quaternion, whose basis is
  LeapC's ``{normal × direction, −normal, −direction}`` (``LEAP_PALM.orientation`` in
  ``LeapC.h``): normal = −(basis y), direction = −(basis z) (`palm_axes`). Checked on person 3's
  frames: the direction is within 16° of palm centre → middle knuckle in every frame, and the
  normal × (index knuckle − pinky knuckle) runs along the direction, as a right hand's does;
- not recorded, so given fixed values that nothing in the static model reads: ``palm_velocity``
  0 (the poses are held), ``palm_width`` `PALM_WIDTH_MM`, each bone's ``width``
  `BONE_WIDTH_MM` (0 for a zero-length bone, as LeapC gives it), ``pinch_strength`` 0;
  ``grab_strength`` ← ``grab_angle`` / π (LeapC's grab angle runs 0 open to π closed);
- a line that is no JSON, misses a field, or gives a hand that breaks the contract
  (``cbgo.wire.HAND``) is counted and skipped, never scored.

Poses (`GESTURES`): ``five`` → five, ``ok`` → pinch (the paper's pinch is an ok sign's shape:
``mmhgr.POSE_MAP``), ``thumb`` → thumbsup, ``ng`` ("no gesture") → none: right where the
frame is rejected (``none`` on top or top p < 0.5). `score` reads every hand of every readable
file alone, through the model's own classifier (the service's rule on hands that change pose is
not applied: these are held poses), and gives per pose the share right and what the others
were read as.

Examples::

    cbgo data fetch collaborice              # the train folder, into the cache
    cbgo data convert collaborice            # what the cached copy holds, file by file
    cbgo bench static --no-crossval --no-latency   # its scores among the bench's figures
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from cbgo import wire
from cbgo.config import cache_dir
from cbgo.errors import RejectedMessage
from cbgo.services.leap_bridge.leap_device import hand_from_leap
from cbgo.services.static_gesture.classifier import NONE, answers

GESTURES = {"five": "five", "ok": "pinch", "thumb": "thumbsup", "ng": NONE}
"""The set's pose files → cbgo's gesture (``none``: no gesture, right when rejected)."""
MM_PER_UNIT = 1000.0  # the recorder wrote LeapC's mm divided by 1000
PALM_WIDTH_MM = 80.0  # not recorded; an adult palm (the HGR loader stands in the same)
BONE_WIDTH_MM = 15.0  # not recorded; a finger's width (the HGR loader stands in the same)
_FINGERS = ("thumb", "index", "middle", "ring", "pinky")
_BONES = ("metacarpal", "proximal", "intermediate", "distal")
_LEAP = SimpleNamespace(HandType=SimpleNamespace(Left="left"))  # what hand_from_leap reads


def default_folder() -> Path:
    """The fetched copy: ``<cache>/collaborice`` (``cbgo data fetch collaborice``)."""
    return cache_dir() / "collaborice"


def palm_axes(q: Any) -> tuple[np.ndarray, np.ndarray]:
    """Returns (palm normal, hand direction) of a LeapC palm orientation ``(x, y, z, w)``.

    The quaternion turns the sensor's axes into the palm's basis ``{normal × direction,
    −normal, −direction}``, so the normal is minus its second column, the direction minus its
    third.

    Raises:
        ValueError: not four finite numbers, or all zero.
    """
    q = np.asarray(q, dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if q.shape != (4,) or not math.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"a palm orientation is a non-zero quaternion (x, y, z, w), got {q}")
    x, y, z, w = q / norm
    basis_y = np.array([2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)])
    basis_z = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    return -basis_y, -basis_z


def _vector(values: list[float]) -> SimpleNamespace:
    x, y, z = (MM_PER_UNIT * float(v) for v in values)
    return SimpleNamespace(x=x, y=y, z=z)


def _bone(bone: dict) -> SimpleNamespace:
    prev, nxt = bone["prev_joint"], bone["next_joint"]
    zero_length = math.dist(prev, nxt) * MM_PER_UNIT < 1e-3
    x, y, z, w = (float(c) for c in bone["rotation"])
    return SimpleNamespace(prev_joint=_vector(prev), next_joint=_vector(nxt),
                           width=0.0 if zero_length else BONE_WIDTH_MM,
                           rotation=SimpleNamespace(x=x, y=y, z=z, w=w))


def as_leap_hand(record: dict) -> SimpleNamespace:
    """Returns one recorded hand laid out as the bindings' ``leap.datatypes.Hand``.

    Raises:
        ValueError: a side other than left or right, or a zero palm orientation.
        KeyError, TypeError: a field missing or of another type.
    """
    side = str(record["hand_type"]).lower()
    if side not in ("left", "right"):
        raise ValueError(f"hand_type is left or right, got {record['hand_type']!r}")
    keypoints = record["hand_keypoints"]
    normal, direction = palm_axes(keypoints["palm_orientation"])

    def unit(v: np.ndarray) -> SimpleNamespace:
        return SimpleNamespace(x=float(v[0]), y=float(v[1]), z=float(v[2]))

    digits = [SimpleNamespace(**{b: _bone(keypoints["fingers"][f][b]) for b in _BONES})
              for f in _FINGERS]
    return SimpleNamespace(
        id=int(record["hand_id"]), type=side,
        confidence=float(record["confidence"]), digits=digits,
        palm=SimpleNamespace(position=_vector(keypoints["palm_position"]),
                             velocity=SimpleNamespace(x=0.0, y=0.0, z=0.0),
                             normal=unit(normal), direction=unit(direction),
                             width=PALM_WIDTH_MM),
        arm=SimpleNamespace(next_joint=_vector(keypoints["arm"]["next_joint"])),
        grab_strength=float(keypoints["grab_angle"]) / math.pi, pinch_strength=0.0)


def hands_of_line(line: str) -> list[dict]:
    """Returns the contract hands of one JSON line (`as_leap_hand`, then ``hand_from_leap``).

    Raises:
        ValueError: the line is no JSON frame, misses a field, or a hand breaks the contract.
    """
    try:
        frame = json.loads(line)
        hands = [hand_from_leap(as_leap_hand(h), _LEAP) for h in frame["hands"]]
        for hand in hands:
            wire.validate(hand, wire.HAND, "hands/frame")
    except (json.JSONDecodeError, KeyError, TypeError, ValueError, ZeroDivisionError,
            RejectedMessage) as e:
        raise ValueError(f"{type(e).__name__}: {e}") from None
    return hands


def read_file(path: Path) -> tuple[list[dict], int]:
    """Returns every valid hand of a pose file, in recording order, and the lines skipped."""
    hands, skipped = [], 0
    with open(path, encoding="utf-8") as lines:
        for line in lines:
            if not line.strip():
                continue
            try:
                hands += hands_of_line(line)
            except ValueError:
                skipped += 1
    return hands, skipped


def pose_files(folder: Path | None = None) -> list[tuple[str, str, Path]]:
    """Returns (person, pose, path) of each known pose file in a fetched copy, sorted."""
    folder = default_folder() if folder is None else Path(folder)
    if not folder.is_dir():
        return []
    return [(path.parent.name, path.stem, path) for path in sorted(folder.glob("*/*.txt"))
            if path.stem in GESTURES]


def score(classifier, folder: Path | None = None) -> dict | None:
    """Scores a `StaticClassifier` on every readable pose file; None when none is cached.

    Returns:
        ``{"files": [{person, pose, truth, hands, skipped, right, answers}], "gestures":
        {truth: {hands, right, answers}}}``; ``answers`` counts each frame's answer as a
        consumer reads it (``none`` when rejected).
    """
    files = pose_files(folder)
    if not files:
        return None
    rows, pooled = [], {}
    for person, pose, path in files:
        truth = GESTURES[pose]
        hands, skipped = read_file(path)
        answered = answers(classifier.names, classifier.classify_hands(hands)) if hands else []
        counts = Counter(str(a) for a in answered)
        rows.append({"person": person, "pose": pose, "truth": truth, "hands": len(hands),
                     "skipped": skipped, "right": counts[truth], "answers": dict(counts)})
        total = pooled.setdefault(truth, {"hands": 0, "right": 0, "answers": Counter()})
        total["hands"] += len(hands)
        total["right"] += counts[truth]
        total["answers"].update(counts)
    return {"files": rows, "gestures": {g: {**t, "answers": dict(t["answers"].most_common())}
                                        for g, t in pooled.items()}}


def _answers_text(counts: dict, hands: int) -> str:
    return ", ".join(f"{name} {n / hands:.1%}" for name, n in
                     sorted(counts.items(), key=lambda kv: -kv[1])) if hands else "no hands"


def print_scores(fig: dict | None, folder: Path | None = None) -> None:
    """Prints `score`'s figures, or one line saying how to fetch the set."""
    if fig is None:
        print(f"CollaborICE's LMC2 frames: not in {folder or default_folder()} (cbgo data fetch "
              "collaborice); skipped")
        return
    print("CollaborICE's LMC2 frames (LeapC, Gemini; people never seen; each frame alone; "
          "right: the pose's gesture with p ≥ 0.5, for ng rejected):")
    for row in fig["files"]:
        skipped = f", {row['skipped']} lines skipped" if row["skipped"] else ""
        share = row["right"] / row["hands"] if row["hands"] else float("nan")
        print(f"  person {row['person']} {row['pose']:6s} ({row['truth']:8s}) {row['hands']} "
              f"hands{skipped}: right {share:.1%}; read as "
              f"{_answers_text(row['answers'], row['hands'])}")
    for truth, t in fig["gestures"].items():
        print(f"  {truth}: {t['right']}/{t['hands']} right; read as "
              f"{_answers_text(t['answers'], t['hands'])}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``cbgo data convert collaborice [SRC]``."""
    parser.add_argument("src", nargs="?", type=Path, default=None,
                        help="a copy of the train folder [the cache's: cbgo data fetch "
                             "collaborice]")


def run(args: argparse.Namespace) -> int:
    """Prints what a fetched copy holds, file by file; 2 when it holds no pose file."""
    files = pose_files(args.src)
    if not files:
        print(f"no pose files in {args.src or default_folder()} (cbgo data fetch collaborice)")
        return 2
    for person, pose, path in files:
        hands, skipped = read_file(path)
        print(f"person {person} {pose} ({GESTURES[pose]}): {len(hands)} hands, {skipped} "
              f"lines skipped ({path})")
    print("scored by: cbgo bench static --no-crossval --no-latency")
    return 0
