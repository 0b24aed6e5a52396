"""Draw the paper's episode figure from a recording (``cbgo plot episode``).

The figure of one episode, after the paper's "episode graph" (gesture detection output of a
single episode), in three panels sharing the time axis (seconds from the episode's start):

1. gesture likelihoods: static probabilities per frame (solid, left legend) and dynamic window
   probabilities over their windows (dashed steps, right legend); "no gesture" classes are left
   out;
2. evidence: recomputed offline from the same messages with the service's evidence model
   (`evidence`, default settings unless given), with the threshold E_t;
3. hand visibility per side and the gesture activations (triggers), with the episode's start
   and end.

Triggers, start and end come from the recorded ``episode/event`` messages, and the title from
``episode/summary`` (g's leaders, focus, params) when the recording has them; without episode
events, episodes are segmented from the frames with the service's segmenter and triggers are
those of the recomputed evidence (the title says so).

Input: an MCAP file made by ``cbgo record`` with ``hands/frame``, ``gestures/static``,
``gestures/dynamic`` and (optionally) ``episode/event`` and ``episode/summary``.

Examples::

    cbgo record -o session.mcap --duration 30
    cbgo plot episode session.mcap -o episode.png                 # the first episode
    cbgo plot episode session.mcap --episode 2 -o third.png       # by index ...
    cbgo plot episode session.mcap --episode ep-20251121T101500-3fa2-0004 -o e.png  # ... or id
    cbgo plot episode session.mcap --list                         # the episodes in the file
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path

from cbgo.errors import RecordingError
from cbgo.evidence import Evidence, EvidenceSettings
from cbgo.recording import read_recording
from cbgo.services.episode.segmenter import Segmenter

SUFFIXES = ("hands/frame", "gestures/static", "gestures/dynamic", "episode/event",
            "episode/summary")
DEBOUNCE_S = 0.15
GAP_S = 0.1  # static samples farther apart than this are not joined by a line


@dataclass
class EpisodeSpan:
    """One episode found in a recording."""

    episode: str
    start: float
    end: float
    triggers: list[dict] = field(default_factory=list)
    summary: dict | None = None
    recomputed: bool = False


@dataclass
class Traffic:
    """The decoded messages of a recording that the figure needs, on the frames' clock."""

    frames: list[tuple[float, list[str]]] = field(default_factory=list)  # (ts, sides visible)
    static: list[tuple[float, str, dict]] = field(default_factory=list)
    dynamic: list[tuple[float, float, str, dict]] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    summaries: dict[str, dict] = field(default_factory=dict)


def load(path: str | Path, prefix: str | None = None) -> Traffic:
    """Reads a recording's frames, gesture messages, events and summaries.

    Raises:
        RecordingError: an unreadable or corrupt file.
    """
    out, frame_ts = Traffic(), {}
    keys = None if prefix is None else [f"{prefix}/{s}" for s in SUFFIXES]
    for rec in read_recording(path, keys):
        suffix = rec.key.split("/", 1)[-1] if prefix is None else rec.key[len(prefix) + 1:]
        m = rec.message
        if suffix == "hands/frame":
            frame_ts[m["seq"]] = m["ts"]
            out.frames.append((m["ts"], [h["side"] for h in m["hands"]]))
        elif suffix == "gestures/static":
            vector = dict(zip(m["names"], m["probs"], strict=True))
            out.static.append((frame_ts.get(m["seq"], m["ts"]), m["side"], vector))
        elif suffix == "gestures/dynamic":
            vector = dict(zip(m["names"], m["probs"], strict=True))
            out.dynamic.append((m["window"][0], m["window"][1], m["side"], vector))
        elif suffix == "episode/event":
            out.events.append(m)
        elif suffix == "episode/summary":
            out.summaries[m["episode"]] = m
    return out


def episodes(traffic: Traffic, settings: EvidenceSettings) -> list[EpisodeSpan]:
    """Returns the episodes of a recording: from its events, else segmented from its frames."""
    spans: dict[str, EpisodeSpan] = {}
    decided: dict[str, float] = {}
    for e in traffic.events:
        span = spans.setdefault(e["episode"], EpisodeSpan(e["episode"], e["ts"], e["ts"]))
        if e["kind"] == "start":
            span.start = e["ts"]
        elif e["kind"] == "trigger":
            span.triggers.append(e)
        else:
            decided[e["episode"]] = e["ts"]
    for span in spans.values():
        span.summary = traffic.summaries.get(span.episode)
        if span.summary is not None:
            span.end = span.summary["ended"]
        else:  # the last hand frame before the end decision
            until = decided.get(span.episode, float("inf"))
            span.end = max([span.start] + [t for t, sides in traffic.frames
                                           if sides and span.start <= t <= until])
    if spans:
        return sorted(spans.values(), key=lambda s: s.start)
    return _segment(traffic, settings)


