"""The workspace as the contract states it, and whether a scene fits in it.

One home for the concept: both robots (mujoco-sim and dry-robot) answer ``cbgo/sim/info``
with `workspace_info` and refuse at ``cbgo/sim/reset`` every scene for which
`workspace_problems` finds something, so that no scene is accepted and fails later.

The rules, in the robot base frame (metres), for a `Grid` (`cbgo.world.grid`):

- **where objects stand**: the centre of every object on the table lies in the *table area*,
  the grid's columns extended by `REACH_MARGIN` (x 0.30 … 0.70, y −0.20 … 0.20 for the default
  grid); stacked, contained and held objects follow their support;
- **what the arm reaches**: top-down, every point of the table area from the table up to the
  grid's top level (a unit test of mujoco-sim solves the Panda's IK at its corners), but
  nothing nearer the robot's base axis than `MIN_REACH` (top-down, the Panda does not fold
  nearer: mujoco-sim's IK fails within 0.285 m for TCP heights 0.05 … 0.22 m). A drawer opens
  along x towards the middle of the table (`cbgo.world.scene.drawer_direction`): towards the
  robot from x ≥ `DRAWER_OPENS_AWAY_BELOW_X` (0.50 m), away from it nearer. So its opened
  tray, `DRAWER_TRAY_OFFSET` out, stays in the table area, and the handle of the opened drawer,
  which the arm grasps to close it, stays at least `MIN_REACH` from the base axis, wherever
  the drawer stands on the table: a drawer may stand in every column. The tray slides out
  `DRAWER_TRAVEL_PER_SIZE` × size (0.09 m for the default 0.11 m cabinet) and its knob is
  grasped `DRAWER_HANDLE_OUT` in front of the tray: the handle of an open drawer at (x, y) is
  at x ± (size/2 + 0.818 × size + 0.018) (`open_handle_x`), between 0.337 and 0.693 m from
  the base axis for a 0.11 m cabinet anywhere on the table (both checked again here, for other
  grids);
- **sizes** (the edge of an object's bounding cube) within `SIZE_RANGES`: cups from 0.03 m
  (the paper's 0.03 … 0.07 m) to what the gripper takes (it opens 80 mm and needs 12 mm
  between each pad and a cup or box); a drawer cabinet fills at most one cell (0.12 m) and
  must hold a cup;
- **room**: the footprints (squares of edge ``size``) of table objects do not overlap, and
  nothing stands where a drawer's tray slides out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from cbgo.world.grid import DEFAULT_GRID, Grid
from cbgo.world.scene import (
    DEFAULT_SIZES,
    DRAWER_CAPACITY,
    DRAWER_OPENS_AWAY_BELOW_X,
    DRAWER_TRAY_OFFSET,
    MAX_STACK,
    Scene,
    SceneObject,
    drawer_direction,
)

REACH_MARGIN = 0.02  # m beyond the outer columns that table positions may lie (the jitter)
# m, per type; cups as the paper draws them (0.03 … 0.07 m): mujoco-sim grasps, pours from and
# into, stacks, places and puts into drawers the smallest (tests/unit/mujoco_sim/
# test_sim_paper_scenes.py; `cbgo bench sim --generator paper`: 99.6 % of feasible actions done)
SIZE_RANGES = {"cup": (0.03, 0.07), "box": (0.03, 0.055), "drawer": (0.09, 0.11)}
# an opened drawer's tray slides out this many times the cabinet's size, and its handle is
# grasped DRAWER_HANDLE_OUT in front of the tray's front (mujoco-sim builds its cabinets so)
DRAWER_TRAVEL_PER_SIZE = 0.818
DRAWER_HANDLE_OUT = 0.018  # m
MIN_REACH = 0.29  # m from the robot's base axis (x, y = 0) that the arm reaches top-down
OVERLAP_TOL = 0.002  # m two footprints may touch by without counting as overlapping


@dataclass(frozen=True)
class Area:
    """An axis-aligned rectangle on the table (m)."""

    x: tuple[float, float]
    y: tuple[float, float]

    def contains(self, x: float, y: float) -> bool:
        """Returns whether a point lies inside (borders included)."""
        return self.x[0] <= x <= self.x[1] and self.y[0] <= y <= self.y[1]

    def describe(self) -> str:
        """Returns the area as text, e.g. ``x 0.30..0.70, y -0.20..0.20``."""
        return f"x {self.x[0]:.2f}..{self.x[1]:.2f}, y {self.y[0]:.2f}..{self.y[1]:.2f}"


def table_area(grid: Grid = DEFAULT_GRID) -> Area:
    """Returns where the centre of an object on the table may lie: the columns ± the margin."""
    (x0, y0), (x1, y1) = grid.column_xy((0, 0)), grid.column_xy((grid.shape[0] - 1,
                                                                grid.shape[1] - 1))
    m = REACH_MARGIN
    return Area((round(x0 - m, 4), round(x1 + m, 4)), (round(y0 - m, 4), round(y1 + m, 4)))


def workspace_info(grid: Grid = DEFAULT_GRID) -> dict[str, Any]:
    """Returns the ``workspace`` of a ``cbgo/sim/info`` reply (docs/protocol.md)."""
    area = table_area(grid)
    nx, ny, nz = grid.shape
    return {
        "grid": {"shape": list(grid.shape), "origin": list(grid.origin),
                 "step": list(grid.step)},
        "columns_x": [round(grid.column_xy((i, 0))[0], 4) for i in range(nx)],
        "columns_y": [round(grid.column_xy((0, j))[1], 4) for j in range(ny)],
        "levels_z": [round(grid.position((0, 0, k))[2], 4) for k in range(nz)],
        "table_area": {"x": list(area.x), "y": list(area.y)},
        "sizes": {kind: {"min": lo, "max": hi, "default": DEFAULT_SIZES[kind]}
                  for kind, (lo, hi) in SIZE_RANGES.items()},
        "drawer_tray_offset": DRAWER_TRAY_OFFSET,
        "drawer_opens_away_below_x": DRAWER_OPENS_AWAY_BELOW_X,
        "min_reach": MIN_REACH,
        "drawer_handle": {"travel_per_size": DRAWER_TRAVEL_PER_SIZE,
                          "out": DRAWER_HANDLE_OUT},
        "drawer_capacity": DRAWER_CAPACITY,
        "max_stack": MAX_STACK,
    }


class SceneError(ValueError):
    """A scene a robot cannot start from: not a scene, against the rules, or out of reach."""


def startable_scene(scene: Scene | Mapping[str, Any], grid: Grid = DEFAULT_GRID) -> Scene:
    """Returns the settled copy of a scene a robot resets to (a `Scene` or a contract body).

    The one path from ``cbgo/sim/reset``'s scene (or a ``--scene`` file) to a robot's world:
    parsed, judged by `reset_refusal` before anything is built, then settled.

    Raises:
        SceneError: not a scene, or refused (every problem named, `reset_refusal`).
    """
    try:
        parsed = Scene.from_dict(dict(scene)) if isinstance(scene, Mapping) else scene.copy()
    except (KeyError, TypeError, ValueError) as e:
        raise SceneError(f"not a scene: {type(e).__name__}: {e}") from None
    reason = reset_refusal(parsed, grid)
    if reason is not None:
        raise SceneError(reason)
    parsed.settle()
    return parsed


def reset_refusal(scene: Scene, grid: Grid = DEFAULT_GRID) -> str | None:
    """Returns why a robot refuses to reset to this scene (None: it accepts it).

    The judgement both robots give at ``cbgo/sim/reset``: first the world model's rules
    (``inconsistent scene: ...``), then the workspace (``outside the workspace: ...``), each
    with every problem found.
    """
    problems = scene.problems()
    if problems:
        return "inconsistent scene: " + "; ".join(problems)
    problems = workspace_problems(scene, grid)
    if problems:
        return "outside the workspace: " + "; ".join(problems)
    return None


def workspace_problems(scene: Scene, grid: Grid = DEFAULT_GRID) -> list[str]:
    """Returns why a robot cannot execute in this scene (empty: it fits), one sentence each.

    Each sentence names the object, where it is and where the workspace is. The scene should
    be consistent (`Scene.problems`); sizes are judged for every object, positions for those
    on the table.
    """
    area = table_area(grid)
    out = [p for obj in scene.objects for p in _size_problems(obj)]
    table = [o for o in scene.objects if _on_table(scene, o)]
    for obj in table:
        out += _position_problems(obj, area)
    out += _overlaps(table)
    return out


def _on_table(scene: Scene, obj: SceneObject) -> bool:
    return obj.on is None and obj.inside is None and not scene.is_held(obj.name)


def _size_problems(obj: SceneObject) -> list[str]:
    lo, hi = SIZE_RANGES.get(obj.type, (0.0, float("inf")))
    if lo <= obj.size <= hi:
        return []
    return [f"{obj.name} is a {obj.type} of size {obj.size:.3f} m; the workspace takes "
            f"{obj.type}s of {lo:.3f}..{hi:.3f} m (see cbgo/sim/info)"]


def _position_problems(obj: SceneObject, area: Area) -> list[str]:
    x, y = float(obj.position[0]), float(obj.position[1])
    if not area.contains(x, y):
        return [f"{obj.name} at ({x:.2f}, {y:.2f}) is outside the workspace: objects on the "
                f"table stand within {area.describe()} (the grid's columns ± "
                f"{REACH_MARGIN:.2f} m; see cbgo/sim/info)"]
    if obj.type != "drawer":
        return []
    tray_x = x + drawer_direction(x) * DRAWER_TRAY_OFFSET
    if not area.contains(tray_x, y):
        return [f"{obj.name} at ({x:.2f}, {y:.2f}) would open its tray {_way(obj)} to x "
                f"{tray_x:.2f}, out of the arm's reach ({area.describe()})"]
    handle = open_handle_x(obj)
    reach = math.floor(math.hypot(handle, y) * 1000) / 1000  # never shown as MIN_REACH itself
    if math.hypot(handle, y) < MIN_REACH:
        return [f"{obj.name} at ({x:.3f}, {y:.2f}) would open its handle to ({handle:.3f}, "
                f"{y:.2f}), {reach:.3f} m from the robot's base axis: the arm reaches "
                f"top-down no nearer than {MIN_REACH:.2f} m (see cbgo/sim/info)"]
    return []


def _way(drawer: SceneObject) -> str:
    """Returns which way a drawer opens, in words."""
    return ("towards the robot" if drawer_direction(drawer.position[0]) < 0
            else "away from the robot")


def open_handle_x(drawer: SceneObject) -> float:
    """Returns the x of a drawer's handle (where the arm grasps it) when the drawer is open."""
    x = float(drawer.position[0])
    out = drawer.size / 2 + DRAWER_TRAVEL_PER_SIZE * drawer.size + DRAWER_HANDLE_OUT
    return x + drawer_direction(x) * out


