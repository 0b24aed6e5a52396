"""The world as the franka service knows it: declared by the user, tracked through its own actions.

A real cell has no simulator to read the objects from. The user declares the layout (a
``--scene`` file or ``cbgo/sim/reset``), as lab demos do, and the service keeps it up to date
with what it moved itself: a done action's effects are the world model's (`cbgo.world.apply`),
the TCP and gripper are measured.

When an action fails part-way (a grasp that closed on nothing, a reflex, a stop, a lost
connection), the service cannot see where the objects it was handling ended up. It says so
instead of guessing: those objects (`Plan.touched`, and the load in the gripper) become
*unknown*. An unknown object leaves ``objects`` in ``cbgo/scene/state`` and is listed under the
extra field ``unknown`` (``[{name, type, size, last_position, why}]``); anything resting on or in
it goes with it. While something is unknown every action is refused, naming it, until the user
declares the scene again (``cbgo/sim/reset``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from cbgo import keys
from cbgo.wire import SCHEMA_VERSION
from cbgo.world import Scene


@dataclass
class Unknown:
    """An object whose place the service no longer knows."""

    name: str
    type: str
    size: float
    last_position: tuple[float, float, float]
    why: str

    def to_dict(self) -> dict[str, Any]:
        """Returns the entry of the ``unknown`` list."""
        return {"name": self.name, "type": self.type, "size": self.size,
                "last_position": [round(float(v), 4) for v in self.last_position],
                "why": self.why}


@dataclass
class TrackedWorld:
    """The declared scene, kept up to date, and what is no longer known."""

    scene: Scene
    unknown: dict[str, Unknown] = field(default_factory=dict)
    seq: int = 0

    def refusal(self) -> str | None:
        """Returns why no action may run on this world (something unknown), or None."""
        if not self.unknown:
            return None
        which = "; ".join(f"{u.name} ({u.why})" for u in self.unknown.values())
        return (f"the place of {', '.join(self.unknown)} is unknown: {which}; declare the scene "
                "again with cbgo/sim/reset")

    def done(self, after: Scene, tcp, holding_ok: bool = True) -> None:
        """An action was done: the world model's effects, at the measured TCP."""
        self.scene = after.copy()
        self.scene.robot.tcp = tuple(float(v) for v in tcp)
        if holding_ok:
            self.scene.settle()

    def lose(self, names, why: str) -> None:
        """Marks objects (and what rests on or in them) unknown and takes them out of the scene."""
        scene = self.scene
        pending = [n for n in names if scene.has(n)]
        while pending:
            name = pending.pop(0)
            if name in self.unknown or not scene.has(name):
                continue
            obj = scene.get(name)
            self.unknown[name] = Unknown(name, obj.type, float(obj.size),
                                         tuple(float(v) for v in obj.position), why)
            pending += [o.name for o in scene.objects if o.on == name or o.inside == name]
        for name in self.unknown:
            if scene.has(name):
                scene.objects = [o for o in scene.objects if o.name != name]
        if scene.robot.holding in self.unknown:
            scene.robot.holding = None

    def release_grip(self, tcp, gripper_open: bool) -> None:
        """Sets the measured TCP and whether the fingers are open (after a failure)."""
        self.scene.robot.tcp = tuple(float(v) for v in tcp)
        self.scene.robot.gripper_open = gripper_open

    def message(self) -> dict[str, Any]:
        """Returns the next ``cbgo/scene/state`` message, with the ``unknown`` list."""
        self.seq += 1
        body = self.scene.to_message(self.seq, time.time())
        body["unknown"] = [u.to_dict() for u in self.unknown.values()]
        return body

    def act_reply(self, ok: bool, error: str | None, duration_s: float = 0.0,
                  **extra: Any) -> dict:
        """Returns a ``robot/act`` reply carrying the world as it is now."""
        return keys.ROBOT_ACT.reply(ok, error, duration_s=round(max(duration_s, 0.0), 4),
                                    scene=self.message(), **extra)


def scene_body(scene: Scene) -> dict[str, Any]:
    """Returns a scene as a contract scene body with the schema version (for logs and tests)."""
    return {"v": SCHEMA_VERSION, **scene.to_dict()}