def _segment(traffic: Traffic, settings: EvidenceSettings) -> list[EpisodeSpan]:
    seg, out = Segmenter(DEBOUNCE_S), []
    for ts, sides in traffic.frames:
        for b in seg.frame(ts, ts, bool(sides)):
            if b.kind == "start":
                out.append(EpisodeSpan(f"#{len(out)}", b.ts, b.ts, recomputed=True))
            else:
                out[-1].end = b.ts
    if seg.open:
        out[-1].end = seg.last_hand_ts
    for span in out:
        curves = evidence_curves(traffic, span, settings)
        span.triggers = [{"gesture": t.gesture, "ts": t.ts, "prob": t.prob}
                         for t in curves[2]]
    return out


def evidence_curves(traffic: Traffic, span: EpisodeSpan, settings: EvidenceSettings
                    ) -> tuple[list[float], dict[str, list[float]], list]:
    """Recomputes an episode's evidence, sampled at its frame times.

    Messages are fed in time order (static at their frame's time, dynamic at their window's
    end), as the service would have received them.

    Returns:
        (times, {gesture: evidence at each time}, the recomputed triggers).
    """
    ev = Evidence(settings)
    lo, hi = span.start, span.end + DEBOUNCE_S
    inputs = sorted([(t, 0, side, (None, v)) for t, side, v in traffic.static if lo <= t <= hi]
                    + [(t1, 1, side, (t0, v)) for t0, t1, side, v in traffic.dynamic
                       if lo <= t1 <= hi], key=lambda x: (x[0], x[1]))
    times = [t for t, _ in traffic.frames if lo - 0.5 <= t <= hi + 0.5]
    values: dict[str, list[float]] = {}
    i = 0
    for k, t in enumerate(times):
        while i < len(inputs) and inputs[i][0] <= t:
            when, kind, side, (t0, vector) = inputs[i]
            if kind == 0:
                ev.static(when, side, vector.keys(), vector.values())
            else:
                ev.dynamic((t0, when), side, vector.keys(), vector.values())
            i += 1
        for name in ev.names:
            values.setdefault(name, [0.0] * len(times))[k] = ev.value(name, t)
    return times, values, ev.triggers


def _colours(names: list[str]) -> dict[str, tuple]:
    from matplotlib import colormaps

    first, more = colormaps["tab10"], colormaps["tab20b"]  # ten distinct colours first
    return {n: first(i) if i < 10 else more((i - 10) % 20) for i, n in enumerate(names)}


def _title(span: EpisodeSpan) -> str:
    head = f"episode {span.episode}  ({span.end - span.start:.2f} s)"
    if span.summary is None:
        return head + ("\n(segmented from the frames; evidence and triggers recomputed)"
                       if span.recomputed else "")
    s = span.summary
    top = sorted(zip(s["gestures"]["probs"], s["gestures"]["names"], strict=True), reverse=True)
    g = ", ".join(f"{n} {p:.2f}" for p, n in top[:3] if p > 0) or "no trigger"
    focus = "none" if s["focus"] is None else (
        f"{s['focus_source']} ({', '.join(f'{v:.2f}' for v in s['focus'])})")
    params = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                       for k, v in s["params"].items()) or "none"
    return f"{head}, user {s['user']}\ng: {g} | focus: {focus} | params: {params}"