def footprint(obj: SceneObject) -> tuple[float, float, float, float]:
    """Returns a table object's footprint (x0, x1, y0, y1): the square of edge ``size``."""
    x, y, half = float(obj.position[0]), float(obj.position[1]), obj.size / 2
    return x - half, x + half, y - half, y + half


def tray_sweep(drawer: SceneObject) -> tuple[float, float, float, float]:
    """Returns where a drawer's tray comes out when it opens (x0, x1, y0, y1)."""
    x0, x1, y0, y1 = footprint(drawer)
    if drawer_direction(drawer.position[0]) < 0:
        return x0 - DRAWER_TRAY_OFFSET, x0, y0, y1
    return x1, x1 + DRAWER_TRAY_OFFSET, y0, y1


def _overlap(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    return (a[0] < b[1] - OVERLAP_TOL and b[0] < a[1] - OVERLAP_TOL
            and a[2] < b[3] - OVERLAP_TOL and b[2] < a[3] - OVERLAP_TOL)


def _overlaps(table: list[SceneObject]) -> list[str]:
    out = []
    for i, a in enumerate(table):
        for b in table[i + 1:]:
            if _overlap(footprint(a), footprint(b)):
                out.append(f"{a.name} at {_xy(a)} and {b.name} at {_xy(b)} overlap on the "
                           f"table (footprints of {a.size:.2f} and {b.size:.2f} m)")
        if a.type != "drawer":
            continue
        for b in table:
            if b is not a and _overlap(tray_sweep(a), footprint(b)):
                out.append(f"{b.name} at {_xy(b)} stands where the tray of {a.name} at "
                           f"{_xy(a)} slides out ({DRAWER_TRAY_OFFSET:.2f} m {_way(a)})")
        for b in table[i + 1:]:
            if b.type == "drawer" and _overlap(tray_sweep(a), tray_sweep(b)):
                out.append(f"the trays of {a.name} at {_xy(a)} and {b.name} at {_xy(b)} "
                           "slide out into the same place")
    return out


def _xy(obj: SceneObject) -> str:
    return f"({obj.position[0]:.2f}, {obj.position[1]:.2f})"
