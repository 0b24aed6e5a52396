"""Motion planning helpers: grasp geometry, travel height, yaw choice, collision sweeps.

Rules:
- grasps are top-down; the finger pads close 2 cm below an object's top (`GRASP_DEPTH`);
- poses are checked kinematically on a scratch copy of the world (objects where they are now,
  the held object carried by the hand) with 8 mm wider collision margins: a pose "collides"
  when the robot or the held object comes within `CLEARANCE` of another object or the table;
- a sweep checks a straight path every centimetre; the first collision names the object hit.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

from cbgo.services.mujoco_sim.build import PAD_INSET, BoxDims, CupDims, Item
from cbgo.services.mujoco_sim.engine import Sim

GRASP_DEPTH = 0.02  # pad centre below an object's top, m
FINGERTIP_BELOW_TCP = 0.012  # lowest point of the fingers under the TCP, m
CLEARANCE = 0.003  # m
CHECK_MARGIN = 0.008  # m, contacts are detected this far out in checks
TRAVEL_MARGIN = 0.04  # m above the highest obstacle while travelling
MIN_TRAVEL_Z = 0.22  # m, TCP height for travelling at least


def grasp_half_width(item: Item) -> float:
    """Returns half the object's width between the pads, m."""
    if isinstance(item.dims, CupDims):
        return item.dims.radius
    if isinstance(item.dims, BoxDims):
        return item.dims.edge / 2
    return 0.012  # a drawer handle knob


def finger_for_width(half_width: float) -> float:
    """Returns the per-finger joint position whose pads are `half_width` from the middle."""
    return max(0.0, half_width - PAD_INSET)


def tcp_below_top(item: Item) -> float:
    """Returns how far under the object's top the TCP sits in a top-down grasp, m."""
    return min(GRASP_DEPTH, item.dims.half_height)


def hang_below_tcp(item: Item | None) -> float:
    """Returns how far what the gripper carries reaches under the TCP, m."""
    if item is None:
        return FINGERTIP_BELOW_TCP
    return max(FINGERTIP_BELOW_TCP, item.dims.half_height * 2 - tcp_below_top(item))


def box_yaw(rot: np.ndarray) -> float:
    """Returns the yaw of a box's faces from its rotation matrix, folded into [-45°, 45°)."""
    yaw = float(np.arctan2(rot[1, 0], rot[0, 0]))
    return (yaw + np.pi / 4) % (np.pi / 2) - np.pi / 4


def fold_yaw(yaw: float) -> float:
    """Returns the equivalent hand yaw in [-90°, 90°) (the gripper is symmetric)."""
    return (yaw + np.pi / 2) % np.pi - np.pi / 2


@dataclass
class Hit:
    """A collision found by a check."""

    what: str  # the object or "table"
    depth: float


