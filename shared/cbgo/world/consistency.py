"""Whether a reported scene can be the truth: the check both robots run before they publish.

After a failed action the world is whatever the failure left, and the planner replans from
what the robot reports; a report that contradicts itself (a cup held and inside a drawer at
once) makes every later decision wrong. `check_consistent` lists such contradictions in a
contract scene body (``{objects, robot}``, or a whole ``cbgo/scene/state`` message), and
`failure_error` names them in a failed action's error, as both robots reply:

- the world model's rules (`Scene.problems`): held objects rest on nothing, one place each, …;
- ``inside`` and ``contains`` agree both ways (read from the message, before `Scene.from_dict`
  fills one from the other);
- a held object is at the gripper: its centre within its size plus `HELD_TOL` of the TCP;
- an object reported on the table (not on, inside or held) lies on it: its centre no higher
  than its size (a cup lying on its side is lower than upright, never higher); higher means it
  stands on something the report does not name, or is still falling.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from cbgo.world.scene import Scene

HELD_TOL = 0.05  # m between the TCP and a held object's centre, beyond its own size
TABLE_TOL = 0.01  # m above its own size that an object on the table may seem to be


def check_consistent(scene: Scene | Mapping[str, Any]) -> list[str]:
    """Returns every contradiction in a reported scene (empty: it can be the truth).

    Args:
        scene: a `Scene` or a contract scene body / ``cbgo/scene/state`` message.
    """
    body = scene.to_dict() if isinstance(scene, Scene) else scene
    parsed = Scene.from_dict(dict(body))
    return (parsed.problems() + _containment_disagreements(body) + _held_away(parsed)
            + _floating(parsed))


def _containment_disagreements(body: Mapping[str, Any]) -> list[str]:
    objects = {o["name"]: o for o in body.get("objects", [])}
    out = []
    for name, drawer in objects.items():
        if drawer.get("type") != "drawer" or drawer.get("contains") is None:
            continue
        for child in drawer["contains"]:
            if child not in objects:
                out.append(f"{name} contains {child}, which is not in the scene")
            elif objects[child].get("inside") != name:
                where = objects[child].get("inside")
                out.append(f"{name} contains {child}, but {child} is "
                           + (f"inside {where}" if where else "inside nothing"))
    for name, obj in objects.items():
        container = objects.get(obj.get("inside") or "")
        if container is not None and container.get("contains") is not None \
                and name not in container["contains"]:
            out.append(f"{name} is inside {obj['inside']}, but {obj['inside']} does not "
                       f"list it in contains")
    return out


def _held_away(scene: Scene) -> list[str]:
    held = scene.robot.holding
    if held is None or not scene.has(held):
        return []
    obj = scene.get(held)
    gap = float(np.linalg.norm(np.subtract(obj.position, scene.robot.tcp)))
    if gap <= obj.size + HELD_TOL:
        return []
    return [f"the robot holds {held}, but {held} is {gap:.2f} m from the TCP"]


def _floating(scene: Scene) -> list[str]:
    out = []
    for obj in scene.objects:
        if obj.on is not None or obj.inside is not None or scene.is_held(obj.name):
            continue
        if obj.type != "drawer" and float(obj.position[2]) > obj.size + TABLE_TOL:
            out.append(f"{obj.name} is reported on the table, but its centre is "
                       f"{obj.position[2]:.2f} m high (it stands on something unnamed or is "
                       "falling)")
    return out


def failure_error(error: str, scene: Scene | Mapping[str, Any]) -> tuple[str, list[str]]:
    """Returns a failed action's error naming every contradiction in the scene after it.

    Returns:
        (the error, with the contradictions appended if any; the contradictions).
    """
    problems = check_consistent(scene)
    if not problems:
        return error, []
    return f"{error}; the scene after it is inconsistent: " + "; ".join(problems), problems
