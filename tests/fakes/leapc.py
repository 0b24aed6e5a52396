"""LeapC tracking frames without a sensor: the C structs and the Python bindings' wrappers.

``Struct`` objects stand for the cffi structs of ``LeapC.h`` (field names as there:
``LEAP_HAND{id, flags, type, confidence, visible_time, pinch_distance, grab_angle,
pinch_strength, grab_strength, palm, thumb, index, middle, ring, pinky, arm}``,
``LEAP_PALM{position, stabilized_position, velocity, normal, width, direction, orientation}``,
``LEAP_DIGIT{finger_id, metacarpal, proximal, intermediate, distal, is_extended}``,
``LEAP_BONE{prev_joint, next_joint, width, rotation}``, ``LEAP_VECTOR{x, y, z}``,
``LEAP_QUATERNION{x, y, z, w}``), and the classes below wrap them the way
``leapc-python-bindings``' ``leap.datatypes`` does (properties returning wrappers,
``Hand.digits`` in union order, ``Hand.type`` a ``HandType``). `leapc_hand` lays a contract hand
out as the Gemini service reports one: the thumb metacarpal of zero length and width with an
identity basis, the arm bone ending at the wrist.
"""

from __future__ import annotations

import enum
from types import SimpleNamespace

import numpy as np

Struct = SimpleNamespace


class HandType(enum.IntEnum):
    """``eLeapHandType``."""

    Left = 0
    Right = 1


class _Wrapper:
    def __init__(self, data):
        self._data = data


class Vector(_Wrapper):
    x = property(lambda self: self._data.x)
    y = property(lambda self: self._data.y)
    z = property(lambda self: self._data.z)


class Quaternion(Vector):
    w = property(lambda self: self._data.w)


class Palm(_Wrapper):
    position = property(lambda self: Vector(self._data.position))
    stabilized_position = property(lambda self: Vector(self._data.stabilized_position))
    velocity = property(lambda self: Vector(self._data.velocity))
    normal = property(lambda self: Vector(self._data.normal))
    width = property(lambda self: self._data.width)
    direction = property(lambda self: Vector(self._data.direction))
    orientation = property(lambda self: Quaternion(self._data.orientation))


class Bone(_Wrapper):
    prev_joint = property(lambda self: Vector(self._data.prev_joint))
    next_joint = property(lambda self: Vector(self._data.next_joint))
    width = property(lambda self: self._data.width)
    rotation = property(lambda self: Quaternion(self._data.rotation))


class Digit(_Wrapper):
    finger_id = property(lambda self: self._data.finger_id)
    metacarpal = property(lambda self: Bone(self._data.metacarpal))
    proximal = property(lambda self: Bone(self._data.proximal))
    intermediate = property(lambda self: Bone(self._data.intermediate))
    distal = property(lambda self: Bone(self._data.distal))
    is_extended = property(lambda self: self._data.is_extended)

    @property
    def bones(self):
        return [self.metacarpal, self.proximal, self.intermediate, self.distal]


class Hand(_Wrapper):
    id = property(lambda self: self._data.id)
    type = property(lambda self: HandType(self._data.type))
    confidence = property(lambda self: self._data.confidence)
    grab_strength = property(lambda self: self._data.grab_strength)
    pinch_strength = property(lambda self: self._data.pinch_strength)
    palm = property(lambda self: Palm(self._data.palm))
    arm = property(lambda self: Bone(self._data.arm))

    @property
    def digits(self):
        return [Digit(getattr(self._data, f)) for f in ("thumb", "index", "middle", "ring",
                                                        "pinky")]


leap = SimpleNamespace(HandType=HandType)
"""Stands for the ``leap`` module where ``hand_from_leap`` needs it."""


def vector(v) -> Struct:
    """A ``LEAP_VECTOR``."""
    return Struct(x=float(v[0]), y=float(v[1]), z=float(v[2]))


IDENTITY = Struct(x=0.0, y=0.0, z=0.0, w=1.0)


def leapc_hand(hand: dict, confidence: float = 1.0) -> Hand:
    """Lays a contract hand out as a Gemini ``LEAP_HAND``, wrapped like the bindings.

    The thumb's metacarpal becomes zero-length (at its proximal's base), zero-width and with an
    identity basis; the arm bone runs from 250 mm behind the wrist to the wrist.
    """
    digits = {}
    for name, finger in zip(("thumb", "index", "middle", "ring", "pinky"), hand["fingers"],
                            strict=True):
        bones = []
        for b in finger["bones"]:
            rot = b.get("rotation") or [0.0, 0.0, 0.0, 1.0]
            bones.append(Struct(prev_joint=vector(b["prev_joint"]),
                                next_joint=vector(b["next_joint"]), width=b["width"],
                                rotation=Struct(x=rot[0], y=rot[1], z=rot[2], w=rot[3])))
        if name == "thumb":
            base = bones[1].prev_joint
            bones[0] = Struct(prev_joint=base, next_joint=base, width=0.0, rotation=IDENTITY)
        digits[name] = Struct(finger_id=len(digits), metacarpal=bones[0], proximal=bones[1],
                              intermediate=bones[2], distal=bones[3], is_extended=1)
    wrist = np.asarray(hand["wrist_position"], dtype=float)
    direction = np.asarray(hand["direction"], dtype=float)
    palm = Struct(position=vector(hand["palm_position"]),
                  stabilized_position=vector(hand["palm_position"]),
                  velocity=vector(hand["palm_velocity"]), normal=vector(hand["palm_normal"]),
                  width=hand["palm_width"], direction=vector(direction), orientation=IDENTITY)
    arm = Struct(prev_joint=vector(wrist - 250.0 * direction), next_joint=vector(wrist),
                 width=55.0, rotation=IDENTITY)
    data = Struct(id=hand["id"], flags=0, type=HandType.Left if hand["side"] == "left"
                  else HandType.Right, confidence=confidence, visible_time=1000,
                  pinch_distance=30.0, grab_angle=0.5, pinch_strength=hand["pinch_strength"],
                  grab_strength=hand["grab_strength"], palm=palm, arm=arm, **digits)
    return Hand(data)
