"""Symbolic scene -> settled physical world, and whether the physics still matches it.

Rules:
- a scene comes from the world model: `cbgo.world.random_scene(seed)` or a contract scene
  dict (`cbgo.world.Scene.from_dict`); an inconsistent one (`Scene.problems`), or one outside
  the workspace (`cbgo.world.workspace_problems`), is refused before anything is built;
- table objects keep their x/y; stacked objects stand centred on their support (the symbolic
  offset kept up to 1 cm); objects in a drawer stand on its tray, in the part that comes out
  of the cabinet; heights follow from the supports, so nothing starts interpenetrating;
- the robot's TCP goes to the scene's TCP, top-down; where the hand or the held object would
  touch something there, to the nearest grid cell (higher first) where it fits;
- a held object starts between the closed fingers with its grasp weld on;
- after `SETTLE_S` of physics, `mismatches` compares the observation with the symbolic scene:
  the relations (on, inside, held), the states (open, full) and x/y within `POSITION_TOL`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from cbgo.services.mujoco_sim import observe
from cbgo.services.mujoco_sim.build import HOME_Q, DrawerDims, Item, build
from cbgo.services.mujoco_sim.engine import Sim
from cbgo.services.mujoco_sim.ik import top_down
from cbgo.services.mujoco_sim.plan import (
    Checker,
    finger_for_width,
    grasp_half_width,
    tcp_below_top,
)
from cbgo.world import DEFAULT_GRID, Grid, Scene, random_scene
from cbgo.world import workspace as world_workspace
from cbgo.world.workspace import startable_scene

SETTLE_S = 0.4
POSITION_TOL = 0.03  # m, x/y of a settled object against its symbolic position


# The scene cannot be built (refused by the world model or the workspace, or the robot fits
# nowhere): the robot cells' one error for it.
SceneError = world_workspace.SceneError


@dataclass
class Loaded:
    """A settled world and the symbolic scene it was built from."""

    sim: Sim
    scene: Scene
    compile_s: float
    settle_s: float


def scene_for_seed(seed: int, grid: Grid = DEFAULT_GRID) -> Scene:
    """Returns the world model's random valid scene of a seed."""
    return random_scene(seed, grid)


def load(scene: Scene | dict, grid: Grid = DEFAULT_GRID) -> Loaded:
    """Builds, places and settles a scene.

    Raises:
        SceneError: the scene breaks the world model's rules or does not fit in the workspace
            (`cbgo.world.reset_refusal`), or the robot cannot be placed.
    """
    scene = startable_scene(scene, grid)  # judged before building: never accepted to fail later
    objects = [{"name": o.name, "type": o.type, "size": o.size, "position": list(o.position)}
               for o in scene.objects]
    points = [grid.column_xy(c) for c in grid.columns()]
    built = build(objects, points)
    sim = Sim(built, full={o.name: o.full for o in scene.objects if o.type == "cup"})
    _place_objects(sim, scene)
    _place_robot(sim, scene, grid)
    t0 = sim.time
    sim.settle(SETTLE_S)
    return Loaded(sim, scene, built.compile_s, sim.time - t0)


# ------------------------------------------------------------------------- objects


def _set_free(sim: Sim, item: Item, pos, quat=(1.0, 0.0, 0.0, 0.0)) -> None:
    sim.data.qpos[item.qpos:item.qpos + 3] = pos
    sim.data.qpos[item.qpos + 3:item.qpos + 7] = quat


def _order(scene: Scene) -> list[str]:
    """Returns object names so that every support comes before what stands on it."""
    out: list[str] = []

    def visit(name: str) -> None:
        if name in out:
            return
        obj = scene.get(name)
        for dep in (obj.on, obj.inside):
            if dep is not None:
                visit(dep)
        out.append(name)

    for name in scene.names:
        visit(name)
    return out


def _place_objects(sim: Sim, scene: Scene) -> None:
    d = sim.data
    for name in _order(scene):
        obj, item = scene.get(name), sim.items[name]
        if item.type == "drawer":
            d.qpos[item.qpos] = item.dims.travel if obj.open else 0.0
            continue
        if scene.is_held(name):
            continue
        mujoco.mj_kinematics(sim.model, d)
        half = item.dims.half_height
        x, y = obj.position[:2]
        if obj.on is not None:
            base = sim.items[obj.on]
            bxy = (observe.drawer_center(sim, base) if base.type == "drawer"
                   else d.xpos[base.body])[:2]
            x, y = bxy + np.clip(np.array([x, y]) - bxy, -0.01, 0.01)
            z = observe.top_z(sim, obj.on) + half + 0.0005
        elif obj.inside is not None:
            x, y, z = _tray_spot(sim, sim.items[obj.inside], y, half)
        else:
            z = half + 0.0005
        _set_free(sim, item, [x, y, z])
    mujoco.mj_forward(sim.model, d)


