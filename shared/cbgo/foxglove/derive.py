"""The derived Foxglove channels of a cbgo message stream: scene, frame transforms, log.

`Deriver` is fed the valid wire messages of a session in order (a recording, or the live
traffic) and returns the Foxglove messages they imply. It keeps the little state a picture
needs: the last hand frame (for its ``to_base`` and the pointing fingertip), the last scene,
the target of the last accepted intent, the robot's TCP. It never touches the network or a
file, so export, ``cbgo record --encoding json`` and the live bridge derive the same channels.
"""

from __future__ import annotations

from dataclasses import dataclass

from cbgo.foxglove import scene as fx

SCENE_TOPIC = "foxglove/scene"
TRANSFORMS_TOPIC = "foxglove/transforms"
LOG_TOPIC = "foxglove/log"
SCENE_SCHEMA, TRANSFORMS_SCHEMA, LOG_SCHEMA = ("foxglove.SceneUpdate",
                                               "foxglove.FrameTransforms", "foxglove.Log")
DERIVED_TOPICS = {SCENE_TOPIC: SCENE_SCHEMA, TRANSFORMS_TOPIC: TRANSFORMS_SCHEMA,
                  LOG_TOPIC: LOG_SCHEMA}
TRANSFORM_PERIOD_S = 1.0  # transforms are repeated so that a late viewer gets them too
INFO, WARNING, ERROR = 2, 3, 4  # foxglove.LogLevel


@dataclass
class Derived:
    """One derived Foxglove message.

    Attributes:
        topic: its channel (a key of `DERIVED_TOPICS`).
        message: the message, fitting the channel's Foxglove schema.
        ts: its time, s since the Unix epoch (the wire message's ``ts``).
    """

    topic: str
    message: dict
    ts: float


class Deriver:
    """Turns wire messages into SceneUpdate, FrameTransforms and Log messages."""

    def __init__(self):
        self.frame: dict | None = None
        self.scene: dict | None = None
        self.arm: dict | None = None  # the last robot/state: its joints pose the drawn arm
        self.target: str | None = None
        self._transform_key: tuple | None = None
        self._transform_ts = float("-inf")
        self._plan_last: tuple | None = None

    def feed(self, suffix: str, message: dict) -> list[Derived]:
        """Returns what one valid wire message on `suffix` (``hands/frame``...) implies."""
        handler = getattr(self, "_on_" + suffix.replace("/", "_"), None)
        return handler(message) if handler else []

    # ------------------------------------------------------------------ per key

    def _on_hands_frame(self, frame: dict) -> list[Derived]:
        self.frame = frame
        out = [_scene(frame["ts"], fx.hands_entity(frame))]
        key = tuple(frame.get("to_base") or ())
        if key != self._transform_key or frame["ts"] - self._transform_ts >= TRANSFORM_PERIOD_S:
            self._transform_key, self._transform_ts = key, frame["ts"]
            out.append(Derived(TRANSFORMS_TOPIC, {"transforms": [fx.leap_transform(frame)]},
                               frame["ts"]))
        return out

    def _on_gaze(self, gaze: dict) -> list[Derived]:
        origin, nominal = fx.ray_origin(gaze, self.frame)
        return [_scene(gaze["ts"], fx.focus_entity(gaze, origin, nominal))]

    def _on_scene_state(self, scene: dict) -> list[Derived]:
        self.scene = scene
        robot = scene["robot"]
        tcp = self.arm["tcp"] if self.arm else robot["tcp"]
        return [_scene(scene["ts"], fx.objects_entity(scene, self.target),
                       fx.robot_entity(scene["ts"], tcp, robot["gripper_open"],
                                       robot["holding"], **self._joints()))]

    def _on_robot_state(self, state: dict) -> list[Derived]:
        self.arm = state
        robot = self.scene["robot"] if self.scene else {"gripper_open": None, "holding": None}
        return [_scene(state["ts"], fx.robot_entity(state["ts"], state["tcp"],
                                                    robot["gripper_open"], robot["holding"],
                                                    **self._joints()))]

    def _joints(self) -> dict:
        """The last robot/state's joints; nominal where it says it has no kinematics."""
        if not self.arm:
            return {}
        return {"joints": self.arm["joints"], "nominal": self.arm.get("kinematics") is False}

    def _on_intent(self, intent: dict) -> list[Derived]:
        action, obj = intent["action"], intent["object"]
        what = f"{action}({obj or ''})" if action else "nothing"
        out = [_log(intent["ts"], WARNING if intent["status"] != "accepted" else INFO,
                    "intent", f"intent {intent['status']}: {what} confidence "
                              f"{intent['confidence']:.2f}"
                    + (f"; {intent['reason']}" if intent["reason"] else ""))]
        if intent["status"] == "accepted":
            self.target = obj
            if self.scene is not None:
                out.append(_scene(intent["ts"], fx.objects_entity(self.scene, self.target)))
        return out

    def _on_episode_event(self, event: dict) -> list[Derived]:
        words = f"episode {event['kind']} {event['episode']}"
        if event["kind"] == "trigger":
            words = (f"trigger {event['gesture']} p={event.get('prob', 0.0):.2f} "
                     f"({event['episode']})")
        return [_log(event["ts"], INFO, "episode", words)]

    def _on_episode_summary(self, summary: dict) -> list[Derived]:
        g = summary["gestures"]
        best = sorted(zip(g["probs"], g["names"], strict=True), reverse=True)[:3]
        words = ", ".join(f"{name} {p:.2f}" for p, name in best)
        return [_log(summary["ts"], INFO, "episode",
                     f"episode of {summary['user']}, {summary['ended'] - summary['started']:.2f}"
                     f" s: g = {words}; focus {summary['focus_source'] or 'none'}")]

    def _on_plan_status(self, plan: dict) -> list[Derived]:
        steps = " -> ".join(f"{s['action']}({s['object'] or ''})" for s in plan["sequence"])
        key = (plan["intent"]["ts"], plan["state"])
        if plan["state"] == "running" and key == self._plan_last:
            return []  # one line per plan start, not one per step update
        self._plan_last = key
        level = {"failure": ERROR, "success": INFO}.get(plan["state"], INFO)
        error = f": {plan['error']}" if plan["error"] else ""
        return [_log(plan["ts"], level, "planner", f"plan {plan['state']}: {steps}{error}")]


def _scene(ts: float, *entities: dict) -> Derived:
    return Derived(SCENE_TOPIC, {"deletions": [], "entities": list(entities)}, ts)


def _log(ts: float, level: int, name: str, words: str) -> Derived:
    return Derived(LOG_TOPIC, {"timestamp": fx.stamp(ts), "level": level, "message": words,
                               "name": name, "file": "", "line": 0}, ts)
