"""Printing the live and replayed benches' figures: `report_live`, `report_replay`.

Each scores the rows it is given (`scoring.score`) by every answer (``dynamic``: the most
probable reported gesture; ``finals``: the most probable final window; ``first``: the first
reported gesture; ``summary``: the episode summary's g, live only), prints the confusion and
recall, the simulated users' figures by style (`print_by_style`), the streams and the latency,
then the goals (`scoring.GOALS`), and writes the whole result as JSON when asked.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cbgo import metrics
from cbgo_tools.dynamic_gesture.scoring import (
    describe_streams,
    live_goals,
    score,
    stream_totals,
    trial_goals,
)


def report_live(result: dict, json_path: Path | None, log=print, synthetic: bool = False
                ) -> int:
    """Scores and prints what `live.play_live` collected; writes it to `json_path` if given.

    `synthetic`: the trials are simulated users' strokes, judged against the synthetic goal.
    """
    for field in ("dynamic", "finals", "first", "summary"):
        result[field] = score(result["trials"], field)
        _print_score(field, result[field])
    if synthetic:
        result["by_style"] = print_by_style(result["trials"], "dynamic")
    total = stream_totals(result["streams"])
    if total["strokes"]:
        log(f"\ncontinuous streams ({len(result['streams'])}, hand never leaves): "
            + describe_streams(total))
    stray = result.get("episode_stray") or {}
    if any(stray.values()):
        log(f"episode service: {stray.get('late', 0)} gesture messages arrived after their "
            f"episode had ended, {stray.get('outside', 0)} about no episode; no summary holds "
            f"them")
    lat = result["latency_ms"]
    if lat:
        log(f"latency stroke end -> last window arrives: p50 {lat['p50']:.0f} ms, p90 "
            f"{lat['p90']:.0f} ms, max {lat['max']:.0f} ms ({lat['strokes']} strokes)")
    result["goals"] = live_goals(result, total, synthetic)
    log("\ngoals (over the wire, real time):\n" + metrics.format_goals(result["goals"]))
    if json_path:
        json_path.write_text(json.dumps(result, indent=1))
    return 0


def report_replay(result: dict, json_path: Path | None, log=print) -> int:
    """Scores and prints simulated trials replayed offline (``bench --replay-sim``)."""
    for field in ("dynamic", "finals", "first"):
        result[field] = score(result["trials"], field)
        _print_score(field, result[field])
    result["by_style"] = print_by_style(result["trials"], "dynamic")
    result["goals"] = trial_goals(result, True, ("dynamic",))
    log("\ngoals (the service's logic offline, as it answers live; the episode "
        "summary needs --live-sim):\n" + metrics.format_goals(result["goals"]))
    if json_path:
        json_path.write_text(json.dumps(result, indent=1))
    return 0


def print_by_style(rows: list[dict], field: str) -> dict:
    """Prints and returns the share of simulated trials answered right per user style.

    A style is the user's stroke size and speed against the middle of the drawn ranges
    (`simdata.StyleRanges.quarter`): the held-out range's smallest, slowest users swipe as
    slowly as people re-position their hand, and one overall figure would hide that.
    """
    styles: dict[str, list[int]] = {}
    for r in rows:
        if r.get("style") and r["truth"] != "none":
            right = styles.setdefault(r["style"], [0, 0])
            right[0] += r[field] == r["truth"]
            right[1] += 1
    if styles:
        print("by the users' stroke size / speed (against the middle of their ranges): "
              + ", ".join(f"{name} {ok}/{n} = {ok / n:.1%}"
                          for name, (ok, n) in sorted(styles.items())))
    return {name: {"right": ok, "trials": n} for name, (ok, n) in styles.items()}


def _print_score(field: str, block: dict) -> None:
    where = {"dynamic": "gestures/dynamic (its most probable message)",
             "finals": "gestures/dynamic, final windows only (one answer per stroke)",
             "first": "gestures/dynamic, its first gesture (a consumer that acts at once)",
             "summary": "episode/summary g"}[field]
    print(f"\n{where}: balanced accuracy over {', '.join(block['recall'])} "
          f"{block['balanced_accuracy']:.1%}"
          f"{metrics.format_interval(block.get('interval'), block.get('people'))}")
    print(metrics.format_confusion(np.asarray(block["confusion"]), block["names"]))
    print("recall " + ", ".join(f"{n} {r:.0%}" for n, r in block["recall"].items()))
    if block["other_trials"]:
        print(f"other gestures (no swipe of ours): {block['other_false']} of "
              f"{block['other_trials']} trials reported a dynamic gesture")
