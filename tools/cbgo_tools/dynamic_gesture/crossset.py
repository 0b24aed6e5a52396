"""Every real development set at once, in one table: a change is judged on all of them.

``cbgo bench dynamic --sets`` replays each set offline through the service's own logic
(segmenter, return filter, library: `bench.replay_trial`, `streams.replay_stream`), which
answers trial by trial as the live services do, in a fraction of real time. Rows:

- **trials** of each real set in the cache (`REAL_SETS`): SHREC'17's train split (depth
  camera), GestureMidAir's train people (a Leap, slow short swipes drawn in the air),
  Guinevere (a Leap, LeapJS), ``leapmotion-swipes`` (12 people's own swipes, either hand) and
  ``leapmotion-left`` (real left hands). Balanced accuracy over the swipes, the swipes that
  gave no answer, and the other gestures (grab, tap, pinch, ...) that were reported as one;
- **streams**, the hand never leaving: simulated users (`streams.stream_scenario`), SHREC'17's
  train people (`streams.person_streams`) and Guinevere's people with a return move after each
  swipe (`streams.trials_stream`); recall and false triggers per minute outside the gestures.

Columns say which people the library in use was fitted on. The shipped library is learned
from SHREC'17's train people and simulated users only (`FITTED`), so every other set is a set
left out entirely: its figure is the leave-one-set-out one. SHREC'17's own row is in-sample;
``--left-out LIB`` replays the fitted sets again with a library learned without them
(``cbgo train dynamic --out LIB``: simulated users only), which fills the "left out" column,
and its leave-people-out figure is ``cbgo train dynamic --real DIR --folds 4``. Reserved
people (SHREC'17's test split, GestureMidAir's test people) are never read here.

``--segmenter KEY=VALUE`` replays with a segmenter setting changed (the service's
``SegmenterConfig`` fields), to judge a rule on every set before it is adopted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from cbgo.config import cache_dir
from cbgo.services.dynamic_gesture.stroke import SegmenterConfig
from cbgo_tools.data import leapjs
from cbgo_tools.dynamic_gesture import scoring, streams, trials
from cbgo_tools.dynamic_gesture.scoring import NOTHING


@dataclass(frozen=True)
class RealSet:
    """A cached real set: its cache folder and what it is."""

    name: str
    folder: str
    what: str


REAL_SETS = (
    RealSet("shrec17", "shrec17", "depth camera, 20 train people (the shipped library's)"),
    RealSet("gesturemidair", "gesturemidair", "Leap, 5 train people, lines drawn in the air"),
    RealSet("guinevere", "guinevere", "Leap (LeapJS), 4 people"),
    RealSet("leapmotion-swipes", "leapmotion-swipes", "Leap, 12 people's own swipes"),
    RealSet("leapmotion-left", "leapmotion-left", "Leap, real left hands"),
)


FITTED = ("shrec17",)
"""The real sets the shipped library is fitted on (`cbgo train dynamic --real DIR`)."""


def parse_overrides(items: list[str]) -> dict:
    """Returns ``KEY=VALUE`` items as SegmenterConfig overrides, typed as its fields.

    Raises:
        ValueError: an unknown field or a malformed item, naming the known fields.
    """
    known = {f.name: f.type for f in fields(SegmenterConfig)}
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in known:
            raise ValueError(f"--segmenter {item!r}: expected KEY=VALUE with KEY one of "
                             f"{sorted(known)}")
        kind = str(known[key])
        out[key] = (value.lower() in ("1", "true", "yes") if "bool" in kind
                    else int(value) if kind == "int" else float(value))
    return out


def trial_row(classifier, name: str, root: Path, config: SegmenterConfig, replay) -> dict:
    """Replays one real set's trials (its train people); returns its figures."""
    device, chosen, _ = trials.real_trials(root, "train")
    # moves along one direction with another hand shape or path are neither swipe nor none
    rows = [replay(classifier, t, config) for t in chosen
            if not t.gesture.startswith(leapjs.SWIPE_LIKE)]
    block = scoring.score(rows, "dynamic")
    swipes = [r for r in rows if r["truth"] != "none"]
    return {"set": name, "device": device, "swipes": len(swipes),
            "people": len({r["person"] for r in swipes}),
            "balanced_accuracy": block["balanced_accuracy"], "recall": block["recall"],
            "silent": sum(r["dynamic"] == NOTHING for r in swipes),
            "other_trials": block["other_trials"], "other_false": block["other_false"],
            "misses": [f"{r['person']} {r['gesture']} → {r['dynamic']}" for r in swipes
                       if r["dynamic"] != r["truth"]]}


