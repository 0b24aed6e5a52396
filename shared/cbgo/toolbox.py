"""The paper's gesture toolbox's JSON hand recordings, as contract ``hands/frame`` messages.

`load_toolbox_json` converts a recording of imitrob/teleop_gesture_toolbox into contract
``hands/frame`` messages; its docstring says what that format is and how fields the JSON lacks
are filled in. (It lived in `cbgo.recording`, which still re-exports it.)
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from cbgo import keys, wire
from cbgo.errors import RecordingError, RejectedMessage

TOOLBOX_DEVICE = "toolbox-json"
_SIDE_KEYS = (("l", "left"), ("r", "right"), ("left", "left"), ("right", "right"))
PINCH_CLOSED_MM, PINCH_OPEN_MM = 20.0, 70.0  # thumb-index tip distance for pinch 1 and 0


class _FieldError(Exception):
    """A problem at a field of one frame; turned into RecordingError with the frame index."""

    def __init__(self, path: str, problem: str):
        super().__init__(f"{path}: {problem}" if path else problem)


def _number(value: Any, path: str) -> float:
    if type(value) not in (int, float) or not math.isfinite(value):
        raise _FieldError(path, f"expected a finite number, got {value!r}"[:120])
    return float(value)


def _vec3(value: Any, path: str) -> np.ndarray:
    if isinstance(value, dict) and all(k in value for k in "xyz"):
        value = [value["x"], value["y"], value["z"]]
    if not isinstance(value, list) or len(value) != 3:
        raise _FieldError(path, "expected a vector {x, y, z} or [x, y, z], got "
                                f"{value!r}"[:120])
    return np.array([_number(v, f"{path}[{i}]") for i, v in enumerate(value)])


def _optional(hand: dict, name: str, path: str, parse) -> Any:
    """Returns the parsed field, or None when it is absent or null (then it is derived)."""
    value = hand.get(name)
    return None if value is None else parse(value, f"{path}.{name}")


def _unit(v: np.ndarray | None) -> np.ndarray | None:
    if v is None:
        return None
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else None


def _quaternion(basis: Any, path: str) -> list[float] | None:
    """Returns [qx, qy, qz, qw] of a Leap bone basis (x, y, z axes), or None if unusable.

    Leap gives left hands a left-handed basis; flipping its x axis makes it a rotation and keeps
    the z axis, whose negative is the bone's direction (the contract's convention).
    """
    if not isinstance(basis, list) or len(basis) != 3:
        return None
    try:
        m = np.column_stack([_vec3(b, f"{path}[{i}]") for i, b in enumerate(basis)])
    except _FieldError:
        return None
    if np.linalg.det(m) < 0:
        m[:, 0] = -m[:, 0]
    if not np.allclose(m.T @ m, np.eye(3), atol=0.05):
        return None  # the toolbox's all-zero default basis, or a bad one
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i], q[j], q[k] = s / 4, (m[j, i] + m[i, j]) / s, (m[k, i] + m[i, k]) / s
    q = np.array(q) / np.linalg.norm(q)
    return [float(x) for x in q]


def _bones(finger: Any, path: str) -> list[dict]:
    bones = finger.get("bones") if isinstance(finger, dict) else finger
    if not isinstance(bones, list) or len(bones) != 4:
        raise _FieldError(path + ".bones", "expected 4 bones (metacarpal to distal)")
    out = []
    for btype, bone, i in zip(wire.BONE_TYPES, bones, range(4), strict=True):
        where = f"{path}.bones[{i}]"
        if not isinstance(bone, dict):
            raise _FieldError(where, "expected a bone object")
        entry = {"type": btype, "prev_joint": _vec3(bone.get("prev_joint"), where + ".prev_joint"),
                 "next_joint": _vec3(bone.get("next_joint"), where + ".next_joint"),
                 "width": _optional(bone, "width", where, _number)}
        rotation = _quaternion(bone.get("basis"), where + ".basis")
        if rotation is not None:
            entry["rotation"] = rotation
        out.append(entry)
    return out


def _estimates(fingers: list[list[dict]], side: str, direction: np.ndarray | None) -> dict:
    """Hand fields derived from the joints, for files that lack them (see load_toolbox_json)."""
    knuckle = {f: fingers[i][0]["next_joint"] for i, f in enumerate(wire.FINGER_TYPES)}
    wrist = np.mean([fingers[i][0]["prev_joint"] for i in range(1, 5)], axis=0)
    derived_direction = _unit(knuckle["middle"] - wrist)
    direction = direction if direction is not None else derived_direction
    across = knuckle["pinky"] - knuckle["index"]
    normal = None
    if direction is not None:
        normal = _unit(np.cross(direction, across) * (1.0 if side == "right" else -1.0))
    curls = []
    for i in range(1, 5):
        distal = _unit(fingers[i][3]["next_joint"] - fingers[i][3]["prev_joint"])
        if distal is not None and direction is not None:
            curls.append(math.acos(float(np.clip(np.dot(distal, direction), -1, 1))) / math.pi)
    pinch_mm = float(np.linalg.norm(fingers[0][3]["next_joint"] - fingers[1][3]["next_joint"]))
    pinch = (PINCH_OPEN_MM - pinch_mm) / (PINCH_OPEN_MM - PINCH_CLOSED_MM)
    return {
        "wrist_position": wrist, "direction": derived_direction, "palm_normal": normal,
        # four fingers side by side: the knuckles span three of the four finger widths
        "palm_width": float(np.linalg.norm(across)) * 4.0 / 3.0,
        "grab_strength": float(np.clip(np.mean(curls), 0.0, 1.0)) if curls else 0.0,
        "pinch_strength": float(np.clip(pinch, 0.0, 1.0)),
    }


def _side_of(hand: dict, default: str | None, path: str) -> str:
    side = hand.get("side")
    if side in ("left", "right"):
        return side
    if hand.get("is_left") is True:
        return "left"
    if hand.get("is_right") is True:
        return "right"
    if default is None:
        raise _FieldError(path, "cannot tell the side: expected side, is_left or is_right")
    return default


def _hand(hand: dict, side: str, path: str, index: int) -> dict:
    fingers_raw = hand.get("fingers")
    if not isinstance(fingers_raw, list) or len(fingers_raw) != 5:
        raise _FieldError(path + ".fingers", "expected 5 fingers (thumb to pinky)")
    fingers = [_bones(f, f"{path}.fingers[{i}]") for i, f in enumerate(fingers_raw)]
    palm = _vec3(hand.get("palm_position"), path + ".palm_position")
    given = {name: _optional(hand, name, path, _vec3)
             for name in ("palm_velocity", "palm_normal", "direction", "wrist_position")}
    given.update({name: _optional(hand, name, path, _number)
                  for name in ("palm_width", "grab_strength", "pinch_strength", "confidence")})
    given["direction"] = _unit(given["direction"])
    given["palm_normal"] = _unit(given["palm_normal"])
    derived = _estimates(fingers, side, given["direction"])
    out = {name: given[name] if given[name] is not None else derived[name] for name in derived}
    for name in ("direction", "palm_normal"):
        if out[name] is None:
            raise _FieldError(f"{path}.{name}", "missing, and the joints are too degenerate "
                                                "to derive it")
    hand_id = hand.get("id")
    return {
        "id": hand_id if type(hand_id) is int else index, "side": side,
        "confidence": 1.0 if given["confidence"] is None else given["confidence"],
        "palm_position": palm, "palm_velocity": given["palm_velocity"], **out,
        "fingers": [{"type": ftype, "bones": [{**b, "width": b["width"] or 0.0} for b in bones]}
                    for ftype, bones in zip(wire.FINGER_TYPES, fingers, strict=True)],
    }


def _frame_hands(frame: dict) -> list[dict]:
    found = []
    for key, side in _SIDE_KEYS:
        hand = frame.get(key)
        if hand is None:
            continue
        if not isinstance(hand, dict):
            raise _FieldError(key, "expected a hand object")
        if hand.get("visible", True):
            found.append((hand, _side_of(hand, side, key), key))
    listed = frame.get("hands")  # a list of hands; the toolbox itself stores a count here
    if isinstance(listed, list):
        for j, hand in enumerate(listed):
            if not isinstance(hand, dict):
                raise _FieldError(f"hands[{j}]", "expected a hand object")
            if hand.get("visible", True):
                found.append((hand, _side_of(hand, None, f"hands[{j}]"), f"hands[{j}]"))
    return [_hand(hand, side, path, i) for i, (hand, side, path) in enumerate(found)]


def _frame_time(frame: dict) -> float:
    sec = frame.get("sec", frame.get("secs"))
    if sec is not None:
        nanosec = frame.get("nanosec", frame.get("nsecs")) or 0
        t = _number(sec, "sec") + _number(nanosec, "nanosec") * 1e-9
    elif frame.get("ts") is not None:
        t = _number(frame["ts"], "ts")
    else:
        raise _FieldError("sec", "missing timestamp (expected sec and nanosec, or ts)")
    if t < 0:
        raise _FieldError("sec", f"expected a timestamp >= 0, got {t}")
    return t


def _fill_velocities(frames: list[tuple[float, list[dict]]]) -> None:
    """Finite differences of palm positions (mm/s) for hands without a palm velocity."""
    def same_side(i: int, side: str) -> dict | None:
        if 0 <= i < len(frames):
            return next((h for h in frames[i][1] if h["side"] == side), None)
        return None

    for i, (t, hands) in enumerate(frames):
        for hand in hands:
            if hand["palm_velocity"] is not None:
                continue
            velocity = np.zeros(3)
            for j in (i - 1, i + 1):
                other = same_side(j, hand["side"])
                dt = (t - frames[j][0]) if other is not None else 0.0
                if other is not None and dt != 0:
                    velocity = (hand["palm_position"] - other["palm_position"]) / dt
                    break
            hand["palm_velocity"] = velocity


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return [float(x) for x in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def load_toolbox_json(path: str | Path) -> list[tuple[float, dict]]:
    """Returns the frames of a gesture-toolbox JSON recording as contract hand frames.

    The format is the one imitrob/teleop_gesture_toolbox writes with ``json.dumps(frames,
    cls=FrameEncoder)`` (``gesture_detector/utils/saving.py``): a JSON list of ``Frame``
    objects' ``__dict__`` (``hand_processing/frame_lib.py``). A frame has ``seq``, ``sec`` and
    ``nanosec`` (``secs``/``nsecs`` in ROS 1 files), ``fps``, ``hands`` (a count), ``l`` and
    ``r`` (one hand each, ``visible`` false when absent) and ``leapgestures``. A hand has
    ``id``, ``is_left``/``is_right``, ``confidence``, ``grab_strength``, ``pinch_strength``,
    ``palm_position``, ``palm_velocity``, ``palm_normal``, ``direction``, ``wrist_position``,
    ``palm_width`` and ``fingers``: 5 (thumb to pinky) of ``{"bones": [4 bones]}``, each bone
    with ``prev_joint``, ``next_joint``, ``width``, ``basis`` (3 axis vectors) and more.
    Vectors are ``{"x", "y", "z"}`` objects in the Leap frame (mm). Also accepted: ``left``/
    ``right`` instead of ``l``/``r``, a ``hands`` list of hands with ``side`` (or
    ``is_left``/``is_right``), ``[x, y, z]`` lists for vectors, ``ts`` (s) for the time.

    Mapping: ``source`` "replay", ``device`` "toolbox-json", ``seq`` the frame's seq (else its
    index), ``ts`` the frame time ``sec + nanosec * 1e-9`` as the file has it (the Leap
    service's clock, not the Unix epoch). Bones keep their joints, so the thumb's metacarpal is
    zero-length when the sensor made it so; a bone's ``basis`` becomes its ``rotation``
    (quaternion; the x axis of a left-handed basis is flipped). Fields the JSON lacks or has as
    null are filled in, never invented silently:

    - ``palm_velocity``: finite difference of the palm positions of the same side in the
      previous (else next) frame, mm/s; zeros for a hand seen in one frame only;
    - ``confidence``: 1.0; bone ``width``: 0.0 (unknown);
    - ``wrist_position``: the mean of the index-to-pinky metacarpal bases;
    - ``direction``: wrist to middle knuckle; ``palm_normal``: direction x (index to pinky
      knuckle), negated for left hands;
    - ``palm_width``: 4/3 of the index-to-pinky knuckle distance (four finger widths);
    - ``grab_strength``: the mean over the four fingers of the angle between the distal bone and
      the hand direction, divided by 180 degrees (straight 0, folded back 1);
    - ``pinch_strength``: 1 at thumb-index tip distance <= 20 mm, 0 at >= 70 mm, linear between.

    Args:
        path: the JSON file.

    Returns:
        (frame time in seconds, hands/frame message) per frame, in file order.

    Raises:
        RecordingError: unreadable file, not JSON, not a list, or a malformed frame (naming the
            frame index and the field).
    """
    path = Path(path)
    try:
        raw = json.loads(path.read_text())
    except OSError as e:
        raise RecordingError(f"cannot read toolbox recording {path}: {e.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise RecordingError(f"{path} is not JSON: {e}") from None
    if not isinstance(raw, list):
        raise RecordingError(f"{path}: expected a JSON list of frames, got "
                             f"{type(raw).__name__}")
    frames = []
    for i, frame in enumerate(raw):
        try:
            if not isinstance(frame, dict):
                raise _FieldError("", "expected a frame object")
            frames.append((_frame_time(frame), _frame_hands(frame)))
        except _FieldError as e:
            raise RecordingError(f"{path}: frame {i}: {e}") from None
    _fill_velocities(frames)
    out = []
    for i, ((t, hands), frame) in enumerate(zip(frames, raw, strict=True)):
        seq = frame.get("seq")
        message = keys.HANDS_FRAME.message(ts=t,
                   seq=seq if type(seq) is int and seq >= 0 else i,
                   source="replay", device=TOOLBOX_DEVICE, hands=_plain(hands))
        try:
            wire.validate(message, wire.HANDS_FRAME, "hands/frame")
        except RejectedMessage as e:
            raise RecordingError(f"{path}: frame {i}: {e}") from None
        out.append((t, message))
    return out
