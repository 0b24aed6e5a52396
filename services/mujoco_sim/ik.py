"""Damped-least-squares inverse kinematics of the Panda's TCP site (position and orientation).

Rules:
- IK runs on its own `mujoco.MjData` (kinematics only), never on the simulation's data;
- a solve starts from a seed (the last commanded joints), so following a path in small steps
  converges in a few iterations and stays on one branch;
- a null-space pull towards a rest posture keeps the elbow up and away from joint limits;
- joints are clamped to their limits at every iteration.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

# Top-down: the hand's z axis (towards the fingertips) points down, its y axis (the fingers'
# closing axis) along world y at yaw 0.
DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def rot_z(angle: float) -> np.ndarray:
    """Returns the rotation matrix about world z by angle (rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_axis(axis, angle: float) -> np.ndarray:
    """Returns the rotation matrix about a unit axis by angle (rad) (Rodrigues)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def top_down(yaw: float) -> np.ndarray:
    """Returns the TCP orientation of a top-down grasp whose fingers close along yaw + 90°."""
    return rot_z(yaw) @ DOWN


def orientation_error(current: np.ndarray, target: np.ndarray,
                      target_quat: np.ndarray | None = None) -> np.ndarray:
    """Returns the rotation vector (world frame) that turns `current` into `target`."""
    quat_c, err = np.zeros(4), np.zeros(3)
    mujoco.mju_mat2Quat(quat_c, current.ravel())
    if target_quat is None:
        target_quat = np.zeros(4)
        mujoco.mju_mat2Quat(target_quat, target.ravel())
    mujoco.mju_subQuat(err, target_quat, quat_c)  # in current's frame
    return current @ err


@dataclass
class IKResult:
    """The joints of one solve and how well they reach the target."""

    q: np.ndarray
    pos_err: float
    rot_err: float
    iterations: int

    @property
    def ok(self) -> bool:
        """Whether the solve reached the target (1 mm, 0.01 rad)."""
        return self.pos_err < 1e-3 and self.rot_err < 1e-2


class IK:
    """Solves TCP poses for the arm joints of one compiled model.

    Args:
        model: the compiled world (any scene: only the arm's kinematics are used).
        site: the TCP site id.
        qpos_adr: qpos addresses of the 7 arm joints.
        dof_adr: dof addresses of the 7 arm joints.
        rest: the null-space rest posture.
    """

    def __init__(self, model: mujoco.MjModel, site: int, qpos_adr: np.ndarray,
                 dof_adr: np.ndarray, rest: np.ndarray, damping: float = 0.03):
        self.model, self.site = model, site
        self.qpos_adr, self.dof_adr = qpos_adr, dof_adr
        self.rest = np.asarray(rest, float)
        self.damping = damping
        self.data = mujoco.MjData(model)
        joints = [int(np.where(model.jnt_qposadr == a)[0][0]) for a in qpos_adr]
        self.lo = model.jnt_range[joints, 0].copy()
        self.hi = model.jnt_range[joints, 1].copy()
        self._jacp = np.zeros((3, model.nv))
        self._jacr = np.zeros((3, model.nv))

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Returns the TCP position and rotation matrix at joints q."""
        self.data.qpos[self.qpos_adr] = q
        mujoco.mj_kinematics(self.model, self.data)
        return self.data.site_xpos[self.site].copy(), self.data.site_xmat[self.site].reshape(
            3, 3).copy()

    def solve(self, pos, rot, seed, iterations: int = 50, tol: float = 2e-4,
              rot_weight: float = 0.5, null_gain: float = 0.05) -> IKResult:
        """Returns joints that put the TCP at pos with orientation rot.

        Args:
            pos: target position (3,).
            rot: target rotation matrix (3, 3).
            seed: starting joints (7,).
            iterations: most Gauss-Newton steps.
            tol: stop once the weighted error norm is below this.
            rot_weight: metres per radian in the error norm.
            null_gain: pull towards the rest posture in the Jacobian's null space.
        """
        q = np.clip(np.asarray(seed, float).copy(), self.lo, self.hi)
        pos, rot = np.asarray(pos, float), np.asarray(rot, float)
        quat_t = np.zeros(4)
        mujoco.mju_mat2Quat(quat_t, rot.ravel())
        damp = self.damping ** 2 * np.eye(6)
        eye6 = np.eye(6)
        pair = np.empty((2, 6, 6))
        err = np.zeros(6)
        jac = np.empty((6, 7))
        rot_tol = tol * rot_weight * 5
        it = 0
        for it in range(1, iterations + 1):  # noqa: B007 - reported in the result
            p, r = self.forward(q)
            err[:3] = pos - p
            err[3:] = orientation_error(r, rot, quat_t) * rot_weight
            if np.dot(err[:3], err[:3]) < tol * tol and np.dot(err[3:], err[3:]) < rot_tol ** 2:
                break
            mujoco.mj_comPos(self.model, self.data)
            mujoco.mj_jacSite(self.model, self.data, self._jacp, self._jacr, self.site)
            jac[:3] = self._jacp[:, self.dof_adr]
            jac[3:] = self._jacr[:, self.dof_adr] * rot_weight
            jjt = jac @ jac.T
            pair[0] = jjt + damp
            pair[1] = jjt + 1e-8 * eye6
            damped, exact = np.linalg.inv(pair)  # one call: numpy's per-call cost dominates
            # The null-space pull keeps the elbow up; its projector is (nearly) undamped so
            # that it cannot disturb the task.
            pull = null_gain * (self.rest - q)
            dq = jac.T @ (damped @ err) + pull - jac.T @ (exact @ (jac @ pull))
            step = np.max(np.abs(dq))
            if step > 0.2:  # keep each step inside the linear region
                dq *= 0.2 / step
            q = np.minimum(np.maximum(q + dq, self.lo), self.hi)
        p, r = self.forward(q)
        return IKResult(q, float(np.linalg.norm(pos - p)),
                        float(np.linalg.norm(orientation_error(r, rot))), it)
