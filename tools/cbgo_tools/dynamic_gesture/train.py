"""Learn the default dynamic-gesture templates from real and simulated people; calibrate them.

1. Training users (styles drawn from `simdata.TRAIN`, whose stroke habits are fitted to real
   people) perform every dynamic gesture ``--reps`` times, mixed with static poses; the frames
   go through the service's own segmenter, and each end-of-stroke window whose frames are
   mostly one gesture is a demonstration of it.
2. With ``--real DIR`` (the SHREC'17 skeletons, `shrec`), the people of its official **train
   split** add their real swipes (each sequence's stroke that goes farthest in the swipe's
   direction) and their other gestures (grab, tap, pinch, expand, shake) as "no gesture".
   Returns are dropped as the service drops them; the other strokes of a swipe's recording
   that move farther than a twitch are left out (a preparation or an unfiltered return is
   swipe-shaped, and calling it "none" would teach that swipes are nothing). The test split's
   people are never read.
3. One ProMP template per gesture is learned from its demonstrations (`classifier.Template`).
4. The shared weights of the conditional logit (`classifier.NeuralCalibration`) are fitted on
   every window the service would evaluate (mid-stroke and final) of the calibration users —
   other simulated people — and of the real people, gestures and non-gestures alike, so the
   probabilities (``none`` included) are calibrated, to a prior in which the "none" windows
   together weigh `NONE_WEIGHT` of the gestures'. The trajectory network (`trajnet`), a
   second opinion that reads each window's whole path, learns from the same windows and the
   training users' too, with the same weights. With ``--folds N`` the real people are
   also split into N groups first, and each group is scored by a library learned without
   it: the leave-people-out figures.
5. The library goes to ``<data dir>/models/dynamic-gesture.json`` (which the service then uses
   in place of the shipped one) or ``--out``, with a summary of the run.

Examples::

    cbgo train dynamic --real ~/.cache/cbgo/shrec17 --folds 4
    cbgo train dynamic --real DIR --out services/dynamic_gesture/models/default.json  # ship it
    cbgo train dynamic --users 8 --calib-users 4 --out /tmp/dyn.json   # simulated only, quick
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from cbgo import metrics
from cbgo.config import data_dir
from cbgo.services.dynamic_gesture import trajnet
from cbgo.services.dynamic_gesture.classifier import (
    MIRROR,
    MIRROR_X,
    NONE,
    Calibration,
    Classifier,
    NeuralCalibration,
    Template,
    fit_neural_calibration,
    mirrored,
)
from cbgo.services.dynamic_gesture.library import save_default, trained_path
from cbgo.services.dynamic_gesture.stroke import (
    GESTURE_P,
    RATE_HZ,
    ReturnFilter,
    SegmenterConfig,
    reported,
)
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.data import shrec
from cbgo_tools.dynamic_gesture import scoring, simdata, streams

TRAIN_SEED = 1000
CALIB_SEED = 2000
USERS, CALIB_USERS, REPS = 30, 24, 2  # the shipped library's simulated users, each gesture ×2
# In the calibration fit all "none" windows weigh together this share of the gesture windows'
# weight. Unweighted, the many "none" windows (preparations, returns, the data set's other
# gestures) pull the fit towards "none" and real swipes, often unsure, go unreported; a missed
# gesture costs a user a repeat, a false one is mostly filtered downstream (the episode's
# evidence threshold, the intent's decision). Chosen, with the neural calibration, among 0.1,
# 0.15, 0.2 and 0.25 on the train split's leave-people-out trials and the held-out simulated
# users' strokes: above 0.15 the simulated users' small swipes go to "none", below it the
# other gestures report more swipes for little gain.
NONE_WEIGHT = 0.15
RULES = ("all", "finals", "first")
"""How a trial is answered: by every reported window, by the final windows only, or by the
first reported gesture (what a consumer that acts at once sees)."""
SUFFIXES = {"all": "", "finals": "_finals", "first": "_first"}  # of the figures' keys
STREAMS_PER_PERSON = 2  # continuous streams of each held-out person (`streams.person_streams`)
# Two streams per person give about ten false triggers over 20 people: enough to see a rule
# move them a lot, too few to tell 0.8/min from 1.2/min; a few more streams per person still
# move the rate by half from one draw to the next, so `--streams 24` (about 2000 swipes, two
# hours outside the gestures) is the false-trigger figure to go by.


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer's flags."""
    parser.add_argument("--users", type=int, default=USERS, help=f"training users [{USERS}]")
    parser.add_argument("--calib-users", type=int, default=CALIB_USERS,
                        help=f"calibration users [{CALIB_USERS}]")
    parser.add_argument("--reps", type=int, default=REPS,
                        help=f"times each user performs every gesture [{REPS}]")
    parser.add_argument("--seed", type=int, default=TRAIN_SEED,
                        help=f"first training user's seed [{TRAIN_SEED}]")
    parser.add_argument("--jobs", type=int, default=2, help="processes simulating users [2]")
    parser.add_argument("--out", type=Path, default=None,
                        help="where to write the library [<data dir>/models/dynamic-gesture.json]")
    parser.add_argument("--real", type=Path, metavar="DIR", default=None,
                        help="the SHREC'17 datasetShrec folder: add its train split's people")
    parser.add_argument("--folds", type=int, default=0,
                        help="also score the real people leave-group-out in N groups [0: no]")
    parser.add_argument("--streams", type=int, default=STREAMS_PER_PERSON, metavar="N",
                        help="with --folds: continuous streams played per held-out person "
                             f"[{STREAMS_PER_PERSON}]; the false-trigger rate of a few is a "
                             "small sample that moves by half between draws: 24 gives a "
                             "steadier figure (about 2 min more on 2 cores)")
    parser.add_argument("--calibration-seed", type=int, default=0, metavar="K",
                        help="seed of the calibration network's initial weights [0]; the "
                             "leave-people-out figures move by a few tenths of a point from "
                             "one to the next: compare changes over several")
    parser.add_argument("--misses", action="store_true",
                        help="with --folds: list every held-out swipe recording answered wrong, "
                             "with how far its palm moved")


