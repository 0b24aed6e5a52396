"""Calibrate the static-gesture poses of the hand model against the real Leap recordings.

"Tune the hand model, not the classifier": for each of the 8 static gestures this fits the
model's joint angles and palm orientation so that the 57 features of the built hand match the
real recordings (``cbgo/data/leap_static_features.npz``), then fits a spread per parameter so
that simulated feature spreads resemble the real ones. It writes ``cbgo/hands/poses.json``.

Rules:

- The recordings are left hands (see ``cbgo.hands.features``), so the fit builds right hands
  against the mirrored recordings (yaw differences negated); the fitted poses are anatomical
  and serve both sides.
- Real statistics per gesture and feature: the centre is the median (distances) or the
  circular median (angles, whose ±2π jumps are part of the definition); the spread is the
  IQR / 1.349 of the values (wrapped around the centre for angles), floored at 0.03 rad / 2 mm.
- The thumb-metacarpal features 2..5 are excluded (the recording device's convention, see
  ``cbgo.hands.features``).
- Stage 1 (means): torch autograd through ``cbgo.hands.model.forward_kinematics`` and
  ``cbgo.hands.features.features_from_geometry`` (the very code that builds frames), a
  soft-L1 loss on the wrapped, spread-normalised residuals plus a weak pull towards the
  neutral pose, Adam from several random starts (the restart with the lowest total loss wins).
  Joint angles stay inside the limits through a sigmoid. The default hand is fitted jointly
  for all gestures: its scale, wrist offset, a length factor of each finger's phalanges and
  the thumb's CMC position, with priors that keep it within a few % / mm of the anatomy.
- The palm's yaw is invisible to the features except through the ±2π jumps of the yaw
  differences, so stage 1 keeps it at 0 and stage 3 fits its mean (within ±90°: fingers away
  from the user) and spread per gesture to the real fraction of positive yaw differences, by
  Monte Carlo over a grid.
- Stage 2 (spreads): linearised at the mean (central differences), the variance of feature j
  is ``diag(J S C S Jᵀ)_j`` with S the spreads and C ``poses.parameter_correlation``, plus the
  hand-size variation of simulated users; the spreads (≤ 25°) minimise the squared log ratio
  to the real variances.
- Deterministic for a given ``--seed``.

Examples::

    cbgo train hands                 # writes shared/cbgo/hands/poses.json
    cbgo train hands --out /tmp/poses.json --restarts 4 --steps 300
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from cbgo.hands import features as F
from cbgo.hands import model as M
from cbgo.hands.data import load_real_features, real_features_sha256
from cbgo.hands.poses import correlated_normal, parameter_correlation

POSES_FILE = Path(str(resources.files("cbgo.hands") / "poses.json"))
TRUSTED = np.array([j for j in range(F.N_FEATURES) if j not in F.UNTRUSTED_FEATURES])
USER_SCALE_SD = 0.3 / math.sqrt(12.0)  # simulated users' sizes: uniform in [0.85, 1.15]
_ANGLE_FLOOR, _DISTANCE_FLOOR = 0.03, 2.0
_MAX_SPREAD = np.deg2rad(25.0)
MAX_MEAN_YAW_DEG = 90.0


@dataclass(frozen=True)
class RealStats:
    """Per-gesture real feature statistics (G, 57) and the gesture names."""

    names: tuple[str, ...]
    center: np.ndarray
    spread: np.ndarray
    positive: np.ndarray  # fraction of values > 0 (what the yaw jumps look like)


def wrap(x):
    """Wraps angles to [-π, π) (numpy or torch; differentiable almost everywhere)."""
    return (x + math.pi) % (2 * math.pi) - math.pi


def real_statistics(x: np.ndarray, y: np.ndarray, names: tuple[str, ...]) -> RealStats:
    """Computes the robust centre and spread of every feature for every gesture."""
    center, spread = np.zeros((len(names), 57)), np.zeros((len(names), 57))
    positive = np.zeros((len(names), 57))
    angles, dists = F.ANGLE_FEATURES, F.DISTANCE_FEATURES
    for g in range(len(names)):
        xg = x[y == g]
        mean_dir = np.arctan2(np.sin(xg[:, angles]).mean(0), np.cos(xg[:, angles]).mean(0))
        around = wrap(xg[:, angles] - mean_dir)
        center[g, angles] = wrap(mean_dir + np.median(around, 0))
        q25, q75 = np.percentile(wrap(xg[:, angles] - center[g, angles]), [25, 75], axis=0)
        spread[g, angles] = np.maximum((q75 - q25) / 1.349, _ANGLE_FLOOR)
        center[g, dists] = np.median(xg[:, dists], 0)
        q25, q75 = np.percentile(xg[:, dists], [25, 75], axis=0)
        spread[g, dists] = np.maximum((q75 - q25) / 1.349, _DISTANCE_FLOOR)
        positive[g] = (xg > 0).mean(0)
    return RealStats(names, center, spread, positive)


# --------------------------------------------------------------------------- torch model

SHAPE_PARAMS = ("log_scale", "wrist_x", "wrist_y", "wrist_z", "log_thumb_length",
                "log_index_length", "log_middle_length", "log_ring_length", "log_pinky_length",
                "thumb_cmc_x", "thumb_cmc_y", "thumb_cmc_z")
"""The default-hand parameters fitted jointly for all gestures (mm at scale 1)."""


def initial_shape_vector() -> np.ndarray:
    """The uncalibrated anatomy of ``cbgo.hands.model`` as a shape vector (12,)."""
    anatomy = M.HandShape()
    return np.concatenate([[0.0], anatomy.wrist, np.zeros(5), anatomy.knuckles[0]])


def shape_parameters(vec: np.ndarray) -> dict:
    """Turns a shape vector into the JSON/``HandShape.default`` form."""
    return {"scale": round(float(np.exp(vec[0])), 5),
            "wrist_mm": [round(float(v), 3) for v in vec[1:4]],
            "phalanx_factors": [round(float(np.exp(v)), 5) for v in vec[4:9]],
            "thumb_cmc_mm": [round(float(v), 3) for v in vec[9:12]]}


def _torch_shape(vec: torch.Tensor) -> dict[str, torch.Tensor]:
    """Shape arrays (batch B) of the default hand described by shape vectors (B, 12)."""
    base = {k: torch.as_tensor(v, dtype=torch.float64)
            for k, v in M.shape_arrays(M.HandShape()).items()}
    scale = torch.exp(vec[:, 0])[:, None, None]
    phalanx = torch.exp(vec[:, 4:9])[:, :, None].expand(-1, 5, 3)
    lengths = torch.cat([base["lengths"][None, :, :1].expand(len(vec), 5, 1),
                         base["lengths"][None, :, 1:] * phalanx], -1)
    knuckles = torch.cat([vec[:, None, 9:12], base["knuckles"][None, 1:].expand(
        len(vec), 4, 3)], 1)
    return {"lengths": lengths * scale, "knuckles": knuckles * scale,
            "bases": base["bases"] * scale, "meta_frames": base["meta_frames"],
            "wrist": vec[:, 1:4] * scale[:, 0]}


def torch_features(theta: torch.Tensor, shape_vec: torch.Tensor) -> torch.Tensor:
    """Features (B, 57) of right hands from parameters (B, 24) and shapes (B, 12)."""
    rest = torch.as_tensor(M.thumb_rest_frame(), dtype=torch.float64)
    fk = M.forward_kinematics(torch, theta, _torch_shape(shape_vec), rest)
    palm = torch.zeros_like(theta[:, :3])
    return F.features_from_geometry(
        torch, palm, fk["wrist"], -fk["hand_rot"][..., 2], fk["frames"][..., :, 2],
        fk["joints"][:, :, 4])


def _residuals(feats: torch.Tensor, center: torch.Tensor, spread: torch.Tensor) -> torch.Tensor:
    diff = feats - center
    angles = torch.as_tensor(F.ANGLE_FEATURES)
    diff[..., angles] = wrap(diff[..., angles])
    return (diff / spread)[..., torch.as_tensor(TRUSTED)]


class _MeanFit(torch.nn.Module):
    """Free parameters of stage 1: R restarts × G gestures, one hand shape per restart."""

    def __init__(self, restarts: int, gestures: int, gen: torch.Generator) -> None:
        super().__init__()
        self.u = torch.nn.Parameter(torch.randn(restarts, gestures, M.N_JOINT_PARAMS,
                                                generator=gen, dtype=torch.float64))
        roll = (torch.rand(restarts, gestures, generator=gen, dtype=torch.float64) - 0.5) * 3.4
        pitch = (torch.rand(restarts, gestures, generator=gen, dtype=torch.float64) - 0.5) * 1.6
        self.orient = torch.nn.Parameter(torch.stack([roll, pitch], -1))
        self.shape_vec = torch.nn.Parameter(
            torch.as_tensor(initial_shape_vector()).repeat(restarts, 1))
        self.lo = torch.as_tensor(M.JOINT_LIMITS[:, 0])
        self.hi = torch.as_tensor(M.JOINT_LIMITS[:, 1])

    def theta(self) -> torch.Tensor:
        """Parameter vectors (R, G, 24), yaw fixed at 0."""
        joints = self.lo + (self.hi - self.lo) * torch.sigmoid(self.u)
        yaw = torch.zeros_like(self.orient[..., :1])
        return torch.cat([joints, self.orient, yaw], -1)

    def forward(self) -> torch.Tensor:
        """Features (R, G, 57)."""
        theta = self.theta()
        r, g = theta.shape[:2]
        shape = self.shape_vec[:, None].expand(r, g, len(SHAPE_PARAMS)).reshape(r * g, -1)
        return torch_features(theta.reshape(-1, M.N_PARAMS), shape).reshape(r, g, 57)

    def shape_prior(self) -> torch.Tensor:
        """Keeps the default hand anatomical: proportions within a few % and mm, per restart."""
        d = self.shape_vec - torch.as_tensor(initial_shape_vector())
        return ((d[:, 4:9] / 0.08) ** 2).sum(-1) + ((d[:, 9:12] / 8.0) ** 2).sum(-1)


def _prior(theta: torch.Tensor) -> torch.Tensor:
    """Weak pull of the joint angles towards the neutral pose, per (restart, gesture)."""
    neutral = torch.as_tensor(M.neutral_pose().to_vector()[:M.N_JOINT_PARAMS])
    span = torch.as_tensor(M.JOINT_LIMITS[:, 1] - M.JOINT_LIMITS[:, 0])
    return (((theta[..., :M.N_JOINT_PARAMS] - neutral) / span) ** 2).sum(-1)


def fit_means(stats: RealStats, restarts: int, steps: int, seed: int,
              progress: bool = True) -> dict:
    """Stage 1: the mean pose of every gesture and the shared default shape.

    Returns:
        ``theta`` (G, 24) radians (yaw 0), ``shape`` (12,) the shape vector, ``loss`` (G,)
        the per-gesture mean soft-L1 residual.
    """
    gen = torch.Generator().manual_seed(seed)
    fit = _MeanFit(restarts, len(stats.names), gen)
    center = torch.as_tensor(stats.center)
    spread = torch.as_tensor(stats.spread)
    opt = torch.optim.Adam(fit.parameters(), lr=0.05)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps, eta_min=0.003)
    for _ in tqdm(range(steps), desc="fitting mean poses", disable=not progress, leave=False):
        opt.zero_grad()
        _total_loss(fit, center, spread).sum().backward()
        opt.step()
        sched.step()
    with torch.no_grad():
        best = int(torch.argmin(_total_loss(fit, center, spread)))
        data = _soft_l1(_residuals(fit(), center, spread)).mean(-1)
        return {"theta": fit.theta()[best].numpy().copy(),
                "shape": fit.shape_vec[best].numpy().copy(), "loss": data[best].numpy().copy()}


def _total_loss(fit: _MeanFit, center: torch.Tensor, spread: torch.Tensor) -> torch.Tensor:
    """Loss per restart (R,): the gestures' mean soft-L1 residuals plus the priors."""
    per_gesture = _soft_l1(_residuals(fit(), center, spread)).mean(-1)
    return (per_gesture + 0.05 * _prior(fit.theta())).sum(-1) + 0.01 * fit.shape_prior()


