"""One valid example message per key and role, built from the contract.

Used by `docs/protocol.md` (the example payloads are generated from here), by `cbgo pub
--example`, and by tests as factories (`example("hands/frame", hands=[])`). Every example
passes `cbgo.wire` validation; a test keeps it that way.
"""

from __future__ import annotations

import copy
import time
from typing import Any

from cbgo.wire import BONE_TYPES, FINGER_TYPES, SCHEMA_VERSION, STATIC_GESTURES
from cbgo.world.workspace import workspace_info

# Bone lengths (mm) of an adult hand, metacarpal to distal; the thumb's metacarpal is zero
# length, as in the Leap SDK.
_BONE_LENGTHS = {
    "thumb": (0.0, 46.0, 32.0, 25.0),
    "index": (68.0, 40.0, 23.0, 17.0),
    "middle": (64.0, 45.0, 27.0, 18.0),
    "ring": (58.0, 42.0, 26.0, 18.0),
    "pinky": (53.0, 33.0, 18.0, 16.0),
}
_KNUCKLE_X = {"thumb": -22.0, "index": -18.0, "middle": 0.0, "ring": 16.0, "pinky": 30.0}


def open_hand(palm: tuple[float, float, float] = (0.0, 200.0, 30.0), side: str = "right",
              hand_id: int = 1) -> dict:
    """Returns a flat open hand (all fingers straight, pointing away from the user).

    A geometric example, not a hand model: fingers run along -z from the wrist, palm down.
    """
    px, py, pz = palm
    wrist = [px, py, pz + 45.0]
    fingers = []
    for ftype in FINGER_TYPES:
        x = px + _KNUCKLE_X[ftype] * (1 if side == "right" else -1)
        z = wrist[2]
        bones = []
        for btype, length in zip(BONE_TYPES, _BONE_LENGTHS[ftype], strict=True):
            bone = {"type": btype, "prev_joint": [x, py, z], "next_joint": [x, py, z - length],
                    "width": 16.0 if ftype != "pinky" else 14.0}
            if ftype == "thumb" and btype == "metacarpal":
                bone["rotation"] = [0.0, 0.0, 0.0, 1.0]
            bones.append(bone)
            z -= length
        fingers.append({"type": ftype, "bones": bones})
    return {
        "id": hand_id, "side": side, "confidence": 1.0,
        "palm_position": [px, py, pz], "palm_velocity": [0.0, 0.0, 0.0],
        "palm_normal": [0.0, -1.0, 0.0], "direction": [0.0, 0.0, -1.0],
        "wrist_position": wrist, "palm_width": 85.0,
        "grab_strength": 0.0, "pinch_strength": 0.0, "fingers": fingers,
    }


def _scene_body() -> dict:
    return {
        "objects": [
            {"name": "cup1", "type": "cup", "position": [0.5, 0.1, 0.05], "size": 0.08,
             "full": True, "on": None, "inside": None},
            {"name": "drawer1", "type": "drawer", "position": [0.6, -0.3, 0.1], "size": 0.2,
             "open": False, "opening": 0.0, "contains": []},
            {"name": "box1", "type": "box", "position": [0.4, 0.2, 0.025], "size": 0.05,
             "on": None},
        ],
        "robot": {"tcp": [0.3, 0.0, 0.4], "gripper_open": True, "holding": None},
    }


def _intent(ts: float) -> dict:
    return {
        "v": SCHEMA_VERSION, "ts": ts, "episode": "ep-0001", "action": "pick_up",
        "object": "cup1", "params": {},
        "p_action": {"pick_up": 0.93, "pour": 0.04, "open": 0.03},
        "p_object": {"cup1": 0.91, "box1": 0.06, "drawer1": 0.03},
        "confidence": 0.85, "status": "accepted", "reason": "", "model": "intent-ours-1",
    }


def _static_probs() -> dict:
    probs = [0.01] * len(STATIC_GESTURES)
    probs[STATIC_GESTURES.index("grab")] = 1.0 - 0.01 * (len(STATIC_GESTURES) - 1)
    return {"names": list(STATIC_GESTURES), "probs": probs}