def demonstrations(users: list[simdata.UserData]) -> dict[str, list]:
    """Returns, per gesture, the end-of-stroke windows labelled with it.

    In the right hand's space: a left hand's swipe_left is kept as the right hand's
    swipe_right it mirrors (`MIRROR`).
    """
    out: dict[str, list] = {g: [] for g in DYNAMIC_GESTURES}
    for user in users:
        for lw in user.windows:
            if lw.window.final and lw.truth in out:
                if lw.window.side == "left":
                    out[MIRROR[lw.truth]].append(mirrored_window(lw.window))
                else:
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
                                        [w.pose_change for w in windows], mirror=MIRROR[name]))
    return templates


def labelled_windows(classifier: Classifier, users: list[simdata.UserData],
                     finals_only: bool = False) -> tuple[list, list[int]]:
    """Returns the users' windows and each one's truth as an index of the classifier's names.

    With `finals_only`, the final windows only; a truth the classifier lacks is ``none``.
    """
    index = {name: i for i, name in enumerate(classifier.names)}
    chosen = [lw for user in users for lw in user.windows if lw.window.final or not finals_only]
    return [lw.window for lw in chosen], [index.get(lw.truth, index[NONE]) for lw in chosen]


def labelled_features(classifier: Classifier, users: list[simdata.UserData],
                      finals_only: bool = False) -> tuple[list[np.ndarray], list[int]]:
    """Returns the feature rows and true-alternative indices of the users' windows."""
    windows, labels = labelled_windows(classifier, users, finals_only)
    return [classifier.window_features(w) for w in windows], labels


