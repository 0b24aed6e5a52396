"""The eleven actions: their preconditions and their symbolic effects on a `Scene`.

`failures(action, object, scene)` lists every unmet precondition as a `Failure` (a stable
``code``, a sentence for people, and where one exists the action that would repair it — hints
for the planner's behaviour tree); `check` returns the first sentence or None; `apply` returns
the scene after the action, or raises `InfeasibleAction`. Nothing here mutates its input.

Preconditions (the paper's, made explicit; "free" = nothing stands on it and it is neither
inside a drawer nor held):

==========  ======================================================================
action      needs
==========  ======================================================================
move_*      the TCP stays inside the grid (``params.distance`` m, default one cell);
            up/down along z, left/right as the person sees it (left = −y); the gripper
            fits at the goal (`gripper_room`)
place       a held object and a free table column (the TCP's, else the nearest;
            ``params.position`` asks for a given one); the column a drawer opens into is
            kept free for its tray
pick_up     an empty gripper; a free cup or box
put_on      a held object; a free box or drawer cabinet as target, not inside a drawer,
            the tower staying within `MAX_STACK`
put_into    a held object; an open drawer with room (`DRAWER_CAPACITY`)
pour        a held full cup; another cup that is empty and not in a closed drawer
            (``params.angle_deg``, default 90)
open/close  a closed/open drawer
==========  ======================================================================

**The gripper at a move's goal** (`gripper_room`): seen top-down, at the goal TCP, neither
what hangs under the TCP (the fingertips, `FINGERTIP_BELOW_TCP` down and `FINGER_HALF` either
side; or the held object, grasped `GRASP_DEPTH` under its top, its footprint) nor the hand
(from `HAND_BOTTOM` above the TCP up; `HAND_HALF` m across and along the fingers' closing
axis, world y: top-down at yaw 0) may overlap an object whose top is above its bottom (5 mm
tolerance). Footprints are squares of edge ``size``; an open drawer's also covers its tray
and handle in front of the cabinet, on the side it opens to (`drawer_direction`;
`DRAWER_TRAVEL_PER_SIZE` × size + 0.03 m, top 0.01 m under the cabinet's). A robot may refuse
more (mujoco-sim also checks the way there and the hand's real yaw).

Moves and place ignore the object (`OBJECT_AGNOSTIC`). Effects: moves shift the TCP by whole
cells and carry the held object; pick_up takes the object to the gripper (the TCP goes to it);
place, put_on and put_into release it on the table, on the target or into the drawer (the TCP
ends at the released object); pour fills the target and empties the held cup; open/close
switch the drawer (its contents ride on the tray) and leave the TCP where it was.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cbgo.wire import ACTIONS
from cbgo.world.grid import DEFAULT_GRID, Column, Grid
from cbgo.world.scene import (
    DRAWER_CAPACITY,
    GRASPABLE,
    MAX_STACK,
    SUPPORTS,
    Scene,
    SceneObject,
    drawer_direction,
)
from cbgo.world.workspace import DRAWER_TRAVEL_PER_SIZE

MOVES: dict[str, tuple[int, int, int]] = {
    "move_up": (0, 0, 1), "move_down": (0, 0, -1),
    "move_left": (0, -1, 0), "move_right": (0, 1, 0),  # the person faces the robot along −x
}
OBJECT_AGNOSTIC = frozenset({*MOVES, "place"})
TARGET_TYPES: dict[str, tuple[str, ...]] = {
    "pick_up": GRASPABLE, "put_on": SUPPORTS, "put_into": ("drawer",), "pour": ("cup",),
    "open": ("drawer",), "close": ("drawer",),
}
DEFAULT_PARAMS: dict[str, dict[str, Any]] = {"pour": {"angle_deg": 90.0}}
# the gripper, top-down (mujoco-sim's Panda hand): see "The gripper at a move's goal" above
FINGERTIP_BELOW_TCP = 0.012  # m
FINGER_HALF = 0.02  # m either side of the TCP that the (empty) fingers take
GRASP_DEPTH = 0.02  # m under a held object's top that the TCP holds it (at most half its size)
HAND_BOTTOM = 0.045  # m from the TCP up to the underside of the hand
HAND_HALF = (0.035, 0.105)  # m, the hand's half extents along x and y (across and along the
# fingers' closing axis)
ROOM_TOL = 0.005  # m an object's top may reach above the bottom of the gripper's part
TRAY_OUT_EXTRA = 0.03  # m the open tray's front panel and handle reach beyond its travel


@dataclass(frozen=True)
class Failure:
    """One unmet precondition.

    Attributes:
        code: stable identifier, e.g. ``drawer_closed``, ``holding``, ``not_free``.
        message: a sentence for people, e.g. ``drawer1 is closed``.
        repair: the (action, object) that would satisfy it, when one action does.
    """

    code: str
    message: str
    repair: tuple[str, str | None] | None = None


class InfeasibleAction(ValueError):
    """`apply` was asked for an action whose preconditions do not hold."""

    def __init__(self, action: str, obj: str | None, failures: list[Failure]):
        self.action, self.object, self.failures = action, obj, failures
        target = f"({obj})" if obj else ""
        super().__init__(f"{action}{target}: " + "; ".join(f.message for f in failures))


# ==================================================================== preconditions


def failures(action: str, obj: str | None, scene: Scene, params: Mapping[str, Any] | None = None,
             grid: Grid = DEFAULT_GRID) -> list[Failure]:
    """Returns every unmet precondition of `action` on `obj` (empty: feasible).

    Args:
        action: one of `cbgo.wire.ACTIONS`.
        obj: the target object's name; ignored by moves and place.
        scene: the world.
        params: metric parameters (``distance`` for moves, ``position`` for place).
        grid: the TCP grid.
    """
    params = params or {}
    if action not in ACTIONS:
        return [Failure("unknown_action", f"unknown action {action!r} (known: "
                                          f"{', '.join(ACTIONS)})")]
    if action in MOVES:
        return _move_failures(action, scene, params, grid)
    if action == "place":
        return _place_failures(scene, params, grid)
    if obj is None:
        return [Failure("needs_object", f"{action} needs a target object")]
    if not scene.has(obj):
        return [Failure("unknown_object", f"there is no {obj} in the scene")]
    target = scene.get(obj)
    if target.type not in TARGET_TYPES[action]:
        kinds = " or ".join(f"a {t}" for t in TARGET_TYPES[action])
        return [Failure("wrong_type", f"{action} needs {kinds}; {obj} is a {target.type}")]
    return _TARGET_CHECKS[action](scene, obj)


def check(action: str, obj: str | None, scene: Scene, params: Mapping[str, Any] | None = None,
          grid: Grid = DEFAULT_GRID) -> str | None:
    """Returns why `action` on `obj` is infeasible (the first reason), or None if it is feasible."""
    found = failures(action, obj, scene, params, grid)
    return found[0].message if found else None


def feasible(action: str, obj: str | None, scene: Scene, params: Mapping[str, Any] | None = None,
             grid: Grid = DEFAULT_GRID) -> bool:
    """Returns whether every precondition of `action` on `obj` holds."""
    return not failures(action, obj, scene, params, grid)


def candidates(scene: Scene, grid: Grid = DEFAULT_GRID) -> list[tuple[str, str | None]]:
    """Returns every feasible (action, object) pair; moves and place once, with object None."""
    out: list[tuple[str, str | None]] = []
    for action in ACTIONS:
        targets = [None] if action in OBJECT_AGNOSTIC else scene.names
        out += [(action, o) for o in targets if feasible(action, o, scene, grid=grid)]
    return out


def _holding_failures(scene: Scene) -> list[Failure]:
    if scene.robot.holding is None:
        return [Failure("not_holding", "the gripper holds nothing")]
    return []


def _cell_steps(action: str, params: Mapping[str, Any], grid: Grid) -> int | Failure:
    distance = params.get("distance")
    if distance is None:
        return 1
    if type(distance) not in (int, float) or not 0 < distance < 10:
        return Failure("bad_param", f"distance must be a positive number of metres, got "
                                    f"{distance!r}")
    axis = [abs(v) for v in MOVES[action]].index(1)
    return max(1, round(float(distance) / grid.step[axis]))


def _move_failures(action: str, scene: Scene, params: Mapping[str, Any],
                   grid: Grid) -> list[Failure]:
    steps = _cell_steps(action, params, grid)
    if isinstance(steps, Failure):
        return [steps]
    cell = grid.cell_of(scene.robot.tcp)
    target = tuple(c + steps * d for c, d in zip(cell, MOVES[action], strict=True))
    if not grid.contains(target):
        way = action.removeprefix("move_")
        return [Failure("out_of_reach", f"the TCP cannot move {way} by {steps} cell(s): it would "
                                        "leave the workspace grid")]
    blocker = gripper_room(scene, grid.position(target))
    if blocker is not None:
        return [Failure("no_room", f"the gripper does not fit at the goal cell {list(target)}: "
                                   f"{blocker} is there")]
    return []


def gripper_room(scene: Scene, tcp) -> str | None:
    """Returns the object the gripper (and its load) would overlap with the TCP at tcp, or None.

    The rule of "The gripper at a move's goal" in the module docstring.
    """
    held = scene.get(scene.robot.holding) if scene.robot.holding is not None else None
    x, y, z = (float(v) for v in tcp)
    if held is None:
        parts = [(z - FINGERTIP_BELOW_TCP, FINGER_HALF, FINGER_HALF)]
    else:
        hang = max(FINGERTIP_BELOW_TCP, held.size - min(GRASP_DEPTH, held.size / 2))
        parts = [(z - hang, held.size / 2, held.size / 2)]
    parts.append((z + HAND_BOTTOM, *HAND_HALF))
    for obj in scene.objects:
        if held is not None and obj.name == held.name:
            continue
        for (x0, x1, y0, y1), top in _footprints(obj):
            for bottom, hx, hy in parts:
                if (top > bottom - ROOM_TOL and x0 - hx < x < x1 + hx
                        and y0 - hy < y < y1 + hy):
                    return obj.name
    return None


def _footprints(obj: SceneObject) -> list[tuple[tuple[float, float, float, float], float]]:
    """Returns an object's footprints ((x0, x1, y0, y1), top z): an open drawer has two."""
    x, y, z = (float(v) for v in obj.position)
    half = obj.size / 2
    out = [((x - half, x + half, y - half, y + half), z + half)]
    if obj.type == "drawer" and obj.open:
        way = drawer_direction(x)
        front = x + way * half
        out_to = front + way * (DRAWER_TRAVEL_PER_SIZE * obj.size + TRAY_OUT_EXTRA)
        out.append(((min(front, out_to), max(front, out_to), y - half, y + half),
                    obj.size - 0.01))
    return out


