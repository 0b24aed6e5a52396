"""Arm and gripper motions: Cartesian straight lines tracked by IK, travel at a safe height.

Rules:
- a line interpolates position linearly and orientation by slerp with a minimum-jerk time
  law; every control tick solves IK from the last command (a few warm-started iterations) and
  sends the joints to the arm's position servos;
- a motion ends when the TCP is within `tol` of its goal, or fails with `MotionError`;
- the hand's yaw is folded (the gripper is symmetric) to the equivalent closest to the current
  wrist angle, so the wrist never winds up against its limit;
- every tick can raise `engine.Stopped` (robot/stop).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from cbgo.services.mujoco_sim.build import FINGER_OPEN, HOME_Q
from cbgo.services.mujoco_sim.engine import STEPS_PER_TICK, Sim
from cbgo.services.mujoco_sim.ik import IKResult

SPEED = 0.4  # m/s along a line
SLOW = 0.12  # m/s for the last centimetres of an approach, and for drawers
ANGULAR_SPEED = 2.0  # rad/s


class MotionError(Exception):
    """A motion could not be carried out (unreachable pose, or it did not arrive)."""


def tick_dt(sim: Sim) -> float:
    """Returns the duration of one control tick, s."""
    return sim.model.opt.timestep * STEPS_PER_TICK


def commanded_pose(sim: Sim) -> tuple[np.ndarray, np.ndarray]:
    """Returns the TCP pose of the current arm command (continuous from motion to motion)."""
    return sim.ik.forward(sim.q_cmd)


def _slerp(r0: np.ndarray, r1: np.ndarray, s: float) -> np.ndarray:
    q0, q1, out = np.zeros(4), np.zeros(4), np.zeros(4)
    mujoco.mju_mat2Quat(q0, r0.ravel())
    mujoco.mju_mat2Quat(q1, r1.ravel())
    if np.dot(q0, q1) < 0:
        q1 = -q1
    dot = float(np.clip(np.dot(q0, q1), -1.0, 1.0))
    theta = math.acos(dot)
    if theta < 1e-6:
        out = q1
    else:
        out = (math.sin((1 - s) * theta) * q0 + math.sin(s * theta) * q1) / math.sin(theta)
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, out / np.linalg.norm(out))
    return mat.reshape(3, 3)


def _angle(r0: np.ndarray, r1: np.ndarray) -> float:
    cos = (np.trace(r0.T @ r1) - 1.0) / 2.0
    return float(math.acos(float(np.clip(cos, -1.0, 1.0))))


def _min_jerk(s: float) -> float:
    return s * s * s * (10 - 15 * s + 6 * s * s)


def solve(sim: Sim, pos, rot, seed=None) -> IKResult:
    """Solves a pose from a seed (default: the current command) with a full budget.

    Near the edge of the workspace a solve can stall on a poor branch; it is retried from the
    rest posture and from the seed with the wrist turned.
    """
    seed = sim.q_cmd if seed is None else np.asarray(seed, float)
    best = sim.ik.solve(pos, rot, seed, iterations=100)
    if best.ok:
        return best
    for other in (HOME_Q, seed + [0, 0, 0, 0, 0, 0, np.pi / 2], seed - [0, 0, 0, 0, 0, 0,
                                                                         np.pi / 2]):
        res = sim.ik.solve(pos, rot, other, iterations=100)
        if res.ok:
            return res
        if res.pos_err < best.pos_err:
            best = res
    return best


def line(sim: Sim, pos, rot, speed: float = SPEED, tol: float = 0.003,
         settle_s: float = 1.0) -> None:
    """Moves the TCP along a straight line to (pos, rot).

    Raises:
        MotionError: the goal is out of reach, or the TCP did not arrive within settle_s.
        Stopped: robot/stop arrived.
    """
    pos, rot = np.asarray(pos, float), np.asarray(rot, float)
    goal = solve(sim, pos, rot)
    if not goal.ok:
        raise MotionError(f"the pose at {np.round(pos, 3).tolist()} is out of reach "
                          f"({goal.pos_err * 1000:.0f} mm off)")
    p0, r0 = commanded_pose(sim)
    duration = max(np.linalg.norm(pos - p0) / speed, _angle(r0, rot) / ANGULAR_SPEED, 0.06)
    n = max(1, math.ceil(duration / tick_dt(sim)))
    q = sim.q_cmd
    sim.moving = True
    for k in range(1, n + 1):
        s = _min_jerk(k / n)
        res = sim.ik.solve(p0 + s * (pos - p0), _slerp(r0, rot, s), q, iterations=8)
        q = res.q
        sim.set_arm(q)
        sim.tick()
    sim.set_arm(sim.ik.solve(pos, rot, q, iterations=50).q)
    wait_arrival(sim, pos, tol, settle_s)


def wait_arrival(sim: Sim, pos, tol: float, settle_s: float) -> None:
    """Ticks until the TCP is within tol of pos and slow.

    Raises:
        MotionError: it did not arrive within settle_s (blocked, most likely).
    """
    for _ in range(max(1, int(settle_s / tick_dt(sim)))):
        tcp, _ = sim.tcp()
        speed = float(np.abs(sim.data.qvel[sim.built.arm_dof]).max())
        if np.linalg.norm(tcp - pos) < tol and speed < 0.05:
            sim.moving = False
            return
        sim.tick()
    sim.moving = False
    tcp, _ = sim.tcp()
    raise MotionError(f"the arm did not reach {np.round(pos, 3).tolist()} "
                      f"(stuck {np.linalg.norm(tcp - pos) * 1000:.0f} mm away) qvel "
                      f"{np.round(sim.data.qvel[sim.built.arm_dof], 3).tolist()}")


# rad a grasp pose's joints keep from their limits where the hand turned by 180° allows it:
# with 0.22 rad at the elbow, the arm swung back towards its rest posture on the lift and
# squeezed a 0.03 m cup out of the pads (tests/unit/mujoco_sim/test_sim_paper_scenes.py)
LIMIT_MARGIN = 0.3


def fold_to_wrist(sim: Sim, pos, rot) -> np.ndarray:
    """Returns rot or rot turned 180° about the TCP axis, whichever keeps the wrist nearer.

    The gripper is symmetric, so both grasp the same way. The one that turns the hand less
    is tried first and kept unless it ends near a joint limit.
    """
    flip = rot @ np.diag([-1.0, -1.0, 1.0])
    _, now = commanded_pose(sim)
    order = sorted((rot, flip), key=lambda r: _angle(now, r))
    for cand in order:
        res = sim.ik.solve(pos, cand, sim.q_cmd, iterations=60)
        if res.ok and _limit_penalty(sim, res.q) == 0.0:
            return cand
    return order[0]


def _limit_penalty(sim: Sim, q: np.ndarray) -> float:
    lo, hi = sim.ik.lo, sim.ik.hi
    margin = np.minimum(q - lo, hi - q)
    return float(np.sum(np.clip(LIMIT_MARGIN - margin, 0.0, None)))


def travel(sim: Sim, pos, rot, height: float, approach: float = 0.05, fold: bool = True) -> None:
    """Goes up to `height`, across to above pos (turning to rot), and down to pos.

    The last `approach` metres of the descent are slow. With `fold`, the hand may arrive
    turned by 180° about its axis (see `fold_to_wrist`).
    """
    pos = np.asarray(pos, float)
    if fold:
        rot = fold_to_wrist(sim, pos, rot)
    tcp, rnow = commanded_pose(sim)
    height = max(height, pos[2])
    if tcp[2] < height - 0.005:
        line(sim, [tcp[0], tcp[1], height], rnow)
    if np.linalg.norm(tcp[:2] - pos[:2]) > 0.003 or _angle(rnow, rot) > 0.02:
        line(sim, [pos[0], pos[1], height], rot)
    above = min(height, pos[2] + approach)
    if height - above > 0.005:
        line(sim, [pos[0], pos[1], above], rot)
    line(sim, pos, rot, speed=SLOW, tol=0.002)


def gripper(sim: Sim, per_finger: float, seconds: float = 0.3) -> None:
    """Commands the fingers and waits until they stop (at most `seconds` more)."""
    sim.set_fingers(min(per_finger, FINGER_OPEN))
    dt = tick_dt(sim)
    ticks = max(3, int(seconds / dt))
    for i in range(ticks):
        sim.tick()
        if i >= 5 and float(np.abs(sim.data.qvel[sim.built.finger_dof]).max()) < 0.002:
            break


def pause(sim: Sim, seconds: float) -> None:
    """Lets the physics run with the arm holding its command."""
    sim.tick(max(1, int(seconds / tick_dt(sim))))


def follow(sim: Sim, poses: list[tuple[np.ndarray, np.ndarray]], duration: float,
           tol: float = 0.004) -> None:
    """Moves the TCP through a sequence of poses (piecewise lines and slerps) in `duration`.

    Raises:
        MotionError: a pose is out of reach or the TCP did not arrive at the last one.
    """
    n = max(1, math.ceil(duration / tick_dt(sim)))
    q = sim.q_cmd
    sim.moving = True
    segments = len(poses) - 1
    for k in range(1, n + 1):
        u = _min_jerk(k / n) * segments
        i = min(int(u), segments - 1)
        f = u - i
        (p0, r0), (p1, r1) = poses[i], poses[i + 1]
        q = sim.ik.solve(p0 + f * (p1 - p0), _slerp(r0, r1, f), q, iterations=15).q
        sim.set_arm(q)
        sim.tick()
    pos, rot = poses[-1]
    final = sim.ik.solve(pos, rot, q, iterations=50)
    if not final.ok:
        raise MotionError(f"the pose at {np.round(pos, 3).tolist()} is out of reach")
    sim.set_arm(final.q)
    wait_arrival(sim, pos, tol, 1.0)
