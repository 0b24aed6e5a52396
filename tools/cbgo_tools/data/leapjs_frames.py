"""Leap Motion frames in LeapJS's JSON format (``{"data": [frame, ...]}``) as contract hands.

LeapJS (the Leap Motion JavaScript client, SDK v2..v4) and tools built on it (QuantumLeap's
recordings: the Guinevere sets, ``leapmotion-all``) write each frame as JSON. Every assumption
of the conversion, written down:

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

Used by dynamic-gesture's real-data benches (`cbgo_tools.data.leapjs`) and
static-gesture's (`cbgo_tools.data.guinevere`).
"""

from __future__ import annotations

import math
from collections import Counter

from cbgo.wire import BONE_TYPES, FINGER_TYPES, SCHEMA_VERSION

JOINTS = ("carpPosition", "mcpPosition", "pipPosition", "dipPosition", "btipPosition")
"""A pointable's joints, base to tip: the ends of its four bones."""


def vector(value) -> list[float]:
    """Returns a LeapJS 3-vector as 3 floats.

    Raises:
        ValueError: not 3 finite numbers.
    """
    out = [float(v) for v in value]
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise ValueError(f"expected 3 finite numbers, got {value!r}"[:100])
    return out


def _fingers(pointables: list[dict]) -> list[dict]:
    by_type = {int(p["type"]): p for p in pointables}
    fingers = []
    for index, ftype in enumerate(FINGER_TYPES):
        p = by_type[index]
        joints = [vector(p[k]) for k in JOINTS]
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
        "palm_position": vector(hand["palmPosition"]),
        "palm_velocity": vector(hand["palmVelocity"]),
        "palm_normal": vector(hand["palmNormal"]), "direction": vector(hand["direction"]),
        "wrist_position": vector(hand["wrist"]), "palm_width": float(hand["palmWidth"]),
        "grab_strength": min(max(float(hand["grabStrength"]), 0.0), 1.0),
        "pinch_strength": min(max(float(hand["pinchStrength"]), 0.0), 1.0),
        "fingers": _fingers(own)}


def to_frames(recording: dict, rejected: Counter | None = None) -> list[dict]:
    """Returns a parsed LeapJS recording (``{"data": [frame, ...]}``) as hands/frame messages.

    A hand that cannot be converted (a field missing or malformed, a finger without its
    pointable) is left out of its frame, each counted in ``rejected`` by reason when given: one
    bad hand does not cost a recording. A frame left with no hand although the sensor saw one
    is left out too (it would read as the hand gone), as is a frame without a usable timestamp.

    Raises:
        KeyError, TypeError: the recording has no ``data`` list.
    """
    stamped = [(t, f) for f in recording["data"] if (t := _timestamp(f, rejected)) is not None]
    t0 = stamped[0][0] if stamped else 0.0
    out = []
    for t, frame in stamped:
        seen = frame.get("hands") or []
        hands = []
        for hand in seen:
            try:
                hands.append(to_hand(hand, frame.get("pointables") or []))
            except (KeyError, ValueError, TypeError, AttributeError) as e:
                if rejected is not None:
                    rejected[f"hand: {type(e).__name__} {e}"[:80]] += 1
        if seen and not hands:
            continue
        out.append({"v": SCHEMA_VERSION, "ts": (t - t0) / 1e6,
                    "seq": len(out), "source": "replay", "device": "leapjs", "hands": hands})
    return out


def _timestamp(frame, rejected: Counter | None = None) -> float | None:
    """A frame's device time in µs, or None (counted) when it has none."""
    try:
        t = float(frame["timestamp"])
    except (KeyError, TypeError, ValueError):
        t = math.nan
    if math.isfinite(t):
        return t
    if rejected is not None:
        rejected["frame without a timestamp"] += 1
    return None