def reserved_columns(scene: Scene, grid: Grid = DEFAULT_GRID) -> dict[Column, str]:
    """Returns the table columns taken, each with the object that takes it.

    A column is taken by an object standing on the table there, and a drawer also takes the
    column it opens into (`drawer_direction`) for its tray.
    """
    taken: dict[Column, str] = {}
    for obj in scene.objects:
        if obj.on is None and obj.inside is None and not scene.is_held(obj.name):
            i, j = grid.column_of(obj.position)
            taken[(i, j)] = obj.name
            tray = (i + drawer_direction(obj.position[0]), j)
            if obj.type == "drawer" and grid.contains((*tray, 0)):
                taken.setdefault(tray, obj.name)
    return taken


def place_column(scene: Scene, params: Mapping[str, Any] | None = None,
                 grid: Grid = DEFAULT_GRID) -> Column | Failure:
    """Returns the table column `place` would use, or the Failure why there is none."""
    taken = reserved_columns(scene, grid)
    wanted = (params or {}).get("position")
    if wanted is not None:
        if (not isinstance(wanted, Sequence) or len(wanted) != 3
                or not all(type(v) in (int, float) for v in wanted)):
            return Failure("bad_param", f"position must be [x, y, z] in metres, got {wanted!r}")
        column = grid.column_of(wanted)
        if column in taken:
            return Failure("place_taken", f"the table at {list(wanted)} is taken by "
                                          f"{taken[column]}")
        return column
    for column in grid.columns_by_distance(grid.column_of(scene.robot.tcp)):
        if column not in taken:
            return column
    return Failure("no_free_place", "there is no free place on the table")


