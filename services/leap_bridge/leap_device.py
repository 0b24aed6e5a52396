"""A live Leap Motion / Ultraleap sensor, read through Ultraleap's Python bindings for LeapC.

Install the Ultraleap tracking service (Gemini or later) and its Python bindings
(https://github.com/ultraleap/leapc-python-bindings: ``pip install`` its ``leapc-python-api``
folder), which provide the ``leap`` module. Without them this source fails at start with that
advice. This file is the only place that knows the bindings' types.

How a LeapC ``LEAP_HAND`` becomes a contract hand (``docs/protocol.md``, hands/frame). The
bindings wrap the C structs one to one (``leap.datatypes``: ``Hand``, ``Palm``, ``Digit``,
``Bone``, ``Vector``, ``Quaternion``); units and frame are LeapC's in Desktop tracking mode,
which is the contract's Leap frame (mm, +y up, +z towards the user), so nothing is converted:

- ``id`` ← ``hand.id``; ``side`` ← ``hand.type`` (``eLeapHandType_Left`` → left, else right);
- ``confidence`` ← ``hand.confidence``, clipped to [0, 1], passed on as the service reports it;
- ``palm_position`` ← ``hand.palm.position`` (not ``stabilized_position``: smoothed, it lags);
  ``palm_velocity``, ``palm_normal``, ``direction`` (palm towards the fingers) and
  ``palm_width`` ← ``hand.palm.velocity``, ``.normal``, ``.direction``, ``.width``;
- ``wrist_position`` ← ``hand.arm.next_joint`` (the arm bone runs elbow → wrist);
- ``grab_strength``, ``pinch_strength`` ← the same fields, clipped to [0, 1];
- ``fingers[f]`` ← ``hand.digits[f]``: thumb, index, middle, ring, pinky (``LEAP_HAND``'s
  union order); ``bones[b]`` ← ``digit.metacarpal``, ``.proximal``, ``.intermediate``,
  ``.distal``, each ``prev_joint`` (towards the wrist), ``next_joint`` (towards the tip),
  ``width`` and ``rotation`` (x, y, z, w; left out for a zero-length bone, below).

The thumb: LeapC gives it a metacarpal of ZERO length and width with an IDENTITY basis ("for
ease of programming"; anatomically the thumb lacks the intermediate phalanx instead). That
identity basis is a placeholder, not an orientation — its z axis is the sensor's +z whatever
the thumb does — so a zero-length bone is sent WITHOUT ``rotation``: the feature extractor
then takes the proximal's direction for it (``cbgo.hands.features``), and the thumb's proximal,
intermediate and distal joints are where the older Leap SDKs and the multi-modal Leap HGR set
put them too. The static-gesture model reads only device-independent features
(``cbgo.services.static_gesture.invariant``), which never look at a metacarpal.

``tests/fakes/leapc.py`` builds frames laid out as these structs are, and
``tests/unit/leap_bridge/test_leap_device.py`` checks the mapping on them.
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


ZERO_LENGTH_MM = 1e-3


def _vec(v: Any) -> list[float]:
    return [float(v.x), float(v.y), float(v.z)]


def _prob(value: Any) -> float:
    return min(1.0, max(0.0, float(value)))


def _bone(bone: Any, btype: str) -> dict:
    prev, nxt = _vec(bone.prev_joint), _vec(bone.next_joint)
    out = {"type": btype, "prev_joint": prev, "next_joint": nxt,
           "width": max(0.0, float(bone.width))}
    length = sum((a - b) ** 2 for a, b in zip(prev, nxt, strict=True)) ** 0.5
    q = bone.rotation
    rotation = [float(q.x), float(q.y), float(q.z), float(q.w)]
    if length >= ZERO_LENGTH_MM and sum(c * c for c in rotation) > 1e-12:
        out["rotation"] = rotation
    return out


def hand_from_leap(hand: Any, leap: Any) -> dict:
    """Returns the contract hand of one ``leap`` Hand (the mapping in the module docstring).

    Args:
        hand: a ``leap.datatypes.Hand`` (or anything with its attributes).
        leap: the ``leap`` module (for ``HandType``).
    """
    fingers = []
    for ftype, digit in zip(FINGER_TYPES, hand.digits, strict=True):
        bones = [digit.metacarpal, digit.proximal, digit.intermediate, digit.distal]
        fingers.append({"type": ftype,
                        "bones": [_bone(b, t) for b, t in zip(bones, BONE_TYPES, strict=True)]})
    palm = hand.palm
    return {
        "id": int(hand.id), "side": "left" if hand.type == leap.HandType.Left else "right",
        "confidence": _prob(hand.confidence), "palm_position": _vec(palm.position),
        "palm_velocity": _vec(palm.velocity), "palm_normal": _vec(palm.normal),
        "direction": _vec(palm.direction), "wrist_position": _vec(hand.arm.next_joint),
        "palm_width": max(0.0, float(palm.width)), "grab_strength": _prob(hand.grab_strength),
        "pinch_strength": _prob(hand.pinch_strength), "fingers": fingers,
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
