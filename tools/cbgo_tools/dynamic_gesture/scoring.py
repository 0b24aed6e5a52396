"""Scoring what the service answered: trials, continuous streams, latency, and the goals.

- **Trials** (`score`): the answer of each trial against its truth, the confusion over the
  dynamic gestures (+ `NOTHING`), per-class recall and the balanced accuracy over the gestures
  the trials hold, with its 95 % interval over people (`cbgo.metrics.people_interval`: how far
  other people could move it). A gesture reported for one of a set's other gestures (grab,
  tap, pinch...) is a false trigger.
- **Continuous streams** (`stream_figures`): recall of the swipes, and false triggers: a
  stroke reported as a gesture (p ≥ 0.5) that overlaps no stroke of that name, counted once
  however many of its windows were reported. Those that overlap one of the other gestures are
  counted apart; the rest fired on returns, preparations, holds and moves, and are given per
  minute of the time outside every gesture.
- **Latency** (`latency_figures`): from a stroke's last sample (``window[1]``) to the arrival
  of its last window.
- **Goals** (`GOALS`): the acceptance lines each figure is judged against, left unjudged
  where the sample is too small to say (`trial_goals`, `stream_goals`).
"""

from __future__ import annotations

import numpy as np

from cbgo import metrics
from cbgo_tools.data import shrec

NOTHING = "nothing"  # a trial's answer when no gesture was reported at p ≥ 0.5
STREAM_COUNTS = ("strokes", "recalled", "false_triggers", "other_gesture_triggers", "misread",
                 "other_minutes")
GOALS = {"real": 0.95, "synthetic": 0.97, "summary": 0.95, "stream_recall": 0.90,
         "false_per_min": 1.0, "stream_swipes": 50, "stream_minutes": 10.0,
         "synthetic_trials": 250}
"""The acceptance figures: balanced accuracy of real swipes, of synthetic strokes and of the
episode summary's g; continuous streams' recall and false triggers per minute. The streams'
figures are judged only over `stream_swipes` swipes and `stream_minutes` outside the gestures
at least: a few streams move them by half between draws. Synthetic strokes are judged only over
`synthetic_trials` trials (50 users) at least: users are drawn from wide ranges of style, and
the 80 trials of 16 users (``--live-sim 16``) move by several points from one draw to the next
(compare blocks of 16 users in ``cbgo bench dynamic --replay-sim 100 --json FILE``). A real set
is judged on the trials it holds."""


def score(rows: list[dict], field: str) -> dict:
    """Returns the confusion over the dynamic gestures (+ nothing) and the balanced accuracy.

    The balanced accuracy is over the gestures the trials hold: the four swipes of a real set,
    rotate too for simulated users.
    """
    names = [*shrec.SWIPES.values(), "rotate", NOTHING]
    swipe_rows = [r for r in rows if r["truth"] != "none"]
    y = [names.index(r["truth"]) for r in swipe_rows]
    pred = [names.index(r[field]) if r[field] in names else names.index(NOTHING)
            for r in swipe_rows]
    confusion = metrics.confusion_matrix(np.array(y), np.array(pred), len(names))
    recall = {n: float(confusion[i, i] / confusion[i].sum()) for i, n in enumerate(names[:5])
              if confusion[i].sum()}
    false = sum(1 for r in rows if r["truth"] == "none" and r[field] != NOTHING)
    people = [r.get("person", "") for r in swipe_rows]
    interval = list(metrics.people_interval(y, pred, people)) if len(set(people)) > 1 else None
    return {"recall": recall, "balanced_accuracy": float(np.mean(list(recall.values()))),
            "interval": interval, "people": len(set(people)),
            "confusion": confusion.tolist(), "names": names,
            "other_trials": sum(1 for r in rows if r["truth"] == "none"),
            "other_false": false}


def stream_figures(reports: list[tuple], strokes: list[tuple], seconds: float,
                   others: list[tuple] = ()) -> dict:
    """Recall and false triggers of a continuous stream.

    Args:
        reports: (gesture, t_start, t_end, stroke key) of every reported window.
        strokes: (gesture, t_start, t_end) of the true strokes.
        seconds: the stream's length.
        others: (name, t_start, t_end) of the gestures in the stream that are none of ours
            (grab, tap, thumbs...).

    A true stroke is recalled when a window of its gesture overlaps it; a window that overlaps
    none of its gesture is a false trigger, counted once per stroke however many windows. A
    stroke that also recalled a true stroke was that gesture, misread in some of its windows
    (early ones, mostly): it is counted as ``misread``, not as a trigger. A false trigger that
    overlaps one of `others` is counted apart (``other_gesture_triggers``): what is left
    (``false_triggers``) fired on returns, preparations, holds and moves, per
    ``other_minutes`` of the time outside every gesture.
    """
    hit = [False] * len(strokes)
    recalling, false_strokes, during_other = set(), set(), set()
    for name, w0, w1, key in reports:
        match = [i for i, (g, a, b) in enumerate(strokes) if g == name and w0 < b and w1 > a]
        for i in match:
            hit[i] = True
        if match:
            recalling.add(key)
        elif any(w0 < b and w1 > a for _, a, b in others):
            during_other.add(key)
        else:
            false_strokes.add(key)
    busy = sum(b - a for _, a, b in [*strokes, *others])
    return {"strokes": len(strokes), "recalled": int(sum(hit)),
            "false_triggers": len(false_strokes - during_other - recalling),
            "other_gesture_triggers": len(during_other - recalling),
            "misread": len((false_strokes | during_other) & recalling),
            "other_minutes": max(seconds - busy, 1e-9) / 60.0}


