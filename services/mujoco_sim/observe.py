"""Physics -> contract: the scene and the arm as `cbgo/scene/state` and `cbgo/robot/state` say.

Everything is read from the simulation, nothing is bookkept:
- positions: a cup's or box's body centre; a drawer's cabinet centre;
- drawers: ``opening`` = slide joint / travel, ``open`` once it is half out, ``contains`` the
  objects whose centre lies in the drawer's inner box;
- ``on``: the object under it that it touches (contacts, with a 5 mm geometric fallback for
  resting stacks between contact updates); the table and a drawer's inner bottom give null;
- ``inside``: the drawer whose inner box holds the object's centre, unless the object is held
  (in the gripper, never also inside); ``contains`` lists exactly the objects inside;
- ``full``: the cup's liquid state (changed physically, see `engine.Sim.update_liquid`);
- robot: ``tcp`` from the TCP site, ``holding`` from the grasp weld, ``gripper_open`` when
  nothing is held and the fingers are apart.
"""

from __future__ import annotations

import time

import numpy as np

from cbgo import keys
from cbgo.services.mujoco_sim.build import DrawerDims, Item
from cbgo.services.mujoco_sim.engine import Sim

OPEN_AT = 0.5  # a drawer counts as open from half its travel
GRIPPER_OPEN_AT = 0.015  # per finger, m
RESTING_TOL = 0.005  # m: geometric "stands on" tolerance


def drawer_opening(sim: Sim, item: Item) -> float:
    """Returns how far a drawer is out, 0 (closed) .. 1 (fully open)."""
    dims: DrawerDims = item.dims
    return float(np.clip(sim.data.qpos[item.qpos] / dims.travel, 0.0, 1.0))


def drawer_center(sim: Sim, item: Item) -> np.ndarray:
    """Returns the centre of a drawer's cabinet (its contract position)."""
    return sim.data.xpos[item.cabinet] + np.array([0.0, 0.0, item.dims.size / 2])


def tray_point(sim: Sim, item: Item, local) -> np.ndarray:
    """Returns a point given in a drawer's tray frame (`build.DrawerDims`) in the world frame."""
    return sim.data.xpos[item.body] + sim.data.xmat[item.body].reshape(3, 3) @ np.asarray(local)


def inner_box(sim: Sim, item: Item) -> tuple[np.ndarray, np.ndarray]:
    """Returns a drawer's inner box (lo, hi corners, world frame) at its current opening.

    The box rises to just under the cabinet's top, so a stack inside still counts.
    """
    d: DrawerDims = item.dims
    x0, x1 = d.inner_x
    a = tray_point(sim, item, [x0, -d.inner_half_y, d.floor_top - 0.005])
    b = tray_point(sim, item, [x1, d.inner_half_y, d.size - 0.01])
    return np.minimum(a, b), np.maximum(a, b)


def inside_of(sim: Sim, name: str) -> str | None:
    """Returns the drawer whose inner box holds an object's centre, if any."""
    pos = sim.data.xpos[sim.items[name].body]
    for item in sim.items.values():
        if item.type == "drawer":
            lo, hi = inner_box(sim, item)
            if np.all(pos >= lo) and np.all(pos <= hi):
                return item.name
    return None


def bottom_z(sim: Sim, name: str) -> float:
    """Returns the height of an upright object's underside."""
    item = sim.items[name]
    return float(sim.data.xpos[item.body][2] - item.dims.half_height)


def top_z(sim: Sim, name: str) -> float:
    """Returns the height of an object's top surface (drawers: the cabinet's top)."""
    item = sim.items[name]
    if item.type == "drawer":
        return float(sim.data.xpos[item.cabinet][2] + item.dims.size)
    return float(sim.data.xpos[item.body][2] + item.dims.half_height)


def footprint(sim: Sim, name: str) -> tuple[np.ndarray, float]:
    """Returns an object's centre in xy and the half-extent of its footprint."""
    item = sim.items[name]
    if item.type == "drawer":
        return drawer_center(sim, item)[:2], item.dims.size / 2
    radius = item.dims.radius if item.type == "cup" else item.dims.edge / 2
    return sim.data.xpos[item.body][:2].copy(), radius


