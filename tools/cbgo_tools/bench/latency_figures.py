"""The latency bench's figures: what was observed, per-episode records, measures, the table.

Pure bookkeeping on time stamps (no processes, no Zenoh): `cbgo_tools.bench.latency` runs the
pipeline and fills an `Observed`; this module turns it into records (`episode_record`),
figures (`measure`, `stage_durations`), the goals (`goals`), a tally and the printed table
(`report`). The measures are defined in `cbgo_tools.bench.latency`'s docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

MEASURES = ("end_condition_to_intent", "last_hand_frame_to_intent", "frame_to_static",
            "intent_to_first_robot_action")
STAGES = ("summary_stamped", "summary_received", "intent_stamped", "intent_received")


# ============================================================================ observations


@dataclass
class Frame:
    """What the bench keeps of one hand frame."""

    ts: float
    has_hand: bool
    received: float


@dataclass
class Observed:
    """Everything the bench's own subscriptions saw, with arrival times (one lock for all)."""

    frames: dict[int, Frame] = field(default_factory=dict)
    static: dict[int, float] = field(default_factory=dict)  # frame seq -> first arrival
    summaries: dict[str, tuple[float, dict]] = field(default_factory=dict)
    intents: dict[str, tuple[float, dict]] = field(default_factory=dict)
    plans: dict[str, tuple[float, dict]] = field(default_factory=dict)  # episode -> terminal
    robot_actions: list[float] = field(default_factory=list)  # robot/state ts, action set


@dataclass
class Run:
    """One played episode: what was asked and when."""

    index: int
    gesture: str
    expected: str
    played: float
    duration_s: float
    finished: float = 0.0
    reset_after: bool = False


# ============================================================================ measuring


def figures(values_s: list[float]) -> dict:
    """Returns n, p50, p90, p99, max, min in ms of a list of seconds."""
    ms = np.asarray(values_s, dtype=float) * 1e3
    if ms.size == 0:
        return {"n": 0}
    return {"n": int(ms.size), "p50": float(np.percentile(ms, 50)),
            "p90": float(np.percentile(ms, 90)), "p99": float(np.percentile(ms, 99)),
            "max": float(ms.max()), "min": float(ms.min())}


def episode_record(run: Run, next_played: float, seen: Observed, debounce_s: float,
                   first_act) -> dict:
    """Returns the time stamps and latencies (s) of one played episode, or why it was lost."""
    mine = sorted((s for _, s in seen.summaries.values()
                   if run.played <= s["started"] < next_played), key=lambda s: s["started"])
    record = {"index": run.index, "gesture": run.gesture, "expected": run.expected,
              "summaries": len(mine), "reset_after": run.reset_after}
    if not mine:
        return {**record, "lost": "no episode summary (no hand seen, or the episode service "
                                  "missed it)"}
    summary = mine[-1]
    if summary["episode"] not in seen.intents:
        return {**record, "episode": summary["episode"], "lost": "no intent for the summary"}
    summary_rx = seen.summaries[summary["episode"]][0]
    intent_rx, intent = seen.intents[summary["episode"]]
    last_hand = summary["ended"]
    end = last_hand + debounce_s
    record.update(
        episode=summary["episode"], lost=None, status=intent["status"],
        action=intent["action"], object=intent["object"], reason=intent["reason"],
        confidence=intent["confidence"],
        last_hand_ts=last_hand, end_condition=end, summary_ts=summary["ts"],
        summary_received=summary_rx, intent_ts=intent["ts"], intent_received=intent_rx,
        bench_last_hand_ts=_bench_last_hand(seen, summary))
    plan = seen.plans.get(summary["episode"])
    record["plan"] = plan[1]["state"] if plan else None
    record["plan_error"] = plan[1]["error"] if plan else None
    # Searched from the intent's own stamp: the bench's receipt could come after the planner's
    # first action if this process was held up; the latency is still taken from the receipt.
    act = first_act(intent["ts"], next_played) if intent["status"] == "accepted" else None
    record["first_robot_action"] = act
    return record


def _bench_last_hand(seen: Observed, summary: dict) -> float | None:
    """The last frame with a hand the bench itself saw within the summary's episode."""
    stamps = [f.ts for f in seen.frames.values()
              if f.has_hand and summary["started"] <= f.ts <= summary["ended"] + 1e-9]
    return max(stamps) if stamps else None


def static_latencies(seen: Observed, runs: list[Run]) -> tuple[list[float], int]:
    """Returns frame ts → static arrival (s) for the measured frames with a hand; and misses.

    Misses: frames with a hand that got no static message (dropped under load).
    """
    start, stop = runs[0].played, runs[-1].finished
    values, missing = [], 0
    for seq, frame in seen.frames.items():
        if frame.has_hand and start <= frame.ts <= stop:
            if seq in seen.static:
                values.append(seen.static[seq] - frame.ts)
            else:
                missing += 1
    return values, missing


def measure(records: list[dict], static: list[float], debounce_s: float) -> dict:
    """Returns the four measures and the stage breakdown (figures in ms)."""
    ok = [r for r in records if not r["lost"]]
    acted = [r for r in ok if r["first_robot_action"] is not None]
    out = {
        "end_condition_to_intent": figures([r["intent_received"] - r["end_condition"]
                                            for r in ok]),
        "last_hand_frame_to_intent": figures([r["intent_received"] - r["last_hand_ts"]
                                              for r in ok]),
        "frame_to_static": figures(static),
        "intent_to_first_robot_action": figures([r["first_robot_action"] - r["intent_received"]
                                                 for r in acted]),
    }
    stamps = {"summary_stamped": "summary_ts", "summary_received": "summary_received",
              "intent_stamped": "intent_ts", "intent_received": "intent_received"}
    breakdown = {stage: figures([r[field_] - r["end_condition"] for r in ok])
                 for stage, field_ in stamps.items()}
    return {"measures": out, "breakdown_from_end_condition": breakdown,
            "stages": stage_durations(ok)}