def stream_totals(rows: list[dict]) -> dict:
    """Returns the sums of several streams' `stream_figures`."""
    return {key: sum(row[key] for row in rows) for key in STREAM_COUNTS}


def describe_streams(total: dict) -> str:
    """Returns `stream_totals` as one line: recall, false triggers per minute, the rest."""
    return (f"recall {total['recalled']}/{total['strokes']} = "
            f"{total['recalled'] / max(total['strokes'], 1):.1%}; false triggers on returns, "
            f"preparations, holds and moves {total['false_triggers']} in "
            f"{total['other_minutes']:.1f} min outside every gesture = "
            f"{total['false_triggers'] / max(total['other_minutes'], 1e-9):.2f}/min; reported "
            f"during the other gestures {total['other_gesture_triggers']}; swipes misread in "
            f"some windows {total['misread']}")


def latency_figures(ms: list[float]) -> dict:
    """Returns the count, median, 90th percentile and largest of `live.stroke_latencies`."""
    if not ms:
        return {}
    return {"strokes": len(ms), "p50": float(np.median(ms)), "p90": float(np.percentile(ms, 90)),
            "max": float(np.max(ms))}


def live_goals(result: dict, streams: dict, synthetic: bool) -> list[tuple]:
    """Returns the acceptance checks against one live run (`GOALS`, `format_goals`).

    A figure goes with its 95 % interval over people where the run has one: a sample of a few
    people passes or misses by chance more often than the figure suggests.
    """
    out = trial_goals(result, synthetic, ("dynamic", "summary"))
    out += stream_goals(streams)
    return out


def trial_goals(result: dict, synthetic: bool, fields: tuple[str, ...]) -> list[tuple]:
    """Returns the trials' checks: each field's balanced accuracy against its goal.

    Synthetic trials are judged over `GOALS` ``synthetic_trials`` at least (`_sampled_goal`).
    """
    kind = "synthetic" if synthetic else "real"
    what = "synthetic strokes, rotate included" if synthetic else "real swipes"
    names = {"dynamic": f"gestures/dynamic ≥ {GOALS[kind]:.0%} balanced",
             "summary": f"episode summary's g ≥ {GOALS['summary']:.0%} balanced"}
    goal = {"dynamic": GOALS[kind], "summary": GOALS["summary"]}
    trials = sum(1 for row in result["trials"] if row["truth"] != "none")
    # which simulated people: the held-out ones are slower and smaller than real people
    who = f" of {result['ranges']} users" if result.get("ranges") else ""
    out = []
    for field in fields:
        block = result[field]
        figure = (f"{block['balanced_accuracy']:.1%}"
                  + metrics.format_interval(block["interval"], block["people"]))
        met = block["balanced_accuracy"] >= goal[field]
        if synthetic:
            out.append(_sampled_goal(f"{what}: {names[field]}", met,
                                     f"{figure}, {trials} trials{who}",
                                     trials >= GOALS["synthetic_trials"],
                                     f"{GOALS['synthetic_trials']} trials",
                                     "play more users (--replay-sim: offline, faster)"))
        else:
            out.append((f"{what}: {names[field]}", met, figure))
    return out


def stream_goals(streams: dict) -> list[tuple]:
    """Returns the continuous streams' checks: recall, and false triggers per minute."""
    if not streams["strokes"]:
        return [("continuous streams", None, "none played")]
    recall = streams["recalled"] / streams["strokes"]
    minutes = streams["other_minutes"]
    rate = streams["false_triggers"] / max(minutes, 1e-9)
    return [_sampled_goal(f"continuous streams: recall ≥ {GOALS['stream_recall']:.0%}",
                          recall >= GOALS["stream_recall"],
                          f"{streams['recalled']}/{streams['strokes']} = {recall:.1%}",
                          streams["strokes"] >= GOALS["stream_swipes"],
                          f"{GOALS['stream_swipes']} swipes"),
            _sampled_goal(f"continuous streams: false triggers ≤ {GOALS['false_per_min']:g}/min",
                          rate <= GOALS["false_per_min"],
                          f"{streams['false_triggers']} in {minutes:.1f} min = {rate:.2f}/min",
                          minutes >= GOALS["stream_minutes"],
                          f"{GOALS['stream_minutes']:g} min outside the gestures")]


def _sampled_goal(name: str, met: bool, figure: str, enough: bool, least: str,
                  more: str = "play more streams") -> tuple:
    """Returns one goal line, left unjudged (None) when its sample is under `least`."""
    if enough:
        return name, met, figure
    return name, None, f"{figure} (under {least}: too few to judge; {more})"