class Checker:
    """Kinematic collision checks on a scratch copy of the simulated world.

    The copy collides only what moves (the robot and the carried object) with the rest:
    resting objects do not collide with each other or the table there, so a check costs one
    `mj_fwdPosition` over a handful of pairs.

    Args:
        sim: the simulation; its current object poses are copied at each `sync`.
    """

    def __init__(self, sim: Sim):
        self.sim = sim
        self.model = copy.copy(sim.model)
        m = self.model
        m.geom_margin[:] = CHECK_MARGIN
        root = m.body("link0").id
        self.robot_geoms = frozenset(g for g in range(m.ngeom)
                                     if m.body_rootid[m.geom_bodyid[g]] == root)
        self.owner: dict[int, str] = {}
        self.names = ["" for _ in range(m.ngeom)]
        for item in sim.items.values():
            for g in item.geoms:
                self.owner[g] = self.names[g] = item.name
                m.geom_contype[g], m.geom_conaffinity[g] = 1, 2  # the robot's contype is 2
        table = sim.built.table_geom
        self.owner[table] = self.names[table] = "table"
        m.geom_conaffinity[table] = 0  # the table still touches fingers (conaffinity 1)
        self.data = mujoco.MjData(m)
        self.carried: str | None = None
        self.ignore: set[str] = set()
        self.ignore_geoms: set[int] = set()
        self._mover = np.zeros(m.ngeom, bool)
        self._robot = np.zeros(m.ngeom, bool)
        self._robot[list(self.robot_geoms)] = True

    def sync(self, carried: str | None = None, ignore: tuple[str, ...] = (),
             ignore_geoms=()) -> None:
        """Copies the world's state; `carried` moves with the hand in later checks.

        Args:
            carried: the held object (its pose relative to the hand is kept).
            ignore: objects whose contacts do not count (e.g. the one about to be grasped).
            ignore_geoms: geoms whose contacts do not count (the surface a load is put on).
        """
        m = self.model
        if self.carried is not None:  # back to a resting object
            for g in self.sim.items[self.carried].geoms:
                m.geom_contype[g], m.geom_conaffinity[g] = 1, 2
        self.data.qpos[:] = self.sim.data.qpos
        self.data.eq_active[:] = 0
        self.carried = carried
        self.ignore = set(ignore)
        self.ignore_geoms = set(ignore_geoms)
        self._mover[:] = self._robot
        self._rel = None
        if carried is not None:
            geoms = list(self.sim.items[carried].geoms)
            m.geom_contype[geoms], m.geom_conaffinity[geoms] = 2, 1  # moves like a finger
            self._mover[geoms] = True
            hand, body = self.sim.built.hand_body, self.sim.items[carried].body
            d = self.sim.data
            r_hand = d.xmat[hand].reshape(3, 3)
            self._rel = (r_hand.T @ (d.xpos[body] - d.xpos[hand]),
                         r_hand.T @ d.xmat[body].reshape(3, 3))

    def hits(self, q: np.ndarray, fingers: float | None = None) -> list[Hit]:
        """Returns what the robot (and the carried object) would touch at joints q."""
        b = self.sim.built
        self.data.qpos[b.arm_qpos] = q
        if fingers is not None:
            self.data.qpos[b.finger_qpos] = fingers
        if self.carried is not None:
            self._place_carried()
        mujoco.mj_fwdPosition(self.model, self.data)
        n = self.data.ncon
        if n == 0:
            return []
        contact = self.data.contact
        g1, g2, dist = contact.geom1[:n], contact.geom2[:n], contact.dist[:n]
        m1, m2 = self._mover[g1], self._mover[g2]
        out: list[Hit] = []
        for i in np.flatnonzero((m1 != m2) & (dist <= CLEARANCE)):
            other = int(g2[i] if m1[i] else g1[i])
            name = self.names[other]
            if not name or name in self.ignore or other in self.ignore_geoms:
                continue
            if name == "table" and (self._robot[g1[i]] or self._robot[g2[i]]) and dist[i] > 0:
                continue  # the fingers may skim the table top; they must not dig in
            out.append(Hit(name, float(CLEARANCE - dist[i])))
        return out

    def _place_carried(self) -> None:
        mujoco.mj_kinematics(self.model, self.data)
        hand = self.sim.built.hand_body
        pos = self.data.xpos[hand] + self.data.xmat[hand].reshape(3, 3) @ self._rel[0]
        rot = self.data.xmat[hand].reshape(3, 3) @ self._rel[1]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, rot.ravel())
        adr = self.sim.items[self.carried].qpos
        self.data.qpos[adr:adr + 3] = pos
        self.data.qpos[adr + 3:adr + 7] = quat


def travel_height(sim: Sim, carried: Item | None, exclude: tuple[str, ...] = ()) -> float:
    """Returns a TCP height from which the gripper and its load clear every object."""
    from cbgo.services.mujoco_sim.observe import top_z

    tops = [top_z(sim, name) for name in sim.items
            if name not in exclude and (carried is None or name != carried.name)]
    highest = max(tops, default=0.0)
    return max(MIN_TRAVEL_Z, highest + hang_below_tcp(carried) + TRAVEL_MARGIN)


def yaw_candidates(item: Item | None, sim: Sim, preferred: float = 0.0) -> list[float]:
    """Returns hand yaws to try for grasping or releasing an object, best guess first."""
    if item is not None and isinstance(item.dims, BoxDims) and sim.holding != item.name:
        base = box_yaw(sim.pose(item.name)[1])
        options = [fold_yaw(base), fold_yaw(base + np.pi / 2)]
    else:
        options = [fold_yaw(preferred + np.radians(a)) for a in
                   (0, 90, 45, -45, 30, -30, 60, -60, 15, -15, 75, -75)]
    return sorted(set(options), key=lambda y: options.index(y))
