"""The symbolic scene: objects, how they rest on each other, and the robot; to and from the wire.

A `Scene` is what `cbgo/scene/state` describes (docs/protocol.md), as dataclasses the intent
service, the planner and the dry robot share. Its rules:

- object types are ``cup``, ``drawer`` and ``box``; names are unique;
- an object rests in exactly one place: on the table, ``on`` a box or a drawer cabinet's top,
  ``inside`` a drawer, or in the gripper (``robot.holding``); drawers stand on the table only;
- at most one object rests directly on another, a drawer holds at most `DRAWER_CAPACITY`
  objects, and a tower counts at most `MAX_STACK` objects (the grid's four levels);
- only cups and boxes are graspable; nothing rests on a cup.

Positions are centres of an object's bounding cube of edge ``size`` (metres, robot base frame).
Table objects keep the position they are given; the positions of stacked, contained and held
objects follow from their support (`Scene.settle`): on top of the support, on the drawer's
floor (pulled out by `DRAWER_TRAY_OFFSET` while the drawer is open), or at the TCP.

Drawers open along x, towards the middle of the table (`drawer_direction`): one standing at
x ≥ `DRAWER_OPENS_AWAY_BELOW_X` opens towards the robot (−x), one nearer the robot opens away
from it (+x). Opened towards the robot, a drawer that near would bring its handle closer to the
robot's base than the arm reaches top-down (`cbgo.world.workspace.MIN_REACH`); opened away, it
stays within reach wherever it stands on the table.

`Scene.state_bit` is the binary object state the paper's decision tables condition on: a cup is
full, a drawer is open, a box is blocked (something stands on it, or it is inside a drawer).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Any

from cbgo.wire import OBJECT_TYPES, SCHEMA_VERSION

GRASPABLE = ("cup", "box")
SUPPORTS = ("box", "drawer")  # what another object can be put on
DEFAULT_SIZES = {"cup": 0.06, "drawer": 0.11, "box": 0.05}
DRAWER_CAPACITY = 1
DRAWER_TRAY_OFFSET = 0.08  # m the tray slides out (`drawer_direction`) when the drawer is open
# m: a drawer whose centre lies nearer the robot than this opens away from it (+x), the others
# towards it (−x); the middle of the grid's columns (0.32 … 0.68), so that the opened handle of
# every drawer on the table lies between 0.337 and 0.69 m from the robot's base axis
DRAWER_OPENS_AWAY_BELOW_X = 0.50
DRAWER_FLOOR = 0.01  # m between the cabinet's bottom and its tray's floor
MAX_STACK = 4  # objects in one tower, the bottom one included


def drawer_direction(x: float) -> int:
    """Returns the way along x a drawer standing at x opens: −1 towards the robot, +1 away."""
    return 1 if float(x) < DRAWER_OPENS_AWAY_BELOW_X else -1


@dataclass
class SceneObject:
    """One object of the scene.

    Attributes:
        name: unique name, e.g. ``cup1``.
        type: ``cup``, ``drawer`` or ``box``.
        position: centre (m, robot base frame).
        size: edge of its bounding cube (m).
        full: a cup holds liquid.
        open: a drawer is open.
        on: the box or drawer it stands on, or None.
        inside: the drawer it is in, or None.
    """

    name: str
    type: str
    position: tuple[float, float, float]
    size: float
    full: bool = False
    open: bool = False
    on: str | None = None
    inside: str | None = None


@dataclass
class Robot:
    """The robot as the symbolic world sees it: its TCP, gripper and held object."""

    tcp: tuple[float, float, float] = (0.44, 0.0, 0.36)
    gripper_open: bool = True
    holding: str | None = None


@dataclass
class Scene:
    """Objects and robot; see the module docstring for the rules."""

    objects: list[SceneObject] = field(default_factory=list)
    robot: Robot = field(default_factory=Robot)

    # ---------------------------------------------------------------- lookups

    @property
    def names(self) -> list[str]:
        """Object names in scene order."""
        return [o.name for o in self.objects]

    def has(self, name: str | None) -> bool:
        """Returns whether an object of that name is in the scene."""
        return name is not None and any(o.name == name for o in self.objects)

    def get(self, name: str) -> SceneObject:
        """Returns the object of that name.

        Raises:
            KeyError: no such object (the message lists the scene's names).
        """
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"no object {name!r} in the scene (objects: {', '.join(self.names)})")

    def copy(self) -> Scene:
        """Returns an independent copy."""
        return copy.deepcopy(self)

    def above(self, name: str) -> str | None:
        """Returns the object standing directly on `name`, or None."""
        return next((o.name for o in self.objects if o.on == name), None)

    def contents(self, drawer: str) -> list[str]:
        """Returns the objects inside a drawer, in scene order."""
        return [o.name for o in self.objects if o.inside == drawer]

    def is_held(self, name: str) -> bool:
        """Returns whether the robot holds the object."""
        return self.robot.holding == name

    def is_hidden(self, name: str) -> bool:
        """Returns whether the object is inside a closed drawer (out of sight)."""
        inside = self.get(name).inside
        return inside is not None and self.has(inside) and not self.get(inside).open

    def is_free(self, name: str) -> bool:
        """Returns whether nothing stands on the object and it is neither inside nor held."""
        obj = self.get(name)
        return self.above(name) is None and obj.inside is None and not self.is_held(name)

    def tower_below(self, name: str) -> list[str]:
        """Returns the objects under `name`, from the one it stands on down to the table."""
        out, current = [], self.get(name).on
        while current is not None and current not in out and self.has(current):
            out.append(current)
            current = self.get(current).on
        return out

    def tower_above(self, name: str) -> list[str]:
        """Returns the objects stacked on `name`, from the one directly on it upwards."""
        out, current = [], self.above(name)
        while current is not None and current not in out:
            out.append(current)
            current = self.above(current)
        return out

    def stack_level(self, name: str) -> int:
        """Returns how many objects are under `name` in its tower (0: on the table)."""
        return len(self.tower_below(name))

    def state_bit(self, name: str) -> int:
        """Returns the paper's binary state: cup full, drawer open, box blocked."""
        obj = self.get(name)
        if obj.type == "cup":
            return int(obj.full)
        if obj.type == "drawer":
            return int(obj.open)
        return int(self.above(name) is not None or obj.inside is not None)

    # ---------------------------------------------------------------- geometry

    def resting_position(self, name: str) -> tuple[float, float, float]:
        """Returns where an object's support puts it (its own position if on the table)."""
        obj = self.get(name)
        if self.is_held(name):
            return tuple(float(v) for v in self.robot.tcp)
        if obj.on is not None and self.has(obj.on):
            base = self.get(obj.on)
            x, y, z = self.resting_position(base.name)
            return x, y, z + base.size / 2 + obj.size / 2
        if obj.inside is not None and self.has(obj.inside):
            drawer = self.get(obj.inside)
            x, y, z = self.resting_position(drawer.name)
            x += drawer_direction(x) * DRAWER_TRAY_OFFSET if drawer.open else 0.0
            return x, y, z - drawer.size / 2 + DRAWER_FLOOR + obj.size / 2
        x, y, _ = obj.position
        return float(x), float(y), obj.size / 2

    def settle(self) -> None:
        """Moves stacked, contained and held objects to where their support puts them."""
        for obj in self.objects:
            if obj.on is not None or obj.inside is not None or self.is_held(obj.name):
                obj.position = self.resting_position(obj.name)

    # ---------------------------------------------------------------- consistency

    def problems(self) -> list[str]:
        """Returns every broken rule (empty for a consistent scene), one sentence each."""
        out: list[str] = []
        names = self.names
        for name in sorted({n for n in names if names.count(n) > 1}):
            out.append(f"object name {name!r} is used more than once")
        for obj in self.objects:
            out += self._object_problems(obj)
        out += self._robot_problems()
        return out

    def _object_problems(self, obj: SceneObject) -> list[str]:
        out = []
        if obj.type not in OBJECT_TYPES:
            return [f"{obj.name} has unknown type {obj.type!r} (known: {', '.join(OBJECT_TYPES)})"]
        if obj.on is not None and obj.inside is not None:
            out.append(f"{obj.name} is both on {obj.on} and inside {obj.inside}")
        if obj.on is not None:
            out += self._support_problems(obj)
        if obj.inside is not None:
            if not self.has(obj.inside) or self.get(obj.inside).type != "drawer":
                out.append(f"{obj.name} is inside {obj.inside!r}, which is not a drawer here")
            elif obj.type not in GRASPABLE:
                out.append(f"{obj.name} is a {obj.type} and cannot be inside a drawer")
        if obj.type == "drawer" and len(self.contents(obj.name)) > DRAWER_CAPACITY:
            out.append(f"{obj.name} holds {len(self.contents(obj.name))} objects; its capacity "
                       f"is {DRAWER_CAPACITY}")
        on_it = [o.name for o in self.objects if o.on == obj.name]
        if len(on_it) > 1:
            out.append(f"{', '.join(on_it)} all stand on {obj.name}; one at most")
        return out

    def _support_problems(self, obj: SceneObject) -> list[str]:
        if obj.type == "drawer":
            return [f"{obj.name} is a drawer and must stand on the table, not on {obj.on}"]
        if not self.has(obj.on) or obj.on == obj.name:
            return [f"{obj.name} stands on {obj.on!r}, which is not another object here"]
        base = self.get(obj.on)
        if base.type not in SUPPORTS:
            return [f"{obj.name} stands on {base.name}, a {base.type}; only boxes and drawers "
                    "carry objects"]
        below = self.tower_below(obj.name)
        if obj.name in below:
            return [f"{obj.name} is part of a cycle of objects standing on each other"]
        if base.inside is not None:
            return [f"{obj.name} stands on {base.name}, which is inside {base.inside}"]
        if len(below) + 1 > MAX_STACK:
            return [f"the tower under {obj.name} is {len(below) + 1} objects high; at most "
                    f"{MAX_STACK}"]
        return []

    def _robot_problems(self) -> list[str]:
        held = self.robot.holding
        if held is None:
            return []
        if not self.has(held):
            return [f"the robot holds {held!r}, which is not in the scene"]
        obj, out = self.get(held), []
        if obj.type not in GRASPABLE:
            out.append(f"the robot holds {held}, a {obj.type}, which is not graspable")
        if obj.on is not None or obj.inside is not None:
            out.append(f"the robot holds {held}, which also rests on or inside another object")
        if self.above(held) is not None:
            out.append(f"the robot holds {held}, but {self.above(held)} stands on it")
        if self.robot.gripper_open:
            out.append(f"the robot holds {held} with an open gripper")
        return out

    # ---------------------------------------------------------------- wire

    def to_dict(self) -> dict[str, Any]:
        """Returns the contract's scene body: ``{objects: [...], robot: {...}}``."""
        objects = []
        for obj in self.objects:
            item: dict[str, Any] = {"name": obj.name, "type": obj.type,
                                    "position": [float(v) for v in obj.position],
                                    "size": float(obj.size)}
            if obj.type == "cup":
                item["full"] = bool(obj.full)
            if obj.type == "drawer":
                item.update(open=bool(obj.open), opening=1.0 if obj.open else 0.0,
                            contains=self.contents(obj.name))
            else:
                item.update(on=obj.on, inside=obj.inside)
            objects.append(item)
        robot = {"tcp": [float(v) for v in self.robot.tcp],
                 "gripper_open": bool(self.robot.gripper_open), "holding": self.robot.holding}
        return {"objects": objects, "robot": robot}

    def to_message(self, seq: int = 0, ts: float | None = None) -> dict[str, Any]:
        """Returns a complete ``cbgo/scene/state`` message."""
        return {"v": SCHEMA_VERSION, "ts": time.time() if ts is None else ts, "seq": seq,
                **self.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scene:
        """Builds a scene from a contract scene body or ``scene/state`` message.

        Optional fields default to the resting state (cup empty, drawer closed, on the table).
        A drawer counts as open when ``open`` is true or, without ``open``, when ``opening``
        is at least 0.5. A drawer's ``contains`` fills in its objects' missing ``inside``.
        Consistency is not checked here: call `problems()`.
        """
        objects = []
        for item in data.get("objects", []):
            is_open = item.get("open")
            if is_open is None:
                is_open = float(item.get("opening") or 0.0) >= 0.5
            objects.append(SceneObject(
                name=item["name"], type=item["type"],
                position=tuple(float(v) for v in item["position"]),
                size=float(item.get("size", DEFAULT_SIZES.get(item["type"], 0.05))),
                full=bool(item.get("full", False)), open=bool(is_open),
                on=item.get("on"), inside=item.get("inside")))
        scene = cls(objects)
        for item in data.get("objects", []):
            for child in item.get("contains") or []:
                if scene.has(child) and scene.get(child).inside is None:
                    scene.get(child).inside = item["name"]
        robot = data.get("robot") or {}
        scene.robot = Robot(tcp=tuple(float(v) for v in robot.get("tcp", Robot.tcp)),
                            gripper_open=bool(robot.get("gripper_open", True)),
                            holding=robot.get("holding"))
        return scene