def footprints(sim: Sim, item: Item) -> list[tuple[tuple[float, float, float, float], float]]:
    """Returns an object's footprints as ((x0, x1, y0, y1), top z).

    A drawer has two when open: its cabinet and the part of its tray outside the cabinet.
    """
    if item.type != "drawer":
        (x, y), half = footprint(sim, item.name)
        return [((x - half, x + half, y - half, y + half), top_z(sim, item.name))]
    d: DrawerDims = item.dims
    (x, y), half = footprint(sim, item.name)
    out = [((x - half, x + half, y - half, y + half), top_z(sim, item.name))]
    way = item.direction
    cabinet_front = x + way * half
    tray_front = float(tray_point(sim, item, [d.tray_x[0], 0.0, 0.0])[0])
    if way * (tray_front - cabinet_front) > 0.005:
        reach = tray_front + way * 0.03  # the front panel and the handle stick out
        out.append(((min(cabinet_front, reach), max(cabinet_front, reach),
                     y - d.tray_half_y, y + d.tray_half_y), d.size - 0.01))
    return out


def support_of(sim: Sim, name: str) -> str | None:
    """Returns the object that an object stands on (None: the table, a drawer's bottom, air).

    A support touches the object's underside: a contact between them below the object's
    centre, or (between contact updates) a top within 5 mm of its bottom, overlapping in xy.
    """
    item = sim.items[name]
    if sim.holding == name:
        return None
    center_z = sim.data.xpos[item.body][2]
    for g1, g2, pos in sim.contacts():
        if g1 in item.geoms or g2 in item.geoms:
            other = sim.item_of_geom(g2 if g1 in item.geoms else g1)
            if other is None or other.name == name or pos[2] > center_z - 0.3 * item.size:
                continue
            if other.type == "drawer" and not _on_cabinet_top(sim, other, pos):
                continue  # a drawer's inner bottom or walls: that is "inside", not "on"
            return other.name
    xy, half = footprint(sim, name)
    bottom = bottom_z(sim, name)
    for other in sim.items.values():
        if other.name == name:
            continue
        oxy, ohalf = footprint(sim, other.name)
        if (abs(top_z(sim, other.name) - bottom) < RESTING_TOL
                and np.all(np.abs(xy - oxy) < ohalf)):
            return other.name
    return None


def _on_cabinet_top(sim: Sim, drawer: Item, contact_pos: np.ndarray) -> bool:
    return contact_pos[2] > sim.data.xpos[drawer.cabinet][2] + drawer.dims.size - 0.01


def observe_objects(sim: Sim) -> list[dict]:
    """Returns the contract objects of the scene, read from the physics."""
    objects = []
    held = sim.holding
    # A held object is in the gripper, whatever its centre passes through (a failed put_into
    # leaves it hanging in a drawer's inner box): never held and inside at once.
    inside = {name: None if name == held else inside_of(sim, name)
              for name, it in sim.items.items() if it.type != "drawer"}
    for item in sim.items.values():
        obj: dict = {"name": item.name, "type": item.type, "size": item.size}
        if item.type == "drawer":
            opening = drawer_opening(sim, item)
            obj["position"] = _vec(drawer_center(sim, item))
            obj.update(open=opening >= OPEN_AT, opening=round(opening, 4),
                       contains=sorted(n for n, d in inside.items() if d == item.name))
        else:
            obj["position"] = _vec(sim.data.xpos[item.body])
            obj.update(on=support_of(sim, item.name), inside=inside[item.name])
            if item.type == "cup":
                obj["full"] = bool(sim.full.get(item.name, False))
        objects.append(obj)
    return objects


def observe_robot(sim: Sim) -> dict:
    """Returns the contract robot part of the scene (TCP, gripper, held object)."""
    holding = sim.holding
    tcp, _ = sim.tcp()
    gripper_open = holding is None and float(sim.fingers.mean()) >= GRIPPER_OPEN_AT
    return {"tcp": _vec(tcp), "gripper_open": bool(gripper_open), "holding": holding}


def scene_state(sim: Sim, seq: int) -> dict:
    """Returns a full `cbgo/scene/state` message."""
    return keys.SCENE_STATE.message(ts=time.time(), seq=seq,
            objects=observe_objects(sim), robot=observe_robot(sim))


def robot_state(sim: Sim, seq: int) -> dict:
    """Returns a `cbgo/robot/state` message."""
    tcp, _ = sim.tcp()
    return keys.ROBOT_STATE.message(ts=time.time(), seq=seq,
            joints=_vec(sim.q), gripper_width=round(float(max(sim.fingers.sum(), 0.0)), 5),
            tcp=_vec(tcp), moving=bool(sim.moving), action=sim.action)


def _vec(values) -> list[float]:
    return [round(float(v), 5) for v in values]
