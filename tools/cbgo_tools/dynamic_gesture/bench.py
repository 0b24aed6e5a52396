"""Benchmark dynamic gestures: accuracy on held-out users, calibration, cost, latency.

1. **Accuracy.** Simulated users the templates never saw (other seeds) and whose styles lie
   outside the training range on every axis (`simdata.HELD_OUT`: slower and faster, smaller
   and larger strokes, more curvature, more tremor, other hand sizes, other roll angles) perform
   every gesture ``--reps`` times among static poses; their frames go through the service's
   segmenter and classifier. Each end-of-stroke window is one sample (truth: the gesture most of
   its frames perform, else ``none``); a true stroke that no end-of-stroke window caught counts
   as predicted ``none``. Printed: the confusion matrix (rows true), per-class recall, balanced
   accuracy, ECE, and the same for the windows evaluated mid-stroke. ``still`` sessions (a hand
   held still for seconds) add the false strokes of a resting hand to the ``none`` row. Their
   strokes start wherever the hand is and cross the middle of the field, mostly without a
   rest, and come back (the habits fitted to real people). Then ``--streams-sim`` continuous
   streams (`run_streams`, `streams.stream_scenario`): one long episode each, the hand never
   leaving, swipes and rotates among drift, wobble, slow re-positioning and slow palm turns;
   recall of the strokes and false triggers (a reported gesture, p ≥ 0.5, that no stroke of its
   name overlaps) per minute outside the strokes.
2. **Cost.** Time per classification against the whole library (median, p99) on those
   windows, and DTW implementations compared on the same windows: vectorised numpy exact DTW,
   plain-Python exact DTW, fastdtw's exact ``dtw`` and its approximate ``fastdtw`` (radius 1)
   with ``dist=2`` as installed — compiled when its extension was built, else pure Python —
   and ``fastdtw`` with a Python callable as ``dist``; the approximation's error; and the
   classifier's accuracy on fastdtw's approximate distances.
3. **Latency.** A router, a leap-bridge (simulated user) and dynamic-gesture as real processes;
   the leap-bridge plays ``dynamic-all``; for each stroke's final window, the time from the
   stroke's end (``window[1]``, the frame where the hand slowed down) to the service's publish
   (``ts``) and to arrival at a subscriber. It includes the ``end_hold_s`` the segmenter waits
   to be sure the hand stopped.

4. **Real people** (``--real DIR``): the SHREC'17 skeletons or Leap Motion recordings
   (LeapJS frames, `leapjs`) as trials (`trials`) and continuous streams (`streams`) through
   live services (`live`), scored (`scoring`) and printed (`report`); ``--realism DIR``
   compares the simulated users' swipe habits with theirs (`realism`; ``--plot FIG`` draws
   them).
   ``--live-sim N`` plays N held-out simulated users the same way
   (`trials.simulated_trials`: each dynamic gesture once per appearance of the hand,
   rotate included), to score the episode summary on them too. ``--replay-sim N`` replays
   the same trials of many more users offline through the service's own logic (segmenter,
   return filter, library: `replay_trial`), which answers trial by trial as the live services
   do, in a fraction of real time: a synthetic figure is judged over
   `scoring.GOALS["synthetic_trials"]` trials at least (a draw of 16 users moves it by
   several points).

5. **Plain strokes** (``--plain-strokes REPS``): textbook minimum-jerk swipes and rotates on a
   grid of length (or angle) and duration, from random places in the field, tilted, bowed and
   rolling, rotates with the palm drifting, after a rest or drifting in (`plainstrokes`),
   replayed offline like ``--replay-sim``: no simulated person's habits, so where in length
   and duration a stroke stops being heard.

Every live run and the simulated streams end with the acceptance goals, judged on the figures
just measured (`scoring.live_goals`, `scoring.stream_goals`).

Examples::

    cbgo bench dynamic
    cbgo bench dynamic --real ~/.cache/cbgo/shrec17
    cbgo bench dynamic --real ~/.cache/cbgo/guinevere --per-class 0   # real Leap recordings
    cbgo bench dynamic --real ~/.cache/cbgo/guinevere --mirror   # the same as left hands
    cbgo bench dynamic --real ~/.cache/cbgo/guinevere --stream-returns   # streams with returns
    cbgo bench dynamic --real ~/.cache/cbgo/leapmotion-left --per-class 0   # real left hands
    cbgo bench dynamic --realism ~/.cache/cbgo/shrec17 --plot /tmp/fig
    cbgo bench dynamic --realism ~/.cache/cbgo/shrec17 --ranges default
    cbgo bench dynamic --live-sim 16           # simulated users through live services
    cbgo bench dynamic --replay-sim 100        # 500 such trials, offline, in about 3 min
    cbgo bench dynamic --plain-strokes 2       # textbook strokes on a grid: what is heard
    cbgo bench dynamic --plain-strokes 2 --mirror   # ... made by a left hand
    cbgo bench dynamic --sets --streams-sim 20   # every real set and the streams, one table
    cbgo train dynamic --out /tmp/simonly.json && \
        cbgo bench dynamic --sets --left-out /tmp/simonly.json   # + leave-one-set-out
    cbgo bench dynamic --users 6 --no-latency --json /tmp/dynamic.json
    cbgo bench dynamic --ranges train          # held-out users inside the training range
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import keys, metrics, wire
from cbgo.services.dynamic_gesture.classifier import NONE, Classifier, normalised
from cbgo.services.dynamic_gesture.dtw import dtw_naive, fastdtw_backend
from cbgo.services.dynamic_gesture.library import DEFAULT_PATH, Library, save_default
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig
from cbgo.simuser.scenario import load_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo_tools.data import shrec
from cbgo_tools.dynamic_gesture import (
    calibration,
    crossset,
    live,
    plainstrokes,
    realism,
    report,
    scoring,
    simdata,
    streams,
    train,
    trials,
)

BENCH_SEED = 50_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--users", type=int, default=16, help="held-out users [16]")
    parser.add_argument("--reps", type=int, default=2, help="strokes per gesture and user [2]")
    parser.add_argument("--ranges", choices=sorted(simdata.RANGES), default=None,
                        help="style ranges of the users: held-out (outside the training "
                             "range), train (inside it), default (every user of the default "
                             "style, as a scenario file's) [held-out; train with --realism]")
    parser.add_argument("--seed", type=int, default=BENCH_SEED, help=f"[{BENCH_SEED}]")
    parser.add_argument("--still", type=int, default=4, help="still-hand sessions [4]")
    parser.add_argument("--jobs", type=int, default=2, help="processes simulating users [2]")
    parser.add_argument("--streams-sim", type=int, default=6,
                        help="continuous streams of simulated users (hand never leaves) [6]")
    parser.add_argument("--templates", type=Path, default=DEFAULT_PATH,
                        help="template library [the shipped models/default.json]")
    parser.add_argument("--live-sim", type=int, default=0, metavar="USERS",
                        help="instead of the above: USERS simulated users (--ranges, --seed) "
                             "perform each dynamic gesture once per appearance of the hand, "
                             "played like --real through live dynamic-gesture and episode "
                             "services in real time [0: off]")
    parser.add_argument("--plain-strokes", type=int, default=0, metavar="REPS",
                        help="instead of the above: a grid of plain minimum-jerk swipes and "
                             "rotates (`plainstrokes`: length or angle × duration × rest or "
                             "not, REPS each, from random places, tilted, bowed, rolling) "
                             "replayed offline through the service's logic (--templates): "
                             "where a stroke stops being heard [0: off]")
    parser.add_argument("--replay-sim", type=int, default=0, metavar="USERS",
                        help="instead of the above: the --live-sim trials of USERS simulated "
                             "users replayed offline through the service's segmenter, return "
                             "filter and library (--templates), as the live services answer "
                             "them; no episode summary [0: off]")
    parser.add_argument("--sets", action="store_true",
                        help="instead of the above: every real development set in the cache "
                             "and the continuous streams, replayed offline through the "
                             "service's logic (--templates), in one table (`crossset`)")
    parser.add_argument("--calibration", action="store_true",
                        help="instead of the above: each person of the cached real sets "
                             "calibrated from k = 0, 1, 3, 5 of their own swipes (as `cbgo "
                             "gestures calibrate` does), scored on their other recordings "
                             "and streams (`calibration`)")
    parser.add_argument("--left-out", type=Path, default=None, metavar="LIB",
                        help="with --sets: a library fitted on none of the real sets the "
                             "--templates one was (`cbgo train dynamic --out LIB`: simulated "
                             "users only), for their leave-one-set-out column")
    parser.add_argument("--segmenter", action="append", default=[], metavar="KEY=VALUE",
                        help="with --sets: replay with this segmenter setting changed "
                             "(SegmenterConfig's fields; repeatable)")
    parser.add_argument("--latency", action=argparse.BooleanOptionalAction, default=True,
                        help="measure latency through real processes [on]")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    real = parser.add_argument_group(
        "real people (SHREC'17 skeletons, `shrec`; Leap Motion LeapJS recordings, `leapjs`)")
    real.add_argument("--real", type=Path, metavar="DIR", default=None,
                      help="instead of the above: play real recordings through live services "
                           "(live): a SHREC'17 datasetShrec folder, or a folder of LeapJS "
                           "recordings (the Guinevere set)")
    real.add_argument("--split", choices=("train", "test"), default="train",
                      help="which official split's people [train; test is reserved for "
                           "acceptance checks]")
    real.add_argument("--per-class", type=int, default=12,
                      help="recordings per swipe, and of the other gestures; 0: all [12]")
    real.add_argument("--others", type=int, default=None, metavar="N",
                      help="recordings of the other gestures (grab, tap, pinch...) instead: "
                           "0 plays none, -1 all [as --per-class]")
    real.add_argument("--streams", type=int, default=3,
                      help="continuous streams (one person each, hand never leaves) [3]")
    real.add_argument("--folds", type=int, default=0, metavar="N",
                      help="with --real on the SHREC'17 train split: deal its people into N "
                           "groups and play each group's recordings (--per-class of each per "
                           "group, --streams per group) against a library learned here "
                           "without them (as `cbgo train dynamic --folds N` does offline; "
                           "about 3 min per group on 2 cores): held-out people through live "
                           "services, the episode summary included; 0: the installed library "
                           "[0]")
    real.add_argument("--mirror", action="store_true",
                      help="with --real: play every recording mirrored, as the other hand "
                           "makes it (x negated, sides swapped, swipe_left scored as "
                           "swipe_right): the left-hand path on real motion, both sets being "
                           "right hands; with --plain-strokes: a left hand's strokes")
    real.add_argument("--stream-returns", action="store_true",
                      help="with --real on LeapJS recordings: follow each swipe of a stream "
                           "with a return move (0.95 of its length, 0.92 of its speed: the "
                           "SHREC'17 train split's medians), as real people make one and the "
                           "recordings stop before it; without it, a swipe that reverses the "
                           "one before comes about 1 s after it, the hardest case")
    real.add_argument("--realism", type=Path, metavar="DIR", default=None,
                      help="instead: compare the simulated users' swipe habits with the real "
                           "train split's in this datasetShrec folder")
    real.add_argument("--plot", type=Path, metavar="DIR", default=None,
                      help="with --realism: also draw the habits, real beside simulated, as "
                           "DIR/realism.png")


# ============================================================================ accuracy


def still_windows(sessions: int, seed: int) -> list[simdata.Labelled]:
    """Returns the windows a resting hand produced (every one is truly none)."""
    out = []
    for i in range(sessions):
        scenario = load_scenario("still")
        scenario.seed = seed + i
        style = next(iter(scenario.users.values()))
        style.tremor_mm = 1.0 + i * 0.5  # 1 to 2.5 mm: up to a shaky hand
        segmenter = Segmenter()
        for frame in SimulatedUser(scenario, 60.0).frames():
            out += [simdata.Labelled(w, NONE) for w in segmenter.update(frame.t, frame.hands)]
    return out


def score(classifier: Classifier, users: list[simdata.UserData],
          extra: list[simdata.Labelled]) -> dict:
    """Returns accuracy and calibration figures of final and mid-stroke windows."""
    index = {name: i for i, name in enumerate(classifier.names)}
    rows: dict[bool, tuple[list, list]] = {True: ([], []), False: ([], [])}
    windows = [lw for u in users for lw in u.windows] + extra
    for lw in windows:
        probs, truths = rows[lw.window.final]
        probs.append(classifier.classify(lw.window))
        truths.append(index.get(lw.truth, index[NONE]))
    missed = [g for u in users for g, _, _ in u.missed]
    n = len(classifier.names)
    out = {}
    for final, (probs, truths) in rows.items():
        p = np.asarray(probs).reshape(-1, n)
        y = np.asarray(truths, dtype=int)
        pred = p.argmax(1) if len(p) else np.zeros(0, dtype=int)
        if final:  # a stroke nobody caught is a gesture predicted as none
            y = np.concatenate([y, [index[g] for g in missed]]).astype(int)
            pred = np.concatenate([pred, [index[NONE]] * len(missed)]).astype(int)
        confusion = metrics.confusion_matrix(y, pred, n)
        out["final" if final else "mid_stroke"] = {
            "samples": len(y), "balanced_accuracy": metrics.balanced_accuracy(y, pred, n),
            "recall": dict(zip(classifier.names, np.nan_to_num(
                metrics.per_class_recall(confusion)).tolist(), strict=True)),
            "ece": metrics.expected_calibration_error(p, y[:len(p)]) if len(p) else 0.0,
            "confusion": confusion.tolist()}
    out["final"]["missed_strokes"] = len(missed)
    out["final"]["true_strokes"] = sum(len(u.strokes) for u in users)
    out["still_false_strokes"] = sum(
        1 for lw in extra if lw.window.final
        and classifier.names[int(classifier.classify(lw.window).argmax())] != NONE)
    out["still_windows"] = len(extra)
    return out


def run_streams(classifier, users: int, seed: int, config, ranges) -> dict:
    """Scores `users` continuous streams of simulated users; prints and returns the totals."""
    total = streams.synthetic_streams(classifier, users, seed, config, ranges)
    print(f"\nsynthetic continuous streams ({users} simulated users, hand never leaves; "
          f"swipes from anywhere, returns, drift, wobble, slow re-positioning, slow palm "
          f"turns): " + scoring.describe_streams(total))
    return total


# ============================================================================ cost


def _timed(fn, reps: int = 1, clock=time.perf_counter) -> float:
    t0 = clock()
    for _ in range(reps):
        fn()
    return (clock() - t0) / reps * 1e3


def cost(classifier: Classifier, windows: list, limit: int = 120) -> dict:
    """Returns ms per classification and the DTW implementations compared on real windows."""
    per = np.array([_timed(lambda w=w: classifier.classify(w)) for w in windows])
    # CPU time as well: on a shared machine, wall-clock outliers are other processes' turns.
    cpu = np.array([_timed(lambda w=w: classifier.classify(w), clock=time.process_time)
                    for w in windows])
    lengths = np.array([len(w.obs) for w in windows])
    shapes = classifier.shapes
    obs = [normalised(w.obs) for w in windows[:limit]]
    out = {"classify_ms_median": float(np.median(per)),
           "classify_ms_p99": float(np.percentile(per, 99)),
           "classify_cpu_ms_median": float(np.median(cpu)),
           "classify_cpu_ms_p99": float(np.percentile(cpu, 99)),
           "stroke_samples": [int(lengths.min()), int(np.median(lengths)), int(lengths.max())],
           "template_samples": [len(t) for t in shapes], "templates": len(shapes),
           "dtw": classifier.implementation, "fastdtw": fastdtw_backend()}
    runs = {"exact, numpy (TemplateBank)": (lambda o: classifier.bank.distances(o), obs),
            "exact, plain Python": (lambda o: [dtw_naive(o, t) for t in shapes], obs[:30])}
    if out["fastdtw"] is not None:
        from fastdtw import dtw, fastdtw

        def euclid(a, b):
            return float(np.linalg.norm(a - b))

        kind = out["fastdtw"]
        runs[f"exact, fastdtw dtw dist=2 ({kind})"] = (
            lambda o: [dtw(o, t, dist=2) for t in shapes], obs)
        runs[f"approx., fastdtw r=1 dist=2 ({kind})"] = (
            lambda o: [fastdtw(o, t, radius=1, dist=2) for t in shapes], obs)
        runs[f"approx., fastdtw r=1 dist=callable ({kind})"] = (
            lambda o: [fastdtw(o, t, radius=1, dist=euclid) for t in shapes], obs[:20])
        exact = np.array([classifier.bank.costs(o) for o in obs])
        approx = np.array([[fastdtw(o, t, radius=1, dist=2)[0] for t in shapes] for o in obs])
        out["fastdtw_error_median"] = float(np.median(approx / exact - 1))
        out["fastdtw_error_max"] = float(np.max(approx / exact - 1))
    out["dtw_ms_per_library"] = {
        name: float(np.median([_timed(lambda o=o, fn=fn: fn(o)) for o in items]))
        for name, (fn, items) in runs.items()}
    return out


# ============================================================================ latency


def latency(seconds_limit: float = 90.0) -> dict:
    """Plays dynamic-all through real processes; returns the end-of-stroke latencies."""
    from cbgo.testing import Stack

    expected = [step.gesture for e in load_scenario("dynamic-all").episodes
                for step in e.gestures]
    got: list[tuple[float, dict]] = []
    lock = threading.Lock()

    def on_sample(sample) -> None:
        arrival = time.time()
        with lock:
            got.append((arrival, wire.decode(sample.payload.to_bytes())))

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.start_service("leap-bridge")
        stack.start_service("dynamic-gesture", env={"CBGO_DATA_DIR": tmp})
        stack.wait_alive(["router", "leap-bridge", "dynamic-gesture"], timeout=60)
        stack.session().declare_subscriber(stack.keys.of(keys.GESTURES_DYNAMIC), on_sample)
        time.sleep(0.5)
        (ok, reply), = stack.query(stack.keys.ctl("leap-bridge", "play"),
                                   {"scenario": "dynamic-all"})
        if not ok:
            raise RuntimeError(f"leap-bridge refused to play: {reply}")
        time.sleep(min(seconds_limit, reply["duration_s"] + 1.5))
    finals: dict[float, tuple[float, dict]] = {}
    for arrival, msg in got:  # the last window of each stroke is its final one
        finals[msg["window"][0]] = (arrival, msg)
    publish = [msg["ts"] - msg["window"][1] for _, msg in finals.values()]
    arrive = [a - msg["window"][1] for a, msg in finals.values()]
    winners = [msg["names"][int(np.argmax(msg["probs"]))] for _, msg in finals.values()]
    gestures = [w for w in winners if w != NONE]
    return {"strokes": len(finals), "winners": winners, "expected": expected,
            "correct": gestures == expected,
            "end_to_publish_ms": _stats(publish), "end_to_arrival_ms": _stats(arrive)}


def _stats(values: list[float]) -> dict:
    if not values:
        return {}
    v = np.asarray(values) * 1e3
    return {"median": float(np.median(v)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max())}


# ============================================================================ run


def _print_block(title: str, block: dict, names: list[str]) -> None:
    print(f"\n{title}: {block['samples']} windows")
    print(metrics.format_confusion(np.asarray(block["confusion"]), names))
    print("recall: " + ", ".join(f"{k} {v:.1%}" for k, v in block["recall"].items()))
    print(f"balanced accuracy {block['balanced_accuracy']:.2%}, ECE {block['ece']:.3f}")


def run_real(root: Path, split: str, per_class: int, stream_count: int, seed: int,
             json_path: Path | None, mirror: bool = False, returns: bool = False,
             log=print, others: int | None = None, library: Path | None = None) -> int:
    """``--real DIR``: a real set's trials and streams through the live services, scored.

    `mirror`: as left hands; `returns`: LeapJS streams with a return move after each swipe;
    `others`: how many recordings of the other gestures (`trials.pick_trials`); `library`: a
    library file the service uses instead of the installed one (`live.play_live`).
    """
    device, all_trials, sequences = trials.real_trials(root, split)
    if device == "shrec17" and split == "test":
        log("note: the test split's people are reserved for acceptance checks; never tune on "
            "these figures")
    chosen = trials.pick_trials(all_trials, per_class, seed, others)
    played = streams.stream_sets(device, all_trials, sequences, stream_count, seed + 1, returns)
    where = f"{device}'s {split} split" if device == "shrec17" else device
    if mirror:
        chosen, played, where = trials.mirrored_set(chosen, played, where)
    return report.report_live(live.play_live(chosen, played, device, where, log, library),
                              json_path, log)


def run_real_folds(args: argparse.Namespace) -> int:
    """``--real DIR --folds N``: each group of people live, against a library learned without it.

    The libraries are learned as `cbgo train dynamic --real DIR` learns the shipped one (the
    same simulated users, the other groups' people); the trials of all groups are scored
    together.
    """
    device, all_trials, sequences = trials.real_trials(args.real, "train")
    if device != "shrec17" or args.split != "train":
        print("--folds needs the SHREC'17 datasetShrec folder and its train split: the libraries "
              "are learned from the other groups of that split's people", file=sys.stderr)
        return 2
    return_s = SegmenterConfig().return_s
    sim_train, sim_calib = train.simulated_sets(train.USERS, train.CALIB_USERS, train.REPS,
                                                 train.TRAIN_SEED, args.jobs)
    recordings = shrec.sequence_windows(sequences)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (held, classifier) in enumerate(train.fold_classifiers(
                sim_train, sim_calib, recordings, args.folds, return_s)):
            library = Path(tmp) / f"group-{k + 1}.json"
            save_default(library, classifier.templates, classifier.calibration,
                         train.observation(), {"held_out_people": sorted(held)}, classifier.net)
            people = {str(person) for person in held}
            chosen = trials.pick_trials([t for t in all_trials if t.person in people],
                                        args.per_class, args.seed + k, args.others)
            played = streams.stream_sets(device, [], [s for s in sequences if s.person in held],
                                         args.streams, args.seed + 1 + k)
            where = f"group {k + 1}/{args.folds} of shrec17's train split, people {sorted(held)}"
            if args.mirror:
                chosen, played, where = trials.mirrored_set(chosen, played, where)
            results.append(live.play_live(chosen, played, device, where, library=library))
    latency = [ms for r in results for ms in r["stroke_latencies_ms"]]
    merged = {"trials": [t for r in results for t in r["trials"]],
              "streams": [s for r in results for s in r["streams"]],
              "stroke_latencies_ms": latency, "latency_ms": scoring.latency_figures(latency),
              "episode_stray": {key: sum(r["episode_stray"].get(key, 0) for r in results)
                                for key in ("late", "outside")}}
    print(f"\nall {args.folds} groups, each played against a library learned without it:")
    return report.report_live(merged, args.json)


def replay_trial(classifier: Classifier, trial: trials.Trial, config: SegmenterConfig
                 ) -> dict:
    """Returns what the live services' `gestures/dynamic` would answer for one trial.

    The trial's frames go through the service's segmenter, then the hand leaves; its windows
    through the return filter and the library (`train.trial_answers`), as the service decides
    what it publishes. ``dynamic`` is the most probable reported gesture, ``first`` the first,
    ``finals`` the most probable among final windows (``nothing`` where none has p ≥
    `stroke.GESTURE_P`), as `live.run_trials` scores the live messages.
    """
    windows = shrec.recording_windows(trial.frames(), Segmenter(config))
    answers = train.trial_answers(classifier, windows, config.return_s)
    return trial.row(dynamic=answers["all"], first=answers["first"], finals=answers["finals"])


def run_replay_sim(args: argparse.Namespace) -> int:
    """``--replay-sim USERS``: the ``--live-sim`` trials of many users, replayed offline."""
    classifier = Library(args.templates, None).load().classifier()
    config = SegmenterConfig()
    ranges = simdata.RANGES[args.ranges]
    rows = []
    t0 = time.perf_counter()
    for k in range(args.replay_sim):  # one user at a time: the same trials as --live-sim's
        rows += [replay_trial(classifier, trial, config)
                 for trial in trials.simulated_trials(1, args.seed + k, ranges)]
        if (k + 1) % 10 == 0 or k + 1 == args.replay_sim:
            print(f"  {k + 1}/{args.replay_sim} users, {len(rows)} trials, "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    result = {"users": args.replay_sim, "ranges": args.ranges, "trials": rows}
    print(f"\n{len(rows)} trials of {args.replay_sim} simulated {args.ranges} users, replayed "
          f"offline through the service's segmenter, return filter and library")
    return report.report_replay(result, args.json)


def run_sets(args: argparse.Namespace) -> int:
    """``--sets``: every cached real set and the streams, offline, in one table."""
    try:
        overrides = crossset.parse_overrides(args.segmenter)
    except ValueError as e:
        print(e, file=sys.stderr)
        return 2
    classifier = Library(args.templates, None).load().classifier()
    left_out = None if args.left_out is None else \
        Library(args.left_out, None).load().classifier()
    result = crossset.run(classifier, overrides, args.streams_sim, args.seed, replay_trial,
                          left_out=left_out)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


def run_plain_strokes(args: argparse.Namespace) -> int:
    """``--plain-strokes REPS``: the grid of `plainstrokes`, replayed offline."""
    classifier = Library(args.templates, None).load().classifier()
    strokes = plainstrokes.grid(args.plain_strokes, args.seed)
    t0 = time.perf_counter()
    rows = plainstrokes.score(strokes, classifier, SegmenterConfig(), replay_trial,
                              args.mirror)
    hand = "left" if args.mirror else "right"
    print(f"{len(rows)} plain strokes of a {hand} hand replayed in "
          f"{time.perf_counter() - t0:.0f} s")
    figures = plainstrokes.report(rows)
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1))
    return 0


def _chosen_library(args: argparse.Namespace) -> Path | None:
    """Returns the ``--templates`` file the live services must use (None: the installed one)."""
    return None if args.templates == DEFAULT_PATH else args.templates


def run(args: argparse.Namespace) -> int:
    """Runs the three parts and prints their figures (or the real-data bench)."""
    if args.ranges is None:  # --realism compares the range fitted to real people by default
        args.ranges = "train" if args.realism is not None else "held-out"
    if args.plot is not None and args.realism is None:
        print("--plot draws the --realism comparison: give --realism DIR too", file=sys.stderr)
        return 2
    if args.real is not None and args.folds > 0:
        return run_real_folds(args)
    if args.real is not None:
        return run_real(args.real, args.split, args.per_class, args.streams,
                        args.seed, args.json, args.mirror, args.stream_returns,
                        others=args.others, library=_chosen_library(args))
    if args.live_sim > 0:
        simulated = trials.simulated_trials(args.live_sim, args.seed,
                                            simdata.RANGES[args.ranges])
        result = live.play_live(simulated, [], "simulated",
                                f"{args.live_sim} simulated {args.ranges} users",
                                library=_chosen_library(args))
        result["ranges"] = args.ranges
        return report.report_live(result, args.json, synthetic=True)
    if args.replay_sim > 0:
        return run_replay_sim(args)
    if args.sets:
        return run_sets(args)
    if args.calibration:
        rows = calibration.run(Library(args.templates, None).load().classifier(), replay_trial,
                               args.seed)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
        return 0
    if args.plain_strokes > 0:
        return run_plain_strokes(args)
    if args.realism is not None:
        config = SegmenterConfig()
        real = realism.real_habits(args.realism, "train", config)
        ranges = simdata.RANGES[args.ranges]
        print(f"simulated: {args.users} {args.ranges} users")
        simulated = realism.simulated_habits(args.users, args.seed, config, ranges)
        table = realism.print_realism(real, simulated)
        table["spread"] = realism.print_spread(real, simulated)
        table["by_way"] = realism.by_way(real, simulated)
        table["geometry"] = realism.print_geometry(real, simulated)
        ungated = realism.ungated(config)
        table["speed_by_length"] = realism.print_speed_by_length(
            realism.real_habits(args.realism, "train", ungated),
            realism.simulated_habits(args.users, args.seed, ungated, ranges))
        if args.json:
            args.json.write_text(json.dumps(table, indent=1))
        if args.plot:
            print(f"wrote {realism.plot_realism(real, simulated, args.plot)}")
        return 0
    library = Library(args.templates, None).load()
    classifier = library.classifier()
    t0 = time.perf_counter()
    users = simdata.generate(list(range(args.seed, args.seed + args.users)),
                             simdata.RANGES[args.ranges], args.reps, args.jobs)
    extra = still_windows(args.still, args.seed + 10_000)
    print(f"simulated {args.users} {args.ranges} users and {args.still} still hands in "
          f"{time.perf_counter() - t0:.0f} s; templates: {', '.join(library.names)}")
    figures = {"users": args.users, "ranges": args.ranges, "reps": args.reps,
               "accuracy": score(classifier, users, extra)}
    acc = figures["accuracy"]
    _print_block("end-of-stroke windows (missed strokes count as none)", acc["final"],
                 classifier.names)
    print(f"true strokes {acc['final']['true_strokes']}, missed {acc['final']['missed_strokes']}"
          f"; still hands: {acc['still_windows']} windows, {acc['still_false_strokes']} "
          "final ones won by a gesture")
    _print_block("mid-stroke windows", acc["mid_stroke"], classifier.names)
    if args.streams_sim > 0:  # --streams-sim 0: no continuous streams
        figures["streams"] = run_streams(classifier, args.streams_sim, args.seed + 20_000,
                                         SegmenterConfig(), simdata.RANGES[args.ranges])
        print("goals:\n" + metrics.format_goals(scoring.stream_goals(figures["streams"])))
    finals = [lw.window for u in users for lw in u.windows if lw.window.final]
    figures["cost"] = cost(classifier, finals)
    c = figures["cost"]
    print(f"\nclassification against {c['templates']} templates (DTW: {c['dtw']}): median "
          f"{c['classify_ms_median']:.3f} ms, p99 {c['classify_ms_p99']:.3f} ms wall-clock; "
          f"CPU time median {c['classify_cpu_ms_median']:.3f} ms, p99 "
          f"{c['classify_cpu_ms_p99']:.3f} ms; stroke samples min/median/max "
          f"{c['stroke_samples']}, templates {c['template_samples']}")
    for name, ms in c["dtw_ms_per_library"].items():
        print(f"  DTW against the library, {name}: {ms:.3f} ms (median)")
    if c["fastdtw"] is not None:
        fast = Classifier(classifier.templates, classifier.calibration, "fastdtw",
                          classifier.net, classifier.net_known)
        fast_acc = score(fast, users, [])["final"]["balanced_accuracy"]
        c["fastdtw_balanced_accuracy"] = fast_acc
        print(f"  fastdtw cost error vs exact: median {c['fastdtw_error_median']:.2%}, max "
              f"{c['fastdtw_error_max']:.2%}; balanced accuracy with fastdtw {fast_acc:.2%}")
    if args.latency:
        figures["latency"] = lat = latency()
        print(f"\nlatency through router + leap-bridge + dynamic-gesture ({lat['strokes']} "
              f"strokes, gestures in order: {lat['correct']}; winners {lat['winners']}):")
        for name in ("end_to_publish_ms", "end_to_arrival_ms"):
            s = lat[name]
            if s:
                print(f"  {name}: median {s['median']:.1f}, p99 {s['p99']:.1f}, "
                      f"max {s['max']:.1f}")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2, default=float))
        print(f"\nwrote {args.json}")
    return 0
