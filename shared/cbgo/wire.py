"""The wire format: msgpack encode/decode and one schema per message of docs/protocol.md.

Rules every receiver applies (the contract):
- a payload is one msgpack map with string keys, at most `max_bytes` long;
- every required field is present with the right type; numbers are finite (no NaN/inf) and in
  range; enumerations hold one of their listed values;
- fields a schema does not know are tolerated and passed on untouched;
- a message that breaks a rule raises `RejectedMessage` naming the field (``hands[0].
  palm_position[2]``) and what was expected, so the sender can fix it.

Schemas are plain data (`Obj`, `ListOf`, `Num`, ...: the nodes of `cbgo.spec`) so
`docs/protocol.md`, the validators and the CLI all read the same definition. `SCHEMAS` maps
each topic suffix to its schema; queries have one schema for the query payload and one for the
reply (`QUERY_SCHEMAS`, `REPLY_SCHEMAS`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import msgpack
import numpy as np

from cbgo.errors import RejectedMessage
from cbgo.spec import (  # the schema nodes, used here and read through `wire` by many modules
    AnyValue,
    Bool,
    Bytes,
    Int,
    ListOf,
    MapOf,
    Nullable,
    Num,
    Obj,
    Spec,
    Str,
    Vec,
    show_value,
)

SCHEMA_VERSION = 1
DEFAULT_MAX_BYTES = 1 << 20  # 1 MiB: a hand frame is ~4 KB, a scene a few KB
MAX_BYTES_RENDER = 32 << 20  # a PNG render reply may be several MB

# The no-gesture class: a classifier's "nothing I know" (relaxed and transition poses, a
# preparation or return move). The contract: "probs include a no-gesture class where the model
# has one"; it never triggers and is not in g. NO_GESTURE_NAMES also accepts an older spelling.
NO_GESTURE = "none"
NO_GESTURE_NAMES = (NO_GESTURE, "no_gesture")
STATIC_GESTURES = ("grab", "pinch", "point", "two", "three", "four", "five", "thumbsup")
DYNAMIC_GESTURES = ("swipe_up", "swipe_down", "swipe_left", "swipe_right", "rotate")
PAPER_GESTURES = (
    "swipe_up", "swipe_left", "swipe_down", "swipe_right", "five", "grab", "thumbsup", "rotate",
    "point",
)
OBJECT_TYPES = ("cup", "drawer", "box")
ACTIONS = (
    "move_up", "move_down", "move_left", "move_right", "put_into", "put_on", "pour", "pick_up",
    "place", "open", "close",
)
FINGER_TYPES = ("thumb", "index", "middle", "ring", "pinky")
BONE_TYPES = ("metacarpal", "proximal", "intermediate", "distal")
PROB_SUM_TOLERANCE = 1e-3  # float32 probabilities summed in float64
REPLAYED = "replayed"
"""The optional common field (``true``) of a message from a recording (`cbgo replay`), and of
what the services derive from recorded hands; a planner does not act on it
(docs/protocol.md, "Common fields")."""


# --------------------------------------------------------------------------- rules


def _names_probs(value: dict, sums_to_one: bool) -> None:
    names, probs = value["names"], value["probs"]
    if len(names) != len(probs):
        raise RejectedMessage(
            f"expected as many probs as names, got {len(probs)} probs for {len(names)} names",
            "probs")
    if len(set(names)) != len(names):
        raise RejectedMessage("expected unique names, got duplicates", "names")
    if sums_to_one and abs(sum(probs) - 1.0) > PROB_SUM_TOLERANCE:
        raise RejectedMessage(f"expected probs summing to 1, got sum {sum(probs):.6f}", "probs")


def _probs_sum_to_one(value: dict) -> None:
    _names_probs(value, sums_to_one=True)


def _probs_paired(value: dict) -> None:
    _names_probs(value, sums_to_one=False)


def _ordered_types(key: str, types: tuple[str, ...]) -> Callable[[dict], None]:
    def rule(value: dict) -> None:
        got = tuple(item["type"] for item in value[key])
        if got != types:
            raise RejectedMessage(
                f"expected types in the order {list(types)}, got {list(got)}", key)
    return rule


def _window_ordered(value: dict) -> None:
    start, end = value["window"]
    if end < start:
        raise RejectedMessage(f"expected t_start <= t_end, got [{start}, {end}]", "window")


def _trigger_names_gesture(value: dict) -> None:
    if value["kind"] == "trigger" and "gesture" not in value:
        raise RejectedMessage("missing required field for kind 'trigger' (expected a non-empty "
                              "string)", "gesture")


def _ended_after_started(value: dict) -> None:
    if value["ended"] < value["started"]:
        raise RejectedMessage(f"expected ended >= started, got {value['ended']} < "
                              f"{value['started']}", "ended")


def _unique_object_names(value: dict) -> None:
    names = [o["name"] for o in value["objects"]]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise RejectedMessage(f"expected unique object names, got duplicates {dup}", "objects")


def _error_when_not_ok(value: dict) -> None:
    error = value.get("error")
    if not value["ok"] and not (isinstance(error, str) and error.strip()):
        raise RejectedMessage("expected a non-empty error reason when ok is false", "error")


def _nonzero_quaternion(value: dict) -> None:
    if "rotation" in value and sum(q * q for q in value["rotation"]) < 1e-12:
        raise RejectedMessage("expected a non-zero quaternion [qx, qy, qz, qw]", "rotation")


# --------------------------------------------------------------------------- schemas

V = Int(lo=1)
TS = Num(lo=0.0)
SEQ = Int(lo=0)
NAME = Str()
POS = Vec(3)
PROB = Num(0.0, 1.0)
MM = Num(lo=0.0)
PARAM_VALUE = Nullable(AnyValue())


class _Params(Spec):
    """Metric parameters: a map of names to finite numbers, strings, bools, null or lists."""

    description = "a map of parameter names to numbers, strings, booleans or null"

    def check(self, value: Any, path: str) -> None:
        """Rejects non-maps and non-finite numbers anywhere inside."""
        if not isinstance(value, dict):
            self.fail(value, path)
        for k, v in value.items():
            if type(k) is not str or not k:
                self.fail(k, path, "non-empty string keys")
            _finite_everywhere(v, f"{path}.{k}")


MAX_PARAM_DEPTH = 8  # parameters are flat in practice; deep nesting is an attack or a bug


def _finite_everywhere(value: Any, path: str, depth: int = 0) -> None:
    if type(value) is float and not math.isfinite(value):
        raise RejectedMessage(f"expected a finite number, got {show_value(value)}", path)
    if isinstance(value, (list, dict)) and depth >= MAX_PARAM_DEPTH:
        raise RejectedMessage(f"expected at most {MAX_PARAM_DEPTH} levels of nesting", path)
    if isinstance(value, list):
        for i, v in enumerate(value):
            _finite_everywhere(v, f"{path}[{i}]", depth + 1)
    elif isinstance(value, dict):
        for k, v in value.items():
            _finite_everywhere(v, f"{path}.{k}", depth + 1)


PARAMS = _Params()

BONE = Obj(
    {"type": Str(BONE_TYPES), "prev_joint": POS, "next_joint": POS, "width": MM},
    optional={"rotation": Vec(4)},
    rules=(_nonzero_quaternion,),
)
FINGER = Obj(
    {"type": Str(FINGER_TYPES), "bones": ListOf(BONE, 4, 4)},
    rules=(_ordered_types("bones", BONE_TYPES),),
)
HAND = Obj(
    {
        "id": Int(), "side": Str(("left", "right")), "confidence": PROB,
        "palm_position": POS, "palm_velocity": POS, "palm_normal": POS, "direction": POS,
        "wrist_position": POS, "palm_width": MM, "grab_strength": PROB, "pinch_strength": PROB,
        "fingers": ListOf(FINGER, 5, 5),
    },
    rules=(_ordered_types("fingers", FINGER_TYPES),),
)
HANDS_FRAME = Obj(
    {
        "v": V, "ts": TS, "seq": SEQ, "source": Str(("leap", "replay", "simulated")),
        "device": Str(nonempty=False), "hands": ListOf(HAND, 0, 16),
    },
    optional={"to_base": Vec(16)},
)
GAZE = Obj({"v": V, "ts": TS, "point": POS,
            "source": Str(("eyetracker", "simulated", "pointing"))})
USER = Obj({"v": V, "ts": TS, "user": NAME})
PREVIEW_LANDMARKS = 21  # MediaPipe's hand landmarks: wrist, then four per finger, thumb first
CAMERA_PREVIEW = Obj({
    "v": V, "ts": TS, "seq": SEQ, "width": Int(lo=1), "height": Int(lo=1), "jpeg": Bytes(),
    "hands": ListOf(Obj({"side": Str(("left", "right")),
                         "points": ListOf(Vec(2), PREVIEW_LANDMARKS, PREVIEW_LANDMARKS)}), 0, 16),
})

GESTURE_FIELDS: dict[str, Spec] = {
    "v": V, "ts": TS, "seq": SEQ, "hand_id": Int(), "side": Str(("left", "right")),
    "names": ListOf(NAME, 1), "probs": ListOf(PROB, 1), "model": Str(nonempty=False),
}
GESTURES_STATIC = Obj(GESTURE_FIELDS, rules=(_probs_sum_to_one,))
GESTURES_DYNAMIC = Obj({**GESTURE_FIELDS, "window": Vec(2)}, optional={"final": Bool()},
                       rules=(_probs_sum_to_one, _window_ordered))

EPISODE_EVENT = Obj(
    {"v": V, "ts": TS, "episode": NAME, "kind": Str(("start", "end", "trigger"))},
    optional={"gesture": NAME, "prob": PROB},
    rules=(_trigger_names_gesture,),
)
GESTURE_VECTOR = Obj({"names": ListOf(NAME), "probs": ListOf(PROB)}, rules=(_probs_paired,))
TRIGGER = Obj({"gesture": NAME, "ts": TS, "prob": PROB})
EPISODE_SUMMARY = Obj(
    {
        "v": V, "ts": TS, "episode": NAME, "user": NAME, "started": TS, "ended": TS,
        "gestures": GESTURE_VECTOR, "triggers": ListOf(TRIGGER), "params": PARAMS,
        "focus": Nullable(POS), "focus_source": Nullable(Str(("gaze", "pointing"))),
    },
    rules=(_ended_after_started,),
)

SCENE_OBJECT = Obj(
    {"name": NAME, "type": Str(OBJECT_TYPES), "position": POS, "size": Num(lo=0.0)},
    optional={
        "full": Bool(), "open": Bool(), "opening": PROB, "on": Nullable(NAME),
        "inside": Nullable(NAME), "contains": ListOf(NAME),
    },
)
ROBOT = Obj({"tcp": POS, "gripper_open": Bool(), "holding": Nullable(NAME)})
SCENE_BODY = Obj({"objects": ListOf(SCENE_OBJECT, 0, 256), "robot": ROBOT},
                 rules=(_unique_object_names,))
SCENE_STATE = Obj({"v": V, "ts": TS, "seq": SEQ, **SCENE_BODY.fields},
                  rules=SCENE_BODY.rules)

INTENT_INFER_QUERY = Obj(
    {"v": V, "gestures": GESTURE_VECTOR, "scene": SCENE_BODY, "focus": Nullable(POS),
     "user": NAME},
    optional={"params": PARAMS, "model": NAME},
)
INTENT = Obj({
    "v": V, "ts": TS, "episode": Nullable(NAME), "action": Nullable(NAME),
    "object": Nullable(NAME), "params": PARAMS, "p_action": MapOf(PROB),
    "p_object": MapOf(PROB), "confidence": PROB,
    "status": Str(("accepted", "low_confidence", "infeasible")), "reason": Str(nonempty=False),
    "model": Str(nonempty=False),
}, optional={"clarification": NAME})
INTENT_FEEDBACK = Obj({"v": V, "ts": TS, "episode": Nullable(NAME), "user": NAME,
                       "action": NAME, "object": Nullable(NAME)})
CLARIFY_STATES = ("open", "confirmed", "expired", "cancelled")
CLARIFY_ANSWERS = ("confirm", "next", "previous", "cancel")
MAX_CANDIDATES = 8


def _highlight_is_a_candidate(value: dict) -> None:
    if value["highlighted"] >= len(value["candidates"]):
        raise RejectedMessage(f"expected the index of a candidate (0-"
                              f"{len(value['candidates']) - 1}), got {value['highlighted']}",
                              "highlighted")


CANDIDATE = Obj({"action": Str(ACTIONS), "object": Nullable(NAME), "p": PROB})
INTENT_CLARIFY = Obj({
    "v": V, "ts": TS, "id": NAME, "episode": Nullable(NAME), "user": NAME,
    "state": Str(CLARIFY_STATES), "candidates": ListOf(CANDIDATE, 1, MAX_CANDIDATES),
    "highlighted": Int(lo=0), "expires": TS, "reason": Str(nonempty=False),
}, rules=(_highlight_is_a_candidate,))
INTENT_ANSWER = Obj({"v": V, "ts": TS, "id": NAME, "user": NAME,
                     "answer": Str(CLARIFY_ANSWERS)}, optional={"choice": Int(lo=0)})

ROBOT_ACT_QUERY = Obj({"v": V, "action": NAME, "object": Nullable(NAME), "params": PARAMS})
ROBOT_ACT_REPLY = Obj(
    {"v": V, "ok": Bool(), "error": Nullable(Str(nonempty=False)), "duration_s": Num(lo=0.0),
     "scene": Nullable(SCENE_STATE)},
    rules=(_error_when_not_ok,),
)
ROBOT_STATE = Obj({
    "v": V, "ts": TS, "seq": SEQ, "joints": Vec(7), "gripper_width": Num(lo=0.0),
    "tcp": POS, "moving": Bool(), "action": Nullable(NAME),
})

RESET_OBJECT = SCENE_OBJECT
RESET_ROBOT = Obj({}, optional={"tcp": POS, "gripper_open": Bool(),
                                "holding": Nullable(NAME)})
SIM_RESET_QUERY = Obj(
    {"v": V},
    optional={"seed": Int(lo=0), "scene": Obj({"objects": ListOf(RESET_OBJECT, 0, 256)},
                                              optional={"robot": RESET_ROBOT},
                                              rules=(_unique_object_names,))},
)
SIM_RESET_REPLY = Obj({"v": V, "ok": Bool(), "error": Nullable(Str(nonempty=False)),
                       "scene": Nullable(SCENE_STATE)}, rules=(_error_when_not_ok,))
SIM_RENDER_QUERY = Obj({"v": V}, optional={"camera": NAME, "width": Int(16, 4096),
                                            "height": Int(16, 4096)})
SIM_RENDER_REPLY = Obj({"v": V, "ok": Bool(), "error": Nullable(Str(nonempty=False))},
                       optional={"png": Bytes()}, rules=(_error_when_not_ok,))

RANGE = ListOf(Num(), 2, 2)
SIZE_RANGE = Obj({"min": Num(lo=0.0), "max": Num(lo=0.0), "default": Num(lo=0.0)})
WORKSPACE = Obj({
    "grid": Obj({"shape": ListOf(Int(lo=1), 3, 3), "origin": POS, "step": POS}),
    "columns_x": ListOf(Num(), 1), "columns_y": ListOf(Num(), 1), "levels_z": ListOf(Num(), 1),
    "table_area": Obj({"x": RANGE, "y": RANGE}),
    "sizes": MapOf(SIZE_RANGE), "drawer_tray_offset": Num(lo=0.0),
    "drawer_capacity": Int(lo=0), "max_stack": Int(lo=1),
}, optional={"min_reach": Num(lo=0.0), "drawer_opens_away_below_x": Num(),
             "drawer_handle": Obj({"travel_per_size": Num(lo=0.0), "out": Num(lo=0.0)})})
SIM_INFO_QUERY = Obj({"v": V})
SIM_INFO_REPLY = Obj({"v": V, "ok": Bool(), "error": Nullable(Str(nonempty=False)),
                      "robot": NAME, "workspace": Nullable(WORKSPACE)},
                     rules=(_error_when_not_ok,))

PLAN_STEP = Obj({"action": NAME, "object": Nullable(NAME), "params": PARAMS,
                 "state": Str(("pending", "running", "done", "failed"))})
PLAN_STATUS = Obj({
    "v": V, "ts": TS, "intent": INTENT, "sequence": ListOf(PLAN_STEP),
    "state": Str(("running", "success", "failure")), "tree": Str(nonempty=False),
    "error": Nullable(Str(nonempty=False)),
})

COUNTERS = Obj({"received": Int(lo=0), "published": Int(lo=0), "rejected": Int(lo=0),
                "errors": Int(lo=0)})
SERVICE_STATUS = Obj({
    "v": V, "ts": TS, "name": NAME, "version": NAME, "pid": Int(lo=0), "host": NAME,
    "uptime_s": Num(lo=0.0), "config": MapOf(AnyValue()), "counters": COUNTERS,
    "last_error": Nullable(MapOf(AnyValue())),
})

# robot/stop: "any message stops robot motion", so it has no schema and any payload counts.
ANY_PAYLOAD = frozenset({"robot/stop"})
SCHEMAS: dict[str, Spec | None] = {
    "hands/frame": HANDS_FRAME, "gaze": GAZE, "camera/preview": CAMERA_PREVIEW, "user": USER,
    "gestures/static": GESTURES_STATIC, "gestures/dynamic": GESTURES_DYNAMIC,
    "episode/event": EPISODE_EVENT, "episode/summary": EPISODE_SUMMARY,
    "scene/state": SCENE_STATE, "intent": INTENT, "intent/feedback": INTENT_FEEDBACK,
    "intent/clarify": INTENT_CLARIFY, "intent/answer": INTENT_ANSWER,
    "robot/state": ROBOT_STATE, "robot/stop": None, "plan/status": PLAN_STATUS,
}
QUERY_SCHEMAS: dict[str, Spec] = {
    "intent/infer": INTENT_INFER_QUERY, "robot/act": ROBOT_ACT_QUERY,
    "sim/reset": SIM_RESET_QUERY, "sim/render": SIM_RENDER_QUERY, "sim/info": SIM_INFO_QUERY,
}
REPLY_SCHEMAS: dict[str, Spec] = {
    "intent/infer": INTENT, "robot/act": ROBOT_ACT_REPLY, "sim/reset": SIM_RESET_REPLY,
    "sim/render": SIM_RENDER_REPLY, "sim/info": SIM_INFO_REPLY,
}
MAX_BYTES_OVERRIDES = {"sim/render": MAX_BYTES_RENDER}


# --------------------------------------------------------------------------- encode / decode


def _to_builtin(obj: Any) -> Any:
    """Msgpack `default` hook: numpy scalars and arrays become plain Python values."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, tuple):
        return list(obj)
    raise TypeError(f"cannot encode {type(obj).__name__} as msgpack")


