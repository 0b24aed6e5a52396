"""A person calibrated from k of their own swipes, scored on their other swipes and streams.

``cbgo bench dynamic --calibration`` measures `cbgo.services.dynamic_gesture.pace` as a user
meets it (``cbgo gestures calibrate --user NAME --takes k``), with people kept apart: each
person of a real set is calibrated from k takes of each swipe drawn from their own recordings
(each take found as `user_pace` finds it: the stroke going farthest the swipe's way, no
slow-move line), and scored on their remaining recordings only: the swipes, the other gestures
(which must stay unreported) and, for SHREC'17, continuous streams of their recordings (false
triggers per minute outside the gestures). k = 0 is zero-shot: the lines as configured.

Sets: SHREC'17's train people (up to 10 takes of each swipe per person) and GestureMidAir's
train people (one take of each swipe: k = 1 calibrates on one swipe and scores the other).
Nothing is fitted on any of them: the library in use is the shipped one.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.services.dynamic_gesture.pace import SWIPES, pace_of, swipe_take
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig
from cbgo.services.dynamic_gesture.user_pace import unlined
from cbgo_tools.dynamic_gesture import scoring, streams, trials
from cbgo_tools.dynamic_gesture.scoring import NOTHING

KS = (0, 1, 3, 5)
STREAMS_PER_PERSON = 3  # a stream or two per person move the false-trigger rate by half


def take_of(trial: trials.Trial):
    """Returns a swipe trial's calibration take (`user_pace`'s rule), or None."""
    segmenter = Segmenter(unlined())
    frames = trial.frames()
    windows = [w for t, hands in frames for w in segmenter.update(t, hands)]
    windows += segmenter.update(frames[-1][0] + 1.0, [])  # the hand leaves
    return swipe_take(windows, trial.truth)


def person_config(takes: list, k: int, rng: np.random.Generator, person: str,
                  leave_out: int | None = None) -> SegmenterConfig | None:
    """Returns the person's settings from k takes of each swipe (None: no take to use).

    `takes`: (trial index, truth, take window or None) of the person's swipe trials; the
    trial `leave_out` (the one scored) is never one of them.
    """
    windows = []
    for gesture in SWIPES:
        pool = [w for i, truth, w in takes
                if truth == gesture and w is not None and i != leave_out]
        windows += [pool[j] for j in rng.permutation(len(pool))[:k]]
    if not windows:
        return None
    return pace_of(person, windows).applied(SegmenterConfig())


def score_set(name: str, root: Path, classifier, replay, seed: int, ks=KS,
              streams_too: bool = False, log=print) -> list[dict]:
    """Scores every k on one set; returns a row per k.

    Each recording is scored with a calibration drawn from the person's other recordings; a
    person's streams (SHREC'17, `streams_too`) with one drawn from all of theirs (a stream is
    scored for its false triggers, which no take can have seen).
    """
    device, all_trials, sequences = trials.real_trials(root, "train")
    people = sorted({t.person for t in all_trials})
    takes = {i: take_of(t) for i, t in enumerate(all_trials) if t.truth != "none"}
    t0 = time.perf_counter()
    rows = []
    for k in ks:
        rng = np.random.default_rng(seed)
        scored, stream_rows, lines = [], [], []
        for person in people:
            own = [(i, t) for i, t in enumerate(all_trials) if t.person == person]
            mine = [(i, t.truth, takes.get(i)) for i, t in own if t.truth != "none"]
            for i, trial in own:
                config = person_config(mine, k, rng, person, leave_out=i) if k else None
                if k and config is None:
                    continue  # no take of this person to calibrate on
                config = config or SegmenterConfig()
                lines.append(config.min_peak_speed_mm_s)
                scored.append(replay(classifier, trial, config))
            if device == "shrec17" and streams_too:
                config = (person_config(mine, k, rng, person) if k else None) or SegmenterConfig()
                sequences_of = [s for s in sequences if str(s.person) == person]
                played = streams.person_streams(sequences_of, STREAMS_PER_PERSON, rng)
                stream_rows.append(streams.replay_played(classifier, played, config))
        block = scoring.score(scored, "dynamic")
        swipes = [r for r in scored if r["truth"] != "none"]
        row = {"set": name, "k": k, "people": len({r["person"] for r in swipes}),
               "swipes": len(swipes), "balanced_accuracy": block["balanced_accuracy"],
               "silent": sum(r["dynamic"] == NOTHING for r in swipes),
               "other_false": block["other_false"], "other_trials": block["other_trials"],
               "median_line_mm_s": float(np.median(lines)) if lines else None}
        if stream_rows:
            row["stream"] = scoring.stream_totals(stream_rows)
        rows.append(row)
        log(f"  {name} k={k}: {time.perf_counter() - t0:.0f} s", flush=True)
    return rows


def run(classifier, replay, seed: int, log=print) -> list[dict]:
    """Scores each cached set at each k and prints the table."""
    rows = []
    root = cache_dir() / "shrec17"
    if root.is_dir():
        rows += score_set("shrec17", root, classifier, replay, seed, streams_too=True, log=log)
    root = cache_dir() / "gesturemidair"
    if root.is_dir():
        rows += score_set("gesturemidair", root, classifier, replay, seed, ks=(0, 1), log=log)
    print_table(rows, log)
    return rows


def print_table(rows: list[dict], log=print) -> None:
    """Prints one line per set and k."""
    log("\n| set | k takes of each swipe | people | swipes scored | balanced | silent | "
        "others reported | median line (mm/s) | stream false / min |")
    log("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        stream = r.get("stream")
        rate = (f"{stream['false_triggers'] / max(stream['other_minutes'], 1e-9):.2f} "
                f"(recall {stream['recalled'] / max(stream['strokes'], 1):.1%})"
                if stream else "")
        line = f"{r['median_line_mm_s']:.0f}" if r["median_line_mm_s"] is not None else ""
        log(f"| {r['set']} | {r['k']} | {r['people']} | {r['swipes']} | "
            f"{r['balanced_accuracy']:.1%} | {r['silent']} | {r['other_false']}/"
            f"{r['other_trials']} | {line} | {rate} |")

