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

**Left hands.** Both sets above are right hands. The same repository's history holds another
LeapJS set, ``leapmotion-all`` (commit ``bec964af``, folder
``backend/src/datasets/dynamic/leapmotion-all``; no licence file either), in which 16 people
each made a "previous" and a "next" gesture of their own choosing, some with the left hand.
`LEFT_HAND_SWIPES` names its ten clean left-hand swipes (8 people) and the direction each
palm goes; ``python -m cbgo.services.dynamic_gesture.leapjs left-hands SRC DST`` writes them
as a set of the layout above (left-hand frames only), for ``cbgo bench dynamic --real DST``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from cbgo.wire import BONE_TYPES, FINGER_TYPES, SCHEMA_VERSION

LEFT_HAND_SWIPES = {
    "precedent/participant-12-12": "swipe_right", "precedent/participant-14-10": "swipe_right",
    "precedent/participant-2-6": "swipe_right", "precedent/participant-7-9": "swipe_right",
    "precedent/participant-5-1": "swipe_left", "suivant/participant-11-10": "swipe_left",
    "suivant/participant-12-14": "swipe_left", "suivant/participant-13-1": "swipe_left",
    "suivant/participant-19-8": "swipe_left", "suivant/participant-7-18": "swipe_left"}
"""The ``leapmotion-all`` recordings whose left hand swipes, and where its palm goes.

Its own labels are commands ("precedent", "suivant": previous, next) whose gesture each person
chose, so the direction is read from the left hand's palm path: from first to last frame it
goes 187–438 mm along x, and its range along x (222–447 mm) is wider than along y or z (at
most 0.8 of it). Left out: the left-hand recordings that go mostly along z, move under 100 mm,
last under 0.3 s, or jump by 600 mm between two hand ids."""

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


def left_hand_only(recording: dict) -> dict:
    """Returns a parsed LeapJS recording with its right hands (and their fingers) removed."""
    frames = []
    for frame in recording["data"]:
        hands = [h for h in frame["hands"] if h.get("type") == "left"]
        ids = {h["id"] for h in hands}
        frames.append({**frame, "hands": hands,
                       "pointables": [p for p in frame.get("pointables", [])
                                      if p.get("handId") in ids]})
    return {**recording, "data": frames}


def arrange_left_hands(src: Path, dst: Path) -> int:
    """Writes `LEFT_HAND_SWIPES` of a ``leapmotion-all`` folder as a set `read_set` reads.

    ``dst/participant-P/swipe_X-T.json``, left-hand frames only. Returns how many it wrote.

    Raises:
        OSError: a recording of `LEFT_HAND_SWIPES` is not under `src`, or unreadable.
        ValueError: a recording is not JSON.
    """
    for name, gesture in LEFT_HAND_SWIPES.items():
        stem = Path(name).name  # participant-P-T
        person, _, take = stem.rpartition("-")
        out = Path(dst) / person / f"{gesture}-{take}.json"
        out.parent.mkdir(parents=True, exist_ok=True)
        recording = json.loads((Path(src) / f"{name}.json").read_text())
        out.write_text(json.dumps(left_hand_only(recording)))
    return len(LEFT_HAND_SWIPES)


def main(argv: list[str] | None = None) -> int:
    """``left-hands SRC DST``: see the module docstring."""
    import argparse  # noqa: PLC0415

    parser = argparse.ArgumentParser(
        prog="python -m cbgo.services.dynamic_gesture.leapjs",
        description="Real Leap Motion recordings (LeapJS frames) for the dynamic-gesture bench.")
    sub = parser.add_subparsers(dest="command", required=True)
    left = sub.add_parser("left-hands", help="write the left-hand swipes of leapmotion-all "
                                             "as a set for `cbgo bench dynamic --real`")
    left.add_argument("src", type=Path, help="the leapmotion-all folder (precedent/, suivant/)")
    left.add_argument("dst", type=Path, nargs="?",
                      default=Path.home() / ".cache" / "cbgo" / "leapmotion-left",
                      help="where to write it [~/.cache/cbgo/leapmotion-left]")
    args = parser.parse_args(argv)
    try:
        count = arrange_left_hands(args.src, args.dst)
    except (OSError, ValueError) as exc:  # a recording missing, unreadable or not JSON
        print(f"error: {exc}")
        return 2
    print(f"wrote {count} left-hand swipes under {args.dst}; "
          f"cbgo bench dynamic --real {args.dst} --per-class 0")
    return 0


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


if __name__ == "__main__":
    raise SystemExit(main())