def encode(message: Mapping[str, Any]) -> bytes:
    """Returns the msgpack bytes of a message (numpy values converted to plain ones).

    Raises:
        TypeError: a value has no msgpack form.
    """
    return msgpack.packb(message, use_bin_type=True, default=_to_builtin)


def decode(payload: bytes, max_bytes: int = DEFAULT_MAX_BYTES) -> dict:
    """Returns the map in a msgpack payload.

    Raises:
        RejectedMessage: too large, not msgpack, trailing bytes, or not a map with string keys.
    """
    if len(payload) > max_bytes:
        raise RejectedMessage(f"payload of {len(payload)} bytes exceeds the limit of "
                              f"{max_bytes} bytes")
    try:
        message = msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except (msgpack.ExtraData, ValueError, TypeError, msgpack.UnpackException) as e:
        # TypeError: a map key that Python cannot hash (a list or a map used as a key)
        raise RejectedMessage(f"not a msgpack payload ({type(e).__name__}: {e})") from None
    if not isinstance(message, dict):
        raise RejectedMessage(f"expected a msgpack map at the top level, got {show_value(message)}")
    if not all(type(k) is str for k in message):
        raise RejectedMessage("expected string keys in the top-level map")
    return message


def check_version(message: dict) -> None:
    """Rejects a message whose schema version this build cannot read."""
    v = message.get("v") if isinstance(message, dict) else None
    if type(v) is int and v > SCHEMA_VERSION:
        raise RejectedMessage(f"schema version {v} is newer than this build's "
                              f"{SCHEMA_VERSION}; upgrade cbgo", "v")


