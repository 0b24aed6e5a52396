"""The planner's rules: which unmet preconditions it repairs, and with which objects.

Preconditions come from the world model (`cbgo.world.actions.failures`, one `Failure` per unmet
precondition, each with a stable ``code``). The planner adds two rules of its own, physical
facts the symbolic model leaves out (`planner_failures`):

- ``hand_busy``: open/close grasp the drawer's handle, which one parallel gripper cannot do while
  it holds something;
- ``arm_inside``: close would drag the arm with the tray while the TCP is inside the open
  drawer (below the cabinet's top, over the tray).

The repairs, by failure code (the behaviour tree in `tree` builds one guard per row):

==================================  ===============================================================
unmet precondition (codes)          repair
==================================  ===============================================================
``holding`` (pick_up)               place the held object on the nearest free table column
``hand_busy``/``holding``           place the held object first (it is picked again later if the
(open, close)                       goal needs it)
``not_free`` (pick_up, put_on)      take the tower above the object off, top first: pick the top
                                    object, place it; repeat until the object is free
``drawer_closed`` (put_into; pour   open that drawer (itself repaired: place first if holding)
into a cup in a closed drawer)
``not_holding`` (put_into, put_on,  pick the source object (`choose_source`); a held object that
pour), ``held_not_cup``,            is not the source is placed first
``held_empty``, ``is_held`` (pour)
``arm_inside`` (close)              move_up until the TCP is out of the drawer
goal already true: ``is_held``      nothing to do: the plan succeeds with no action
(pick_up), ``already_open``
(open), ``already_closed`` (close)
==================================  ===============================================================

Anything else (a full drawer or cup, a target inside a drawer, no free table column, a move
out of the grid, a wrong or unknown object, a tower too high) has no repair: the tree fails
with ``no repair for: <the world model's sentence>``.

Which object to fetch (`choose_source`), first that fits: the object named in the intent's
``params.source``; the object the robot held when the intent arrived (the payload a repair set
aside); the object it held most recently before that; for pour only, the full cup the person
attended to most (the intent's ``p_object``, highest first; ties: nearest the target). It must be
graspable, in the scene, not the target, not inside a drawer, and for pour a full cup.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from cbgo.world import Failure, Scene
from cbgo.world import failures as world_failures
from cbgo.world.scene import DRAWER_TRAY_OFFSET, GRASPABLE, drawer_direction

DRAWER_ACTIONS = ("open", "close")
FETCH_ACTIONS = ("put_into", "put_on", "pour")
# world-model codes that mean "the intent names something the planner cannot act on"
_INVALID_TARGET = frozenset({"unknown_action", "needs_object", "unknown_object", "wrong_type"})

# failure codes each repair answers (a guard of the tree holds while none of them is reported)
HAND_BUSY = frozenset({"hand_busy", "holding"})
NOT_FREE = frozenset({"not_free"})
DRAWER_CLOSED = frozenset({"drawer_closed"})
ARM_INSIDE = frozenset({"arm_inside"})
# goal already reached: the intended action has nothing left to do
GOAL_CODES: dict[str, str] = {"pick_up": "is_held", "open": "already_open",
                              "close": "already_closed"}


@dataclass(frozen=True)
class PlanMemory:
    """What the planner remembers when an intent starts; fixed for the whole plan.

    Attributes:
        source_hint: the object named in ``params.source``, if any.
        payload: what the robot held when the intent arrived (a repair may set it aside).
        last_held: the object the robot held most recently before this intent.
        attention: objects by the intent's ``p_object``, most attended first.
    """

    source_hint: str | None = None
    payload: str | None = None
    last_held: str | None = None
    attention: tuple[str, ...] = field(default_factory=tuple)

    @classmethod
    def at_start(cls, intent: Mapping[str, Any], scene: Scene,
                 last_held: str | None = None) -> PlanMemory:
        """Returns the memory of a plan that starts now, from the intent and the scene."""
        hint = (intent.get("params") or {}).get("source")
        p_object = intent.get("p_object") or {}
        attention = tuple(sorted(p_object, key=lambda name: (-float(p_object[name]), name)))
        return cls(source_hint=hint if isinstance(hint, str) else None,
                   payload=scene.robot.holding, last_held=last_held, attention=attention)


def planner_failures(action: str, obj: str | None, scene: Scene) -> list[Failure]:
    """Returns the unmet preconditions the planner adds to the world model's (see module doc)."""
    if action not in DRAWER_ACTIONS or not scene.has(obj) or scene.get(obj).type != "drawer":
        return []
    out = []
    held = scene.robot.holding
    if held is not None:
        out.append(Failure("hand_busy", f"the gripper holds {held} and must be free to grasp "
                                        f"the handle of {obj}", ("place", None)))
    if action == "close" and arm_inside(scene, obj):
        out.append(Failure("arm_inside", f"the gripper is inside {obj}", ("move_up", None)))
    return out