def labelled_probabilities(classifier: Classifier, users: list[simdata.UserData],
                           finals_only: bool = False) -> tuple[np.ndarray, list[int]]:
    """Returns the classifier's probabilities and true-alternative indices of users' windows.

    As the service answers: the trajectory network's opinion blended in.
    """
    windows, labels = labelled_windows(classifier, users, finals_only)
    return np.array([classifier.classify(w) for w in windows]), labels


def evaluate(classifier: Classifier, probs: np.ndarray, labels: list[int]) -> dict:
    """Returns balanced accuracy, ECE, log-loss and the confusion of windows' probabilities."""
    y = np.asarray(labels)
    n = len(classifier.names)
    pred = probs.argmax(1)
    return {"balanced_accuracy": metrics.balanced_accuracy(y, pred, n),
            "ece": metrics.expected_calibration_error(probs, y),
            "log_loss": float(-np.mean(np.log(np.maximum(probs[np.arange(len(y)), y], 1e-12)))),
            "confusion": metrics.confusion_matrix(y, pred, n), "samples": len(y)}


def none_weights(labels: list[int], none_index: int, share: float = NONE_WEIGHT) -> np.ndarray:
    """Returns per-window weights giving the "none" windows `share` of the gestures' weight."""
    nones = np.asarray(labels) == none_index
    weights = np.ones(len(labels))
    weights[nones] = share * max(int((~nones).sum()), 1) / max(int(nones.sum()), 1)
    return weights


def fit(sim_train: list, sim_calib: list, real_people: list, calibration_seed: int = 0
        ) -> Classifier:
    """Learns the templates, fits the calibration and the trajectory network (module docstring).

    ``calibration_seed`` draws both networks' initial weights: each fit lands in a different
    optimum, and the held-out real people read a few tenths of a point apart (`cbgo train
    dynamic --calibration-seed`).
    """
    classifier = Classifier(learn_templates(sim_train + real_people), Calibration())
    feats, labels = labelled_features(classifier, sim_calib + real_people)
    weights = none_weights(labels, classifier.names.index(NONE))
    classifier.calibration = fit_neural_calibration(feats, labels, weights=weights,
                                                    seed=calibration_seed)
    every = [lw for user in sim_train + sim_calib + real_people for lw in user.windows]
    nones = [int(lw.truth not in classifier.names[:-1]) for lw in every]
    net = trajnet.fit([lw.window for lw in every], [lw.truth for lw in every],
                      classifier.names, none_weights(nones, 1), calibration_seed)
    return Classifier(classifier.templates, classifier.calibration, net=net)


def fold_classifiers(sim_train: list, sim_calib: list, recordings: list, folds: int,
                     return_s: float, calibration_seed: int = 0):
    """Yields (held-out people, a classifier learned without them) for each of `folds` groups.

    The SHREC'17 recordings' people, sorted, are dealt into the groups in turn.
    """
    people = sorted({seq.person for seq, _, _ in recordings})
    for k in range(folds):
        held = set(people[k::folds])
        train_people = shrec.people_data([r for r in recordings if r[0].person not in held],
                                         return_s)
        yield held, fit(sim_train, sim_calib, train_people, calibration_seed)


def simulated_sets(users: int, calib_users: int, reps: int, seed: int, jobs: int
                   ) -> tuple[list, list]:
    """Returns the simulated training users and the calibration users (seeds `CALIB_SEED` on)."""
    sim_train = simdata.generate(list(range(seed, seed + users)), simdata.TRAIN, reps, jobs)
    calib_seed = seed + CALIB_SEED
    sim_calib = simdata.generate(list(range(calib_seed, calib_seed + calib_users)),
                                 simdata.TRAIN, reps, jobs)
    return sim_train, sim_calib


def observation() -> dict:
    """Returns how a library's templates observe a stroke (its ``observation`` block)."""
    return {"rate_hz": RATE_HZ, "dims": ["x", "y", "z", "k*roll"],
            "roll_scale_mm_per_rad": SegmenterConfig().roll_scale_mm_per_rad}


