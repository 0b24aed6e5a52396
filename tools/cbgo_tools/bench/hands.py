"""Benchmark how real the simulated hand looks to classifiers trained on real Leap recordings.

1. Two classifiers are trained ONLY on the real recordings (the vendored training file
   ``cbgo/data/leap_static_features.npz``), with the thumb-metacarpal features 2..5 dropped: a
   torch MLP with input standardisation and a k-nearest-neighbour classifier (standardised
   features). Their accuracy on a held-out fifth of the real recordings is printed first, as a
   yardstick.
2. ``--per-gesture`` simulated renditions of each static gesture are drawn from varied
   simulated users (a new ``HandShape`` per rendition, scale 0.85–1.15, left and right hands
   alternating, random palm positions), built into contract hands by ``cbgo.hands.model`` and
   turned into features with ``to_recorded_side=True`` (the recordings are left hands; right
   hands are mirrored into their space).
3. Printed: per-gesture recognition accuracy of the simulated hands by each classifier (the
   goal is ≥ 95 %), the confusion matrices, the mean standardised feature distance per gesture
   and the 10 worst (gesture, feature) pairs: real median/IQR against simulated median/IQR,
   the distance being |Δmedian| / (real IQR / 1.349), angles compared on the circle.

Deterministic for a given ``--seed``.

Examples::

    cbgo bench hands
    cbgo bench hands --per-gesture 500 --seed 3 --json /tmp/hands.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch

from cbgo.hands import features as F
from cbgo.hands.data import load_real_features
from cbgo.hands.model import HandShape, build_hands
from cbgo.hands.poses import gesture_pose

KEPT = np.array([j for j in range(F.N_FEATURES) if j not in F.UNTRUSTED_FEATURES])
GOAL = 0.95


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--per-gesture", type=int, default=300,
                        help="simulated renditions per gesture [300]")
    parser.add_argument("--seed", type=int, default=0, help="random seed [0]")
    parser.add_argument("--epochs", type=int, default=400, help="MLP training epochs [400]")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")


# --------------------------------------------------------------------------- classifiers


class Standardiser:
    """Feature standardisation learnt on the real training rows."""

    def __init__(self, x: np.ndarray) -> None:
        self.mean = x.mean(0)
        self.std = np.maximum(x.std(0), 1e-6)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Returns standardised features."""
        return (x - self.mean) / self.std


