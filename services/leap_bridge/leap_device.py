"""A live Leap Motion / Ultraleap sensor, read through Ultraleap's Python bindings for LeapC.

Install the Ultraleap tracking service (Gemini or later) and its Python bindings
(https://github.com/ultraleap/leapc-python-bindings: ``pip install`` its ``leapc-python-api``
folder), which provide the ``leap`` module. Without them this source fails at start with that
advice. This file is the only place that knows the bindings' types; it maps every field of the
contract and cannot be tested on machines without a sensor.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from typing import Any

from cbgo.errors import ConfigError, DeviceError
from cbgo.wire import BONE_TYPES, FINGER_TYPES

INSTALL_HINT = (
    "the Ultraleap Python bindings are not installed: install the Ultraleap tracking service "
    "(https://developer.leapmotion.com/tracking-software-download), then `pip install` the "
    "leapc-python-api folder of https://github.com/ultraleap/leapc-python-bindings, which "
    "provides the `leap` module")
NO_FRAME_TIMEOUT_S = 5.0  # the service sends frames even without hands; silence means a fault


def _vec(v: Any) -> list[float]:
    return [float(v.x), float(v.y), float(v.z)]


def _bone(bone: Any, btype: str) -> dict:
    rotation = bone.rotation
    return {"type": btype, "prev_joint": _vec(bone.prev_joint),
            "next_joint": _vec(bone.next_joint), "width": float(bone.width),
            "rotation": [float(rotation.x), float(rotation.y), float(rotation.z),
                         float(rotation.w)]}


def hand_from_leap(hand: Any, leap: Any) -> dict:
    """Returns the contract hand of one ``leap`` Hand."""
    fingers = []
    for ftype, digit in zip(FINGER_TYPES, hand.digits, strict=True):
        bones = [digit.metacarpal, digit.proximal, digit.intermediate, digit.distal]
        fingers.append({"type": ftype,
                        "bones": [_bone(b, t) for b, t in zip(bones, BONE_TYPES, strict=True)]})
    return {
        "id": int(hand.id), "side": "left" if hand.type == leap.HandType.Left else "right",
        "confidence": float(hand.confidence), "palm_position": _vec(hand.palm.position),
        "palm_velocity": _vec(hand.palm.velocity), "palm_normal": _vec(hand.palm.normal),
        "direction": _vec(hand.palm.direction), "wrist_position": _vec(hand.arm.next_joint),
        "palm_width": float(hand.palm.width), "grab_strength": float(hand.grab_strength),
        "pinch_strength": float(hand.pinch_strength), "fingers": fingers,
    }


class LeapSource:
    """Frames from the sensor as they arrive (``t`` is None: publish at once)."""

    def __init__(self):
        try:
            import leap  # noqa: PLC0415 - optional, vendor-provided
        except ImportError:
            raise ConfigError(INSTALL_HINT) from None
        self._leap = leap
        self._frames: queue.Queue = queue.Queue(maxsize=8)
        self.device = "leap"

    def frames(self, stop: threading.Event) -> Iterator[list[dict]]:
        """Yields each tracking frame's hands until `stop` is set.

        Raises:
            DeviceError: no frame for NO_FRAME_TIMEOUT_S seconds (sensor unplugged, service
                down), so that the supervisor restarts the process.
        """
        leap = self._leap
        source = self

        class _Listener(leap.Listener):
            def on_tracking_event(self, event):
                hands = [hand_from_leap(h, leap) for h in event.hands]
                try:
                    source._frames.put_nowait(hands)
                except queue.Full:  # newest wins: drop the oldest
                    source._frames.get_nowait()
                    source._frames.put_nowait(hands)

        connection = leap.Connection()
        connection.add_listener(_Listener())
        with connection.open():
            connection.set_tracking_mode(leap.TrackingMode.Desktop)
            while not stop.is_set():
                try:
                    yield self._frames.get(timeout=NO_FRAME_TIMEOUT_S)
                except queue.Empty:
                    raise DeviceError(f"no frame from the Leap service for "
                                      f"{NO_FRAME_TIMEOUT_S:g} s") from None