def trial_answers(classifier: Classifier, windows: list, return_s: float) -> dict[str, str]:
    """Returns what the service reports for one recording, per rule of `RULES`.

    Its most probable gesture among every reported window ("all"), and among the strokes'
    final windows only ("finals": what a consumer that reads one answer per stroke, ``final``
    on the wire, sees); the first reported gesture ("first": what a consumer that acts on the
    first answer sees); "nothing" when no such window has a gesture at p ≥ `stroke.GESTURE_P`.
    """
    best = {rule: ("nothing", 0.0) for rule in RULES}
    for window, probs in reported(windows, ReturnFilter(return_s), classifier.classify):
        top = int(np.argmax(probs[:-1]))
        if probs[top] < GESTURE_P:
            continue
        for rule in RULES:
            counts = window.final or rule != "finals"
            surer = probs[top] > best[rule][1] if rule != "first" else best[rule][1] == 0.0
            if counts and surer:
                best[rule] = (classifier.names[top], float(probs[top]))
    return {rule: name for rule, (name, _) in best.items()}


def cross_validate(sim_train: list, sim_calib: list, recordings: list, folds: int,
                   return_s: float, log=print, streams_per_person: int = STREAMS_PER_PERSON,
                   calibration_seed: int = 0) -> dict:
    """Scores each group of real people with a library learned without them.

    Each trial (recording) is answered twice: by every reported window, and by the final
    windows only. The swipes are answered again mirrored, as a left hand makes them (the
    recordings are all of right hands). Each held-out person also plays `streams_per_person`
    continuous streams of their recordings, the hand never leaving, through the service's
    logic offline (`streams.replay_stream`).
    """
    people = sorted({seq.person for seq, _, _ in recordings})
    names = [*shrec.SWIPE_DIRECTIONS, "rotate", "nothing"]
    confusion = {rule: np.zeros((len(names), len(names)), dtype=int) for rule in RULES}
    left_right = {rule: {n: [0, 0] for n in shrec.SWIPE_DIRECTIONS} for rule in RULES}
    other = 0
    other_false = dict.fromkeys(RULES, 0)
    misses = []
    scored = []  # (person, truth, {rule: answer}) of every held-out swipe recording
    stream_rows = []
    rng = np.random.default_rng(TRAIN_SEED)
    config = SegmenterConfig(return_s=return_s)
    for k, (held, classifier) in enumerate(fold_classifiers(sim_train, sim_calib, recordings,
                                                            folds, return_s,
                                                            calibration_seed)):
        for seq, windows, _ in recordings:
            if seq.person not in held:
                continue
            other += seq.name not in shrec.SWIPE_DIRECTIONS
            answers = trial_answers(classifier, windows, return_s)
            for rule, answer in answers.items():
                if seq.name in shrec.SWIPE_DIRECTIONS:
                    confusion[rule][names.index(seq.name), names.index(answer)] += 1
                else:
                    other_false[rule] += answer != "nothing"
            if seq.name in shrec.SWIPE_DIRECTIONS:
                scored.append((seq.person, seq.name, answers))
                if set(answers.values()) != {seq.name}:
                    misses.append(_miss(seq, answers))
            if seq.name in shrec.SWIPE_DIRECTIONS:
                lefts = [mirrored_window(w) for w in windows]
                for rule, answer in trial_answers(classifier, lefts, return_s).items():
                    left_right[rule][MIRROR[seq.name]][0] += answer == MIRROR[seq.name]
                    left_right[rule][MIRROR[seq.name]][1] += 1
        for person in sorted(held):
            own = [seq for seq, _, _ in recordings if seq.person == person]
            stream_rows += [streams.replay_stream(classifier, frames,
                                                  *streams.split_spans(spans), config)
                            for frames, spans in streams.person_streams(own, streams_per_person,
                                                                        rng)]
        log(f"  fold {k + 1}/{folds}: people {sorted(held)} scored")
    out = {"folds": folds, "people": people, "names": names, "other_trials": other,
           "streams": scoring.stream_totals(stream_rows),
           "streams_per_person": streams_per_person,
           "misses": misses}
    for rule in RULES:
        c = confusion[rule]
        recall = {n: float(c[i, i] / c[i].sum()) for i, n in enumerate(names[:4]) if c[i].sum()}
        suffix = SUFFIXES[rule]
        out.update({f"confusion{suffix}": c.tolist(), f"recall{suffix}": recall,
                    f"balanced_accuracy{suffix}": float(np.mean(list(recall.values()))),
                    f"interval{suffix}": _interval(scored, rule),
                    f"other_reported{suffix}": other_false[rule],
                    f"left_hand_balanced_accuracy{suffix}": float(np.mean(
                        [right / n for right, n in left_right[rule].values() if n]))})
    return out


