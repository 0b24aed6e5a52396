"""Learn the default dynamic-gesture templates from simulated users and calibrate them.

1. Training users (styles drawn from `simdata.TRAIN`) perform every dynamic gesture ``--reps``
   times, mixed with static poses; the frames go through the service's own segmenter, and each
   end-of-stroke window whose frames are mostly one gesture is a demonstration of it.
2. One ProMP template per gesture is learned from its demonstrations (`classifier.Template`).
3. Calibration users — other people, same style range — are segmented the same way; the
   shared weights of the conditional logit are fitted on every window the service would
   evaluate for them (mid-stroke and final), gestures and non-gestures alike, so the
   probabilities (``none`` included) are calibrated.
4. The library is written to ``models/default.json`` (or ``--out``), with a summary of the
   run; the calibration users' balanced accuracy and ECE on end-of-stroke windows are printed
   (in-sample for the calibration; `cbgo bench dynamic` measures on held-out users).

Examples::

    cbgo train dynamic                          # the shipped default (a few minutes, 2 cores)
    cbgo train dynamic --users 8 --calib-users 4 --out /tmp/dyn.json   # a quick try
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from cbgo import metrics
from cbgo.services.dynamic_gesture import simdata
from cbgo.services.dynamic_gesture.classifier import (
    NONE,
    Calibration,
    Classifier,
    Template,
    fit_calibration,
    softmax_rows,
)
from cbgo.services.dynamic_gesture.library import DEFAULT_PATH, save_default
from cbgo.services.dynamic_gesture.stroke import RATE_HZ, SegmenterConfig
from cbgo.wire import DYNAMIC_GESTURES

TRAIN_SEED = 1000
CALIB_SEED = 2000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer's flags."""
    parser.add_argument("--users", type=int, default=30, help="training users [30]")
    parser.add_argument("--calib-users", type=int, default=24, help="calibration users [24]")
    parser.add_argument("--reps", type=int, default=2,
                        help="times each user performs every gesture [2]")
    parser.add_argument("--seed", type=int, default=TRAIN_SEED,
                        help=f"first training user's seed [{TRAIN_SEED}]")
    parser.add_argument("--jobs", type=int, default=2, help="processes simulating users [2]")
    parser.add_argument("--out", type=Path, default=DEFAULT_PATH,
                        help="where to write the library [the shipped models/default.json]")


def demonstrations(users: list[simdata.UserData]) -> dict[str, list]:
    """Returns, per gesture, the end-of-stroke windows labelled with it."""
    out: dict[str, list] = {g: [] for g in DYNAMIC_GESTURES}
    for user in users:
        for lw in user.windows:
            if lw.window.final and lw.truth in out:
                out[lw.truth].append(lw.window)
    return out


def learn_templates(users: list[simdata.UserData]) -> list[Template]:
    """Returns one template per dynamic gesture, learned from the users' strokes.

    Raises:
        ValueError: a gesture has no demonstration.
    """
    templates = []
    for name, windows in demonstrations(users).items():
        if not windows:
            raise ValueError(f"no demonstration of {name}; simulate more users")
        templates.append(Template.learn(name, [w.obs for w in windows],
                                        [w.t_end - w.t_start for w in windows],
                                        [w.pose_change for w in windows]))
    return templates


def labelled_features(classifier: Classifier, users: list[simdata.UserData],
                      finals_only: bool = False) -> tuple[list[np.ndarray], list[int]]:
    """Returns the feature rows and true-alternative indices of the users' windows."""
    index = {name: i for i, name in enumerate(classifier.names)}
    feats, labels = [], []
    for user in users:
        for lw in user.windows:
            if lw.window.final or not finals_only:
                w = lw.window
                feats.append(classifier.features(w.obs, w.final, w.pose_change))
                labels.append(index.get(lw.truth, index[NONE]))
    return feats, labels


def evaluate(classifier: Classifier, feats: list[np.ndarray], labels: list[int]) -> dict:
    """Returns balanced accuracy, ECE, log-loss and the confusion of feature rows."""
    probs = np.array([softmax_rows(f, classifier.calibration.theta) for f in feats])
    y = np.asarray(labels)
    n = len(classifier.names)
    pred = probs.argmax(1)
    return {"balanced_accuracy": metrics.balanced_accuracy(y, pred, n),
            "ece": metrics.expected_calibration_error(probs, y),
            "log_loss": float(-np.mean(np.log(np.maximum(probs[np.arange(len(y)), y], 1e-12)))),
            "confusion": metrics.confusion_matrix(y, pred, n), "samples": len(y)}


def train(users: int, calib_users: int, reps: int, seed: int, jobs: int,
          log=print) -> tuple[list[Template], Calibration, dict]:
    """Runs the whole training; returns templates, calibration and a summary."""
    t0 = time.perf_counter()
    train_data = simdata.generate(list(range(seed, seed + users)), simdata.TRAIN, reps, jobs)
    t1 = time.perf_counter()
    templates = learn_templates(train_data)
    counts = {name: len(w) for name, w in demonstrations(train_data).items()}
    log(f"simulated {users} training users in {t1 - t0:.1f} s; demonstrations: {counts}")
    calib_seed = seed + CALIB_SEED
    calib_data = simdata.generate(list(range(calib_seed, calib_seed + calib_users)),
                                  simdata.TRAIN, reps, jobs)
    t2 = time.perf_counter()
    classifier = Classifier(templates, Calibration())
    feats, labels = labelled_features(classifier, calib_data)
    calibration = fit_calibration(feats, labels)
    classifier.calibration = calibration
    t3 = time.perf_counter()
    log(f"simulated {calib_users} calibration users in {t2 - t1:.1f} s; fitted in "
        f"{t3 - t2:.1f} s on {len(feats)} windows (mid-stroke and final)")
    figures = evaluate(classifier, *labelled_features(classifier, calib_data, finals_only=True))
    summary = {"users": users, "calib_users": calib_users, "reps": reps, "seed": seed,
               "style_ranges": "train", "demonstrations": counts,
               "calibration_set": {k: v for k, v in figures.items() if k != "confusion"},
               "seconds": round(t3 - t0, 1)}
    summary["calibration_set"]["confusion"] = figures["confusion"].tolist()
    return templates, calibration, summary


def run(args: argparse.Namespace) -> int:
    """Trains, prints the figures and writes the library."""
    templates, calibration, summary = train(args.users, args.calib_users, args.reps, args.seed,
                                            args.jobs)
    config = SegmenterConfig()
    observation = {"rate_hz": RATE_HZ, "dims": ["x", "y", "z", "k*roll"],
                   "roll_scale_mm_per_rad": config.roll_scale_mm_per_rad}
    save_default(args.out, templates, calibration, observation, summary)
    figures = summary["calibration_set"]
    names = [t.name for t in templates] + [NONE]
    print(metrics.format_confusion(np.asarray(figures["confusion"]), names))
    print(f"calibration users: balanced accuracy {figures['balanced_accuracy']:.2%}, "
          f"ECE {figures['ece']:.3f}, log-loss {figures['log_loss']:.3f}")
    print(f"theta {np.round(calibration.theta, 3).tolist()}; scales "
          f"{ {t.name: round(t.scale, 3) for t in templates} }")
    print(f"wrote {args.out} in {summary['seconds']:.0f} s")
    return 0
