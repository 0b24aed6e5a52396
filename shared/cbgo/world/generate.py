"""Random valid scenes, as the paper samples them (section "Scene generation"); seeded.

Two layouts of the same procedure:

- `paper_scene`: the paper's distribution as its text states it. Every object lands on a
  column drawn uniformly from the whole grid, drawers included, and cups are 0.03 … 0.07 m
  high (drawn from 0.03, 0.04, … 0.07 m, as the paper's code draws them). This is what the
  robots must execute: `cbgo bench sim --generator paper` resets its scenes in mujoco-sim and
  tries every feasible action.
- `random_scene`: the layout the intent datasets are generated from: drawers in the back row
  (where the paper's code puts them first), the default sizes (`DEFAULT_SIZES`).

The procedure:

1. n = round(N(3.5, 1)) clipped to [2, 7] objects: the first n of `TYPE_ORDER`
   (cup, drawer, box, cup, drawer, box, cup), named by type and count (cup1, drawer1, box1,
   cup2, ...), listed in that order.
2. Placed on the grid's columns — drawers first, then boxes, then cups. A drawer keeps the
   column it opens into (`cbgo.world.scene.drawer_direction`) free for its tray; an object
   landing on an occupied column is stacked on its top object if that is a box or a drawer and
   the tower stays within `MAX_STACK`, else it is drawn again ("replaced"), and so is one
   landing where a tray slides out (or a drawer whose tray would slide into something).
   Table positions are perturbed by up to ±`jitter` m, and by no more than the room their cell
   leaves around them (so that neighbouring drawer cabinets never overlap).
3. Containment and stacking: each drawer, with probability `p_contain`, takes a free cup or box
   inside; each free cup or box, with probability `p_stack`, moves onto a free box or drawer.
4. Random states: each drawer open, each cup full, with probability 1/2.
5. The robot: with probability `p_hold` it holds a random free cup or box, its TCP on a random
   cell above the lowest level; otherwise its TCP is on a random cell and its gripper open.

Every scene satisfies `Scene.problems() == []` and fits the workspace
(`cbgo.world.workspace_problems`). The same seed gives the same scene.
"""

from __future__ import annotations

import numpy as np

from cbgo.world.grid import DEFAULT_GRID, Column, Grid
from cbgo.world.scene import (
    DEFAULT_SIZES,
    DRAWER_CAPACITY,
    GRASPABLE,
    MAX_STACK,
    SUPPORTS,
    Robot,
    Scene,
    SceneObject,
    drawer_direction,
)

TYPE_ORDER = ("cup", "drawer", "box", "cup", "drawer", "box", "cup")
PLACEMENT_ORDER = ("drawer", "box", "cup")
MIN_OBJECTS, MAX_OBJECTS = 2, 7
PAPER_CUP_SIZES = (0.03, 0.04, 0.05, 0.06, 0.07)  # m, drawn uniformly (the paper's code)


def _rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def object_count(rng: np.random.Generator) -> int:
    """Returns round(N(3.5, 1)) clipped to [2, 7]."""
    return int(np.clip(round(rng.normal(3.5, 1.0)), MIN_OBJECTS, MAX_OBJECTS))


def random_scene(seed: int | np.random.Generator | None = None, grid: Grid = DEFAULT_GRID, *,
                 n_objects: int | None = None, p_contain: float = 0.5, p_stack: float = 0.3,
                 p_hold: float = 0.5, jitter: float = 0.01) -> Scene:
    """Returns a random valid scene with drawers in the back row and default sizes.

    Args:
        seed: an int seed, a numpy Generator (advanced in place), or None for fresh entropy.
        grid: the workspace grid.
        n_objects: force the object count (2-7) instead of drawing it.
        p_contain: probability that a drawer gets an object inside.
        p_stack: probability that a free cup or box is moved onto another object.
        p_hold: probability that the robot holds an object.
        jitter: maximum perturbation of table positions, metres.
    """
    return _generate(_rng(seed), grid, n_objects, p_contain, p_stack, p_hold, jitter,
                     paper=False)


def paper_scene(seed: int | np.random.Generator | None = None, grid: Grid = DEFAULT_GRID, *,
                n_objects: int | None = None, p_contain: float = 0.5, p_stack: float = 0.3,
                p_hold: float = 0.5, jitter: float = 0.01) -> Scene:
    """Returns a random valid scene of the paper's distribution: drawers anywhere, cups 3-7 cm.

    The arguments are `random_scene`'s.
    """
    return _generate(_rng(seed), grid, n_objects, p_contain, p_stack, p_hold, jitter,
                     paper=True)


def _generate(rng: np.random.Generator, grid: Grid, n_objects: int | None, p_contain: float,
              p_stack: float, p_hold: float, jitter: float, *, paper: bool) -> Scene:
    n = object_count(rng) if n_objects is None else int(np.clip(n_objects, MIN_OBJECTS,
                                                                 MAX_OBJECTS))
    scene = Scene(_named_objects(TYPE_ORDER[:n]), Robot())
    if paper:
        for obj in scene.objects:
            if obj.type == "cup":
                obj.size = float(PAPER_CUP_SIZES[rng.integers(len(PAPER_CUP_SIZES))])
    columns = _place(scene, rng, grid, jitter, drawers_anywhere=paper)
    _contain(scene, rng, p_contain)
    _stack(scene, rng, p_stack)
    for obj in scene.objects:
        obj.open = obj.type == "drawer" and bool(rng.random() < 0.5)
        obj.full = obj.type == "cup" and bool(rng.random() < 0.5)
    _robot(scene, rng, grid, p_hold)
    for obj in scene.objects:  # table objects rest on the table at their column
        if obj.on is None and obj.inside is None and not scene.is_held(obj.name):
            x, y = columns[obj.name]
            obj.position = (x, y, obj.size / 2)
    scene.settle()
    return scene