def all_failures(action: str, obj: str | None, scene: Scene,
                 params: Mapping[str, Any] | None = None) -> list[Failure]:
    """Returns the world model's unmet preconditions plus the planner's own."""
    found = world_failures(action, obj, scene, params)
    if any(f.code in _INVALID_TARGET for f in found):
        return found
    return found + [f for f in planner_failures(action, obj, scene)
                    if f.code not in {g.code for g in found}]


def arm_inside(scene: Scene, drawer: str) -> bool:
    """Returns whether the TCP is inside an open drawer: over its tray, below its top."""
    d = scene.get(drawer)
    if not d.open:
        return False
    x, y, z = scene.resting_position(drawer)
    x += drawer_direction(x) * DRAWER_TRAY_OFFSET
    half = d.size / 2
    tx, ty, tz = scene.robot.tcp
    return abs(tx - x) <= half and abs(ty - y) <= half and tz < z + half


def codes(found: list[Failure]) -> set[str]:
    """Returns the codes of a list of failures."""
    return {f.code for f in found}


def source_fits(action: str, name: str | None, target: str | None, scene: Scene) -> bool:
    """Returns whether `name` can be fetched as what `action` moves onto/into/out of `target`."""
    if name is None or name == target or not scene.has(name):
        return False
    obj = scene.get(name)
    if obj.type not in GRASPABLE or obj.inside is not None:
        return False
    return action != "pour" or (obj.type == "cup" and obj.full)


def choose_source(action: str, target: str | None, scene: Scene,
                  memory: PlanMemory) -> str | None:
    """Returns the object to fetch for put_into/put_on/pour (see the module doc), or None."""
    ordered = [memory.source_hint, memory.payload, memory.last_held]
    if action == "pour":
        ordered += list(memory.attention)
        ordered += sorted((o.name for o in scene.objects if o.type == "cup"),
                          key=lambda n: _distance(scene, n, target))
    for name in ordered:
        if source_fits(action, name, target, scene):
            return name
    return None


def no_source_reason(action: str, target: str | None) -> str:
    """Returns why no source object could be chosen, as a sentence for people."""
    what = ("full cup to pour from" if action == "pour"
            else f"object to {action.replace('_', ' ')} {target}")
    return (f"the gripper holds nothing and there is no {what} (name one in params.source, or "
            "hold it when giving the intent)")


def top_of(scene: Scene, name: str) -> str | None:
    """Returns the top object of the tower standing on `name`, or None if nothing stands on it."""
    tower = scene.tower_above(name)
    return tower[-1] if tower else None


def drawer_of(scene: Scene, name: str | None) -> str | None:
    """Returns the drawer an object is inside, or the object itself if it is a drawer."""
    if not scene.has(name):
        return None
    obj = scene.get(name)
    return name if obj.type == "drawer" else obj.inside


def _distance(scene: Scene, a: str, b: str | None) -> float:
    if not scene.has(b):
        return 0.0
    pa, pb = scene.resting_position(a), scene.resting_position(b)
    return sum((u - v) ** 2 for u, v in zip(pa, pb, strict=True)) ** 0.5
