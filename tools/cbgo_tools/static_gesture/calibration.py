"""Calibration to one person: k recorded takes per pose, scored on that person's other takes.

Why: a tracker can bend a person's pose out of what the model knows (the Leap Motion
Controller 2 folds some people's raised thumb towards the fist, and thumbs-up reads as grab).
`cbgo gestures record thumbsup --static --takes K --user NAME` stores K takes of the person's
pose and retrains the model with them (`cbgo.services.static_gesture.demonstrate`); this bench
measures what that buys, as the user would get it: the same rows (`hand_features`, the first
hand, mirrored to the recorded side), the same retraining (`train.build_datasets` with the
takes as recorded gestures, `train.fit`, the shipped options).

How, for each person of CollaborICE's LMC2 frames in the cache (people no model was trained
on; `cbgo data fetch collaborice`): each pose file is cut into takes of `TAKE_FRAMES`
consecutive frames, as `cbgo gestures record` takes them. For k in `KS`, k takes of each pose
spread over the recording (`chosen_takes`) are recorded, the model retrained, and every other
take of the person scored: right is the pose's gesture on top with p ≥ 0.5. Zero-shot is the
model the bench loaded, on the same frames. The retrained model also reads the paper's real
test split (``../shared/eval``, other people, evaluation only): the takes must not cost the
others their gestures.

Example::

    cbgo bench static --calibration      # k = 1, 3, 5; three retrainings (minutes each)
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from cbgo.hands.features import hands_features
from cbgo.services.static_gesture import train
from cbgo.services.static_gesture.classifier import StaticClassifier, answers
from cbgo_tools.data import collaborice

TAKE_FRAMES = 60  # frames per take, `cbgo gestures record`'s default
KS = (1, 3, 5)


def person_takes(folder: Path | None = None) -> dict[str, dict[str, np.ndarray]]:
    """Returns {person: {gesture: (takes, TAKE_FRAMES, 57) rows}} of the cached pose files."""
    people: dict[str, dict[str, np.ndarray]] = {}
    for person, pose, path in collaborice.pose_files(folder):
        gesture = collaborice.GESTURES[pose]
        hands, _ = collaborice.read_file(path)
        rows = hands_features(hands, to_recorded_side=True) if hands else np.zeros((0, 57))
        n = len(rows) // TAKE_FRAMES
        if n >= 2:  # one take to record, at least one to score
            people.setdefault(person, {})[gesture] = \
                rows[:n * TAKE_FRAMES].reshape(n, TAKE_FRAMES, 57)
    return people


def chosen_takes(n: int, k: int) -> list[int]:
    """Returns the k take indices of n recorded for k demonstrations.

    They are spread over the recording and nested (the takes for 3 are among those for the
    largest k), so every k is scored on the same takes: those `chosen_takes(n, max(KS))`
    leaves out. One take at least is always left to score.
    """
    spread = sorted({int(i) for i in np.linspace(0, n - 1, min(max(KS), n - 1) + 2)[1:-1]
                     .round()})
    if k >= len(spread):
        return spread
    at = [len(spread) // 2] if k == 1 else np.linspace(0, len(spread) - 1, k).round()
    return [spread[int(i)] for i in at]


def scored_takes(n: int) -> list[int]:
    """Returns the take indices no k records: what every k and zero-shot are scored on."""
    recorded = chosen_takes(n, max(KS))
    return [i for i in range(n) if i not in recorded]


def share_right(clf: StaticClassifier, rows: np.ndarray, gesture: str) -> float:
    """Returns the share of rows answered `gesture` (top, p ≥ 0.5) as a consumer reads them."""
    said = answers(clf.names, clf.predict_features(rows))
    return float(np.mean([str(a) == gesture for a in said]))


def retrained(takes: dict[str, np.ndarray], person: str, options: train.TrainOptions
              ) -> StaticClassifier:
    """Returns the model retrained with `takes` ({gesture: rows}) as the person's recordings."""
    user = [train.UserGesture(gesture, rows, [{"user": person, "count": len(rows)}])
            for gesture, rows in takes.items()]
    datasets = train.build_datasets(replace(options, user_gestures=False), user=user)
    return train.classifier_of(train.fit(datasets, options))


def run(clf: StaticClassifier, eval_path: Path | None, options: train.TrainOptions,
        folder: Path | None = None, log=print) -> dict | None:
    """Prints and returns zero-shot and k-take figures per person; None without the cache."""
    people = person_takes(folder)
    if not people:
        log(f"calibration: no CollaborICE pose files in {folder or collaborice.default_folder()}"
            " (cbgo data fetch collaborice); skipped")
        return None
    x_eval, y_eval = _eval_split(eval_path)
    out: dict = {}
    for person, poses in people.items():
        log(f"\ncalibration to CollaborICE person {person} (LMC2, never trained on): "
            f"{', '.join(f'{g} {len(t)} takes' for g, t in poses.items())} of {TAKE_FRAMES} "
            "frames; right: the pose on top with p ≥ 0.5, on the takes not recorded")
        rows = {"zero-shot": _scores(clf, poses, x_eval, y_eval)}
        log(_line("zero-shot", rows["zero-shot"]))
        for k in KS:
            takes = {g: t[chosen_takes(len(t), k)].reshape(-1, 57) for g, t in poses.items()}
            t0 = time.perf_counter()
            model = retrained(takes, person, options)
            rows[f"k={k}"] = _scores(model, poses, x_eval, y_eval) | {
                "seconds": time.perf_counter() - t0}
            log(_line(f"k={k}", rows[f"k={k}"]))
        out[person] = rows
    return out


def _scores(clf: StaticClassifier, poses: dict[str, np.ndarray], x_eval: np.ndarray | None,
            y_eval: list[str] | None) -> dict:
    fig = {g: share_right(clf, t[scored_takes(len(t))].reshape(-1, 57), g)
           for g, t in poses.items()}
    if x_eval is not None:
        said = answers(clf.names, clf.predict_features(x_eval))
        fig["eval"] = float(np.mean([str(a) == t for a, t in zip(said, y_eval, strict=True)]))
    return fig


def _line(label: str, fig: dict) -> str:
    parts = [f"{g} {v:.1%}" for g, v in fig.items() if g not in ("eval", "seconds")]
    if "eval" in fig:
        parts.append(f"the paper's test split (other people) {fig['eval']:.2%}")
    took = f" (retrained in {fig['seconds']:.0f} s)" if "seconds" in fig else ""
    return f"  {label:<9} " + ", ".join(parts) + took


def _eval_split(path: Path | None) -> tuple[np.ndarray | None, list[str] | None]:
    if path is None:
        return None, None
    with np.load(path, allow_pickle=False) as data:
        names = [str(n) for n in data["names"]]
        return data["X"].astype(np.float64), [names[int(i)] for i in data["y"]]