def _place_failures(scene: Scene, params: Mapping[str, Any], grid: Grid) -> list[Failure]:
    out = _holding_failures(scene)
    if out:
        return out
    column = place_column(scene, params, grid)
    return [column] if isinstance(column, Failure) else []


def _free_failures(scene: Scene, obj: str) -> list[Failure]:
    out = []
    top = scene.above(obj)
    if top is not None:
        out.append(Failure("not_free", f"{top} stands on {obj}", ("pick_up", top)))
    inside = scene.get(obj).inside
    if inside is not None:
        out.append(Failure("inside_drawer", f"{obj} is inside {inside}"))
    return out


def _pick_up(scene: Scene, obj: str) -> list[Failure]:
    held = scene.robot.holding
    if held == obj:
        return [Failure("is_held", f"{obj} is already in the gripper")]
    out = []
    if held is not None:
        out.append(Failure("holding", f"the gripper already holds {held}", ("place", None)))
    return out + _free_failures(scene, obj)


def _put_on(scene: Scene, obj: str) -> list[Failure]:
    out = _holding_failures(scene)
    if scene.is_held(obj):
        return out + [Failure("is_held", f"{obj} is in the gripper")]
    out += _free_failures(scene, obj)
    if not out and scene.stack_level(obj) + 2 > MAX_STACK:
        out.append(Failure("stack_too_high", f"a tower on {obj} would exceed {MAX_STACK} "
                                             "objects"))
    return out