def _interval(scored: list[tuple], rule: str) -> list[float] | None:
    """Returns the 95 % bootstrap interval over people of one rule's balanced accuracy."""
    if not scored:
        return None
    people, truths, answers = zip(*scored, strict=True)
    return list(metrics.people_interval(truths, [a[rule] for a in answers], people))


def _miss(seq: shrec.Sequence, answers: dict[str, str]) -> dict:
    """Returns a held-out swipe recording answered wrong by some rule, for `--misses`.

    With how far its palm went from where it started (mm): the farthest, and the farthest in
    the swipe's direction and against it (some recordings barely move, or mostly the other
    way).
    """
    palm = seq.joints()[:, 1] * 1000.0
    way = palm - palm[0]
    along = way @ np.asarray(shrec.SWIPE_DIRECTIONS[seq.name])
    return {"person": seq.person, "swipe": seq.name, "fingers": seq.fingers, "take": seq.take,
            **answers, "reach_mm": round(float(np.linalg.norm(way, axis=1).max())),
            "along_mm": round(float(max(along.max(), 0.0))),
            "against_mm": round(float(max(-along.min(), 0.0)))}


def mirrored_window(window):
    """Returns a window as the other hand makes the mirrored stroke (x negated, side swapped)."""
    origin = None if window.origin is None else window.origin * MIRROR_X[:3]
    return replace(window, obs=mirrored(window.obs), origin=origin,
                   side="left" if window.side == "right" else "right")


def train(users: int, calib_users: int, reps: int, seed: int, jobs: int,
          real: Path | None = None, folds: int = 0, log=print,
          streams_per_person: int = STREAMS_PER_PERSON, calibration_seed: int = 0
          ) -> tuple[list[Template], NeuralCalibration, dict]:
    """Runs the whole training; returns templates, calibration and a summary."""
    t0 = time.perf_counter()
    return_s = SegmenterConfig().return_s
    sequences = [] if real is None else shrec.read_split(real, "train")  # fails before simulating
    sim_train, sim_calib = simulated_sets(users, calib_users, reps, seed, jobs)
    log(f"simulated {users} training and {calib_users} calibration users in "
        f"{time.perf_counter() - t0:.1f} s")
    recordings = []
    if sequences:
        recordings = shrec.sequence_windows(sequences)
        log(f"segmented {len(recordings)} real recordings of the SHREC'17 train split "
            f"({len({r[0].person for r in recordings})} people)")
    summary: dict = {"users": users, "calib_users": calib_users, "reps": reps, "seed": seed,
                     "style_ranges": "train",
                     "real": "shrec17 train split" if recordings else None}
    if folds and recordings:
        summary["leave_people_out"] = cross_validate(sim_train, sim_calib, recordings, folds,
                                                     return_s, log, streams_per_person,
                                                     calibration_seed)
    real_people = shrec.people_data(recordings, return_s)
    classifier = fit(sim_train, sim_calib, real_people, calibration_seed)
    summary["calibration_seed"] = calibration_seed
    summary["demonstrations"] = {name: len(w) for name, w in
                                 demonstrations(sim_train + real_people).items()}
    figures = evaluate(classifier, *labelled_probabilities(classifier, sim_calib + real_people,
                                                           finals_only=True))
    summary["calibration_set"] = {k: v for k, v in figures.items() if k != "confusion"}
    summary["calibration_set"]["confusion"] = figures["confusion"].tolist()
    summary["seconds"] = round(time.perf_counter() - t0, 1)
    return classifier, summary


