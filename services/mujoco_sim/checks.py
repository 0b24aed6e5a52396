"""Success checks of the actions, read from the physics (in the spirit of LIBERO/robosuite).

Each check returns None when the outcome holds, else the precise failure as a sentence. They
look at the world only, never at what the controller meant to do:

- grasped: lifted >= `LIFT_MIN` above where it stood, both fingers touching, welded;
- released on a support: not held, upright, touching the support, x/y within a tolerance;
- stacked: on the box or cabinet top within `STACK_XY` in x/y, touching it;
- in a drawer: the centre inside the tray's inner box and touching the tray's floor;
- drawer open: opening >= `OPEN_MIN` of the travel; closed: <= `CLOSED_MAX`;
- poured: the held cup empty, the target full (the liquid moved physically);
- moved: the TCP (and the held object with it) displaced to the goal within `MOVE_TOL`.
"""

from __future__ import annotations

import numpy as np

from cbgo.services.mujoco_sim import observe
from cbgo.services.mujoco_sim.engine import Sim

LIFT_MIN = 0.04
STACK_XY = 0.01
PLACE_XY = 0.02
UPRIGHT_DEG = 10.0
OPEN_MIN = 0.75
CLOSED_MAX = 0.05
MOVE_TOL = 0.01


def grasped(sim: Sim, name: str, z_before: float) -> str | None:
    """Checks that `name` is lifted and held between both fingers."""
    left, right = sim.finger_contacts(sim.items[name].geoms)
    lift = sim.pose(name)[0][2] - z_before
    if not (left and right):
        which = "no finger" if not (left or right) else ("only the left finger" if left
                                                           else "only the right finger")
        return f"{name} is not held: {which} touches it"
    if sim.holding != name:
        return f"{name} is not held"
    if lift < LIFT_MIN:
        return f"{name} was lifted {lift * 100:.1f} cm, less than {LIFT_MIN * 100:.0f} cm"
    return None


def _released(sim: Sim, name: str) -> str | None:
    if sim.holding == name:
        return f"{name} is still in the gripper"
    tilt = sim.tilt_deg(name)
    if tilt > UPRIGHT_DEG:
        return f"{name} fell over (tilted {tilt:.0f}°)"
    speed = float(np.linalg.norm(sim.data.cvel[sim.items[name].body][3:]))
    if speed > 0.05:
        return f"{name} is still moving ({speed:.2f} m/s)"
    return None


def placed(sim: Sim, name: str, xy) -> str | None:
    """Checks that `name` stands on the table near xy."""
    problem = _released(sim, name)
    if problem:
        return problem
    if not sim.touching(sim.items[name].geoms, [sim.built.table_geom]):
        support = observe.support_of(sim, name)
        return f"{name} does not stand on the table" + (f" but on {support}" if support else "")
    off = float(np.linalg.norm(sim.pose(name)[0][:2] - np.asarray(xy)[:2]))
    if off > PLACE_XY:
        return f"{name} stands {off * 100:.1f} cm from its place (> {PLACE_XY * 100:.0f} cm)"
    return None


def stacked(sim: Sim, name: str, base: str) -> str | None:
    """Checks that `name` stands on `base`, centred within `STACK_XY`, touching it."""
    problem = _released(sim, name)
    if problem:
        return problem
    item = sim.items[base]
    if not sim.touching(sim.items[name].geoms, item.geoms):
        return f"{name} does not touch {base}"
    center = (observe.drawer_center(sim, item) if item.type == "drawer"
              else sim.pose(base)[0])[:2]
    off = float(np.linalg.norm(sim.pose(name)[0][:2] - center))
    if off > STACK_XY:
        return f"{name} stands {off * 100:.1f} cm off the centre of {base} (> 1 cm)"
    if observe.bottom_z(sim, name) < observe.top_z(sim, base) - 0.005:
        return f"{name} is not on top of {base}"
    return None


def in_drawer(sim: Sim, name: str, drawer: str) -> str | None:
    """Checks that `name` is inside the drawer's tray, standing on its floor."""
    problem = _released(sim, name)
    if problem:
        return problem
    item = sim.items[drawer]
    lo, hi = observe.inner_box(sim, item)
    pos = sim.pose(name)[0]
    if not (np.all(pos >= lo) and np.all(pos <= hi)):
        return f"{name} is not inside {drawer}"
    if not sim.touching(sim.items[name].geoms, [item.bottom_geom]):
        return f"{name} is inside {drawer} but does not touch its bottom"
    return None


def drawer_open(sim: Sim, drawer: str) -> str | None:
    """Checks that the drawer is out by at least `OPEN_MIN` of its travel."""
    opening = observe.drawer_opening(sim, sim.items[drawer])
    if opening < OPEN_MIN:
        return f"{drawer} opened only {opening * 100:.0f} % (needs {OPEN_MIN * 100:.0f} %)"
    return _hand_free(sim, drawer)


def drawer_closed(sim: Sim, drawer: str) -> str | None:
    """Checks that the drawer is in to within `CLOSED_MAX` of its travel."""
    opening = observe.drawer_opening(sim, sim.items[drawer])
    if opening > CLOSED_MAX:
        return f"{drawer} is still {opening * 100:.0f} % open (needs <= {CLOSED_MAX * 100:.0f} %)"
    return _hand_free(sim, drawer)


def _hand_free(sim: Sim, drawer: str) -> str | None:
    if sim.grasped_drawer() is not None:
        return f"the gripper did not let go of {drawer}'s handle"
    return None


def poured(sim: Sim, source: str, target: str) -> str | None:
    """Checks that the liquid went from the held cup into the target cup."""
    if sim.full.get(source):
        return f"nothing was poured: {source} is still full"
    if not sim.full.get(target):
        spilled = any(e.source == source and e.into is None for e in sim.pours)
        return f"the liquid of {source} " + ("was spilled next to " if spilled
                                             else "did not reach ") + target
    if sim.holding != source:
        return f"{source} was dropped while pouring"
    if sim.tilt_deg(source) > UPRIGHT_DEG:
        return f"{source} was not brought back upright"
    return None


def moved(sim: Sim, goal, held: str | None, offset_before=None) -> str | None:
    """Checks that the TCP reached the goal, carrying the held object along.

    Args:
        sim: the simulation.
        goal: the TCP's goal position.
        held: the object held during the move, if any.
        offset_before: the held object's position relative to the TCP before the move.
    """
    tcp, _ = sim.tcp()
    off = float(np.linalg.norm(tcp - np.asarray(goal)))
    if off > MOVE_TOL:
        return f"the gripper stopped {off * 100:.1f} cm from its goal"
    if held is not None:
        if sim.holding != held:
            return f"{held} was dropped"
        slip = float(np.linalg.norm(sim.pose(held)[0] - tcp - np.asarray(offset_before)))
        if slip > MOVE_TOL:
            return f"{held} slipped {slip * 100:.1f} cm in the gripper"
    return None
