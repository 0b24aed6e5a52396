"""People kept apart: the shipped training recipe cross-validated on real frames, by person.

Data: the multi-modal Leap HGR set (`mmhgr`, 25 people; used when its cache file exists). The
people are split into ``folds`` groups (``folds`` = the number of people is leave-one-person-
out); for each group a model is trained exactly as the shipped one (`train.build_dataset` +
`train.fit` with the same options: the paper's recordings, simulated hands, simulated
no-gesture and off-vocabulary poses, the dataset's OTHER people) and tested on the group's
frames, so every test frame is scored by a model that never saw its person.

Unknown poses are held out too: the dataset's unknown poses are split in two halves
(`POSE_HALVES`); a fold trains ``none`` on one half and measures rejection on the other
(alternating between folds), so the rejection rate is on poses AND people no model saw. A frame
counts as rejected when the model answers ``none`` or its top probability is below
``REJECT_BELOW`` (0.5).

Figures: per-class recall and balanced accuracy of the gestures (a ``none`` answer is wrong),
per-person accuracy, the confusion, rejection per held-out pose, accuracy by the tracker's
confidence (the frame's ``Confidence``), accuracy on the frames whose tracker's own finger
flags show their pose and on the others (`mmhgr.Frames.tracker_agrees`: where they differ, the
reported skeleton shows another pose), balanced accuracy with the held-out hands turned
about the palm (`TURNS`: pitched ±30°, +60°, fingers up, rolled ±90°, palm up), hands
midway between two of a held-out person's gestures rejected (`transitions`), and the answers
to the flat open hands no model trains on (`mmhgr.AMBIGUOUS`: palm down, edge-on, palm up;
fingers together, so neither five nor an unknown pose by the data alone). Every model
applies its open-set rule (`openset`, calibrated on its own training rows); the network's
answers without it are scored too, to show what the rule adds to the rejection and costs the
known gestures.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from cbgo import metrics
from cbgo.hands import features as F
from cbgo.hands.data import load_real_features
from cbgo.hands.model import rotation
from cbgo.services.static_gesture import invariant, mmhgr, motion, train
from cbgo.services.static_gesture.classifier import NONE, REJECT_BELOW, answers, is_rejected
from cbgo.services.static_gesture.openset import fade_into_none
from cbgo.simuser.motion import min_jerk
from cbgo.wire import STATIC_GESTURES

POSE_HALVES = (("hang", "down"), ("C", "L", "heavy"))
CONFIDENCE_BINS = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0001)
TURNS = {"pitch -30°": ("x", -30.0), "pitch +30°": ("x", 30.0), "pitch +60°": ("x", 60.0),
         "fingers up (pitch +90°)": ("x", 90.0), "roll +90°": ("z", 90.0),
         "roll -90°": ("z", -90.0), "palm up (roll 180°)": ("z", 180.0)}
"""The held-out people's frames are also scored turned about the palm by these (axis of the
Leap frame, degrees; +pitch raises the fingers, roll turns about the forward axis): how the
model holds when a person, or a sensor mount, holds the hand otherwise. Yaw (about the
vertical) is left out: the features do not see it."""
TRANSITIONS_PER_PERSON = 200
"""Hands midway between two gestures scored per held-out person (`transitions`)."""
FLAT_HAND_NAMES = {"palm": "palm down", "palm_m": "edge-on", "palm_u": "palm up"}
"""What the flat hands of `mmhgr.AMBIGUOUS` are, as the figures name them."""
MAX_FRAME_GAP = 25
"""Two kept frames of one take at most this many tracker frames apart are consecutive
(`finger_motion`; the set keeps one tracker frame in about 13, and stamps no time)."""
MOTION_BINS = (0.0, 4.0, 8.0, 16.0, 32.0, np.inf)
"""Bins of a frame's finger motion (°, `finger_motion`) for the accuracy by motion."""
FINGER_GATES = ((motion.STILL_DEG, motion.MOVING_DEG, motion.CHANGED_TV),
                (5.0, 10.0, 0.2), (10.0, 20.0, 0.0))
"""Lines of the service's finger-motion rule (`motion`; the first is its default): a hand
whose answer changed by at least the third figure (total variation; 0: any) and whose fingers
moved more than the first (°) has its gestures faded into ``none`` in proportion, wholly from
the second. The last is the rule on finger motion alone (``--still-deg 10 --moving-deg 20
--changed-tv 0``). What each costs the held poses is printed."""
TIMED_PER_PERSON = 40
"""Transitions played over time per held-out person (`timed_transitions`)."""
TRANSITION_S = (0.25, 0.6)
"""How long a hand takes to change pose, seconds (drawn uniformly per transition)."""
TIMED_RATE_HZ = 60.0
"""The frame rate the timed transitions are sampled at (a tracker's lowest usual rate)."""
TIME_TENTHS = 10
"""Parts of a change's time the changing hands' answers are split by (`_timed_by_time`)."""


def turn_rotations(n: int, axis: str, deg: float) -> np.ndarray:
    """Returns n copies of the rotation by ``deg`` about the Leap frame's ``axis`` (x, y, z)."""
    r = rotation(np, "xyz".index(axis), np.deg2rad(float(deg)))
    return np.broadcast_to(r, (n, 3, 3))