def print_leave_people_out(block: dict, misses: bool = False) -> None:
    """Prints the leave-people-out trial figures (and the recordings missed, `misses`)."""
    print(f"\nreal people, leave-people-out ({block['folds']} groups of the SHREC'17 train "
          f"split's {len(block['people'])} people), one recording = one trial:")
    for suffix, how in (("", "its most probable reported window"),
                        ("_finals", "its most probable final window (one answer per stroke)"),
                        ("_first", "its first reported gesture (a consumer that acts at once)")):
        if f"confusion{suffix}" not in block:
            continue
        print(f"\nanswered by {how}:")
        print(metrics.format_confusion(np.asarray(block[f"confusion{suffix}"]), block["names"]))
        print("recall " + ", ".join(f"{n} {r:.1%}" for n, r in block[f"recall{suffix}"].items())
              + f"; balanced accuracy {block[f'balanced_accuracy{suffix}']:.1%}"
              + metrics.format_interval(block.get(f"interval{suffix}")))
        print(f"other gestures (grab, tap, expand, pinch, shake): "
              f"{block[f'other_reported{suffix}']} of {block['other_trials']} recordings "
              f"reported a dynamic gesture")
        if f"left_hand_balanced_accuracy{suffix}" in block:
            print(f"the same swipes mirrored, as a left hand makes them: balanced accuracy "
                  f"{block[f'left_hand_balanced_accuracy{suffix}']:.1%}")
    if misses and block.get("misses"):
        print(f"\nheld-out swipe recordings answered wrong by some rule "
              f"({len(block['misses'])}; any window / final windows / first reported; how far "
              f"the palm went from its start: at most, in the swipe's direction, against it):")
        for m in block["misses"]:
            print(f"  person {m['person']:2d} {m['swipe']:11s} fingers {m['fingers']} take "
                  f"{m['take']}: {m['all']} / {m['finals']} / {m['first']}; palm "
                  f"{m['reach_mm']} mm, {m['along_mm']} its way, {m['against_mm']} against")
    s = block.get("streams")
    if s and s["strokes"]:
        each = block.get("streams_per_person", STREAMS_PER_PERSON)
        print(f"\ncontinuous streams of the held-out people ({each} each, 10 "
              f"recordings, hand never leaves; replayed offline): "
              + scoring.describe_streams(s))
        print("goals (these streams replayed offline, not over the wire):\n"
              + metrics.format_goals(scoring.stream_goals(s)))


def run(args: argparse.Namespace) -> int:
    """Trains, prints the figures and writes the library."""
    out = args.out or trained_path(data_dir())
    classifier, summary = train(args.users, args.calib_users, args.reps, args.seed,
                                args.jobs, args.real, args.folds,
                                streams_per_person=args.streams,
                                calibration_seed=args.calibration_seed)
    lpo = summary.get("leave_people_out", {})
    saved = {**summary, "leave_people_out": {k: v for k, v in lpo.items() if k != "misses"}
             } if lpo else summary
    templates = classifier.templates
    save_default(out, templates, classifier.calibration, observation(), saved, classifier.net)
    if "leave_people_out" in summary:
        print_leave_people_out(summary["leave_people_out"], args.misses)
    figures = summary["calibration_set"]
    names = [t.name for t in templates] + [NONE]
    print("\nend-of-stroke windows of the calibration set (in-sample):")
    print(metrics.format_confusion(np.asarray(figures["confusion"]), names))
    print(f"balanced accuracy {figures['balanced_accuracy']:.2%}, "
          f"ECE {figures['ece']:.3f}, log-loss {figures['log_loss']:.3f}")
    print(f"template scales { {t.name: round(t.scale, 3) for t in templates} }")
    print(f"wrote {out} in {summary['seconds']:.0f} s")
    return 0
