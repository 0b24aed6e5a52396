"""Probabilistic movement primitives (ProMP, Paraschos et al. 2013), a small numpy version.

A ProMP represents a family of trajectories ``y(z)``, ``z ∈ [0, 1]`` the time-normalised phase,
as a weighted sum of ``B`` normalised Gaussian basis functions per dimension,
``y_d(z) = Φ(z) w_d``, with a Gaussian over the stacked weights ``w ~ N(μ_w, Σ_w)``:

- fitting: every demonstration is time-normalised (its samples spread evenly over z ∈ [0, 1])
  and its weights are found by ridge regression; ``μ_w`` and ``Σ_w`` are their mean and
  covariance, plus ``weight_floor_mm²`` on the diagonal so that a handful of takes (a user's
  new gesture) still gives a proper, not over-confident, distribution;
- ``sigma_y`` is the observation noise: the RMS residual of the per-demonstration fits,
  at least ``noise_floor_mm``;
- the mean trajectory (``mean(m)``) is what dynamic time warping compares against;
- ``log_likelihood(obs)`` resamples an observation to ``EVAL_POINTS`` phases and evaluates the
  ProMP's predictive Gaussian ``N(Ψ μ_w, Ψ Σ_w Ψᵀ + σ_y² I)``, per value (divided by the number
  of values), so it reads on the same scale whatever the length. The inverse Cholesky factor
  is computed once per ProMP, so a likelihood costs one small matrix-vector product.
"""

from __future__ import annotations

import math

import numpy as np

EVAL_POINTS = 16
ROBUST_NU = 4.0  # degrees of freedom of the robust residual cost


def basis(phases: np.ndarray, n_basis: int) -> np.ndarray:
    """Returns (len(phases), n_basis) normalised Gaussian basis functions on [0, 1]."""
    centres = np.linspace(0.0, 1.0, n_basis)
    width = (centres[1] - centres[0]) ** 2 if n_basis > 1 else 1.0
    phi = np.exp(-((np.asarray(phases)[:, None] - centres[None]) ** 2) / (2.0 * width))
    return phi / phi.sum(1, keepdims=True)


def resample(traj: np.ndarray, points: int) -> np.ndarray:
    """Returns a trajectory (n, D) linearly resampled to `points` evenly spaced phases."""
    traj = np.asarray(traj, dtype=float)
    if len(traj) == 1:
        return np.repeat(traj, points, 0)
    src = np.linspace(0.0, 1.0, len(traj))
    dst = np.linspace(0.0, 1.0, points)
    return np.column_stack([np.interp(dst, src, traj[:, d]) for d in range(traj.shape[1])])