def _named_objects(types: tuple[str, ...]) -> list[SceneObject]:
    counts: dict[str, int] = {}
    out = []
    for kind in types:
        counts[kind] = counts.get(kind, 0) + 1
        out.append(SceneObject(f"{kind}{counts[kind]}", kind, (0.0, 0.0, 0.0),
                               DEFAULT_SIZES[kind]))
    return out


def _place(scene: Scene, rng: np.random.Generator, grid: Grid, jitter: float, *,
           drawers_anywhere: bool) -> dict[str, tuple[float, float]]:
    """Puts every object on a column or a tower; returns each table object's (x, y)."""
    towers: dict[Column, list[str]] = {}
    reserved: set[Column] = set()
    xy: dict[str, tuple[float, float]] = {}
    ordered = sorted(scene.objects, key=lambda o: PLACEMENT_ORDER.index(o.type))
    for obj in ordered:
        if obj.type == "drawer":
            column = _drawer_column(towers, reserved, rng, grid, drawers_anywhere)
            reserved.add(_tray_column(column, grid))
        else:
            column = _column_for(scene, towers, reserved, rng, grid)
        tower = towers.setdefault(column, [])
        if tower:
            obj.on = tower[-1]
        else:
            x, y = grid.column_xy(column)
            # No more than the room its cell leaves: a 0.11 m cabinet in a 0.12 m cell would
            # otherwise push into its neighbour (`cbgo.world.workspace` refuses overlaps).
            j = min(jitter, max(0.0, (min(grid.step[:2]) - obj.size) / 2))
            xy[obj.name] = (x + rng.uniform(-j, j), y + rng.uniform(-j, j))
        tower.append(obj.name)
    return xy


def _tray_column(column: Column, grid: Grid) -> Column:
    """Returns the column a drawer standing on `column` opens its tray into."""
    return column[0] + drawer_direction(grid.column_xy(column)[0]), column[1]


def _drawer_column(towers: dict[Column, list[str]], reserved: set[Column],
                   rng: np.random.Generator, grid: Grid, anywhere: bool) -> Column:
    """Draws a drawer's column: free, not in a tray's way, its own tray's column free.

    Anywhere on the grid, or in the back row. Drawers are placed first, so at most one other
    drawer (and its tray) stands on the grid: a column is always found.
    """
    if not anywhere:
        back = grid.shape[0] - 1
        free = [(back, j) for j in range(grid.shape[1]) if (back, j) not in towers]
        return free[rng.integers(len(free))]
    columns = list(grid.columns())
    while True:
        column = columns[rng.integers(len(columns))]
        tray = _tray_column(column, grid)
        if (column not in towers and column not in reserved and tray not in towers
                and tray not in reserved and grid.contains((*tray, 0))):
            return column


def _column_for(scene: Scene, towers: dict[Column, list[str]], reserved: set[Column],
                rng: np.random.Generator, grid: Grid) -> Column:
    columns = list(grid.columns())
    while True:  # 16 columns for at most 7 objects: an empty one is always found
        column = columns[rng.integers(len(columns))]
        if column in reserved:
            continue
        tower = towers.get(column)
        if not tower:
            return column
        if scene.get(tower[-1]).type in SUPPORTS and len(tower) < MAX_STACK:
            return column


def _free_graspable(scene: Scene) -> list[str]:
    return [o.name for o in scene.objects if o.type in GRASPABLE and scene.is_free(o.name)]


def _contain(scene: Scene, rng: np.random.Generator, p_contain: float) -> None:
    drawers = [o.name for o in scene.objects if o.type == "drawer"]
    for drawer in rng.permutation(drawers) if drawers else []:
        free = _free_graspable(scene)
        if not free or rng.random() >= p_contain or len(scene.contents(drawer)) >= DRAWER_CAPACITY:
            continue
        obj = scene.get(free[rng.integers(len(free))])
        obj.on, obj.inside = None, str(drawer)


def _stack(scene: Scene, rng: np.random.Generator, p_stack: float) -> None:
    graspable = [o.name for o in scene.objects if o.type in GRASPABLE]
    for name in rng.permutation(graspable) if graspable else []:
        if not scene.is_free(name) or rng.random() >= p_stack:
            continue
        supports = [s.name for s in scene.objects
                    if s.type in SUPPORTS and s.name != name and scene.is_free(s.name)
                    and scene.stack_level(s.name) + 2 <= MAX_STACK]
        if supports:
            scene.get(name).on = supports[rng.integers(len(supports))]


def _robot(scene: Scene, rng: np.random.Generator, grid: Grid, p_hold: float) -> None:
    free = _free_graspable(scene)
    nx, ny, nz = grid.shape
    if free and rng.random() < p_hold:
        held = scene.get(free[rng.integers(len(free))])
        held.on = None
        cell = (int(rng.integers(nx)), int(rng.integers(ny)), int(rng.integers(1, nz)))
        scene.robot = Robot(grid.position(cell), gripper_open=False, holding=held.name)
    else:
        cell = (int(rng.integers(nx)), int(rng.integers(ny)), int(rng.integers(nz)))
        scene.robot = Robot(grid.position(cell), gripper_open=True, holding=None)