def _builders(ts: float) -> dict[tuple[str, str], Any]:
    v = SCHEMA_VERSION
    scene_state = {"v": v, "ts": ts, "seq": 42, **_scene_body()}
    return {
        ("hands/frame", "message"): {"v": v, "ts": ts, "seq": 1234, "source": "simulated",
                                     "device": "sim-user-1", "hands": [open_hand()]},
        ("gaze", "message"): {"v": v, "ts": ts, "point": [0.5, 0.1, 0.05],
                              "source": "simulated"},
        ("camera/preview", "message"): {
            "v": v, "ts": ts, "seq": 1234, "width": 320, "height": 240,
            "jpeg": b"\xff\xd8\xff\xe0...", "hands": [{"side": "right", "points": [
                [0.5, 0.8], *[[round(0.4 + 0.05 * f, 2), round(0.7 - 0.08 * j, 2)] for f in range(5)
                              for j in range(4)]]}]},
        ("user", "message"): {"v": v, "ts": ts, "user": "user1"},
        ("gestures/static", "message"): {"v": v, "ts": ts, "seq": 1234, "hand_id": 1,
                                         "side": "right", **_static_probs(),
                                         "model": "static-bnn-1"},
        ("gestures/dynamic", "message"): {
            "v": v, "ts": ts, "seq": 1250, "hand_id": 1, "side": "right",
            "names": ["swipe_up", "swipe_down", "swipe_left", "swipe_right", "rotate",
                      "no_gesture"],
            "probs": [0.02, 0.9, 0.02, 0.02, 0.02, 0.02], "window": [ts - 0.6, ts],
            "final": True, "model": "dynamic-promp-1"},
        ("episode/event", "message"): {"v": v, "ts": ts, "episode": "ep-0001",
                                       "kind": "trigger", "gesture": "grab", "prob": 0.92},
        ("episode/summary", "message"): {
            "v": v, "ts": ts, "episode": "ep-0001", "user": "user1", "started": ts - 2.5,
            "ended": ts - 0.15, "gestures": {"names": ["grab", "point", "swipe_down"],
                                             "probs": [0.92, 0.3, 0.05]},
            "triggers": [{"gesture": "grab", "ts": ts - 1.2, "prob": 0.92}],
            "params": {"distance": 0.04}, "focus": [0.5, 0.1, 0.05], "focus_source": "gaze"},
        ("scene/state", "message"): scene_state,
        ("intent", "message"): _intent(ts),
        ("intent/feedback", "message"): {"v": v, "ts": ts, "episode": "ep-0001",
                                         "user": "user1", "action": "pour", "object": "cup1"},
        ("intent/clarify", "message"): {
            "v": v, "ts": ts, "id": "4711-1", "episode": "ep-0001", "user": "user1",
            "state": "open", "candidates": [{"action": "pick_up", "object": "cup1", "p": 0.43},
                                            {"action": "pick_up", "object": "cup2", "p": 0.41}],
            "highlighted": 0, "expires": ts + 20.0,
            "reason": "uncertain between these; confirm one"},
        ("intent/answer", "message"): {"v": v, "ts": ts, "id": "4711-1", "user": "user1",
                                       "answer": "confirm", "choice": 1},
        ("robot/state", "message"): {"v": v, "ts": ts, "seq": 7,
                                     "joints": [0.0, -0.78, 0.0, -2.36, 0.0, 1.57, 0.78],
                                     "gripper_width": 0.08, "tcp": [0.3, 0.0, 0.4],
                                     "moving": False, "action": None},
        ("robot/stop", "message"): {"v": v, "ts": ts, "reason": "user pressed stop"},
        ("plan/status", "message"): {
            "v": v, "ts": ts, "intent": _intent(ts),
            "sequence": [{"action": "pick_up", "object": "cup1", "params": {},
                          "state": "running"}],
            "state": "running", "tree": "{-} pick_up(cup1) [*]", "error": None},
        ("intent/infer", "query"): {"v": v, "gestures": _static_probs(), "scene": _scene_body(),
                                    "focus": [0.5, 0.1, 0.05], "user": "user1"},
        ("intent/infer", "reply"): _intent(ts),
        ("robot/act", "query"): {"v": v, "action": "pick_up", "object": "cup1", "params": {}},
        ("robot/act", "reply"): {"v": v, "ok": True, "error": None, "duration_s": 3.2,
                                 "scene": scene_state},
        ("sim/reset", "query"): {"v": v, "seed": 7},
        ("sim/reset", "reply"): {"v": v, "ok": True, "error": None, "scene": scene_state},
        ("sim/render", "query"): {"v": v, "camera": "front", "width": 640, "height": 480},
        ("sim/render", "reply"): {"v": v, "ok": True, "error": None,
                                  "png": b"\x89PNG\r\n\x1a\n..."},
        ("sim/info", "query"): {"v": v},
        ("sim/info", "reply"): {"v": v, "ok": True, "error": None, "robot": "mujoco-sim",
                                "workspace": workspace_info()},
    }


EXAMPLE_KEYS = tuple(_builders(0.0))


def example(suffix: str, role: str = "message", ts: float | None = None, **overrides) -> dict:
    """Returns a fresh valid example of a topic's message, query or reply.

    Args:
        suffix: the topic below the prefix, e.g. ``hands/frame``.
        role: ``message``, ``query`` or ``reply``.
        ts: the time stamp to use (now by default).
        **overrides: top-level fields to replace.

    Raises:
        KeyError: no example for that topic and role.
    """
    built = _builders(time.time() if ts is None else ts)[(suffix, role)]
    return {**copy.deepcopy(built), **overrides}
