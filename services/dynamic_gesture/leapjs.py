"""Real Leap Motion recordings in LeapJS's JSON frame format (the Guinevere set) as hand frames.

A second real data set beside SHREC'17 (`shrec`): a different sensor (a Leap Motion
Controller, LeapJS / SDK v2-v4 frames at 100-120 Hz) and different people. The **Guinevere**
set (UCLouvain; 4 people, 23 dynamic gestures, 4 takes each; a public copy in the GitHub
repository ``sluyters/QuantumLeap``, folder ``backend/src/datasets/dynamic/guinevere``) holds
swipes in the four directions with the palm or the index finger, palm rotations and hand
gestures that are no swipe (tap, pinch, thumbs, hand opening). It has no licence file, so
nothing of it is committed: copy that folder into a cache (``~/.cache/cbgo/guinevere``) and
point ``cbgo bench dynamic --real DIR`` at it. It is used for **evaluation only**: nothing
is fitted, tuned or selected on it.

Conversion (every assumption written down):

- **Axes and units.** LeapJS positions are mm in the device frame: +x right, +y up (away from
  the sensor), +z towards the user. That is the contract's Leap frame, so nothing is moved or
  turned.
- **Time.** ``timestamp`` is the device clock in µs; ``ts`` is it in seconds from the first
  frame.
- **Hands.** ``palmPosition``, ``palmVelocity``, ``palmNormal``, ``direction``, ``wrist``,
  ``palmWidth``, ``grabStrength``, ``pinchStrength``, ``confidence``, ``type`` (the side) and
  ``id`` map one to one. Bones come from the hand's pointables (``handId``, ``type`` 0 thumb
  .. 4 pinky): metacarpal ``carpPosition`` → ``mcpPosition``, proximal → ``pipPosition``,
  intermediate → ``dipPosition``, distal → ``btipPosition``, each ``width`` wide (the thumb's
  metacarpal has zero length, as the SDK reports it).
- **Labels.** A file ``NAME-TAKE.json`` in a person's folder; ``NAME`` may carry a variant
  after ``#`` (``swipe_left#palm``, ``swipe_up#index``). The swipes map to ours; ``turn_*``
  (a palm turned like a key) is left out of the swipe scores, as SHREC'17's rotations are;
  every other gesture is a hard "no gesture" case.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from cbgo.wire import BONE_TYPES, FINGER_TYPES, SCHEMA_VERSION

SWIPES = ("swipe_right", "swipe_left", "swipe_up", "swipe_down")
NOT_SCORED = ("turn_clockwise", "turn_counter_clockwise")
# Moves along one direction with another hand shape (an opening hand) or a curved path: no
# swipe of the set, yet swipe-shaped, so they are reported apart (and kept out of streams).
SWIPE_LIKE = ("open_hand_", "C_swipe_")
JOINTS = ("carpPosition", "mcpPosition", "pipPosition", "dipPosition", "btipPosition")


@dataclass(frozen=True)
class Recording:
    """One recorded gesture.

    Attributes:
        gesture: the data set's gesture name without its variant (``swipe_left``).
        variant: what follows ``#`` in the file name ("" if nothing).
        person: the person's folder name.
        take: the take number.
        path: the JSON file.
    """

    gesture: str
    variant: str
    person: str
    take: int
    path: Path

    def frames(self) -> list[dict]:
        """Returns the recording as ``cbgo/hands/frame`` messages (see the module docstring)."""
        return to_frames(json.loads(self.path.read_text()))


def read_set(root: Path) -> list[Recording]:
    """Returns every recording under `root` (a folder of person folders, at any depth).

    Raises:
        FileNotFoundError: no recording there.
    """
    out = []
    for path in sorted(Path(root).rglob("*-*.json")):
        stem, _, take = path.stem.rpartition("-")
        if not take.isdigit():
            continue
        gesture, _, variant = stem.partition("#")
        out.append(Recording(gesture, variant, path.parent.name, int(take), path))
    if not out:
        raise FileNotFoundError(
            f"no LeapJS recordings (NAME-TAKE.json) under {root}: copy the Guinevere folder of "
            f"github.com/sluyters/QuantumLeap (backend/src/datasets/dynamic/guinevere) there")
    return out


def _vec(value) -> list[float]:
    out = [float(v) for v in value]
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise ValueError(f"expected 3 finite numbers, got {value!r}"[:100])
    return out


def _fingers(pointables: list[dict]) -> list[dict]:
    by_type = {int(p["type"]): p for p in pointables}
    fingers = []
    for index, ftype in enumerate(FINGER_TYPES):
        p = by_type[index]
        joints = [_vec(p[k]) for k in JOINTS]
        width = max(float(p.get("width", 15.0)), 1.0)
        fingers.append({"type": ftype, "bones": [
            {"type": btype, "prev_joint": joints[b], "next_joint": joints[b + 1],
             "width": width} for b, btype in enumerate(BONE_TYPES)]})
    return fingers


def to_hand(hand: dict, pointables: list[dict]) -> dict:
    """Returns one contract hand from a LeapJS hand and its pointables.

    Raises:
        KeyError, ValueError: a field is missing or malformed.
    """
    own = [p for p in pointables if p.get("handId") == hand["id"]]
    return {
        "id": int(hand["id"]),
        "side": "left" if hand["type"] == "left" else "right",
        "confidence": min(max(float(hand.get("confidence", 1.0)), 0.0), 1.0),
        "palm_position": _vec(hand["palmPosition"]),
        "palm_velocity": _vec(hand["palmVelocity"]),
        "palm_normal": _vec(hand["palmNormal"]), "direction": _vec(hand["direction"]),
        "wrist_position": _vec(hand["wrist"]), "palm_width": float(hand["palmWidth"]),
        "grab_strength": min(max(float(hand["grabStrength"]), 0.0), 1.0),
        "pinch_strength": min(max(float(hand["pinchStrength"]), 0.0), 1.0),
        "fingers": _fingers(own)}


def to_frames(recording: dict) -> list[dict]:
    """Returns a parsed LeapJS recording (``{"data": [frame, ...]}``) as hands/frame messages."""
    frames = recording["data"]
    t0 = float(frames[0]["timestamp"]) if frames else 0.0
    out = []
    for i, frame in enumerate(frames):
        hands = [to_hand(h, frame.get("pointables", [])) for h in frame["hands"]]
        out.append({"v": SCHEMA_VERSION, "ts": (float(frame["timestamp"]) - t0) / 1e6,
                    "seq": i, "source": "replay", "device": "leapjs", "hands": hands})
    return out