def person_folds(people: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """Splits people into ``folds`` groups at random (seeded); one person each at most."""
    rng = np.random.default_rng(seed)
    folds = max(2, min(int(folds), len(people)))
    return [np.sort(g) for g in np.array_split(rng.permutation(people), folds)]


def transitions(frames: mmhgr.Frames, firsts: np.ndarray, seconds: np.ndarray,
                alpha: float = 0.5, ok_sign: str = "pinch") -> tuple[np.ndarray, np.ndarray]:
    """Returns hands part-way between two gestures of one person: (N, 57) and their pairs.

    Why: a hand changing from one gesture to another passes through shapes that are neither,
    and those should be answered ``none``. The HGR set records no transitions,
    so each is made from two real frames of one person showing different gestures
    (`transition_ends`): every angle of the 57 (yaw differences wrapped) and every distance
    taken ``alpha`` of the way from the first to the second, each joint turning at once, as a
    hand moving between poses does to a first approximation.

    Args:
        frames: the frames the ends index.
        firsts: the frames each hand goes from (`transition_ends`).
        seconds: the frames each hand goes to.
        alpha: how far from the first frame towards the second.
        ok_sign: what the ok signs are (`mmhgr.OK_SIGNS`), for the pairs' names.

    Returns:
        ``(x, pairs)``: features on the recorded side, and each hand's "first/second" gestures
        in alphabetical order. Empty when there are no ends.
    """
    if not len(firsts):
        return np.zeros((0, F.N_FEATURES)), np.zeros(0, dtype=str)
    labels = frames.labels(ok_sign)
    x, step = _start_and_step(frames, firsts, seconds)
    pairs = ["/".join(sorted(pair)) for pair in zip(labels[firsts], labels[seconds], strict=True)]
    return x + alpha * step, np.array(pairs)


def timed_transitions(frames: mmhgr.Frames, firsts: np.ndarray, seconds: np.ndarray,
                      rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Returns the hands of transitions as a tracker reports them over time.

    Why: the midway hands of `transitions` are single frames; the service also sees how fast
    a hand's fingers move (`motion`). Each transition goes from one of a person's gesture
    frames to one of another gesture (`transition_ends`), every joint following one
    minimum-jerk profile over a duration drawn from `TRANSITION_S` (``rng``), sampled at
    `TIMED_RATE_HZ` strictly between the two held poses (the held frames themselves are not
    transitions).

    Returns:
        ``(now, before, which, through)``: (M, 57) features of every sampled hand, and of the
        same hand `motion.WINDOW_S` earlier (the held first pose before the change began);
        (M,) the index of each hand's transition in ``firsts`` and ``seconds``; (M,) how far
        through its change's time each hand is (0-1).
    """
    if not len(firsts):
        return (np.zeros((0, F.N_FEATURES)), np.zeros((0, F.N_FEATURES)),
                np.zeros(0, dtype=int), np.zeros(0))
    x_from, step = _start_and_step(frames, firsts, seconds)
    now, before, which, through = [], [], [], []
    for k, (start, change, seconds_long) in enumerate(zip(
            x_from, step, rng.uniform(*TRANSITION_S, len(step)), strict=True)):
        t = np.arange(1, int(np.ceil(seconds_long * TIMED_RATE_HZ))) / TIMED_RATE_HZ
        now.append(_pose_at(t, start, change, seconds_long))
        before.append(_pose_at(t - motion.WINDOW_S, start, change, seconds_long))
        which.append(np.full(len(t), k))
        through.append(t / seconds_long)
    return (np.concatenate(now), np.concatenate(before), np.concatenate(which),
            np.concatenate(through))


def appearing_transitions(frames: mmhgr.Frames, firsts: np.ndarray, seconds: np.ndarray,
                          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Returns the hands of transitions that a tracker first finds mid-change, while young.

    Why: a hand often comes into view while it forms its pose. For its first `motion.WINDOW_S`
    the service has no frame a window back and compares it with its first frame
    (`motion.FingerMotion`). Each transition is timed as in `timed_transitions`; the tracker
    finds its hand at a moment drawn uniformly over the change (``rng``), and the hand's frames
    from then on, while younger than the window and still changing, are returned.

    Returns:
        ``(now, first, which)``: (M, 57) features of every such hand and of its first frame;
        (M,) the index of each hand's transition in ``firsts`` and ``seconds``.
    """
    now, first, which = [], [], []
    if len(firsts):
        x_from, step = _start_and_step(frames, firsts, seconds)
        for k, (start, change, seconds_long) in enumerate(zip(
                x_from, step, rng.uniform(*TRANSITION_S, len(step)), strict=True)):
            found = rng.uniform(0.0, seconds_long)
            t = found + np.arange(int(np.ceil(motion.WINDOW_S * TIMED_RATE_HZ))) / TIMED_RATE_HZ
            t = t[t < seconds_long]
            now.append(_pose_at(t, start, change, seconds_long))
            first.append(np.repeat(now[-1][:1], len(t), axis=0))
            which.append(np.full(len(t), k))
    if not now:
        return np.zeros((0, F.N_FEATURES)), np.zeros((0, F.N_FEATURES)), np.zeros(0, dtype=int)
    return np.concatenate(now), np.concatenate(first), np.concatenate(which)


def _pose_at(t: np.ndarray, start: np.ndarray, change: np.ndarray, seconds_long: float
             ) -> np.ndarray:
    """Returns (len(t), 57) features of a hand ``t`` seconds into a minimum-jerk change."""
    return start + min_jerk(t / seconds_long)[:, None] * change


def _start_and_step(frames: mmhgr.Frames, firsts: np.ndarray, seconds: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Returns the first frames' 57 features and the step to the seconds' (yaws wrapped)."""
    x = mmhgr.features57(frames.subset(firsts))
    step = mmhgr.features57(frames.subset(seconds)) - x
    step[:, F.YAW_FEATURES] = invariant.wrap(step[:, F.YAW_FEATURES])
    return x, step


def transition_ends(frames: mmhgr.Frames, count: int, rng: np.random.Generator,
                    ok_sign: str = "pinch") -> tuple[np.ndarray, np.ndarray]:
    """Returns the frames transitions go from and to (`transitions`, `timed_transitions`).

    Each pair is one person's two frames of different gestures, the person drawn first (people
    with fewer than two gestures are skipped). Empty when no person shows two gestures.
    ``ok_sign``: what the ok signs are (`mmhgr.OK_SIGNS`).
    """
    labels = frames.labels(ok_sign)
    known = np.flatnonzero(labels != "")
    people = [u for u in np.unique(frames.user[known])
              if len(np.unique(labels[known][frames.user[known] == u])) > 1]
    if not people or count <= 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    firsts, seconds = [], []
    for u in rng.choice(people, count):
        rows = known[frames.user[known] == u]
        a = rng.choice(rows)
        firsts.append(a)
        seconds.append(rng.choice(rows[labels[rows] != labels[a]]))
    return np.array(firsts), np.array(seconds)


def finger_motion(frames: mmhgr.Frames) -> tuple[np.ndarray, np.ndarray]:
    """Returns, per frame, how far its fingers moved since the take's previous kept frame.

    Why: a hand changing pose moves its fingers, a held one should not; whether the service
    could tell transitions by that depends on how still a tracker holds a held pose. The
    measure is `invariant.finger_change`; the previous frame is the one before in the same
    person's take of the same pose, at most `MAX_FRAME_GAP` tracker frames earlier.

    Returns:
        ``(moved, previous)``: (N,) degrees, NaN where a frame has no previous frame; (N,)
        the previous frame's row, -1 where none.
    """
    bends = invariant.bends(mmhgr.features57(frames))
    take = np.char.add(np.char.add(frames.user.astype(str), "/"),
                       np.char.add(frames.session.astype(str), "/" + frames.pose))
    order = np.lexsort((frames.frame, take))
    follows = ((take[order][1:] == take[order][:-1])
               & (np.diff(frames.frame[order]) <= MAX_FRAME_GAP))
    moved = np.full(len(frames), np.nan)
    moved[order[1:][follows]] = invariant.finger_change(bends[order][:-1][follows],
                                                        bends[order][1:][follows])
    previous = np.full(len(frames), -1)
    previous[order[1:][follows]] = order[:-1][follows]
    return moved, previous


def crossvalidate(frames: mmhgr.Frames, options: train.TrainOptions, folds: int = 5,
                  seed: int = 0, samples: int = 32,
                  log: Callable[[str], None] | None = None) -> dict:
    """Trains one model per group of held-out people and scores their frames.

    Args:
        frames: every converted frame (`mmhgr.load`).
        options: the training recipe (``user_gestures`` is turned off).
        folds: groups of people; the number of people gives leave-one-person-out.
        seed: which people go together.
        samples: posterior samples per prediction.
        log: called with a line per fold.

    Returns:
        The figures (see `summarise`) plus ``folds`` and ``seconds``.
    """
    options = replace(options, user_gestures=False)
    real = load_real_features()
    groups = person_folds(np.unique(frames.user), folds, seed)
    parts = []
    t0 = time.monotonic()
    ok = options.ok_sign  # what the ok signs are: a gesture or an unknown pose
    for k, people in enumerate(groups):
        trained_on, held_out = POSE_HALVES[k % 2], POSE_HALVES[1 - k % 2]
        test = np.isin(frames.user, people)
        fold_options = replace(options, seed=options.seed + k)
        data = train.build_datasets(fold_options, real, user=[], frames=frames.subset(~test),
                                    unknown=trained_on)
        clf = train.classifier_of(train.fit(data, fold_options), samples)
        sub = frames.subset(test)
        labels = sub.labels(ok)
        x_test = mmhgr.features57(sub)
        probs = clf.predict_features(x_test)
        network = clf.predict_features(x_test, open_set=False)
        parts.append({"frames": sub, "pred": np.array(clf.names)[probs.argmax(1)],
                      "top": probs.max(1), "probs": probs, "names": clf.names,
                      "labels": labels,
                      "held_unknown": np.isin(sub.pose, held_out),
                      "seen_unknown": np.isin(sub.pose, mmhgr.unknown_poses(ok))
                      & ~np.isin(sub.pose, held_out),
                      "network": (np.array(clf.names)[network.argmax(1)], network.max(1)),
                      "turned": {name: np.array(clf.names)[clf.predict_features(
                          mmhgr.features57(sub, turn_rotations(len(sub), *turn))).argmax(1)]
                          for name, turn in TURNS.items()}})
        ends = transition_ends(sub, TRANSITIONS_PER_PERSON * len(people),
                               np.random.default_rng([seed, k]), ok)
        x_mid, pairs = transitions(sub, *ends, ok_sign=ok)
        mid = clf.predict_features(x_mid) if len(x_mid) else np.zeros((0, len(clf.names)))
        parts[-1]["transitions"] = (pairs, answers(clf.names, mid) == NONE)
        moved, previous = finger_motion(sub)
        parts[-1]["motion"] = (moved, _whole_change(x_test, *ends),
                               _answer_change(probs, previous))
        timed_rng = np.random.default_rng([seed, k, 1])
        timed_ends = transition_ends(sub, TIMED_PER_PERSON * len(people), timed_rng, ok)
        now, before, which, through = timed_transitions(sub, *timed_ends, timed_rng)
        parts[-1]["timed"] = _timed_answers(clf, now, before)
        parts[-1]["timed_through"] = through
        parts[-1]["timed_ends"] = tuple(labels[ends][which] for ends in timed_ends)
        parts[-1]["timed_held"] = _held_other(answers(clf.names, probs), labels,
                                              *timed_ends)
        found_ends = transition_ends(sub, TIMED_PER_PERSON * len(people),
                                     np.random.default_rng([seed, k, 2]), ok)
        now, first, which = appearing_transitions(sub, *found_ends,
                                                  np.random.default_rng([seed, k, 3]))
        parts[-1]["appearing"] = _timed_answers(clf, now, first)[:2]
        parts[-1]["appearing_ends"] = tuple(labels[ends][which] for ends in found_ends)
        if log:
            log(f"  fold {k + 1}/{len(groups)}: people {', '.join(map(str, people))}; "
                f"none trained on {'/'.join(trained_on)}, held out {'/'.join(held_out)}; "
                f"{time.monotonic() - t0:.0f} s")
    fig = summarise(parts)
    fig.update(folds=len(groups), people=int(len(np.unique(frames.user))),
               seconds=time.monotonic() - t0)
    return fig


def _whole_change(x57: np.ndarray, firsts: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """Returns how far each transition moves the fingers from its first frame to its second.

    In degrees, by `invariant.finger_change`, as `finger_motion`.
    """
    bends = invariant.bends(x57)
    return invariant.finger_change(bends[firsts], bends[seconds])


def _answer_change(probs: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """Returns each frame's `motion.answer_change` since its previous frame (NaN: none)."""
    changed = np.full(len(probs), np.nan)
    has = previous >= 0
    changed[has] = motion.answer_change(probs[previous[has]], probs[has])
    return changed


def _timed_answers(clf, now: np.ndarray, before: np.ndarray) -> tuple[np.ndarray, ...]:
    """Returns each timed transition hand's answer (`classifier.answers`), per rule.

    First by the model alone (each frame read alone), then with the service's finger-motion
    rule at each of `FINGER_GATES`.
    """
    if not len(now):
        return tuple(np.zeros(0, dtype=str) for _ in range(len(FINGER_GATES) + 1))
    probs = clf.predict_features(now)
    changed = motion.answer_change(clf.predict_features(before), probs)
    moved = invariant.finger_change(invariant.bends(before), invariant.bends(now))
    out = [answers(clf.names, probs)]
    for lo, hi, tv in FINGER_GATES:
        keep = motion.keep_share(moved, lo, hi, changed, tv)
        out.append(answers(clf.names, fade_into_none(probs, keep, clf.names.index(NONE))))
    return tuple(out)


def _held_other(answered: np.ndarray, labels: np.ndarray, firsts: np.ndarray,
                seconds: np.ndarray) -> np.ndarray:
    """Whether each transition's held ends, read as held, name a gesture of neither end.

    Why: the baseline for `_timed_split`'s ``other``: how often the model misreads the
    poses the hands change between while they are held.
    """
    both = np.concatenate([firsts, seconds])
    ends = (np.concatenate([labels[firsts], labels[seconds]]),
            np.concatenate([labels[seconds], labels[firsts]]))
    return (answered[both] != NONE) & (answered[both] != ends[0]) & (answered[both] != ends[1])


def _timed_by_time(answered: np.ndarray, left: np.ndarray, reached: np.ndarray,
                   through: np.ndarray) -> list[dict]:
    """`_timed_split` of the changing hands by how far through their change's time they are.

    Returns:
        One split per tenth of the change's time, with ``lo``, ``hi`` and ``n`` added, and
        ``way``, how far the hand has gone at the tenth's middle (`min_jerk`).
    """
    out = []
    for lo in np.arange(TIME_TENTHS) / TIME_TENTHS:
        sel = (through >= lo) & (through < lo + 1 / TIME_TENTHS)
        if sel.any():
            middle = lo + 0.5 / TIME_TENTHS
            out.append({"lo": float(lo), "hi": float(lo + 1 / TIME_TENTHS), "n": int(sel.sum()),
                        "way": float(min_jerk(np.array([middle]))[0]),
                        **_timed_split(answered[sel], left[sel], reached[sel])})
    return out


def _timed_split(answered: np.ndarray, left: np.ndarray, reached: np.ndarray) -> dict:
    """What a changing hand's answers are: rejected, the pose it leaves or reaches, or another.

    Why: of a change's frames, the first still hold the pose the hand leaves and the last the
    one it reaches, within a tracker's noise (the change follows a minimum-jerk profile); an
    answer naming either is a gesture the person made. ``other``, a gesture the hand neither
    leaves nor reaches, is evidence of a gesture nobody made.
    """
    rejected = answered == NONE
    return {"rejected": float(rejected.mean()), "left": float((answered == left).mean()),
            "reached": float((answered == reached).mean()),
            "other": float((~rejected & (answered != left) & (answered != reached)).mean())}


def summarise(parts: list[dict]) -> dict:
    """Pools the folds' predictions into the figures.

    Returns:
        ``{classes, recall, balanced_accuracy, accuracy, n, per_person, confusion, names,
        rejection: {pose: rate}, rejection_overall, rejection_n, rejection_seen: {pose: rate}
        (unknown poses other people showed in training), rejection_seen_overall,
        by_confidence: [...], tracker_agrees: {share, balanced, balanced_otherwise,
        thumb_too_share, thumb_too_balanced}}``:
        the last, the frames whose tracker's finger flags show their pose
        (`mmhgr.Frames.tracker_agrees`) apart from the others.
    """
    pose = np.concatenate([p["frames"].pose for p in parts])
    label = np.concatenate([p["labels"] for p in parts])
    user = np.concatenate([p["frames"].user for p in parts])
    conf = np.concatenate([p["frames"].confidence for p in parts])
    pred = np.concatenate([p["pred"] for p in parts])
    top = np.concatenate([p["top"] for p in parts])
    held = np.concatenate([p["held_unknown"] for p in parts])
    known = label != ""
    classes = [g for g in STATIC_GESTURES if (label == g).any()]
    names = [*classes, *sorted(set(pred[known]) - set(classes) - {NONE}), NONE]
    recall = [float((pred[label == g] == g).mean()) for g in classes]
    confusion = [[int(((label == g) & (pred == n)).sum()) for n in names] for g in classes]
    correct = pred == label
    per_person = {int(u): float(correct[known & (user == u)].mean())
                  for u in np.unique(user[known])}
    per_style = {}
    for style, members in tracker_styles(user, conf).items():
        sel = known & np.isin(user, members)
        per_style[style] = {"people": [int(u) for u in members], "n": int(sel.sum()),
                            "accuracy": float(correct[sel].mean()) if sel.any() else None}
    rejected = is_rejected(pred, top)
    rejection = {str(q): float(rejected[held & (pose == q)].mean())
                 for q in np.unique(pose[held])}
    seen = np.concatenate([p["seen_unknown"] for p in parts])
    rejection_seen = {str(q): float(rejected[seen & (pose == q)].mean())
                      for q in np.unique(pose[seen])}
    agrees = np.concatenate([p["frames"].tracker_agrees() for p in parts])
    thumb = agrees & np.concatenate([p["frames"].thumb_agrees() for p in parts])
    tracker = {"share": float(agrees[known].mean()),
               "balanced": _balanced(correct, label, agrees, classes),
               "balanced_otherwise": _balanced(correct, label, known & ~agrees, classes),
               "thumb_too_share": float(thumb[known].mean()),
               "thumb_too_balanced": _balanced(correct, label, thumb, classes)}
    by_conf = []
    for lo, hi in zip(CONFIDENCE_BINS[:-1], CONFIDENCE_BINS[1:], strict=True):
        sel = known & (conf >= lo) & (conf < hi)
        by_conf.append({"lo": lo, "hi": min(hi, 1.0), "n": int(sel.sum()),
                        "accuracy": float(correct[sel].mean()) if sel.any() else None})
    network = None
    if "network" in parts[0]:  # the same frames without the model's open-set rule
        net_pred = np.concatenate([p["network"][0] for p in parts])
        net_rejected = is_rejected(net_pred, np.concatenate([p["network"][1] for p in parts]))
        net_correct = net_pred == label
        network = {"rejection_overall": float(net_rejected[held].mean()),
                   "rejection_seen_overall": float(net_rejected[seen].mean())
                   if seen.any() else None,
                   "accuracy": float(net_correct[known].mean()),
                   "balanced_accuracy": _balanced(net_correct, label, known, classes)}
        for style in per_style.values():
            sel = known & np.isin(user, style["people"])
            style["network_accuracy"] = float(net_correct[sel].mean()) if sel.any() else None
    turned = {}
    for name in parts[0].get("turned") or {}:
        turned_correct = np.concatenate([p["turned"][name] for p in parts]) == label
        turned[name] = _balanced(turned_correct, label, known, classes)
    return {"classes": classes, "recall": recall,
            "transitions": _transition_figures(parts), "flat_hands": _flat_hands(pose, pred, top),
            "finger_motion": _motion_figures(parts, label, correct & ~is_rejected(pred, top)),
            "balanced_accuracy": float(np.mean(recall)),
            "interval": _people_interval(label[known], pred[known], user[known]),
            # the rejection as a one-class recall: every truth NONE, a rejected frame's answer NONE
            "rejection_interval": _people_interval(np.full(int(held.sum()), NONE),
                                                   np.where(rejected[held], NONE, "kept"),
                                                   user[held]),
            "turned": turned, "network": network,
            "accuracy": float(correct[known].mean()), "n": int(known.sum()),
            "per_person": per_person, "per_style": per_style, "confusion": confusion,
            "names": names,
            "rejection": rejection, "rejection_overall": float(rejected[held].mean()),
            "rejection_n": int(held.sum()), "rejection_seen": rejection_seen,
            "rejection_seen_overall": float(rejected[seen].mean()) if seen.any() else None,
            "by_confidence": by_conf, "tracker_agrees": tracker}


def _transition_figures(parts: list[dict]) -> dict | None:
    """Pools the midway hands: ``{rejected, n, per_pair: {pair: rejected}}`` (None: none)."""
    if "transitions" not in parts[0]:
        return None
    pairs = np.concatenate([p["transitions"][0] for p in parts])
    rejected = np.concatenate([p["transitions"][1] for p in parts])
    if not len(pairs):
        return None
    return {"rejected": float(rejected.mean()), "n": int(len(pairs)),
            "per_pair": {str(q): float(rejected[pairs == q].mean()) for q in np.unique(pairs)}}


def _motion_figures(parts: list[dict], label: np.ndarray, right: np.ndarray) -> dict | None:
    """How far held poses' fingers move between kept frames, and what `FINGER_GATES` would do.

    Returns:
        ``{n, held: {50, 95, 99} percentiles (°), by_motion: [{lo, hi (None: no bound), share,
        accuracy}], transitions: {10, 50} percentiles of their whole change (°), appearing,
        timed: {n, rejected_alone, alone, held_other, by_time_alone, by_time}, gates: [{lo,
        hi, tv, lost, worst, touched, timed_rejected, timed}]}``:
        ``worst``, the gesture whose frames answered right the rule rejects most, and that
        share; ``lost``, the
        share of the known frames answered right frame by frame that a rule rejects (top
        probability below 0.5 or ``none`` after the fading); ``touched``, the share it fades
        at all; ``timed_rejected``, the timed transitions' hands (`timed_transitions`) it
        rejects, against ``rejected_alone`` without it; ``timed`` and ``alone``, what those
        hands are answered (`_timed_split`); ``held_other``, how often the poses they change
        between, as held, read as a gesture of neither (`_held_other`); ``by_time`` and
        ``by_time_alone``, with the default rule and without, the same split per tenth of the
        change's time (`_timed_by_time`); ``appearing``, the hands a tracker finds mid-change
        (`_appearing_figures`). None when the parts carry no motion.
    """
    if "motion" not in parts[0]:
        return None
    moved = np.concatenate([p["motion"][0] for p in parts])
    whole = np.concatenate([p["motion"][1] for p in parts])
    changed = np.concatenate([p["motion"][2] for p in parts])
    probs = np.concatenate([p["probs"] for p in parts])
    names = np.array(parts[0]["names"])  # one vocabulary in every fold, as `summarise` reads
    rows = (label != "") & ~np.isnan(moved)
    if not rows.any():
        return None
    by_motion = []
    for lo, hi in zip(MOTION_BINS[:-1], MOTION_BINS[1:], strict=True):
        sel = rows & (moved >= lo) & (moved < hi)
        by_motion.append({"lo": lo, "hi": None if np.isinf(hi) else hi,
                          "share": float(sel.sum() / rows.sum()),
                          "accuracy": float(right[sel].mean()) if sel.any() else None})
    gates = []
    for lo, hi, tv in FINGER_GATES:
        keep = motion.keep_share(moved, lo, hi, changed, tv)
        faded = fade_into_none(probs, keep, list(names).index(NONE))
        still = answers(list(names), faded) != NONE
        lost = right & ~still & rows
        by_class = {}
        for g in np.unique(label[rows]):
            held_right = right & rows & (label == g)
            by_class[str(g)] = float(lost[held_right].sum() / max(1, held_right.sum()))
        gates.append({"lo": lo, "hi": hi, "tv": tv, "lost": float(lost[rows].mean()),
                      "worst": max(by_class.items(), key=lambda item: item[1]),
                      "touched": float((keep < 1.0)[rows].mean())})
    timed = [np.concatenate(rule) for rule in zip(*(p["timed"] for p in parts), strict=True)] \
        if "timed" in parts[0] else []
    if timed and len(timed[0]):
        ends = [np.concatenate([p["timed_ends"][k] for p in parts]) for k in (0, 1)]
        splits = [_timed_split(answered, *ends) for answered in timed]
        for gate, split in zip(gates, splits[1:], strict=True):
            gate["timed_rejected"], gate["timed"] = split["rejected"], split
        through = np.concatenate([p["timed_through"] for p in parts])
        by_time = [_timed_by_time(answered, *ends, through) for answered in timed[:2]]
    return {"n": int(rows.sum()),
            "timed": {"n": int(len(timed[0])), "rejected_alone": splits[0]["rejected"],
                      "alone": splits[0], "held_other": float(np.concatenate(
                          [p["timed_held"] for p in parts]).mean()),
                      "by_time_alone": by_time[0], "by_time": by_time[1]}
            if timed and len(timed[0]) else None,
            "appearing": _appearing_figures(parts),
            "held": {q: float(np.percentile(moved[rows], q)) for q in (50, 95, 99)},
            "by_motion": by_motion, "gates": gates,
            "transitions": {q: float(np.percentile(whole, q)) for q in (10, 50)}
            if len(whole) else None}


def _appearing_figures(parts: list[dict]) -> dict | None:
    """What the hands found mid-change are answered while young (`appearing_transitions`).

    Returns:
        ``{n, alone, with_first}``: `_timed_split` of their answers read alone (as if a young
        hand had nothing to compare with) and with the default rule against their first
        frame. None when the parts carry none.
    """
    if "appearing" not in parts[0]:
        return None
    alone, ruled = (np.concatenate([p["appearing"][k] for p in parts]) for k in (0, 1))
    if not len(alone):
        return None
    ends = [np.concatenate([p["appearing_ends"][k] for p in parts]) for k in (0, 1)]
    return {"n": int(len(alone)), "alone": _timed_split(alone, *ends),
            "with_first": _timed_split(ruled, *ends)}


def _flat_hands(pose: np.ndarray, pred: np.ndarray, top: np.ndarray) -> dict:
    """Per flat-hand pose present: the shares of its answers.

    Returns:
        ``{pose: {n, five, rejected, other, most_other}}``: ``most_other`` is the other gesture
        answered most and its share, None when there is none.
    """
    rejected = is_rejected(pred, top)
    out = {}
    for q in mmhgr.AMBIGUOUS:
        sel = pose == q
        if sel.any():
            five = float((~rejected[sel] & (pred[sel] == "five")).mean())
            refused = float(rejected[sel].mean())
            others = pred[sel & ~rejected & (pred != "five")]
            names, counts = np.unique(others, return_counts=True)
            out[q] = {"n": int(sel.sum()), "five": five, "rejected": refused,
                      "other": 1.0 - five - refused,
                      "most_other": [str(names[counts.argmax()]), float(counts.max() / sel.sum())]
                      if len(others) else None}
    return out


def _people_interval(label: np.ndarray, pred: np.ndarray, user: np.ndarray
                     ) -> list[float] | None:
    """Returns the 95 % bootstrap interval over people of the mean recall (None: no frame)."""
    return list(metrics.people_interval(label, pred, user)) if len(label) else None


def _balanced(correct: np.ndarray, label: np.ndarray, rows: np.ndarray, classes: list[str]
              ) -> float | None:
    """Returns the mean recall over `classes` of the selected rows (None if a class has none)."""
    recalls = [correct[rows & (label == g)] for g in classes]
    return float(np.mean([r.mean() for r in recalls])) if all(len(r) for r in recalls) else None


def tracker_styles(user: np.ndarray, confidence: np.ndarray) -> dict[str, list[int]]:
    """Groups people by how their tracker reports confidence.

    The HGR set's recordings fall into two kinds: frames whose confidence varies (Leap SDK v2
    behaviour) and frames that all say 1.0 (as later tracking software reports it). A person
    belongs to the second when at least 90 % of their frames say 1.0.
    """
    styles: dict[str, list[int]] = {"confidence varies": [], "confidence always 1": []}
    for u in np.unique(user):
        fixed = float((confidence[user == u] >= 0.9999).mean()) >= 0.9
        styles["confidence always 1" if fixed else "confidence varies"].append(int(u))
    return {k: v for k, v in styles.items() if v}


def print_figures(fig: dict) -> None:
    """Prints the cross-validation figures."""
    kind = ("leave-one-person-out" if fig["folds"] == fig["people"]
            else f"{fig['folds']} folds of people")
    print(f"real frames of unseen people (multi-modal Leap HGR, {fig['people']} people, {kind}; "
          f"{fig['seconds']:.0f} s): balanced accuracy {fig['balanced_accuracy']:.2%}"
          f"{metrics.format_interval(fig.get('interval'))}, frame accuracy "
          f"{fig['accuracy']:.2%} (n={fig['n']})")
    print("  per class: " + ", ".join(f"{c} {r:.1%}" for c, r in
                                      zip(fig["classes"], fig["recall"], strict=True)))
    acc = np.array(list(fig["per_person"].values()))
    print(f"  per person: min {acc.min():.1%}, median {np.median(acc):.1%}, max {acc.max():.1%}; "
          + ", ".join(f"{u}: {a:.1%}" for u, a in fig["per_person"].items()))
    for style, s in fig.get("per_style", {}).items():
        people = s["people"]
        alone = (f"; network alone {s['network_accuracy']:.2%}"
                 if s.get("network_accuracy") is not None else "")
        print(f"  tracker style '{style}' (people {', '.join(map(str, people))}): "
              f"{s['accuracy']:.2%} (n={s['n']}){alone}" if s["n"] else f"  {style}: no frames")
    head = " " * 12 + "".join(f"{n[:7]:>8}" for n in fig["names"])
    print("  confusion (rows: true, columns: predicted)\n  " + head)
    for c, row in zip(fig["classes"], fig["confusion"], strict=True):
        print(f"  {c[:11]:<12}" + "".join(f"{v:>8}" for v in row))
    print(f"unknown poses held out of training (none, or top p < {REJECT_BELOW}): "
          f"{fig['rejection_overall']:.1%} rejected"
          f"{metrics.format_interval(fig.get('rejection_interval'))} (n={fig['rejection_n']}); "
          + ", ".join(
              f"{p} {r:.1%}" for p, r in fig["rejection"].items()))
    if fig.get("rejection_seen"):
        print(f"  the same poses where other people's took part in training: "
              f"{fig['rejection_seen_overall']:.1%} rejected; " + ", ".join(
                  f"{p} {r:.1%}" for p, r in fig["rejection_seen"].items()))
    if fig.get("network"):
        o = fig["network"]
        print(f"  the network alone, without the model's open-set rule (`openset`): balanced "
              f"accuracy {o['balanced_accuracy']:.2%}, frame accuracy {o['accuracy']:.2%}; "
              f"unknown poses held out {o['rejection_overall']:.1%} rejected"
              + (f", seen ones {o['rejection_seen_overall']:.1%}"
                 if o["rejection_seen_overall"] is not None else ""))
    if fig.get("turned"):
        print("  the same frames turned about the palm (balanced accuracy): " + ", ".join(
            f"{name} {a:.2%}" for name, a in fig["turned"].items()))
    _print_unknown_shapes(fig)
    _print_finger_motion(fig.get("finger_motion"))
    t = fig.get("tracker_agrees")
    if t and t["balanced"] is not None:
        other = t["balanced_otherwise"]
        print(f"  frames whose tracker's own finger flags (index..pinky) show the pose "
              f"({t['share']:.1%} of them): balanced accuracy {t['balanced']:.2%}; the others, "
              f"where the reported skeleton shows other fingers: "
              + (f"{other:.2%}" if other is not None else "-"))
        if t.get("thumb_too_balanced") is not None:
            print(f"  and whose thumb flag shows the pose's thumb too, where the pose fixes it "
                  f"(grab and four in, thumbs-up and five out; {t['thumb_too_share']:.1%} of "
                  f"them): balanced accuracy {t['thumb_too_balanced']:.2%}")
    print("accuracy by tracking confidence: " + "; ".join(
        f"[{b['lo']:.2f}, {b['hi']:.2f}) {b['accuracy']:.1%} (n={b['n']})" if b["n"] else
        f"[{b['lo']:.2f}, {b['hi']:.2f}) - (n=0)" for b in fig["by_confidence"]))


def _print_unknown_shapes(fig: dict) -> None:
    """Prints the midway hands' rejection and the answers to the never-trained flat hands."""
    mid = fig.get("transitions")
    if mid:
        worst = sorted(mid["per_pair"].items(), key=lambda item: item[1])[:3]
        print(f"hands midway between two of a held-out person's gestures (joint angles "
              f"interpolated; transitions): {mid['rejected']:.1%} rejected (n={mid['n']}); "
              "least: " + ", ".join(f"{q} {r:.1%}" for q, r in worst))
    if fig.get("flat_hands"):
        print("flat open hands, fingers together (trained neither as five nor as none): "
              + "; ".join(f"{FLAT_HAND_NAMES.get(q, q)} five {f['five']:.1%}, rejected "
                          f"{f['rejected']:.1%}, other {f['other']:.1%}"
                          + (f" (most {f['most_other'][0]} {f['most_other'][1]:.1%})"
                             if f["most_other"] else "") + f" (n={f['n']})"
                          for q, f in fig["flat_hands"].items()))


def _print_finger_motion(fig: dict | None) -> None:
    """Prints how far held poses' fingers move between kept frames and what a rule on it costs."""
    if not fig:
        return
    held = fig["held"]
    print(f"finger motion between a take's kept frames (n={fig['n']}; RMS change of the 19 "
          f"bends): median {held[50]:.1f}°, 95th percentile {held[95]:.1f}°, 99th "
          f"{held[99]:.1f}°; answered right by motion: " + "; ".join(
              f"[{b['lo']:g}, {'∞' if b['hi'] is None else format(b['hi'], 'g')})° "
              f"{b['share']:.1%} of frames "
              + (f"{b['accuracy']:.1%}" if b["accuracy"] is not None else "-")
              for b in fig["by_motion"]))
    if fig["transitions"]:
        print(f"  a transition's whole change: median {fig['transitions'][50]:.1f}°, "
              f"10th percentile {fig['transitions'][10]:.1f}°")
    timed = fig.get("timed")
    if timed:
        print(f"  hands changing pose over {TRANSITION_S[0]:g}-{TRANSITION_S[1]:g} s, "
              f"{TIMED_RATE_HZ:g} Hz (n={timed['n']}), frame by frame: "
              + _timed_words(timed["alone"]) + f" (the poses they change between, as held, "
              f"read as another gesture: {timed['held_other']:.1%})")
        print("    with the default rule, by tenth of the change's time (how far the hand has "
              "gone): rejected / pose left / pose reached / another gesture: " + "; ".join(
                  f"{b['lo']:.1f}-{b['hi']:.1f} ({b['way']:.0%}) {b['rejected']:.0%} / "
                  f"{b['left']:.0%} / {b['reached']:.0%} / {b['other']:.0%}"
                  for b in timed["by_time"]))
    found = fig.get("appearing")
    if found:
        print(f"  hands first found mid-change, in their first {motion.WINDOW_S:g} s (n="
              f"{found['n']}): read alone {_timed_words(found['alone'])}; compared with their "
              f"first frame (the service) {_timed_words(found['with_first'])}")
    print("  the service's rule, gestures fading into none as the fingers move and the "
          "answer changes (first: its default lines): " + "; ".join(
              f"{g['lo']:g}°-{g['hi']:g}° when the answer changed by {g['tv']:g} or more "
              f"rejects {g['lost']:.2%} of the known frames answered "
              f"right frame by frame (most of {g['worst'][0]}'s: {g['worst'][1]:.2%}; "
              f"fades {g['touched']:.1%})"
              + (f"; of the changing hands: {_timed_words(g['timed'])}"
                 if "timed" in g else "") for g in fig["gates"]))


def _timed_words(split: dict) -> str:
    return (f"{split['rejected']:.1%} rejected, read as the pose left {split['left']:.1%}, "
            f"as the pose reached {split['reached']:.1%}, as another gesture "
            f"{split['other']:.1%}")