def validate(message: Any, spec: Spec | None, key: str = "") -> dict:
    """Returns the message if it fits `spec` (None accepts anything).

    Raises:
        RejectedMessage: labelled with `key`, naming the field and the expectation.
    """
    if spec is None:
        return message
    try:
        check_version(message)  # first: a newer schema's other changes are not our errors
        spec.check(message, "")
    except RejectedMessage as e:
        raise e.on_key(key) from None
    return message


def schema_for(suffix: str, role: str = "message") -> Spec | None:
    """Returns the schema of a topic suffix; role is 'message', 'query' or 'reply'.

    Raises:
        KeyError: the topic has no schema for that role.
    """
    table = {"message": SCHEMAS, "query": QUERY_SCHEMAS, "reply": REPLY_SCHEMAS}[role]
    return table[suffix]


def max_bytes_for(suffix: str, default: int = DEFAULT_MAX_BYTES) -> int:
    """Returns the payload size limit of a topic (larger for render replies)."""
    return max(default, MAX_BYTES_OVERRIDES.get(suffix, 0))


def decode_checked(payload: bytes, spec: Spec | None, key: str = "",
                   max_bytes: int = DEFAULT_MAX_BYTES) -> dict:
    """Decodes and validates in one step, labelling any rejection with `key`.

    Raises:
        RejectedMessage: see `decode` and `validate`.
    """
    try:
        message = decode(payload, max_bytes)
    except RejectedMessage as e:
        raise e.on_key(key) from None
    return validate(message, spec, key)