def _tray_spot(sim: Sim, drawer: Item, y: float, half: float) -> tuple[float, float, float]:
    """Returns where an object stands in a drawer's tray at its current opening."""
    dims: DrawerDims = drawer.dims
    spot = observe.tray_point(sim, drawer, [dims.spot_x, 0.0, 0.0])
    room = max(0.0, dims.inner_half_y - half - 0.003)
    dy = float(np.clip(y - spot[1], -room, room))
    return float(spot[0]), float(spot[1]) + dy, dims.floor_top + half + 0.0005


def tray_spot(sim: Sim, drawer: str, half: float) -> np.ndarray:
    """Returns where an object of half-height `half` goes into a drawer's tray (its centre)."""
    item = sim.items[drawer]
    return np.array(_tray_spot(sim, item, float(sim.data.xpos[item.body][1]), half))


# ------------------------------------------------------------------------- robot


def _place_robot(sim: Sim, scene: Scene, grid: Grid) -> None:
    held = scene.robot.holding
    item = sim.items[held] if held else None
    checker = Checker(sim)
    checker.sync()
    wanted = np.asarray(scene.robot.tcp, float)
    for tcp in _tcp_candidates(wanted, grid):
        q = _fit_robot(sim, checker, tcp, item)
        if q is not None:
            break
    else:
        raise SceneError("the robot fits nowhere on the grid without touching an object")
    sim.set_arm(q)
    sim.data.qpos[sim.built.arm_qpos] = q
    if item is None:
        fingers = 0.04 if scene.robot.gripper_open else 0.0
        sim.data.qpos[sim.built.finger_qpos] = fingers
        sim.set_fingers(fingers)
        mujoco.mj_forward(sim.model, sim.data)
        return
    _put_in_hand(sim, item, q)


def _tcp_candidates(wanted: np.ndarray, grid: Grid) -> list[np.ndarray]:
    cells = [np.array(grid.position(c)) for c in grid.cells()]
    cells.sort(key=lambda p: (np.linalg.norm((p - wanted)[:2]) + 0.5 * max(0.0, wanted[2]
                                                                            - p[2]),
                              -p[2]))
    return [wanted] + cells


def _held_pose(item: Item, tcp: np.ndarray) -> np.ndarray:
    """Returns where a held object's centre is for a top-down grasp at tcp."""
    return tcp - np.array([0.0, 0.0, item.dims.half_height - tcp_below_top(item)])


def _fit_robot(sim: Sim, checker: Checker, tcp: np.ndarray, item: Item | None):
    res = sim.ik.solve(tcp, top_down(0.0), HOME_Q, iterations=100)
    if not res.ok:
        return None
    if item is None:
        checker.sync()
        return None if checker.hits(res.q, 0.04) else res.q
    sim.data.qpos[sim.built.arm_qpos] = res.q
    _set_free(sim, item, _held_pose(item, tcp))
    mujoco.mj_kinematics(sim.model, sim.data)
    checker.sync(carried=item.name)
    return None if checker.hits(res.q, finger_for_width(grasp_half_width(item))) else res.q


def _put_in_hand(sim: Sim, item: Item, q: np.ndarray) -> None:
    tcp, _ = sim.ik.forward(q)
    _set_free(sim, item, _held_pose(item, tcp))
    fingers = finger_for_width(grasp_half_width(item))
    sim.data.qpos[sim.built.finger_qpos] = fingers
    sim.set_fingers(0.0)
    mujoco.mj_forward(sim.model, sim.data)
    sim.attach(item.name)


# ------------------------------------------------------------------------- comparison


def mismatches(sim: Sim, scene: Scene) -> list[str]:
    """Returns where the settled physics disagrees with the symbolic scene (empty: none)."""
    seen = {o["name"]: o for o in observe.observe_objects(sim)}
    out = []
    holding = sim.holding
    if holding != scene.robot.holding:
        out.append(f"the robot holds {holding} instead of {scene.robot.holding}")
    for obj in scene.objects:
        got = seen[obj.name]
        if obj.type == "drawer":
            if got["open"] != obj.open:
                out.append(f"{obj.name} is {'open' if got['open'] else 'closed'}")
            continue
        for key in ("on", "inside"):
            if got[key] != getattr(obj, key):
                out.append(f"{obj.name} is {key} {got[key]} instead of {getattr(obj, key)}")
        if obj.type == "cup" and got["full"] != obj.full:
            out.append(f"{obj.name} is {'full' if got['full'] else 'empty'}")
        if scene.is_held(obj.name):
            continue
        shift = float(np.linalg.norm(np.subtract(got["position"][:2], obj.position[:2])))
        if shift > POSITION_TOL:
            out.append(f"{obj.name} settled {shift * 100:.1f} cm from its place")
    return out
