"""Score recorded takes of static gestures: your sensor, your people, the model you run.

Why: the figures of `cbgo bench static` come from the paper's recordings, the HGR set and
simulated hands. A user with another sensor (a Leap Motion Controller 2, Gemini tracking) or
other people measures what the model does for them by recording a few takes and scoring them
here, the way an acceptance test measures it: per take, the share of frames answered right.

Rules:

- A take is an MCAP recording (`cbgo record`) of ``hands/frame`` messages made while one pose
  was held, named on the command line as ``LABEL=FILE``. Every hand of every frame is scored
  as the service answers it: the model's own classifier (the same features and posterior),
  then the service's rule on hands that change pose at its default lines (`motion`: a hand
  whose fingers move while its answer changes fades into ``none``), frame after frame in
  recording order.
- A take labelled with a gesture of the model is right where that gesture is the top answer
  with p ≥ 0.5; a take labelled ``none``, or with a name the model does not know (``ok``,
  ``horns``...), is an unknown pose: right where the frame is rejected (``none`` on top or top
  p < 0.5), as the episode service reads it.
- Messages that break the ``hands/frame`` contract are counted and skipped, never scored.
- How still the tracker holds the pose: per hand, how far its fingers moved in the last
  `motion.WINDOW_S` (since its first frame while it is younger), as the service measures it,
  reported as percentiles. The rule on hands that change pose (docs/design/static_gesture.md,
  "Hands that change pose") fades a held pose only where this crosses its line while the
  answer changes; how many hands it rejected, and the take read frame by frame
  without it, are printed beside.

Example::

    cbgo record -o five.mcap hands/frame --duration 10     # hold "five" for 10 s
    cbgo record -o horns.mcap hands/frame --duration 10    # a pose that is no gesture
    cbgo bench static --takes five=five.mcap horns=horns.mcap
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.errors import RecordingError, RejectedMessage
from cbgo.hands import features as F
from cbgo.recording import read_recording
from cbgo.services.static_gesture import invariant, motion
from cbgo.services.static_gesture.classifier import NONE, REJECT_BELOW, StaticClassifier, answers
from cbgo.services.static_gesture.openset import fade_into_none

FRAMES_KEY = "**/" + keys.HANDS_FRAME.suffix


@dataclass
class TakeScore:
    """What a model answered to one take."""

    label: str
    path: str
    unknown: bool  # the label is no gesture of the model: right means rejected
    hands: int = 0
    right: int = 0
    answers: Counter = field(default_factory=Counter)  # top answer ("none" when rejected)
    skipped: int = 0  # messages that break the contract
    top_p: list[float] = field(default_factory=list)
    motion: list[float] = field(default_factory=list)  # `finger_motion`, where measured
    right_alone: int = 0  # right when every frame is read alone, without the motion rule
    rule_rejected: int = 0  # hands the motion rule rejected that read as a gesture alone

    @property
    def share(self) -> float:
        """The share of the take's hands answered right (NaN for an empty take)."""
        return self.right / self.hands if self.hands else float("nan")


def parse_take(spec: str) -> tuple[str, Path]:
    """Returns (label, path) of a ``LABEL=FILE`` argument.

    Raises:
        ValueError: no ``=``, an empty label or file name.
    """
    label, sep, path = spec.partition("=")
    if not sep or not label.strip() or not path.strip():
        raise ValueError(f"a take is LABEL=FILE.mcap (e.g. five=five.mcap), got {spec!r}")
    return label.strip(), Path(path.strip())


def take_hands(path: Path) -> tuple[list[dict], list[float], int]:
    """Returns a recording's valid ``hands/frame`` hands, their frame times, the skipped count.

    Every hand of a valid message, each with its frame's ``ts``; a message that breaks the
    contract is counted and skipped.

    Raises:
        RecordingError: the file is missing or no MCAP recording.
    """
    spec = keys.HANDS_FRAME.schema
    hands, stamps, skipped = [], [], 0
    for recorded in read_recording(path, FRAMES_KEY):
        try:
            message = wire.decode_checked(recorded.payload, spec, recorded.key)
        except RejectedMessage:
            skipped += 1
            continue
        hands += message["hands"]
        stamps += [float(message["ts"])] * len(message["hands"])
    return hands, stamps, skipped