def stream_rows(classifier, config: SegmenterConfig, sim_users: int, seed: int) -> list[dict]:
    """Replays the continuous streams of every source in the cache; returns their figures."""
    out = []
    sim = streams.synthetic_streams(classifier, sim_users, seed, config,
                                    streams.simdata.RANGES["default"])
    out.append({"set": f"simulated, {sim_users} default users", **sim})
    root = cache_dir() / "shrec17"
    if root.is_dir():
        _, _, sequences = trials.real_trials(root, "train")
        played = streams.stream_sets("shrec17", [], sequences, 20, seed)
        out.append({"set": "shrec17 train people",
                    **streams.replay_played(classifier, played, config)})
    root = cache_dir() / "guinevere"
    if root.is_dir():
        device, chosen, _ = trials.real_trials(root, "train")
        played = streams.stream_sets(device, chosen, [], 4, seed, returns=True)
        out.append({"set": "guinevere, with returns",
                    **streams.replay_played(classifier, played, config)})
    return out


def run(classifier, overrides: dict, sim_users: int, seed: int, replay, log=print,
        left_out=None) -> dict:
    """Replays every cached set and prints the table; returns its rows.

    ``left_out``: a classifier fitted on none of `FITTED`, for their leave-one-set-out figure.
    """
    config = replace(SegmenterConfig(), **overrides)
    if overrides:
        log(f"segmenter changed: {overrides}")
    t0 = time.perf_counter()
    rows = []
    for real in REAL_SETS:
        root = cache_dir() / real.folder
        if not root.is_dir():
            log(f"  {real.name}: not in the cache (cbgo data list)")
            continue
        row = {**trial_row(classifier, real.name, root, config, replay), "what": real.what}
        if real.name not in FITTED:
            row["left_out"] = row["balanced_accuracy"]
        elif left_out is not None:
            row["left_out"] = trial_row(left_out, real.name, root, config,
                                        replay)["balanced_accuracy"]
        rows.append(row)
        log(f"  {real.name}: {time.perf_counter() - t0:.0f} s", flush=True)
    stream = stream_rows(classifier, config, sim_users, seed)
    log(f"  streams: {time.perf_counter() - t0:.0f} s\n")
    print_table(rows, stream, log)
    return {"segmenter": overrides, "trials": rows, "streams": stream}


def print_table(rows: list[dict], stream: list[dict], log=print) -> None:
    """Prints the trials' and the streams' table."""
    log("| set | what | people | swipes | balanced | left out | silent | others reported |")
    log("|---|---|---|---|---|---|---|---|")
    for r in rows:
        left_out = f"{r['left_out']:.1%}" if "left_out" in r else "(--left-out LIB)"
        log(f"| {r['set']} | {r['what']} | {r['people']} | {r['swipes']} | "
            f"{r['balanced_accuracy']:.1%} | {left_out} | {r['silent']} | "
            f"{r['other_false']}/{r['other_trials']} |")
    log("\nleft out: the balanced accuracy of a library fitted on no person of the set (for a "
        "set the library in use was fitted on, the --left-out library's)")
    balanced = [r["balanced_accuracy"] for r in rows if r["set"] not in FITTED]
    if balanced:
        log(f"\nmean over the sets never fitted on: {np.mean(balanced):.1%}; lowest "
            f"{min(balanced):.1%}")
    log("\n| stream | swipes | recall | false triggers / min | minutes outside |")
    log("|---|---|---|---|---|")
    for s in stream:
        minutes = s["other_minutes"]
        log(f"| {s['set']} | {s['strokes']} | {s['recalled'] / max(s['strokes'], 1):.1%} | "
            f"{s['false_triggers'] / max(minutes, 1e-9):.2f} | {minutes:.1f} |")
    for r in rows:
        if r["misses"]:
            log(f"\n{r['set']} misses: " + "; ".join(r["misses"][:12])
                + (f" (+{len(r['misses']) - 12})" if len(r["misses"]) > 12 else ""))
