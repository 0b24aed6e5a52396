"""What the page is sent: wire messages made small and browser-ready, at a rate pages keep up.

Rules (no Zenoh here; `main.py` and `replay.py` feed it, the tests call it directly):

- hand frames are turned into skeletons in the robot base frame (m) through the frame's own
  ``to_base`` (`cbgo.transform`, the one place that converts frames; the sensor's default pose
  when a frame has none), so the browser never sees Leap millimetres;
- the high-rate streams (hand frames, static gestures, gaze, robot state, the recomputed
  evidence) are downsampled per stream and hand side to at most ``rate_hz``: the newest message
  of each period is sent, the others are counted as skipped; events, summaries, intents, plans
  and scenes are never skipped;
- a camera preview's JPEG becomes a ``data:`` URL the page's image can show as it is;
- evidence is recomputed from every static and dynamic message (before downsampling) with the
  episode service's own model and default settings (`cbgo.evidence`), reset at
  each episode start, exactly as ``cbgo plot episode`` recomputes it offline: the episode
  service does not publish its evidence.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from cbgo.errors import ConfigError
from cbgo.evidence import Evidence, EvidenceSettings
from cbgo.transform import default_to_base, parse_to_base

# Streams that arrive with every hand frame (or near it): downsampled, newest wins.
RATE_LIMITED = ("hands/frame", "gestures/static", "gaze", "robot/state", "@evidence",
                "camera/preview")


@dataclass
class Downsampler:
    """Lets through at most one message per stream every 1/rate_hz seconds.

    Args:
        rate_hz: the most messages per second per stream (and per hand side).
        clock: the time source (monotonic seconds), injectable for tests.
    """

    rate_hz: float
    clock: Callable[[], float]
    passed: int = 0
    skipped: int = 0
    _last: dict[tuple[str, str], float] = field(default_factory=dict)

    def allow(self, topic: str, side: str = "") -> bool:
        """Returns whether a message of this stream may go out now (and counts it)."""
        if topic not in RATE_LIMITED:
            self.passed += 1
            return True
        now, key = self.clock(), (topic, side)
        # 0.9 periods: a 120 Hz stream cut to 30 Hz passes every 4th frame, not every 5th
        # (arrival jitter makes 4 frames a hair less than one period now and then).
        if now - self._last.get(key, -1e9) < 0.9 / self.rate_hz:
            self.skipped += 1
            return False
        self._last[key] = now
        self.passed += 1
        return True


class BaseFrame:
    """Parses a frame's ``to_base`` once per distinct matrix (a sensor does not move often)."""

    def __init__(self):
        self._cache: dict[tuple, np.ndarray] = {}
        self.default = default_to_base()

    def matrix(self, frame: dict) -> np.ndarray:
        """Returns the frame's Leap→base matrix, the default when it has none or a bad one."""
        values = frame.get("to_base")
        if values is None:
            return self.default
        key = tuple(values)
        if key not in self._cache:
            try:
                self._cache[key] = parse_to_base(list(values))
            except ConfigError:
                self._cache[key] = self.default  # validated frames are rigid; belt and braces
            if len(self._cache) > 64:
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]


def _round(points: np.ndarray) -> list:
    return np.round(points, 4).tolist()  # 0.1 mm: finer than any sensor, fewer JSON bytes


