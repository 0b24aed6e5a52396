"""The running simulation: physics stepping, the arm's servo targets, grasp welds, liquid.

Rules:
- the physics runs in control ticks of `STEPS_PER_TICK` steps; after every tick the stop flag
  is checked (`Stopped` is raised) and `on_tick` is called (state publishing, pacing);
- the arm is position-servoed: `q_cmd` is what the actuators track; holding position means
  `q_cmd` = the measured joints;
- a weld between the hand and an object is switched on only by `attach`, after the caller
  has verified that both fingers touch the object; `holding` is the object whose weld is on;
- each cup carries a liquid boolean that changes physically: a full cup tilted beyond
  `SPILL_DEG` empties, into the cup whose opening is under its lowest rim point if any.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np

from cbgo.services.mujoco_sim.build import (
    EMPTY,
    FINGER_OPEN,
    HOME_Q,
    LIQUID,
    Built,
    CupDims,
    Item,
)
from cbgo.services.mujoco_sim.ik import IK

STEPS_PER_TICK = 8  # 40 ms control period (IK at 25 Hz) at a 5 ms time step
SPILL_DEG = 40.0  # a full cup tilted beyond this pours out


class Stopped(Exception):  # noqa: N818 - a control-flow signal, not an error
    """Raised inside a motion when `cbgo/robot/stop` arrived."""


@dataclass
class PourEvent:
    """Liquid left a cup: into `into` (a cup name) or spilled (None)."""

    source: str
    into: str | None
    tilt_deg: float
    sim_time: float


@dataclass
class Sim:
    """One compiled world being simulated.

    Attributes:
        built: model, data and the object handles.
        full: each cup's liquid state.
        stop: set from any thread to stop the running motion at its next tick.
        on_tick: called after every control tick (publishing state, real-time pacing).
    """

    built: Built
    full: dict[str, bool] = field(default_factory=dict)
    stop: threading.Event = field(default_factory=threading.Event)
    on_tick: Callable[[Sim], None] | None = None
    pours: list[PourEvent] = field(default_factory=list)
    action: str | None = None
    moving: bool = False

    def __post_init__(self):
        b = self.built
        self.model, self.data, self.items = b.model, b.data, b.items
        self.ik = IK(b.model, b.tcp_site, b.arm_qpos, b.arm_dof, HOME_Q)
        self.q_cmd = HOME_Q.copy()
        self.finger_cmd = FINGER_OPEN
        for item in self.items.values():
            if item.type == "cup":
                self.full.setdefault(item.name, False)
        self._body_item = {it.body: it for it in self.items.values()}
        self._body_item.update({it.cabinet: it for it in self.items.values() if it.cabinet >= 0})
        self.refresh_liquid_visuals()

    # ------------------------------------------------------------------ state

    @property
    def time(self) -> float:
        """Simulated seconds since the world was built."""
        return float(self.data.time)

    @property
    def q(self) -> np.ndarray:
        """The arm's measured joints (7,)."""
        return self.data.qpos[self.built.arm_qpos].copy()

    @property
    def fingers(self) -> np.ndarray:
        """The two finger joints (each 0 closed .. 0.04 open), m."""
        return self.data.qpos[self.built.finger_qpos].copy()

    def tcp(self) -> tuple[np.ndarray, np.ndarray]:
        """Returns the TCP position and rotation matrix."""
        site = self.built.tcp_site
        return self.data.site_xpos[site].copy(), self.data.site_xmat[site].reshape(3, 3).copy()

    def pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Returns an object's body position and rotation matrix (drawers: the drawer)."""
        body = self.items[name].body
        return self.data.xpos[body].copy(), self.data.xmat[body].reshape(3, 3).copy()

    def tilt_deg(self, name: str) -> float:
        """Returns the angle between an object's z axis and the vertical, degrees."""
        zaxis = self.data.xmat[self.items[name].body].reshape(3, 3)[:, 2]
        return float(np.degrees(np.arccos(np.clip(zaxis[2], -1.0, 1.0))))

    @property
    def holding(self) -> str | None:
        """The object welded to the hand (switched on only after a verified grasp)."""
        for item in self.items.values():
            if item.type != "drawer" and self.data.eq_active[item.weld]:
                return item.name
        return None

    def grasped_drawer(self) -> str | None:
        """The drawer whose handle is welded to the hand, if any."""
        for item in self.items.values():
            if item.type == "drawer" and self.data.eq_active[item.weld]:
                return item.name
        return None

    # ------------------------------------------------------------------ contacts

    def item_of_geom(self, geom: int) -> Item | None:
        """Returns the object a geom belongs to (None: robot, table or nothing)."""
        return self._body_item.get(int(self.model.geom_bodyid[geom]))

    def contacts(self) -> list[tuple[int, int, np.ndarray]]:
        """Returns the active contacts as (geom1, geom2, position)."""
        d = self.data
        return [(int(c.geom1), int(c.geom2), c.pos.copy()) for c in d.contact[:d.ncon]
                if c.dist < 0.002]

    def touching(self, geoms_a, geoms_b) -> bool:
        """Returns whether any geom of a set touches any geom of another set."""
        a, b = set(geoms_a), set(geoms_b)
        return any((g1 in a and g2 in b) or (g1 in b and g2 in a)
                   for g1, g2, _ in self.contacts())

    def finger_contacts(self, geoms) -> tuple[bool, bool]:
        """Returns whether the left and the right finger touch any of these geoms."""
        fg = self.built.finger_geoms
        return (self.touching(fg[self.built.left_finger], geoms),
                self.touching(fg[self.built.right_finger], geoms))

    # ------------------------------------------------------------------ actuation

    def set_arm(self, q: np.ndarray) -> None:
        """Sets the arm's servo targets."""
        self.q_cmd = np.asarray(q, float).copy()
        self.data.ctrl[:7] = self.q_cmd

    def set_fingers(self, per_finger: float) -> None:
        """Sets the finger servo target (per finger, 0 .. 0.04 m)."""
        self.finger_cmd = float(np.clip(per_finger, 0.0, FINGER_OPEN))
        self.data.ctrl[7] = self.finger_cmd

    def hold_position(self) -> None:
        """Makes the arm hold where it is now (after a stop)."""
        self.set_arm(self.q)

    def tick(self, ticks: int = 1) -> None:
        """Advances the physics by whole control ticks.

        Raises:
            Stopped: robot/stop arrived; the arm was told to hold its position.
        """
        for _ in range(ticks):
            if self.stop.is_set():
                self.hold_position()
                raise Stopped()
            mujoco.mj_step(self.model, self.data, nstep=STEPS_PER_TICK)
            self.update_liquid()
            if self.on_tick is not None:
                self.on_tick(self)

    def settle(self, seconds: float) -> None:
        """Steps the physics for a while without checking the stop flag (reset, settling)."""
        n = max(1, int(round(seconds / (self.model.opt.timestep * STEPS_PER_TICK))))
        for _ in range(n):
            mujoco.mj_step(self.model, self.data, nstep=STEPS_PER_TICK)
            self.update_liquid()

    # ------------------------------------------------------------------ grasp welds

    def attach(self, name: str) -> None:
        """Switches on the weld between the hand and an object at their current poses."""
        m, d = self.model, self.data
        item = self.items[name]
        h, o = self.built.hand_body, item.body
        r1 = d.xmat[h].reshape(3, 3)
        rel_pos = r1.T @ (d.xpos[o] - d.xpos[h])
        inv, rel_quat = np.zeros(4), np.zeros(4)
        mujoco.mju_negQuat(inv, d.xquat[h])
        mujoco.mju_mulQuat(rel_quat, inv, d.xquat[o])
        m.eq_data[item.weld, 0:3] = 0.0
        m.eq_data[item.weld, 3:6] = rel_pos
        m.eq_data[item.weld, 6:10] = rel_quat
        d.eq_active[item.weld] = 1

    def detach(self) -> None:
        """Switches off every grasp weld."""
        for item in self.items.values():
            self.data.eq_active[item.weld] = 0

    # ------------------------------------------------------------------ liquid

    def lip(self, name: str) -> np.ndarray:
        """Returns a cup's lowest rim point (where liquid leaves when tilted)."""
        item = self.items[name]
        dims: CupDims = item.dims
        pos, rot = self.pose(name)
        axis = rot[:, 2]
        top = pos + axis * dims.half_height
        down = np.array([0.0, 0.0, -1.0]) - axis * (-axis[2])  # -z projected on the rim plane
        norm = np.linalg.norm(down)
        return top if norm < 1e-9 else top + dims.radius * down / norm

    def opening_of(self, name: str) -> tuple[np.ndarray, float]:
        """Returns the centre of a cup's opening and its radius."""
        item = self.items[name]
        pos, rot = self.pose(name)
        return pos + rot[:, 2] * item.dims.half_height, item.dims.radius

    def update_liquid(self) -> None:
        """Empties full cups tilted beyond the spill angle, into a cup below the lip if any."""
        for name, is_full in list(self.full.items()):
            if not is_full:
                continue
            tilt = self.tilt_deg(name)
            if tilt < SPILL_DEG:
                continue
            lip = self.lip(name)
            into = None
            for other in self.full:
                if other == name or self.tilt_deg(other) > 30.0:
                    continue
                mouth, radius = self.opening_of(other)
                if (np.linalg.norm(lip[:2] - mouth[:2]) < radius
                        and 0.0 < lip[2] - mouth[2] < 0.15):
                    into = other
                    break
            self.full[name] = False
            if into is not None:
                self.full[into] = True
            self.pours.append(PourEvent(name, into, tilt, self.time))
            self.refresh_liquid_visuals()

    def refresh_liquid_visuals(self) -> None:
        """Shows each cup's liquid state (blue surface when full, the dark inside when empty)."""
        for name, is_full in self.full.items():
            self.model.geom_rgba[self.items[name].liquid_geom] = LIQUID if is_full else EMPTY