def train_mlp(x: np.ndarray, y: np.ndarray, seed: int, epochs: int = 400):
    """Trains a 2-hidden-layer MLP on standardised features; returns a predict function.

    Args:
        x: training features (N, D).
        y: labels (N,).
        seed: torch seed for the weights.
        epochs: full-batch Adam steps.

    Returns:
        ``predict(x) -> labels``.
    """
    torch.manual_seed(seed)
    scaler = Standardiser(x)
    n_classes = int(y.max()) + 1
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], 64), torch.nn.Tanh(),
                              torch.nn.Linear(64, 64), torch.nn.Tanh(),
                              torch.nn.Linear(64, n_classes))
    xt = torch.as_tensor(scaler(x), dtype=torch.float32)
    yt = torch.as_tensor(y)
    opt = torch.optim.Adam(net.parameters(), lr=0.01, weight_decay=1e-4)
    for _ in range(epochs):
        opt.zero_grad()
        torch.nn.functional.cross_entropy(net(xt), yt).backward()
        opt.step()
    net.eval()

    def predict(q: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return net(torch.as_tensor(scaler(q), dtype=torch.float32)).argmax(1).numpy()

    return predict


def train_knn(x: np.ndarray, y: np.ndarray, k: int = 5):
    """Returns a k-nearest-neighbour ``predict(x) -> labels`` on standardised features."""
    scaler = Standardiser(x)
    ref = scaler(x)
    n_classes = int(y.max()) + 1

    def predict(q: np.ndarray) -> np.ndarray:
        qs = scaler(q)
        d2 = (qs * qs).sum(1)[:, None] - 2 * qs @ ref.T + (ref * ref).sum(1)[None]
        nearest = np.argpartition(d2, k, axis=1)[:, :k]
        votes = np.zeros((len(q), n_classes))
        np.add.at(votes, (np.arange(len(q))[:, None], y[nearest]), 1.0)
        return votes.argmax(1)

    return predict


# --------------------------------------------------------------------------- simulation


def simulate(names: tuple[str, ...], per_gesture: int, seed: int) -> tuple[np.ndarray, ...]:
    """Simulated features (N, 57) and labels (N,): a new user per rendition, both sides.

    Args:
        names: gesture names, label order.
        per_gesture: renditions per gesture.
        seed: random seed.

    Returns:
        ``(x, y, sides)`` with the features already in the recordings' side space.
    """
    rng = np.random.default_rng(seed)
    shapes, poses, labels = [], [], []
    for g, name in enumerate(names):
        for i in range(per_gesture):
            shapes.append(HandShape.sample(rng, side=("left", "right")[i % 2]))
            poses.append(gesture_pose(name, rng))
            labels.append(g)
    palms = rng.uniform([-80.0, 150.0, -60.0], [80.0, 300.0, 60.0], size=(len(poses), 3))
    hands = build_hands(shapes, poses, palms)
    sides = np.array([s.side for s in shapes])
    return F.hands_features(hands, to_recorded_side=True), np.array(labels), sides


# --------------------------------------------------------------------------- figures


def _center_spread(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Median and IQR per feature; angles on the circle (around their circular mean)."""
    center, iqr = np.median(x, 0), np.subtract(*np.percentile(x, [75, 25], 0))
    a = F.ANGLE_FEATURES
    mean_dir = np.arctan2(np.sin(x[:, a]).mean(0), np.cos(x[:, a]).mean(0))
    around = np.angle(np.exp(1j * (x[:, a] - mean_dir)))
    center[a] = np.angle(np.exp(1j * (mean_dir + np.median(around, 0))))
    iqr[a] = np.subtract(*np.percentile(np.angle(np.exp(1j * (x[:, a] - center[a]))),
                                        [75, 25], 0))
    return center, iqr


def feature_comparison(x_real: np.ndarray, y_real: np.ndarray, x_sim: np.ndarray,
                       y_sim: np.ndarray, names: tuple[str, ...]) -> list[dict]:
    """One row per (gesture, kept feature): real and simulated median/IQR, standardised gap."""
    rows = []
    for g, name in enumerate(names):
        rc, ri = _center_spread(x_real[y_real == g])
        sc, si = _center_spread(x_sim[y_sim == g])
        gap = sc - rc
        gap[F.ANGLE_FEATURES] = np.angle(np.exp(1j * gap[F.ANGLE_FEATURES]))
        floor = np.where(np.isin(np.arange(57), F.ANGLE_FEATURES), 0.03, 2.0)
        z = np.abs(gap) / np.maximum(ri / 1.349, floor)
        rows += [{"gesture": name, "feature": F.FEATURE_NAMES[j], "index": int(j),
                  "real_median": float(rc[j]), "real_iqr": float(ri[j]),
                  "sim_median": float(sc[j]), "sim_iqr": float(si[j]), "z": float(z[j])}
                 for j in KEPT]
    return rows


def evaluate(per_gesture: int, seed: int, epochs: int = 400) -> dict:
    """Trains on the real recordings, simulates, and returns every figure of the benchmark.

    Args:
        per_gesture: simulated renditions per gesture.
        seed: seeds the split, the MLP weights and the simulation.
        epochs: MLP training epochs.

    Returns:
        The figures (JSON-ready).
    """
    t0 = time.perf_counter()
    x_real, y_real, names = load_real_features()
    perm = np.random.default_rng(seed).permutation(len(y_real))
    held, train = perm[: len(perm) // 5], perm[len(perm) // 5:]
    yardstick = {}
    for label, fit in (("mlp", lambda a, b: train_mlp(a, b, seed, epochs)), ("knn", train_knn)):
        predict = fit(x_real[train][:, KEPT], y_real[train])
        yardstick[label] = float((predict(x_real[held][:, KEPT]) == y_real[held]).mean())
    classifiers = {"mlp": train_mlp(x_real[:, KEPT], y_real, seed, epochs),
                   "knn": train_knn(x_real[:, KEPT], y_real)}
    t_sim = time.perf_counter()
    x_sim, y_sim, sides = simulate(names, per_gesture, seed)
    sim_seconds = time.perf_counter() - t_sim
    results = {}
    for label, predict in classifiers.items():
        pred = predict(x_sim[:, KEPT])
        confusion = np.zeros((len(names), len(names)), dtype=int)
        np.add.at(confusion, (y_sim, pred), 1)
        results[label] = {
            "per_gesture": {n: float(confusion[g, g] / confusion[g].sum())
                            for g, n in enumerate(names)},
            "by_side": {s: float((pred[sides == s] == y_sim[sides == s]).mean())
                        for s in ("left", "right")},
            "confusion": confusion.tolist()}
    comparison = feature_comparison(x_real, y_real, x_sim, y_sim, names)
    return {"names": list(names), "per_gesture": per_gesture, "seed": seed,
            "real_heldout_accuracy": yardstick, "classifiers": results,
            "feature_comparison": comparison,
            "mean_z_per_gesture": {n: float(np.mean([r["z"] for r in comparison
                                                     if r["gesture"] == n])) for n in names},
            "simulated_hands_per_s": len(y_sim) / sim_seconds,
            "seconds": time.perf_counter() - t0}


def _print(fig: dict) -> None:
    names = fig["names"]
    held = fig["real_heldout_accuracy"]
    print(f"classifiers trained on the real recordings (features 2..5 dropped); accuracy on a "
          f"held-out fifth of them: mlp {held['mlp']:.1%}, knn {held['knn']:.1%}")
    print(f"\nsimulated hands recognised ({fig['per_gesture']} per gesture, varied users, "
          f"both sides; goal ≥ {GOAL:.0%}):")
    print(f"{'gesture':<10}" + "".join(f"{c:>8}" for c in fig["classifiers"]))
    for n in names:
        print(f"{n:<10}" + "".join(f"{r['per_gesture'][n]:>8.1%}"
                                   for r in fig["classifiers"].values()))
    for label, r in fig["classifiers"].items():
        sides = ", ".join(f"{s} {a:.1%}" for s, a in r["by_side"].items())
        print(f"\nconfusion, {label} (rows: simulated gesture, columns: predicted; {sides})")
        print(" " * 10 + "".join(f"{n[:7]:>8}" for n in names))
        for n, row in zip(names, r["confusion"], strict=True):
            print(f"{n:<10}" + "".join(f"{v:>8d}" for v in row))
    print("\nmean standardised feature gap per gesture: " + ", ".join(
        f"{n} {z:.2f}" for n, z in fig["mean_z_per_gesture"].items()))
    print("\nworst 10 (gesture, feature): real median [IQR] vs simulated median [IQR], gap z")
    for r in sorted(fig["feature_comparison"], key=lambda r: -r["z"])[:10]:
        print(f"  {r['gesture']:<9} {r['feature']:<27} {r['real_median']:>8.2f} "
              f"[{r['real_iqr']:6.2f}]  vs {r['sim_median']:>8.2f} [{r['sim_iqr']:6.2f}]  "
              f"z {r['z']:.2f}")
    print(f"\n{fig['simulated_hands_per_s']:.0f} simulated hands/s (build + features); "
          f"total {fig['seconds']:.1f} s")


def run(args: argparse.Namespace) -> int:
    """Prints (and optionally writes) the realism figures."""
    fig = evaluate(args.per_gesture, args.seed, args.epochs)
    _print(fig)
    if args.json is not None:
        args.json.write_text(json.dumps(fig, indent=1) + "\n")
    return 0