def hand_view(hand: dict, matrix: np.ndarray) -> dict:
    """Returns one hand as a skeleton in the base frame.

    Returns:
        side, id, confidence, grab, pinch, palm and wrist (m), normal and direction (unit
        vectors in the base frame), and ``fingers``: per finger (thumb first) its five joints
        from the metacarpal's base to the tip.
    """
    rotation = matrix[:3, :3] * 1000.0  # pure rotation: for directions
    joints = [[b["prev_joint"] for b in f["bones"][:1]] + [b["next_joint"] for b in f["bones"]]
              for f in hand["fingers"]]
    points = np.asarray(joints, dtype=float).reshape(-1, 3)
    in_base = points @ matrix[:3, :3].T + matrix[:3, 3]
    singles = np.asarray([hand["palm_position"], hand["wrist_position"]], dtype=float)
    palm, wrist = singles @ matrix[:3, :3].T + matrix[:3, 3]
    return {
        "side": hand["side"], "id": hand["id"], "confidence": round(hand["confidence"], 3),
        "grab": round(hand["grab_strength"], 3), "pinch": round(hand["pinch_strength"], 3),
        "palm": _round(palm), "wrist": _round(wrist),
        "normal": _round(rotation @ np.asarray(hand["palm_normal"], dtype=float)),
        "direction": _round(rotation @ np.asarray(hand["direction"], dtype=float)),
        "fingers": _round(in_base.reshape(5, 5, 3)),
    }


def frame_view(frame: dict, base: BaseFrame) -> dict:
    """Returns a hand frame with its hands as base-frame skeletons."""
    matrix = base.matrix(frame)
    return {"ts": frame["ts"], "seq": frame["seq"], "source": frame["source"],
            "hands": [hand_view(h, matrix) for h in frame["hands"]]}


def preview_view(preview: dict) -> dict:
    """Returns a camera preview with its JPEG as a ``data:`` URL (JSON carries no bytes)."""
    return {"ts": preview["ts"], "seq": preview["seq"], "width": preview["width"],
            "height": preview["height"], "hands": preview["hands"],
            "src": "data:image/jpeg;base64," + base64.b64encode(preview["jpeg"]).decode()}


class EvidenceView:
    """The episode service's evidence, recomputed from the gesture streams.

    Args:
        settings: the evidence model's parameters (the episode service's defaults).
    """

    def __init__(self, settings: EvidenceSettings | None = None):
        self.settings = settings or EvidenceSettings()
        self.evidence = Evidence(self.settings)

    def feed(self, topic: str, message: dict) -> dict | None:
        """Takes one message; returns an ``@evidence`` sample after a gesture message."""
        if topic == "episode/event" and message.get("kind") == "start":
            self.evidence = Evidence(self.settings)
            return None
        side = message.get("side", "")
        if topic == "gestures/static":
            self.evidence.static(message["ts"], side, message["names"], message["probs"])
        elif topic == "gestures/dynamic":
            self.evidence.dynamic(tuple(message["window"]), side, message["names"],
                                  message["probs"])
        else:
            return None
        t = message["ts"]
        values = {n: round(self.evidence.value(n, t), 4) for n in self.evidence.names}
        return {"ts": t, "values": values, "threshold": self.settings.threshold}


class Views:
    """Turns wire messages into what the page is sent, rate-limited.

    Args:
        rate_hz: the most messages per second of each high-rate stream.
        clock: monotonic seconds (injectable).
    """

    def __init__(self, rate_hz: float, clock: Callable[[], float]):
        self.down = Downsampler(rate_hz, clock)
        self.base = BaseFrame()
        self.evidence = EvidenceView()

    def render(self, topic: str, message: dict) -> list[tuple[str, dict]]:
        """Returns the (topic, view) pairs to send for one wire message (often none)."""
        out: list[tuple[str, dict]] = []
        sample = self.evidence.feed(topic, message)
        if sample is not None and self.down.allow("@evidence"):
            out.append(("@evidence", sample))
        if not self.down.allow(topic, message.get("side", "")):
            return out
        if topic == "hands/frame":
            out.append((topic, frame_view(message, self.base)))
        elif topic == "camera/preview":
            out.append((topic, preview_view(message)))
        else:
            out.append((topic, message))
        return out


def to_json(topic: str, view: dict, received: float) -> str:
    """Returns one WebSocket text message: ``{"topic", "t" (received, s), "msg"}``."""
    return json.dumps({"topic": topic, "t": round(received, 4), "msg": view},
                      separators=(",", ":"), allow_nan=False)