def _soft_l1(r: torch.Tensor) -> torch.Tensor:
    return torch.sqrt(1.0 + r * r) - 1.0


# --------------------------------------------------------------------------- spreads


def _jacobians(thetas: np.ndarray, shape_vec: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """Jacobians (G, 57, 24) of the features at each pose: 23 parameters (no yaw), log scale.

    Central differences in one batched forward pass (cheaper than 57 backward passes each);
    angle differences are wrapped, so a feature sitting on a ±2π jump stays differentiable.
    """
    g, k = len(thetas), 24
    x0 = np.concatenate([thetas[:, :23], np.repeat(shape_vec[None, :1], g, 0)], 1)
    delta = np.eye(k) * step
    x = np.concatenate([x0[:, None] + delta, x0[:, None] - delta], 1).reshape(-1, k)
    theta = np.concatenate([x[:, :23], np.zeros((len(x), 1))], 1)
    shapes = np.concatenate([x[:, 23:], np.repeat(shape_vec[None, 1:], len(x), 0)], 1)
    with torch.no_grad():
        feats = torch_features(torch.as_tensor(theta), torch.as_tensor(shapes)).numpy()
    feats = feats.reshape(g, 2, k, 57)
    diff = feats[:, 0] - feats[:, 1]
    diff[..., F.ANGLE_FEATURES] = wrap(diff[..., F.ANGLE_FEATURES])
    return np.swapaxes(diff / (2 * step), 1, 2)


def fit_spreads(stats: RealStats, means: dict, steps: int = 400) -> np.ndarray:
    """Stage 2: per-parameter spreads (G, 23) so that linearised feature variances match.

    The variance of the features is ``diag(J S C S Jᵀ)`` with S the spreads and C the
    parameter correlation that ``gesture_pose`` samples with, plus the simulated users'
    hand-size variation; the spreads minimise the squared log ratio to the real variances.

    Args:
        stats: the real statistics (right-hand space).
        means: ``fit_means`` output.
        steps: Adam steps.

    Returns:
        Standard deviations (rad) of the 21 joint angles, roll and pitch per gesture.
    """
    jac = _jacobians(means["theta"], means["shape"])[:, TRUSTED]
    jac_t = torch.as_tensor(jac[..., :23])
    corr = torch.as_tensor(parameter_correlation()[:23, :23])
    user = torch.as_tensor(jac[..., 23] ** 2) * USER_SCALE_SD ** 2
    target = torch.log(torch.as_tensor(stats.spread[:, TRUSTED] ** 2))
    w = torch.nn.Parameter(torch.full((len(jac), 23), -2.0, dtype=torch.float64))
    opt = torch.optim.Adam([w], lr=0.05)
    for _ in range(steps):
        opt.zero_grad()
        scaled = jac_t * (_MAX_SPREAD * torch.sigmoid(w))[:, None, :]
        var = torch.einsum("gfk,kl,gfl->gf", scaled, corr, scaled) + user + 1e-8
        ((torch.log(var) - target) ** 2).mean().backward()
        opt.step()
    return (_MAX_SPREAD * torch.sigmoid(w)).detach().numpy()


# --------------------------------------------------------------------------- yaw


def _direction_yaws(theta: np.ndarray, shape_vec: np.ndarray) -> tuple:
    """Yaws of the 'previous' and 'this' directions of the 21 yaw features, (N, 21) each."""
    with torch.no_grad():
        th = torch.as_tensor(theta)
        n = th.shape[0]
        rest = torch.as_tensor(M.thumb_rest_frame(), dtype=torch.float64)
        shape = _torch_shape(torch.as_tensor(shape_vec).repeat(n, 1))
        fk = M.forward_kinematics(torch, th, shape, rest)
        hand = F.pitch_yaw(torch, -fk["hand_rot"][..., 2])[1]
        arm = F.pitch_yaw(torch, F.unit(torch, -fk["wrist"]))[1]
        bones = F.pitch_yaw(torch, fk["frames"][..., :, 2])[1]
    # Feature = previous − this; for the wrist pair, (palm − wrist) comes first.
    prev = torch.cat([hand[:, None, None].expand(n, 5, 1), bones[..., :3]], -1)
    this = torch.cat([hand[:, None], bones.reshape(n, 20)], -1).numpy()
    return torch.cat([arm[:, None], prev.reshape(n, 20)], -1).numpy(), this


def fit_yaw(stats: RealStats, means: dict, spreads: np.ndarray, seed: int,
            n: int = 300) -> np.ndarray:
    """Stage 3: mean and spread (G, 2) of the palm yaw that reproduce the real ±2π jumps.

    The yaw differences are invariant to the palm's yaw except where they wrap, so the
    fraction of positive values of every trusted yaw feature is what pins the yaw down.
    """
    rng = np.random.default_rng(seed)
    # People hold their fingers away from themselves: the jump fractions alone would also
    # accept a hand turned towards the user.
    mus = np.deg2rad(np.arange(-MAX_MEAN_YAW_DEG, MAX_MEAN_YAW_DEG + 0.1, 5.0))
    sigmas = np.deg2rad([0.0, 3.0, 6.0, 10.0, 15.0, 20.0, 30.0, 45.0])
    yaw_idx = np.array([j for j in F.YAW_FEATURES if j in TRUSTED])
    keep = np.isin(F.YAW_FEATURES, yaw_idx)
    out = np.zeros((len(stats.names), 2))
    for g in range(len(stats.names)):
        spread = np.concatenate([spreads[g], [0.0]])
        z = correlated_normal(rng, n)
        thetas = M.clip_to_limits(means["theta"][g] + z * spread)
        prev, this = (a[:, keep].astype(np.float32) for a in _direction_yaws(thetas,
                                                                                means["shape"]))
        psi = (mus[:, None, None] + sigmas[None, :, None] * z[:, 23]).astype(np.float32)
        diff = wrap(prev + psi[..., None]) - wrap(this + psi[..., None])  # (mu, sigma, n, f)
        frac = (diff > 0).mean(-2)  # (mu, sigma, features)
        err = ((frac - stats.positive[g, yaw_idx]) ** 2).sum(-1)
        i, k = np.unravel_index(np.argmin(err), err.shape)
        out[g] = mus[i], sigmas[k]
    return out


# --------------------------------------------------------------------------- all stages


def calibrate(restarts: int = 8, steps: int = 800, seed: int = 0,
              progress: bool = True) -> dict:
    """Runs all stages on the vendored recordings and returns the ``poses.json`` content.

    Args:
        restarts: random starts of the mean fit.
        steps: Adam steps of the mean fit.
        seed: makes the result reproducible.
        progress: show a tqdm progress bar.

    Returns:
        The JSON-ready calibration (angles in degrees).
    """
    x, y, names = load_real_features()
    stats = real_statistics(F.mirror_features(x), y, names)
    means = fit_means(stats, restarts, steps, seed, progress)
    spreads = fit_spreads(stats, means)
    yaw = fit_yaw(stats, means, spreads, seed)
    gestures = {}
    for g, name in enumerate(names):
        mean = means["theta"][g].copy()
        mean[23] = yaw[g, 0]
        spread = np.concatenate([spreads[g], [yaw[g, 1]]])
        gestures[name] = {
            "mean_deg": _named_degrees(mean), "spread_deg": _named_degrees(spread),
            "fit_loss": round(float(means["loss"][g]), 4)}
    return {"header": _header(restarts, steps, seed),
            "shape": shape_parameters(means["shape"]),
            "gestures": gestures}


def _named_degrees(v: np.ndarray) -> dict[str, float]:
    return {n: round(float(np.rad2deg(a)), 3) for n, a in zip(M.PARAM_NAMES, v, strict=True)}


def _header(restarts: int, steps: int, seed: int) -> dict:
    return {
        "what": "static gesture poses of cbgo.hands.model, calibrated against real Leap "
                "recordings (mean and per-parameter spread, degrees; poses are anatomical, "
                "valid for both sides)",
        "command": f"cbgo train hands --restarts {restarts} --steps {steps} "
                   f"--seed {seed}",
        "source": "cbgo/data/leap_static_features.npz",
        "source_sha256": real_features_sha256(),
        "feature_version": F.FEATURE_VERSION,
        "method": "the recordings are left hands: right hands are fitted to their mirror "
                  "image; stage 1 torch autograd fit of the means (and the default hand) to "
                  "the real robust feature centres (features 2..5 excluded); stage 2 "
                  "linearised spread fit; stage 3 palm yaw from the real yaw-jump fractions "
                  "(see cbgo_tools.hands.calibrate)",
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds where to write and the optimiser's budget."""
    parser.add_argument("--out", type=Path, default=POSES_FILE, help="where to write the JSON")
    parser.add_argument("--restarts", type=int, default=8, help="random starts [8]")
    parser.add_argument("--steps", type=int, default=800, help="optimiser steps [800]")
    parser.add_argument("--seed", type=int, default=0, help="random seed [0]")


def run(args: argparse.Namespace) -> int:
    """Calibrates and writes the poses file."""
    t0 = time.perf_counter()
    result = calibrate(args.restarts, args.steps, args.seed)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    losses = {n: g["fit_loss"] for n, g in result["gestures"].items()}
    print(f"wrote {args.out} in {time.perf_counter() - t0:.1f} s; fit loss per gesture: "
          f"{losses}")
    return 0