def finger_motion(hands: list[dict], stamps: list[float], x57: np.ndarray, probs: np.ndarray,
                  window_s: float = motion.WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """Returns, per hand, how far its fingers (degrees) and answer moved in ``window_s``.

    Measured as the service measures it (`motion.FingerMotion`: each hand followed by its side
    and id), hand by hand in recording order, from the hands' 57 features (``x57``, as the
    model reads them) and the model's answers (``probs``); a hand younger than ``window_s``
    against its first frame; NaN for a hand's first frame.
    """
    if not len(hands):
        return np.zeros(0), np.zeros(0)
    bends = invariant.bends(x57)
    tracker = motion.FingerMotion(window_s)
    both = [tracker.measure([hand], ts, bends[k:k + 1], probs[k:k + 1])
            for k, (hand, ts) in enumerate(zip(hands, stamps, strict=True))]
    return (np.array([moved[0] for moved, _ in both]),
            np.array([changed[0] for _, changed in both]))


def score_take(classifier: StaticClassifier, label: str, path: Path) -> TakeScore:
    """Scores every hand of a take (see the module docstring for what counts as right)."""
    hands, stamps, skipped = take_hands(path)
    unknown = label == NONE or label not in classifier.names
    score = TakeScore(label, str(path), unknown, skipped=skipped)
    if not hands:
        return score
    x = F.hands_features(hands, to_recorded_side=True)  # once, for the model and the motion
    probs = classifier.predict_features(x)
    finite = np.isfinite(probs).all(1)
    score.skipped += int((~finite).sum())
    probs = probs[finite]
    moved, changed = finger_motion([h for h, ok in zip(hands, finite, strict=True) if ok],
                                   [t for t, ok in zip(stamps, finite, strict=True) if ok],
                                   x[finite], probs)
    score.motion = moved[~np.isnan(moved)].tolist()
    alone = answers(classifier.names, probs)
    if NONE in classifier.names:  # as the service answers: changing hands fade into none
        keep = motion.keep_share(moved, motion.STILL_DEG, motion.MOVING_DEG, changed,
                                 motion.CHANGED_TV)
        probs = fade_into_none(probs, keep, classifier.names.index(NONE))
    answered = answers(classifier.names, probs)
    score.hands = len(probs)
    score.right = _right(answered, label, unknown)
    score.right_alone = _right(alone, label, unknown)
    score.rule_rejected = int(((answered == NONE) & (alone != NONE)).sum())
    score.answers = Counter(answered.tolist())
    score.top_p = probs.max(1).tolist()
    return score


def _right(answered: np.ndarray, label: str, unknown: bool) -> int:
    return int((answered == NONE).sum() if unknown else (answered == label).sum())


def score_takes(classifier: StaticClassifier, specs: list[str]) -> list[TakeScore]:
    """Scores each ``LABEL=FILE`` take.

    Raises:
        ValueError: a malformed take argument.
        RecordingError: a file that cannot be read.
    """
    takes = [parse_take(s) for s in specs]
    for _, path in takes:
        if not path.is_file():
            raise RecordingError(f"{path}: no such file")
    return [score_take(classifier, label, path) for label, path in takes]


def summary(scores: list[TakeScore]) -> dict:
    """Frame accuracy over the known gestures' takes and rejection over the unknown ones."""
    def pooled(items):
        n = sum(s.hands for s in items)
        return sum(s.right for s in items) / n if n else None

    return {"known": pooled([s for s in scores if not s.unknown]),
            "unknown_rejected": pooled([s for s in scores if s.unknown]),
            "hands": sum(s.hands for s in scores), "skipped": sum(s.skipped for s in scores)}


def figures(scores: list[TakeScore]) -> dict:
    """Returns scored takes as plain data (JSON-safe): each take, then the pooled `summary`."""
    return {"per_take": [{"label": s.label, "path": s.path, "unknown": s.unknown,
                          "hands": s.hands, "right": s.right, "share": s.share,
                          "right_alone": s.right_alone, "rule_rejected": s.rule_rejected,
                          "skipped": s.skipped, "answers": dict(s.answers.most_common()),
                          "median_top_p": float(np.median(s.top_p)) if s.top_p else None,
                          "finger_motion": {q: float(np.percentile(s.motion, q))
                                            for q in (50, 95, 99)} if s.motion else None}
                         for s in scores],
            **summary(scores)}


def print_figures(fig: dict, model_id: str, title: str = "recorded takes") -> None:
    """Prints `figures`: one line per take and the pooled figures."""
    print(f"{title}, model {model_id} (right: the take's gesture with p ≥ {REJECT_BELOW}"
          f"; for a pose that is no gesture, rejected):")
    for take in fig["per_take"]:
        what = "unknown pose, rejected" if take["unknown"] else "right"
        answers = ", ".join(f"{name} {count}" for name, count in
                            list(take["answers"].items())[:4])
        median = (f"; median top p {take['median_top_p']:.2f}"
                  if take["median_top_p"] is not None else "")
        skipped = f"; {take['skipped']} skipped (broke the contract)" if take["skipped"] else ""
        moved = take.get("finger_motion")
        moved = (f"; fingers moved in {motion.WINDOW_S:g} s: median {moved[50]:.1f}°, 95th "
                 f"percentile {moved[95]:.1f}°, 99th {moved[99]:.1f}°" if moved else "")
        rule = (f"; the rule on hands that change pose rejected {take['rule_rejected']} "
                f"that read as a gesture alone (read alone: {what} "
                f"{take['right_alone'] / take['hands']:.1%})" if take["rule_rejected"] else "")
        print(f"  {take['label']:10} {take['path']}: {take['hands']} hands, {what} "
              f"{take['share']:.1%} (answers: {answers or 'none'}{median}){skipped}{moved}"
              f"{rule}")
    for key, text in (("known", "known gestures, frames right"),
                      ("unknown_rejected", "unknown poses, frames rejected")):
        if fig[key] is not None:
            print(f"  {text}: {fig[key]:.1%}")