def draw(traffic: Traffic, span: EpisodeSpan, output: str | Path,
         settings: EvidenceSettings, margin_s: float = 0.5) -> Path:
    """Draws the figure of one episode into a PNG file; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0, lo, hi = span.start, span.start - margin_s, span.end + DEBOUNCE_S + margin_s
    none = set(settings.none_names)
    static = [(t, side, v) for t, side, v in traffic.static if lo <= t <= hi]
    dynamic = [w for w in traffic.dynamic if w[1] >= lo and w[0] <= hi]
    static_names = sorted({n for _, _, v in static for n, p in v.items() if n not in none
                           and p > 0.05}, key=lambda n: -max(v.get(n, 0) for _, _, v in static))
    dynamic_names = sorted({n for *_, v in dynamic for n, p in v.items() if n not in none
                            and p > 0.05})
    colour = _colours(static_names + [n for n in dynamic_names if n not in static_names])
    times, evidence, recomputed = evidence_curves(traffic, span, settings)
    fig, (ax1, ax2, ax3) = plt.subplots(3, 1, figsize=(11, 8.5), sharex=True,
                                        gridspec_kw={"height_ratios": [3, 2, 1.3]})
    _likelihoods(ax1, static, dynamic, static_names, dynamic_names, colour, t0)
    _evidence(ax2, times, evidence, colour, settings.threshold, t0)
    triggers = span.triggers if not span.recomputed else [
        {"gesture": t.gesture, "ts": t.ts} for t in recomputed]
    _visibility(ax3, traffic, span, triggers, colour, lo, hi)
    for ax in (ax1, ax2, ax3):
        for trig in triggers:
            ax.axvline(trig["ts"] - t0, color=colour.get(trig["gesture"], "k"), lw=1.2,
                       ls=":", alpha=0.9)
        ax.grid(alpha=0.3)
    ax3.set_xlim(lo - t0, hi - t0)
    ax3.set_xlabel("time since the episode's start [s]")
    fig.suptitle(_title(span), fontsize=10)
    fig.tight_layout()
    output = Path(output)
    fig.savefig(output, dpi=110)
    plt.close(fig)
    return output


def _likelihoods(ax, static, dynamic, static_names, dynamic_names, colour, t0) -> None:
    for name in static_names:
        xs, ys, last = [], [], None
        for t, _, v in static:
            if last is not None and t - last > GAP_S:  # no line across tracking gaps
                xs.append(float("nan"))
                ys.append(float("nan"))
            xs.append(t - t0)
            ys.append(v.get(name, 0.0))
            last = t
        ax.plot(xs, ys, color=colour[name], lw=1.4, label=name)
    ax.set_ylim(-0.02, 1.05)
    ax.set_ylabel("likelihood")
    ax.set_title("gestures: static (left legend), dynamic windows (right legend)", fontsize=9)
    if static_names:
        ax.add_artist(ax.legend(loc="upper left", fontsize=8, title="static", title_fontsize=8))
    handles = []
    for name in dynamic_names:
        for t_start, t_end, _, v in dynamic:
            (line,) = ax.plot([t_start - t0, t_end - t0], [v.get(name, 0.0)] * 2,
                              color=colour[name], lw=2.2, ls="--", label=name)
        handles.append(line)
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize=8, title="dynamic",
                  title_fontsize=8)


def _evidence(ax, times, evidence, colour, threshold, t0) -> None:
    for name, values in evidence.items():
        if max(values, default=0.0) > 0.05:
            ax.plot([t - t0 for t in times], values, color=colour.get(name, "grey"), lw=1.2)
    ax.axhline(threshold, color="k", ls="--", lw=1.0)
    ax.text(0.995, threshold, f"E_t = {threshold:g}", transform=ax.get_yaxis_transform(),
            ha="right", va="bottom", fontsize=8)
    ax.set_ylim(-0.02, 1.05)
    ax.set_ylabel("evidence")


def _visibility(ax, traffic, span, triggers, colour, lo, hi) -> None:
    t0 = span.start
    frames = [(t, sides) for t, sides in traffic.frames if lo <= t <= hi]
    for row, side in enumerate(("left", "right")):
        xs = [t - t0 for t, _ in frames]
        ys = [row + (0.8 if side in sides else 0.0) for _, sides in frames]
        ax.fill_between(xs, row, ys, step="post", color="tab:gray" if row else "tab:brown",
                        alpha=0.5, lw=0)
    ax.set_yticks([0.4, 1.4], ["left hand", "right hand"])
    ax.set_ylim(-0.1, 2.6)
    for trig in triggers:
        ax.annotate(trig["gesture"], (trig["ts"] - t0, 2.0), fontsize=8, ha="center",
                    color=colour.get(trig["gesture"], "k"), fontweight="bold")
    for when, label in ((span.start, "start"), (span.end, "end")):
        ax.axvline(when - t0, color="k", lw=1.0)
        ax.annotate(label, (when - t0, 2.35), fontsize=7, ha="center")
    ax.set_title("hand visibility and gesture activations", fontsize=9)


# ============================================================================ CLI


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the figure's flags."""
    parser.add_argument("file", metavar="FILE.mcap", help="a recording made by cbgo record")
    parser.add_argument("--episode", default="0",
                        help="episode id, or its index in the file (0 = first, -1 = last) [0]")
    parser.add_argument("-o", "--output", default="episode.png", metavar="OUT.png",
                        help="the PNG to write [episode.png]")
    parser.add_argument("--list", action="store_true", help="list the episodes and exit")
    parser.add_argument("--prefix", default=None,
                        help="the key prefix of the recording (default: any)")
    parser.add_argument("--threshold", type=float, default=EvidenceSettings.threshold,
                        help="E_t of the recomputed evidence")
    parser.add_argument("--margin-s", type=float, default=0.5,
                        help="time shown before and after the episode, s [0.5]")


def _pick(spans: list[EpisodeSpan], which: str) -> EpisodeSpan:
    for span in spans:
        if span.episode == which:
            return span
    try:
        return spans[int(which)]
    except (ValueError, IndexError):
        known = ", ".join(s.episode for s in spans[:10])
        raise RecordingError(f"no episode {which!r} in the recording ({len(spans)} episodes: "
                             f"{known}{' ...' if len(spans) > 10 else ''})") from None


def run(args: argparse.Namespace) -> int:
    """Draws (or lists) the episodes of a recording."""
    settings = EvidenceSettings(threshold=args.threshold)
    try:
        traffic = load(args.file, args.prefix)
        spans = episodes(traffic, settings)
        if args.list:
            for i, s in enumerate(spans):
                print(f"{i:>3}  {s.episode}  {s.end - s.start:6.2f} s  triggers: "
                      f"{', '.join(t['gesture'] for t in s.triggers) or '-'}")
            return 0
        if not spans:
            raise RecordingError(f"{args.file}: no episode (no frame with a hand)")
        path = draw(traffic, _pick(spans, args.episode), args.output, settings, args.margin_s)
    except RecordingError as e:
        print(f"cbgo plot episode: {e}", file=sys.stderr)
        return 1
    print(f"wrote {path}")
    return 0
