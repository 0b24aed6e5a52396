"""Classification figures the benchmarks print: balanced accuracy, confusion, calibration.

Expected calibration error (ECE) bins predictions by their top probability and averages, over
bins weighted by their share of samples, the gap between the bin's mean confidence and its
accuracy: a calibrated model that says 0.8 is right 80 % of the time.
"""

from __future__ import annotations

import numpy as np


def confusion_matrix(y_true: np.ndarray, y_pred: np.ndarray, n_classes: int) -> np.ndarray:
    """Returns (n, n) counts: rows true class, columns predicted class."""
    out = np.zeros((n_classes, n_classes), dtype=np.int64)
    np.add.at(out, (np.asarray(y_true), np.asarray(y_pred)), 1)
    return out


def per_class_recall(confusion: np.ndarray) -> np.ndarray:
    """Returns each class's recall (NaN for a class without samples)."""
    totals = confusion.sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.diag(confusion) / totals


def balanced_accuracy(y_true: np.ndarray, y_pred: np.ndarray, n_classes: int) -> float:
    """Returns the mean recall over the classes present in y_true."""
    recall = per_class_recall(confusion_matrix(y_true, y_pred, n_classes))
    return float(np.nanmean(recall))


def people_interval(y_true, y_pred, people, draws: int = 2000, level: float = 0.95,
                    seed: int = 0) -> tuple[float, float]:
    """Returns a bootstrap interval of the balanced accuracy over the people who were scored.

    The people are drawn with replacement (each with all of their trials), so the interval
    says how much the figure would move with other people of the same kind: trials of one
    person are not independent of each other, people are. A percentile interval of `draws`
    resamples, deterministic for a `seed`. Labels may be class indices or names; an answer
    that is no true class of any trial counts as wrong.
    """
    n = len(y_true)
    _, codes = np.unique(np.concatenate([np.asarray(y_true), np.asarray(y_pred)]),
                         return_inverse=True)
    n_classes = int(codes.max()) + 1
    y_true, y_pred = codes[:n], codes[n:]
    ids, index = np.unique(np.asarray(people), return_inverse=True)
    rows = [np.flatnonzero(index == k) for k in range(len(ids))]
    rng = np.random.default_rng(seed)
    figures = []
    for _ in range(draws):
        pick = np.concatenate([rows[k] for k in rng.integers(len(ids), size=len(ids))])
        figures.append(balanced_accuracy(y_true[pick], y_pred[pick], n_classes))
    tail = 50.0 * (1.0 - level)
    lo, hi = np.percentile(figures, [tail, 100.0 - tail])
    return float(lo), float(hi)


def format_interval(interval, people: int | None = None) -> str:
    """Returns " (95 % interval over [the N ]people, bootstrap: lo–hi)", or "" without one."""
    if not interval:
        return ""
    who = f"the {people} people" if people else "people"
    return f" (95 % interval over {who}, bootstrap: {interval[0]:.1%}–{interval[1]:.1%})"


def expected_calibration_error(probs: np.ndarray, y_true: np.ndarray, bins: int = 15) -> float:
    """Returns the ECE of (N, C) probabilities against true labels, equal-width bins."""
    probs = np.asarray(probs)
    confidence = probs.max(1)
    correct = probs.argmax(1) == np.asarray(y_true)
    edges = np.linspace(0.0, 1.0, bins + 1)
    ece = 0.0
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (confidence > lo) & (confidence <= hi)
        if inside.any():
            ece += inside.mean() * abs(confidence[inside].mean() - correct[inside].mean())
    return float(ece)


def format_confusion(confusion: np.ndarray, names: list[str], width: int = 8) -> str:
    """Returns the confusion matrix as a text table (rows true, columns predicted)."""
    head = " " * 12 + "".join(f"{n[:width - 1]:>{width}}" for n in names)
    rows = [f"{name[:11]:<12}" + "".join(f"{v:>{width}}" for v in row)
            for name, row in zip(names, confusion, strict=True)]
    return "\n".join([head, *rows])


def format_goals(goals: list[tuple[str, bool | None, str]]) -> str:
    """Returns a bench's goals as lines "PASS|MISS|----  goal: figure" ("----": not measured)."""
    marks = {True: "PASS", False: "MISS", None: "----"}
    return "\n".join(f"  {marks[ok]}  {name}: {text}" for name, ok, text in goals)