class ProMP:
    """A Gaussian over basis-function weights; see the module docstring.

    Args:
        mean_w: (D*B,) weight mean, dimension-major (all of x's weights, then y's, ...).
        cov_w: (D*B, D*B) weight covariance.
        sigma_y: observation noise, mm.
        dims: D.
        n_basis: B.
    """

    def __init__(self, mean_w: np.ndarray, cov_w: np.ndarray, sigma_y: float, dims: int,
                 n_basis: int):
        self.mean_w = np.asarray(mean_w, dtype=float)
        self.cov_w = np.asarray(cov_w, dtype=float)
        self.sigma_y, self.dims, self.n_basis = float(sigma_y), int(dims), int(n_basis)
        if self.mean_w.shape != (dims * n_basis,) or self.cov_w.shape != (dims * n_basis,) * 2:
            raise ValueError("ProMP weights do not match dims × n_basis")
        self._psi = np.kron(np.eye(dims), basis(np.linspace(0, 1, EVAL_POINTS), n_basis))
        cov = self._psi @ self.cov_w @ self._psi.T + self.sigma_y**2 * np.eye(len(self._psi))
        chol = np.linalg.cholesky(cov)
        self._whiten = np.linalg.inv(chol)  # z = L⁻¹ (y − μ): one small matmul per call
        self._mu = self._psi @ self.mean_w
        self._norm = (2.0 * np.log(np.diag(chol)).sum()
                      + len(self._mu) * math.log(2 * math.pi))

    @classmethod
    def fit(cls, demos: list[np.ndarray], n_basis: int = 8, ridge: float = 1e-3,
            weight_floor_mm: float = 4.0, noise_floor_mm: float = 2.0) -> ProMP:
        """Learns a ProMP from demonstrations.

        Args:
            demos: trajectories (n_i, D), any lengths ≥ 2.
            n_basis: basis functions per dimension.
            ridge: ridge of the per-demonstration weight regression.
            weight_floor_mm: standard deviation added to every weight's variance.
            noise_floor_mm: smallest observation noise.

        Raises:
            ValueError: no demonstrations, or dimensions that differ.
        """
        if not demos:
            raise ValueError("a ProMP needs at least one demonstration")
        dims = demos[0].shape[1]
        if any(d.ndim != 2 or d.shape[1] != dims or len(d) < 2 for d in demos):
            raise ValueError(f"demonstrations must be (n >= 2, {dims}) arrays")
        weights, residuals = [], []
        for demo in demos:
            phi = basis(np.linspace(0.0, 1.0, len(demo)), n_basis)
            w = np.linalg.solve(phi.T @ phi + ridge * np.eye(n_basis), phi.T @ demo)  # (B, D)
            weights.append(w.T.reshape(-1))
            residuals.append(((phi @ w - demo) ** 2).mean())
        weights = np.asarray(weights)
        mean_w = weights.mean(0)
        cov_w = np.cov(weights, rowvar=False) if len(weights) > 1 else np.zeros(
            (len(mean_w), len(mean_w)))
        cov_w = cov_w + weight_floor_mm**2 * np.eye(len(mean_w))
        sigma_y = max(noise_floor_mm, float(np.sqrt(np.mean(residuals))))
        return cls(mean_w, cov_w, sigma_y, dims, n_basis)

    def mean(self, points: int) -> np.ndarray:
        """Returns the mean trajectory (points, D)."""
        phi = basis(np.linspace(0.0, 1.0, points), self.n_basis)
        return phi @ self.mean_w.reshape(self.dims, self.n_basis).T

    def log_likelihood(self, obs: np.ndarray) -> float:
        """Returns the predictive log-density of an observation (n, D), per value.

        Robust: each whitened residual costs ``ν·log(1 + z²/ν)`` (a Student-t with ν =
        `ROBUST_NU`) instead of ``z²``, the same for small residuals but only logarithmic for
        large ones, so a tracking glitch (a hand that flips for a few frames) lowers it a
        little rather than ruling the whole stroke out.
        """
        y = resample(obs, EVAL_POINTS).T.reshape(-1)  # dimension-major, like the weights
        z = self._whiten @ (y - self._mu)
        cost = float(np.sum(ROBUST_NU * np.log1p(z * z / ROBUST_NU)))
        return -0.5 * (cost + self._norm) / len(y)

    def to_dict(self) -> dict:
        """Returns plain data (JSON-safe)."""
        return {"n_basis": self.n_basis, "dims": self.dims, "sigma_y": self.sigma_y,
                "mean_w": self.mean_w.tolist(), "cov_w": self.cov_w.tolist()}

    @classmethod
    def from_dict(cls, data: dict) -> ProMP:
        """Rebuilds a ProMP from `to_dict` data.

        Raises:
            ValueError: malformed data.
        """
        try:
            return cls(np.asarray(data["mean_w"], dtype=float),
                       np.asarray(data["cov_w"], dtype=float), float(data["sigma_y"]),
                       int(data["dims"]), int(data["n_basis"]))
        except (KeyError, TypeError) as e:
            raise ValueError(f"malformed ProMP: {e}") from None