def _put_into(scene: Scene, obj: str) -> list[Failure]:
    out = _holding_failures(scene)
    if not scene.get(obj).open:
        out.append(Failure("drawer_closed", f"{obj} is closed", ("open", obj)))
    if len(scene.contents(obj)) >= DRAWER_CAPACITY:
        out.append(Failure("drawer_full", f"{obj} is full ({', '.join(scene.contents(obj))} "
                                          "inside)"))
    return out


def _pour(scene: Scene, obj: str) -> list[Failure]:
    held = scene.robot.holding
    out = _holding_failures(scene)
    if held is not None:
        if scene.get(held).type != "cup":
            out.append(Failure("held_not_cup", f"the gripper holds {held}, not a cup"))
        elif not scene.get(held).full:
            out.append(Failure("held_empty", f"{held} in the gripper is empty"))
    if held == obj:
        return out + [Failure("is_held", f"{obj} is the cup in the gripper")]
    if scene.get(obj).full:
        out.append(Failure("cup_full", f"{obj} is already full"))
    drawer = scene.get(obj).inside
    if drawer is not None and not scene.get(drawer).open:
        out.append(Failure("drawer_closed", f"{obj} is inside {drawer}, which is closed",
                           ("open", drawer)))
    return out


def _open(scene: Scene, obj: str) -> list[Failure]:
    return [Failure("already_open", f"{obj} is already open")] if scene.get(obj).open else []


def _close(scene: Scene, obj: str) -> list[Failure]:
    return [] if scene.get(obj).open else [Failure("already_closed", f"{obj} is already closed")]


_TARGET_CHECKS = {"pick_up": _pick_up, "put_on": _put_on, "put_into": _put_into, "pour": _pour,
                  "open": _open, "close": _close}


# ==================================================================== effects


def apply(action: str, obj: str | None, params: Mapping[str, Any] | None, scene: Scene,
          grid: Grid = DEFAULT_GRID) -> Scene:
    """Returns the scene after `action` on `obj` (the input is not changed).

    Args:
        action: one of `cbgo.wire.ACTIONS`.
        obj: the target object's name (ignored by moves and place).
        params: metric parameters (see the module docstring); None for none.
        scene: the world before the action.
        grid: the TCP grid.

    Raises:
        InfeasibleAction: a precondition does not hold (it carries the `Failure` list).
    """
    params = dict(params or {})
    found = failures(action, obj, scene, params, grid)
    if found:
        raise InfeasibleAction(action, obj, found)
    after = scene.copy()
    if action in MOVES:
        _apply_move(after, action, params, grid)
    elif action == "place":
        _apply_place(after, params, grid)
    else:
        _APPLY[action](after, obj)
    after.settle()
    return after


def _apply_move(scene: Scene, action: str, params: Mapping[str, Any], grid: Grid) -> None:
    steps = _cell_steps(action, params, grid)
    cell = grid.cell_of(scene.robot.tcp)
    scene.robot.tcp = grid.position(tuple(c + steps * d for c, d in zip(cell, MOVES[action],
                                                                        strict=True)))


def _release(scene: Scene) -> str:
    held = scene.robot.holding
    scene.robot.holding, scene.robot.gripper_open = None, True
    return held


def _apply_place(scene: Scene, params: Mapping[str, Any], grid: Grid) -> None:
    column = place_column(scene, params, grid)
    held = scene.get(_release(scene))
    x, y = grid.column_xy(column)
    held.position = (x, y, held.size / 2)
    scene.robot.tcp = (x, y, scene.robot.tcp[2])


def _apply_pick_up(scene: Scene, obj: str) -> None:
    target = scene.get(obj)
    scene.robot.tcp = tuple(target.position)
    target.on = None
    scene.robot.holding, scene.robot.gripper_open = obj, False


def _apply_put_on(scene: Scene, obj: str) -> None:
    held = scene.get(_release(scene))
    held.on = obj
    held.position = scene.resting_position(held.name)
    scene.robot.tcp = held.position


def _apply_put_into(scene: Scene, obj: str) -> None:
    held = scene.get(_release(scene))
    held.inside = obj
    held.position = scene.resting_position(held.name)
    scene.robot.tcp = held.position


def _apply_pour(scene: Scene, obj: str) -> None:
    scene.get(obj).full = True
    scene.get(scene.robot.holding).full = False


def _apply_open(scene: Scene, obj: str) -> None:
    scene.get(obj).open = True


def _apply_close(scene: Scene, obj: str) -> None:
    scene.get(obj).open = False


_APPLY = {"pick_up": _apply_pick_up, "put_on": _apply_put_on, "put_into": _apply_put_into,
          "pour": _apply_pour, "open": _apply_open, "close": _apply_close}
