"""The eleven actions, executed physically, one at a time, each verified from the physics.

`Robot.execute(action, object, params)`:
1. reads the scene from the physics and checks the preconditions (`Robot.precheck`): the world
   model's (`cbgo.world.check`, which includes room for the gripper at a move's goal with the
   hand at yaw 0), then two it does not know (an empty gripper to grasp a handle; the same room
   with the hand at its real yaw and the physical footprints); if one fails, the action is
   refused with it, without moving;
2. plans it: grasp yaw, travel height, release pose, pouring direction; a plan that would
   collide (the way of a move blocked, no collision-free pour, no yaw at which the hand can
   reach down to a grasp) is refused, without moving;
3. executes it with IK-tracked Cartesian motions and real finger contact; a grasp weld is
   switched on only after both fingers were seen touching the object;
4. verifies the outcome with `checks` and returns an `Outcome` (ok, or the precise failure);
   after a failure (not a stop, which answers at once) it lets loose objects come to rest
   (bounded), so that the scene read next says where a dropped or toppled object lies.

Targets come from the world model where it defines them (the TCP's goal cell of a move, the
table column of ``place``); physical details (where in a drawer, how to tilt) are decided here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cbgo import world
from cbgo.services.mujoco_sim import checks, motion, observe
from cbgo.services.mujoco_sim.build import WALL
from cbgo.services.mujoco_sim.engine import SPILL_DEG, Sim, Stopped
from cbgo.services.mujoco_sim.ik import rot_axis, rot_z, top_down
from cbgo.services.mujoco_sim.motion import MotionError
from cbgo.services.mujoco_sim.plan import (
    Checker,
    Hit,
    finger_for_width,
    fold_yaw,
    grasp_half_width,
    hang_below_tcp,
    tcp_below_top,
    travel_height,
    yaw_candidates,
)
from cbgo.services.mujoco_sim.scenes import tray_spot
from cbgo.world import DEFAULT_GRID, Grid, Scene

OPEN_MARGIN = 0.012  # m between an open pad and the object
POUR_CLEARANCE = 0.025  # m between the pouring cup and the target's rim
MAX_POUR_DEG = 135.0
HANDLE_HALF_WIDTH = 0.012
# m the TCP may sit above the handle knob's centre when grasping it, highest first: the pads
# still close on the knob's upper half, and at 0.014 the hand's underside (HAND_BOTTOM above
# the TCP) is 0.024 m above the cabinet's top, so it clears a neighbouring cabinet (0.09..0.11
# m) or a low tower beside it; level with the knob it grazes them and stalls (`cbgo bench sim`
# with the grasp level: stuck 5-9 mm away, closed 8-13 % short). Lower ones when the wrist would
# touch a tower on the cabinet itself; the first whose grasp and end poses are collision-free
# is taken, else 0.
HANDLE_GRASP_LIFTS = (0.014, 0.007, 0.0)
HAND_BOTTOM = 0.045  # m from the TCP up to the underside of the hand
HAND_HALF = (0.035, 0.105)  # m, the hand's half extents across and along the fingers' axis
RELEASE_LIFTS = (0.0, 0.005, 0.01, 0.015, 0.02, 0.03)  # m above the goal a load may be let go
LOWER_SPEED = 0.03  # m/s while lowering a held load onto its support
REST_SPEED = 0.01  # m/s (and rad/s) under which a released load counts as at rest
REST_TIMEOUT_S = 1.5  # s at most to wait for a released load to come to rest
# s at most for loose objects to come to rest after a failure: a cup dropped from travel
# height bounces, topples and rolls on its side for about 2 s (measured), so 1.5 s would
# report it 5 cm short of where it comes to lie
FAILURE_REST_S = 3.0
SLIDE_MARGIN = 0.002  # m between a pad and a load that slides down between the pads
TRAY_SHIFT_STEP = 0.005  # m between the spots in a drawer's tray that put_into tries
TRAY_WALL_MARGIN = 0.004  # m a load put into a tray keeps from the tray's front wall


class ActionError(Exception):
    """The action was attempted and did not work (a world outcome)."""


class Refused(Exception):  # noqa: N818 - a refusal, not an error
    """The action is infeasible physically; nothing moved."""


@dataclass
class Outcome:
    """What an action did.

    Attributes:
        ok: the success check passed.
        error: the refusal or failure, as a sentence (None when ok).
        sim_s: simulated seconds the action took.
        refused: nothing moved (a precondition failed).
    """

    ok: bool
    error: str | None
    sim_s: float
    refused: bool = False


def missing_preconditions(action: str, scene: Scene) -> str | None:
    """Returns a failed precondition that the world model does not know (yet), or None.

    Grasping a drawer's handle needs an empty gripper.
    """
    if action in ("open", "close") and scene.robot.holding is not None:
        return f"the gripper holds {scene.robot.holding}; it must be empty to grasp a handle"
    return None


class Robot:
    """Executes actions on a simulation.

    Args:
        sim: the simulation.
        grid: the world model's grid.
    """

    def __init__(self, sim: Sim, grid: Grid = DEFAULT_GRID):
        self.sim, self.grid = sim, grid
        self.checker = Checker(sim)

    def symbolic(self) -> Scene:
        """Returns the world model's view of the physics right now."""
        return Scene.from_dict({"objects": observe.observe_objects(self.sim),
                                "robot": observe.observe_robot(self.sim)})

    def precheck(self, action: str, obj: str | None, params: dict | None = None,
                 scene: Scene | None = None) -> str | None:
        """Returns why the action cannot be done in this scene (nothing moves), or None.

        The world model's preconditions, then those it does not know yet: an empty gripper to
        grasp a handle, and a move's goal cell free of objects.
        """
        params = {**world.actions.DEFAULT_PARAMS.get(action, {}), **(params or {})}
        scene = self.symbolic() if scene is None else scene
        reason = world.check(action, obj, scene, params, self.grid)
        if reason is None:
            reason = missing_preconditions(action, scene)
        if reason is None and action in world.MOVES:
            reason = self._goal_cell_taken(action, params, scene)
        return reason

    def _goal_cell_taken(self, action: str, params: dict, scene: Scene) -> str | None:
        """Returns why the gripper (and its load) does not fit at a move's goal, or None."""
        sim = self.sim
        goal = np.asarray(world.apply(action, None, params, scene, self.grid).robot.tcp, float)
        held = sim.holding
        _, rot = sim.tcp()
        yaw = math.atan2(rot[1, 0], rot[0, 0])
        c, s = abs(math.cos(yaw)), abs(math.sin(yaw))
        load = grasp_half_width(sim.items[held]) if held else 0.02
        # (bottom z, half x, half y) of what hangs under the TCP, and of the hand above it
        parts = [(goal[2] - hang_below_tcp(sim.items[held] if held else None), load, load),
                 (goal[2] + HAND_BOTTOM, HAND_HALF[0] * c + HAND_HALF[1] * s,
                  HAND_HALF[0] * s + HAND_HALF[1] * c)]
        for name, item in sim.items.items():
            if name == held:
                continue
            for (x0, x1, y0, y1), top in observe.footprints(sim, item):
                for bottom, hx, hy in parts:
                    if (top > bottom - 0.005 and x0 - hx < goal[0] < x1 + hx
                            and y0 - hy < goal[1] < y1 + hy):
                        cell = list(self.grid.cell_of(goal))
                        return f"the gripper does not fit at the goal cell {cell}: {name} is there"
        return None

    def execute(self, action: str, obj: str | None, params: dict | None = None) -> Outcome:
        """Executes one action and verifies it; see the module docstring."""
        sim = self.sim
        t0 = sim.time
        scene = self.symbolic()
        reason = self.precheck(action, obj, params, scene)
        if reason is not None:
            return Outcome(False, f"refused: {reason}", 0.0, refused=True)
        params = {**world.actions.DEFAULT_PARAMS.get(action, {}), **(params or {})}
        sim.action = action
        try:
            if action in world.MOVES:
                error = self._move(action, params, scene)
            else:
                error = getattr(self, f"_{action}")(obj, params, scene)
        except Refused as e:
            return Outcome(False, f"refused: {e}", sim.time - t0, refused=True)
        except Stopped:
            error = "stopped"
            if sim.grasped_drawer() is not None:
                sim.detach()  # no hidden weld to a handle may outlive the action
        except (MotionError, ActionError) as e:
            error = str(e)
        finally:
            sim.action, sim.moving = None, False
        if error not in (None, "stopped"):  # a stop answers at once, the arm held still
            self.let_world_rest(FAILURE_REST_S)
        return Outcome(error is None, error, sim.time - t0)

    def let_world_rest(self, timeout_s: float) -> None:
        """After a failure: steps the physics until no loose object moves, at most timeout_s.

        A failed action may have dropped or knocked over its load; the scene published after it
        must say where that lies, not where it was in mid-air. The arm holds where it stopped;
        the stop flag is not checked (a stop is what may have ended the action).
        """
        sim = self.sim
        bodies = [it.body for it in sim.items.values()
                  if it.type != "drawer" and it.name != sim.holding]
        calm = 0
        for _ in range(max(1, int(timeout_s / motion.tick_dt(sim)))):
            speed = max((float(np.linalg.norm(sim.data.cvel[b])) for b in bodies), default=0.0)
            calm = calm + 1 if speed < REST_SPEED else 0
            if calm >= 5:
                return
            sim.settle(motion.tick_dt(sim))

    # ------------------------------------------------------------------ planning helpers

    def _q_for(self, pos, rot, seed=None):
        seed = self.sim.q_cmd if seed is None else seed
        res = self.sim.ik.solve(pos, rot, seed, iterations=60)
        return res.q if res.ok else None

    def _pose_hits(self, pos, rot, fingers: float, approach: float = 0.0) -> list[Hit] | None:
        """Returns what the robot would touch at a pose or on the approach from above.

        None: out of reach.
        """
        q = self._q_for(pos, rot)
        if q is None:
            return None
        hits = self.checker.hits(q, fingers)
        seed = q
        for dz in np.arange(0.025, approach + 1e-9, 0.025):
            if hits:
                break
            q_up = self._q_for(np.asarray(pos) + [0, 0, dz], rot, seed)
            if q_up is None:
                return None
            hits = self.checker.hits(q_up, fingers)
            seed = q_up
        return hits

    def _best_pose(self, candidates, pose_of, fingers: float, approach: float,
                   lifts=(0.0,), what: str | None = None, shifts=((0.0, 0.0, 0.0),)):
        """Returns (rot, position) of the first collision-free candidate, else the least bad.

        Shifts are tried in order, within one shift the lifts lowest first, and within one
        lift the yaws in order. With `what` (the object to grasp), a grasp with no
        collision-free candidate is refused instead: the hand would press on a neighbour on
        the way down and stall before the fingers close (a cup in the corner between two
        drawer cabinets, measured: stuck 14-18 mm above it).

        Args:
            candidates: hand yaws to try.
            pose_of: rot -> TCP position at that hand orientation (before the shift and lift).
            fingers: the finger opening during the approach.
            approach: how far above the pose the vertical approach is checked, m.
            lifts: heights above the pose to try, m (a load may drop that far).
            what: the object a grasp is for; refuse rather than take the least bad pose.
            shifts: horizontal displacements of the pose to try, m (a load may go there too).

        Raises:
            Refused: no candidate is reachable.
        """
        best, best_depth = None, math.inf
        for shift in shifts:
            for lift in lifts:
                for yaw in candidates:
                    rot = motion.fold_to_wrist(self.sim, pose_of(top_down(yaw)), top_down(yaw))
                    pos = pose_of(rot) + np.asarray(shift) + [0.0, 0.0, lift]
                    hits = self._pose_hits(pos, rot, fingers, approach)
                    if hits is None:
                        continue
                    depth = sum(h.depth for h in hits) + lift
                    if not hits:
                        return rot, pos
                    if depth < best_depth:
                        best, best_depth = (rot, pos), depth
        if best is None:
            raise Refused("no reachable top-down pose for the gripper there")
        if what is not None:
            hits = self._pose_hits(best[1], best[0], fingers, approach) or []
            near = sorted({h.what for h in hits}) or ["something"]
            raise Refused(f"the gripper has no room to grasp {what}: at every yaw the hand "
                          f"would touch {' or '.join(near)}")
        return best

    # ------------------------------------------------------------------ pick and release

    def _pick_up(self, name: str, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        item = sim.items[name]
        center, _ = sim.pose(name)
        grasp_z = observe.top_z(sim, name) - tcp_below_top(item)
        pre = finger_for_width(grasp_half_width(item) + OPEN_MARGIN)
        self.checker.sync()
        rot, pos = self._best_pose(yaw_candidates(item, sim), lambda _r: np.array(
            [center[0], center[1], grasp_z]), pre, approach=0.1, lifts=(0.0, 0.008), what=name)
        height = travel_height(sim, None)
        motion.gripper(sim, pre, 0.2)
        motion.travel(sim, pos, rot, height, fold=False)
        motion.gripper(sim, 0.0, 0.5)
        left, right = sim.finger_contacts(item.geoms)
        if not (left and right):
            motion.gripper(sim, pre, 0.2)
            motion.line(sim, pos + [0, 0, 0.1], rot)
            raise ActionError(f"could not grasp {name}: "
                              + ("no finger" if not (left or right) else "only one finger")
                              + " touched it")
        sim.attach(name)
        lift_to = max(travel_height(sim, item), pos[2] + 0.06)
        motion.line(sim, [pos[0], pos[1], lift_to], rot)
        return checks.grasped(sim, name, center[2])

    def _release_at(self, goal, surface: list[int], shifts=((0.0, 0.0, 0.0),)) -> None:
        """Puts the held object's centre at `goal` and lets go.

        `surface` are the geoms it lands on, whose contacts do not count while planning;
        `shifts` are displacements of the goal that are as good, tried in order where the
        hand does not fit at the goal itself.
        """
        sim = self.sim
        held = sim.holding
        item = sim.items[held]
        tcp, r_tcp = sim.tcp()
        obj_in_tcp = r_tcp.T @ (sim.pose(held)[0] - tcp)
        release = finger_for_width(grasp_half_width(item) + OPEN_MARGIN)
        self.checker.sync(carried=held, ignore_geoms=surface)
        yaw_now = math.atan2(r_tcp[1, 0], r_tcp[0, 0])
        rot, pos = self._best_pose(yaw_candidates(item, sim, yaw_now),
                                   lambda r: np.asarray(goal) - r @ obj_in_tcp, release,
                                   approach=0.1, lifts=RELEASE_LIFTS, shifts=shifts)
        motion.travel(sim, pos, rot, travel_height(sim, item), fold=False)
        base_z = (np.asarray(goal) - rot @ obj_in_tcp)[2]
        pos = self._lower_until_contact(item, surface, pos, rot, pos[2] - base_z + 0.008)
        if sim.touching(item.geoms, surface):
            # It stands on its support: open while still welded, so that the pads (pressed
            # into the load by the grasp) cannot push it aside as they part.
            motion.gripper(sim, release, 0.6)
        sim.detach()
        if not sim.touching(item.geoms, surface):
            # It must drop (the hand cannot go lower): open just enough for it to slide down
            # between the pads, which keep it upright, until it stands on the surface.
            motion.gripper(sim, finger_for_width(grasp_half_width(item) + SLIDE_MARGIN), 0.3)
            for _ in range(int(0.4 / motion.tick_dt(sim))):
                if sim.touching(item.geoms, surface):
                    break
                sim.tick()
            motion.pause(sim, 0.1)
        motion.gripper(sim, release, 0.6)
        motion.pause(sim, 0.1)
        # Leave straight up and slowly through the first centimetres, so that the pads do not
        # drag the load along; then wait (bounded) until it is at rest before it is checked.
        motion.line(sim, [pos[0], pos[1], pos[2] + 0.03], rot, speed=motion.SLOW)
        up = max(travel_height(sim, None), pos[2] + 0.08)
        motion.line(sim, [pos[0], pos[1], up], rot)
        self._wait_rest(held, REST_TIMEOUT_S)

    def _lower_until_contact(self, item, surface: list[int], pos, rot, max_drop: float):
        """Lowers the hand (still welded to its load) until the load touches `surface`.

        Goes down at most `max_drop` m, slowly, and stops at the first contact or when the
        hand no longer follows (blocked). Returns the TCP position where it stopped.
        """
        sim = self.sim
        pos = np.asarray(pos, float)
        if max_drop <= 0 or sim.touching(item.geoms, surface):
            return pos
        dt = motion.tick_dt(sim)
        step = LOWER_SPEED * dt
        q = sim.q_cmd
        target = pos.copy()
        for _ in range(int(max_drop / step) + 1):
            if sim.touching(item.geoms, surface):
                break
            tcp, _ = sim.tcp()
            if target[2] - tcp[2] < -0.004:  # the hand lags behind its command: blocked
                break
            target = target - [0.0, 0.0, step]
            q = sim.ik.solve(target, rot, q, iterations=8).q
            sim.set_arm(q)
            sim.tick()
        tcp, _ = sim.tcp()
        sim.set_arm(sim.ik.solve(tcp, rot, q, iterations=50).q)  # hold where it is
        sim.moving = False
        motion.pause(sim, 0.05)
        return np.array([pos[0], pos[1], sim.tcp()[0][2]])

    def _wait_rest(self, name: str, timeout_s: float) -> None:
        """Ticks until `name` is at rest (slow for a few ticks in a row), at most timeout_s."""
        sim = self.sim
        body = sim.items[name].body
        calm = 0
        for _ in range(max(1, int(timeout_s / motion.tick_dt(sim)))):
            speed = float(np.linalg.norm(sim.data.cvel[body]))
            calm = calm + 1 if speed < REST_SPEED else 0
            if calm >= 5:
                return
            sim.tick()

    def _place(self, _obj, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        held = sim.holding
        after = world.apply("place", None, params, scene, self.grid)
        x, y, _ = after.get(held).position
        item = sim.items[held]
        self._release_at([x, y, item.dims.half_height + 0.003], [sim.built.table_geom])
        return checks.placed(sim, held, (x, y))

    def _put_on(self, base: str, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        held = sim.holding
        item = sim.items[held]
        b = sim.items[base]
        xy = (observe.drawer_center(sim, b) if b.type == "drawer" else sim.pose(base)[0])[:2]
        z = observe.top_z(sim, base) + item.dims.half_height + 0.003
        surface = [sim.model.geom(f"{base}/cab_top").id] if b.type == "drawer" else b.geoms
        self._release_at([xy[0], xy[1], z], list(surface))
        return checks.stacked(sim, held, base)

    def _put_into(self, drawer: str, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        held = sim.holding
        goal = tray_spot(sim, drawer, sim.items[held].dims.half_height) + [0, 0, 0.003]
        self._release_at(goal, [sim.items[drawer].bottom_geom],
                         self._tray_shifts(sim.items[drawer], sim.items[held]))
        return checks.in_drawer(sim, held, drawer)

    @staticmethod
    def _tray_shifts(drawer, load) -> list[tuple[float, float, float]]:
        """Returns where else in the tray a load may go: towards the tray's front, in steps.

        The spot in the middle of the tray's open part leaves the hand a few millimetres from
        the cabinet's front when it reaches low (a 0.03 m cup, the hand's underside under the
        cabinet's top, measured: stuck 4 mm short); further out, the load still stands on the
        tray's floor, clear of its front wall.
        """
        room = (drawer.dims.travel - WALL) / 2 - grasp_half_width(load) - TRAY_WALL_MARGIN
        steps = np.arange(0.0, max(room, 0.0) + 1e-9, TRAY_SHIFT_STEP)
        return [(drawer.direction * float(d), 0.0, 0.0) for d in steps]

    # ------------------------------------------------------------------ moves

    def _move(self, action: str, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        goal = np.asarray(world.apply(action, None, params, scene, self.grid).robot.tcp, float)
        tcp, rot = sim.tcp()
        held = sim.holding
        self.checker.sync(carried=held)
        start = self._q_for(tcp, rot)
        blocked_at_start = {h.what for h in self.checker.hits(start)} if start is not None \
            else set()
        steps = max(2, int(np.linalg.norm(goal - tcp) / 0.01))
        seed = start
        for s in np.linspace(0.0, 1.0, steps)[1:]:
            q = self._q_for(tcp + s * (goal - tcp), rot, seed)
            if q is None:
                raise Refused(f"the gripper cannot reach {np.round(goal, 2).tolist()}")
            new = [h.what for h in self.checker.hits(q) if h.what not in blocked_at_start]
            if new:
                raise Refused(f"the way {action.removeprefix('move_')} is blocked by {new[0]}")
            seed = q
        offset = sim.pose(held)[0] - tcp if held else None
        motion.line(sim, goal, rot, tol=0.003)
        motion.pause(sim, 0.1)
        return checks.moved(sim, goal, held, offset)

    # ------------------------------------------------------------------ drawers

    def _handle_pose(self, drawer: str, opening: bool, rot, fingers: float) -> np.ndarray:
        """Returns the TCP position that grasps the handle (see `HANDLE_GRASP_LIFTS`).

        The first lift whose grasp pose and the pose where the pull or push ends touch
        nothing but the knob; else the knob's centre (the firmest grasp).
        """
        item = self.sim.items[drawer]
        knob = observe.tray_point(self.sim, item, item.dims.handle)
        q = float(self.sim.data.qpos[item.qpos])
        shift = item.direction * (item.dims.travel - q) if opening else -item.direction * q
        self.checker.sync(ignore_geoms=[item.handle_geom])
        for lift in HANDLE_GRASP_LIFTS:
            pos = knob + [0.0, 0.0, lift]
            if all(self._pose_hits(p, rot, fingers) == [] for p in (pos, pos + [shift, 0, 0])):
                return pos
        return knob

    def _drawer(self, drawer: str, opening: bool) -> str | None:
        sim = self.sim
        item = sim.items[drawer]
        pre = finger_for_width(HANDLE_HALF_WIDTH + OPEN_MARGIN)
        knob = observe.tray_point(sim, item, item.dims.handle)
        rot = motion.fold_to_wrist(sim, knob, top_down(0.0))
        handle = self._handle_pose(drawer, opening, rot, pre)
        motion.gripper(sim, pre, 0.2)
        motion.travel(sim, handle, rot, travel_height(sim, None), fold=False)
        motion.gripper(sim, 0.0, 0.5)
        left, right = sim.finger_contacts([item.handle_geom])
        if not (left and right):
            motion.gripper(sim, pre, 0.2)
            motion.line(sim, handle + [0, 0, 0.08], sim.tcp()[1])
            raise ActionError(f"could not grasp the handle of {drawer}")
        sim.attach(drawer)
        q = float(sim.data.qpos[item.qpos])
        way = item.direction  # the tray slides out along the world's x this way
        shift = way * (item.dims.travel - q - 0.002) if opening else -way * (q + 0.003)
        _, rot_now = sim.tcp()
        try:
            motion.line(sim, handle + [shift, 0.0, 0.0], rot_now, speed=motion.SLOW, tol=0.005,
                        settle_s=0.6)
        except MotionError:
            pass  # the check below says how far the drawer went
        finally:
            sim.detach()
            motion.gripper(sim, pre, 0.3)
        tcp, rot_now = sim.tcp()
        motion.line(sim, tcp + [0, 0, 0.08], rot_now)
        return checks.drawer_open(sim, drawer) if opening else checks.drawer_closed(sim, drawer)

    def _open(self, drawer: str, params: dict, scene: Scene) -> str | None:
        return self._drawer(drawer, opening=True)

    def _close(self, drawer: str, params: dict, scene: Scene) -> str | None:
        return self._drawer(drawer, opening=False)

    # ------------------------------------------------------------------ pour

    def _pour(self, target: str, params: dict, scene: Scene) -> str | None:
        sim = self.sim
        source = sim.holding
        angle = params.get("angle_deg", 90.0)
        if type(angle) not in (int, float):
            raise Refused(f"angle_deg must be a number of degrees, got {angle!r}")
        if not SPILL_DEG + 5 <= angle <= MAX_POUR_DEG:
            raise Refused(f"angle_deg {angle:g} is outside {SPILL_DEG + 5:g}..{MAX_POUR_DEG:g}: "
                          f"liquid leaves a cup tilted beyond {SPILL_DEG:g}°")
        poses = self._pour_path(source, target, math.radians(float(angle)))
        item = sim.items[source]
        motion.travel(sim, poses[0][0], poses[0][1], travel_height(sim, item), fold=False)
        motion.follow(sim, poses, duration=max(1.0, angle / 60.0))
        motion.pause(sim, 0.3)
        motion.follow(sim, poses[::-1], duration=max(1.0, angle / 60.0))
        tcp, rot = sim.tcp()
        motion.line(sim, [tcp[0], tcp[1], travel_height(sim, item)], rot)
        return checks.poured(sim, source, target)

    def _pour_path(self, source: str, target: str, angle: float):
        """Returns TCP poses that tilt the held cup about its lip over the target's opening.

        Of the tilt directions that are reachable and collision-free, the one with the least
        joint travel; from higher up when no low one is free.

        Raises:
            Refused: no direction works.
        """
        sim = self.sim
        mouth, _ = sim.opening_of(target)
        tcp, r_tcp = sim.tcp()
        p_src, r_src = sim.pose(source)
        tcp_in_src = (r_src.T @ (tcp - p_src), r_src.T @ r_tcp)
        dims = sim.items[source].dims
        self.checker.sync(carried=source)
        toward_robot = math.atan2(-mouth[1], -mouth[0])
        for lift in (0.0, 0.035, 0.07):  # pour from higher up when the low path is blocked
            best, best_cost = None, math.inf
            for k in range(8):
                heading = toward_robot + k * math.pi / 4
                d = np.array([math.cos(heading), math.sin(heading), 0.0])
                poses = self._tilt_poses(d, r_tcp, r_src, tcp_in_src, dims, mouth + [0, 0, lift],
                                         angle)
                cost = self._path_cost(poses, best_cost)
                if cost < best_cost:
                    best, best_cost = poses, cost
            if best is not None:
                return best
        raise Refused(f"no reachable, collision-free way to pour into {target}")

    @staticmethod
    def _tilt_poses(d, r_tcp, r_src, tcp_in_src, dims, mouth, angle):
        """Returns TCP poses tilting the held cup towards d about its lip, lip over mouth."""
        axis = np.cross([0.0, 0.0, 1.0], d)
        # Turn the cup about its own axis first so that the fingers sit on the tilt axis: the
        # hand then swings over the lip instead of dipping a finger under it.
        closing = r_tcp[:, 1]
        turn = fold_yaw(math.atan2(axis[1], axis[0]) - math.atan2(closing[1], closing[0]))
        r_start = rot_z(turn) @ r_src
        lip_body = dims.radius * (r_start.T @ d) + np.array([0, 0, dims.half_height])
        poses = []
        for theta in np.linspace(0.0, angle, 10):
            rot_src = rot_axis(axis, theta) @ r_start
            lip = mouth + [0, 0, POUR_CLEARANCE + dims.height * max(math.cos(theta), 0.0)]
            center = lip - rot_src @ lip_body
            poses.append((center + rot_src @ tcp_in_src[0], rot_src @ tcp_in_src[1]))
        return poses

    def _path_cost(self, poses, bound: float = math.inf) -> float:
        """Returns the joint travel along a path of TCP poses.

        Infinite when a pose is unreachable or colliding, the IK jumps between branches, or
        the travel exceeds `bound` (a better path is known).
        """
        start = self.sim.ik.solve(poses[0][0], poses[0][1], self.sim.q_cmd, iterations=60)
        if not start.ok:
            return math.inf
        seed = start.q
        cost = float(np.abs(seed - self.sim.q_cmd).sum())
        for pos, rot in poses:
            res = self.sim.ik.solve(pos, rot, seed, iterations=30)
            cost += float(np.abs(res.q - seed).sum())
            if (not res.ok or np.abs(res.q - seed).max() > 0.5 or cost >= bound
                    or self.checker.hits(res.q)):
                return math.inf
            seed = res.q
        return cost