# (what happens, from which time stamp, to which) between the end condition and the intent
STAGE_SPANS = (
    ("episode: notices the end, builds the summary", "end_condition", "summary_ts"),
    ("summary: episode -> bench", "summary_ts", "summary_received"),
    ("intent: summary -> inference -> stamped", "summary_received", "intent_ts"),
    ("intent: intent -> bench", "intent_ts", "intent_received"),
)


def stage_durations(records: list[dict]) -> dict:
    """Returns the figures of each stage between the end condition and the intent's arrival.

    The summary's arrival at the bench stands in for its arrival at the intent service (both
    subscribe to the same publication through the same router), so the intent's stage may
    come out a fraction of a millisecond below zero: the intent service's copy arrived first.
    """
    return {name: figures([r[stop] - r[start] for r in records])
            for name, start, stop in STAGE_SPANS}


def goals(measures: dict, debounce_s: float) -> dict:
    """Returns, per measure, its goal as text and whether it was met (None: no goal)."""
    end, last = measures["end_condition_to_intent"], measures["last_hand_frame_to_intent"]
    limit = debounce_s * 1e3 + 20.0
    return {
        "end_condition_to_intent": {
            "goal": "p50 <= 20 ms, p99 <= 50 ms",
            "met": bool(end["n"]) and end["p50"] <= 20.0 and end["p99"] <= 50.0},
        "last_hand_frame_to_intent": {
            "goal": f"p50 <= debounce + 20 ms = {limit:g} ms",
            "met": bool(last["n"]) and last["p50"] <= limit},
        "frame_to_static": {"goal": None, "met": None},
        "intent_to_first_robot_action": {"goal": None, "met": None},
    }


def tally(records: list[dict]) -> dict:
    """Counts lost episodes by reason, intent statuses, unexpected actions, plan outcomes."""
    out = {"episodes": len(records), "lost": 0, "lost_reasons": {}, "status": {},
           "as_expected": 0, "unexpected": {}, "plans": {}, "split": 0, "resets": 0,
           "bench_saw_other_last_hand": 0}
    for r in records:
        out["resets"] += r["reset_after"]
        out["split"] += r["summaries"] > 1
        if r["lost"]:
            out["lost"] += 1
            out["lost_reasons"][r["lost"]] = out["lost_reasons"].get(r["lost"], 0) + 1
            continue
        _count(out["status"], f"{r['status']} {r['action']}({r['object'] or ''})"
                              + ("" if r["status"] == "accepted" else f": {r['reason']}"))
        if r["status"] == "accepted" and r["action"] == r["expected"]:
            out["as_expected"] += 1
        else:
            _count(out["unexpected"], f"{r['gesture']} -> {r['status']} {r['action']}"
                                      f"({r['object'] or ''})")
        _count(out["plans"], str(r["plan"]) + (f": {r['plan_error']}" if r["plan_error"] else ""))
        bench_view = r["bench_last_hand_ts"]
        if bench_view is None or abs(bench_view - r["last_hand_ts"]) > 1e-6:
            out["bench_saw_other_last_hand"] += 1
    return out


def _count(table: dict, key: str) -> None:
    table[key] = table.get(key, 0) + 1


# ============================================================================ printing


def _row(name: str, fig: dict, goal: dict | None = None) -> str:
    if not fig.get("n"):
        return f"  {name:<46} {'0':>5}  -"
    text = (f"  {name:<46} {fig['n']:>5} {fig['p50']:8.2f} {fig['p90']:8.2f} {fig['p99']:8.2f} "
            f"{fig['max']:8.2f}")
    if goal and goal["goal"]:
        text += f"   {goal['goal']}: {'met' if goal['met'] else 'MISSED'}"
    return text


def report(results: dict) -> str:
    """Returns the printed table of a results dict."""
    m, g = results["measures"], results["goals"]
    lines = [f"{'measure (ms)':<48} {'n':>5} {'p50':>8} {'p90':>8} {'p99':>8} {'max':>8}   goal"]
    lines += [_row(name.replace("_", " "), m[name], g[name]) for name in MEASURES]
    lines.append("where end condition -> intent goes, stage by stage (ms):")
    lines += [_row(f"  {stage}", fig) for stage, fig in results["stages"].items()]
    t = results["tally"]
    lines.append(f"episodes: {t['episodes']} measured, {t['lost']} lost"
                 + (f" {t['lost_reasons']}" if t["lost"] else "")
                 + f"; {t['as_expected']} as expected; intents {t['status']}")
    if t["unexpected"]:
        lines.append(f"unexpected intents: {t['unexpected']}")
    lines.append(f"plans: {t['plans']}; world resets: {t['resets']}; split episodes: "
                 f"{t['split']}; summaries whose last hand frame the bench saw differently: "
                 f"{t['bench_saw_other_last_hand']}")
    lines.append(f"frames with a hand without a static message: {results['static_missing']}")
    lines.append(f"robot: {results['robot']}; load average before {results['loadavg_before']}, "
                 f"after {results['loadavg_after']}")
    return "\n".join(lines)
