"""Realism: the simulated users' swipe habits beside real people's (``--realism DIR``).

Each swipe of the SHREC'17 train split's people (`real_habits`) and of simulated users
(`simulated_habits`) is cut out by the service's own segmenter and measured the same way
(`habits`): its length, palm roll, where it starts, duration, peak speed, the shape of its
speed profile, its bow, and the strokes around it (a return after it, a preparation before
it). Printed side by side: every habit's median [10th, 90th percentile] (`print_realism`), how
much length, speed and duration differ within a person and between people (`print_spread`),
each way's length and speed (`by_way`), how each way's path leaves its line
(`print_geometry`), and peak speed by length with the speed gates off (`ungated`,
`print_speed_by_length`); `plot_realism` draws the habits (``--plot DIR``:
``DIR/realism.png``). The simulated users' constants (`cbgo.simuser.user`) are fitted on
these tables, on the train split's people only.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from cbgo.services.dynamic_gesture.classifier import path_of
from cbgo.services.dynamic_gesture.stroke import REVERSE_MIN_MM, Segmenter, reverses
from cbgo.simuser.motion import CENTRE_MM
from cbgo.simuser.user import SWIPE_WAY_LENGTH, SimulatedUser, swipe_way
from cbgo_tools.data import shrec
from cbgo_tools.dynamic_gesture import simdata

HABITS = ("length_mm", "roll_deg", "roll_across_deg", "start_along", "duration_s", "peak_mm_s",
          "peak_over_mean", "bow", "returned", "return_speed_ratio", "return_length_ratio",
          "over_preparation")
FORWARD = np.array([0.0, 0.0, -1.0])
"""Away from the person, over a desk sensor (the Leap frame's z points at the person)."""
GEOMETRY = ("arc_sideways", "drift_sideways", "arc_forward", "drift_forward")
"""How a swipe's path leaves its direction, in units of its length (`geometry`), on the axes
`swipe_sideways` and `FORWARD`: printed by way (`print_geometry`)."""
NEIGHBOUR_S = 1.5
"""A stroke this soon after a swipe is its return, this soon before it its preparation
(`habits`)."""


def habits(windows: list, truths: list[str], middle: np.ndarray, roll_scale: float,
           end_t: float = np.inf) -> list[dict]:
    """Measures each swipe stroke of one recording, the way real and simulated are compared.

    Per final window labelled a swipe: its length along the swipe's direction, the palm roll
    over it (and again for swipes across the body only: a right hand's to the left, a left
    hand's to the right), where it started along its direction relative to `middle` (the
    recording's median palm position) in units of its length, its duration and peak speed, how
    peaked its speed profile is (that peak speed over the mean speed along its path), its bow
    (largest sideways deviation / length), and whether a stroke followed it within
    `NEIGHBOUR_S` (a return) and that stroke's peak speed relative to it; when that stroke
    reverses it (`reverses`), how far it went relative to the swipe, and when a stroke within
    `NEIGHBOUR_S` before the swipe reverses it (a preparation), how much farther the swipe
    went: what `ReturnFilter.farther` is chosen on. Whether a swipe was followed is left
    unknown (NaN) when the recording ends (``end_t``, the time of its last frame) sooner than
    `NEIGHBOUR_S` after it, whatever followed: recordings cut after the swipe would otherwise
    count as people who never return, and counting only the returns they show would count
    too many.
    """
    finals = [(w, t) for w, t in zip(windows, truths, strict=True) if w.final]
    out = []
    for i, (w, truth) in enumerate(finals):
        if truth not in shrec.SWIPE_DIRECTIONS:
            continue
        d = np.asarray(shrec.SWIPE_DIRECTIONS[truth])
        xyz = w.obs[:, :3]
        length = max(float(xyz[-1] @ d), 1.0)
        start = w.origin if w.origin is not None else middle
        after = [v for v, _ in finals[i + 1:] if v.t_start - w.t_end <= NEIGHBOUR_S]
        before = [v for v, _ in finals[:i] if w.t_start - v.t_end <= NEIGHBOUR_S][-1:]
        # known only where the recording lasts long enough to show a return, whether or not
        # one came: keeping the short recordings that do show one would bias the share up
        seen_after = end_t - w.t_end >= NEIGHBOUR_S
        roll = float(np.degrees(w.obs[-1, 3] / roll_scale))
        way = swipe_way(truth, w.side)
        out.append({"way": way, "length_mm": length, "roll_deg": roll,
                    "roll_across_deg": roll if way == "across" else np.nan,
                    "start_along": float((start - middle) @ d / length),
                    "duration_s": w.t_end - w.t_start, "peak_mm_s": w.peak_speed,
                    "peak_over_mean": w.peak_speed / _mean_speed(w),
                    "bow": float(np.abs(xyz - np.outer(xyz @ d, d)).max() / length),
                    "returned": float(bool(after)) if seen_after else np.nan,
                    "return_speed_ratio": (after[0].peak_speed / max(w.peak_speed, 1.0)
                                           if after else np.nan),
                    "return_length_ratio": _length_ratio(after[:1], w),
                    "over_preparation": 1.0 / _length_ratio(before, w),
                    **geometry(xyz, length, swipe_sideways(truth, w.side))})
    return out


def swipe_sideways(swipe: str, side: str) -> np.ndarray:
    """Returns the axis in the sensor's plane across a swipe made by a `side` hand.

    Up for a swipe left or right, medial (towards the body's midline: -x for a right hand) for
    a swipe up or down, so that a left hand's swipes are measured as a right hand's mirror
    image.
    """
    if swipe_way(swipe, side) in ("across", "outward"):
        return np.array([0.0, 1.0, 0.0])
    return np.array([-1.0 if side == "right" else 1.0, 0.0, 0.0])


def geometry(xyz: np.ndarray, length: float, sideways: np.ndarray) -> dict:
    """Returns how a swipe's path (n, 3), relative to its start, leaves its direction.

    On the `sideways` axis and on `FORWARD`, in units of the swipe's `length`: ``drift_*``,
    where it ends; ``arc_*``, its farthest signed deviation from the straight line between its
    ends (a path bowed forward in its middle has ``arc_forward`` > 0).
    """
    chord = xyz[-1] / max(float(np.linalg.norm(xyz[-1])), 1e-9)
    off_chord = xyz - np.outer(xyz @ chord, chord)
    out = {}
    for name, axis in (("sideways", sideways), ("forward", FORWARD)):
        deviation = off_chord @ axis
        out[f"arc_{name}"] = float(deviation[np.argmax(np.abs(deviation))] / length)
        out[f"drift_{name}"] = float(xyz[-1] @ axis / length)
    return out


def by_way(real: list[dict], simulated: list[dict]) -> dict:
    """Prints each way's median length and peak speed, real beside simulated; returns them.

    Real people swipe across the body farther than outward, and up and down shorter: the
    benches' users must, or their vertical swipes are too long and slow for their length.
    """
    def medians(rows: list[dict], way: str) -> dict:
        mine = [r for r in rows if r["way"] == way]
        return {"swipes": len(mine),
                **{name: float(np.median([r[name] for r in mine])) if mine else np.nan
                   for name in ("length_mm", "peak_mm_s", "duration_s")}}

    table = {way: {"real": medians(real, way), "simulated": medians(simulated, way)}
             for way in SWIPE_WAY_LENGTH}
    print(f"\n{'by way (medians)':<18}{'real: n, length, peak, duration':>40}{'simulated':>40}")
    for way, sets in table.items():
        print(f"{way:<18}" + "".join(
            f"{m['swipes']:>14d}{m['length_mm']:>8.0f} mm{m['peak_mm_s']:>6.0f} mm/s"
            f"{m['duration_s']:>6.2f} s" for m in sets.values()))
    return table


def print_geometry(real: list[dict], simulated: list[dict]) -> dict:
    """Prints each way's `GEOMETRY`, real beside simulated (median [10th, 90th percentile]).

    Real swipes are no straight lines: they bow forward (away from the person) in their
    middle and end off their direction, each way its own way. The simulated users' swipes bow
    only in the sensor's plane (docs/design/dynamic_gesture.md, "Simulated users": why they
    stay so).
    """
    def spread(rows: list[dict], way: str, name: str) -> list[float]:
        values = np.array([r[name] for r in rows if r["way"] == way], dtype=float)
        return [float(np.percentile(values, q)) for q in (50, 10, 90)] if len(values) else []

    table = {way: {name: {"real": spread(real, way, name),
                          "simulated": spread(simulated, way, name)} for name in GEOMETRY}
             for way in SWIPE_WAY_LENGTH}
    print(f"\n{'geometry by way':<26}{'real: median [p10, p90]':>24}{'simulated':>24}"
          "   (lengths; sideways: up across, medial up/down)")
    for way, names in table.items():
        for name, sets in names.items():
            print(f"{way + ' ' + name:<26}" + "".join(
                f"{v[0]:>9.2f} [{v[1]:>5.2f},{v[2]:>5.2f}]" if v else f"{'-':>24}"
                for v in sets.values()))
    return table


def _mean_speed(window) -> float:
    """Returns the palm's mean speed along its path over a window, mm/s."""
    return max(path_of(window.obs[:, :3]) / max(window.t_end - window.t_start, 1e-3), 1.0)


def _length_ratio(other: list, swipe) -> float:
    """How far `other` (a one-window list) went in space relative to `swipe`, if it reverses it.

    NaN when there is no such window, or it does not reverse the swipe (`stroke.reverses`:
    the cosine of their displacements below `REVERSE_COS_MAX`, as the return filter judges),
    or it moved less than `REVERSE_MIN_MM`.
    """
    if not other:
        return np.nan
    a = other[0].obs[-1] - other[0].obs[0]
    b = swipe.obs[-1] - swipe.obs[0]
    length = float(np.linalg.norm(a[:3]))
    if length < REVERSE_MIN_MM or not reverses(a[:3], b[:3]):
        return np.nan
    return length / max(float(np.linalg.norm(b[:3])), 1.0)


def real_habits(root: Path, split: str, config) -> list[dict]:
    """Returns `habits` of every swipe of a split's people."""
    out = []
    for seq in shrec.read_split(root, split, shrec.SWIPES):
        segmenter = Segmenter(config)
        windows = shrec.segment(seq, segmenter)
        palms = seq.joints()[:, 1] * 1000.0 + shrec.DEFAULT_OFFSET_MM
        rows = habits(windows, shrec.label_windows(seq.name, windows), np.median(palms, 0),
                      segmenter.config.roll_scale_mm_per_rad, (len(palms) - 1) / shrec.RATE_HZ)
        out += [row | {"person": str(seq.person)} for row in rows]
    return out


def simulated_habits(users: int, seed: int, config,
                     ranges: simdata.StyleRanges = simdata.TRAIN) -> list[dict]:
    """Returns `habits` of simulated users' swipes, users drawn from `ranges`."""
    out = []
    swipes = tuple(shrec.SWIPE_DIRECTIONS)
    for user_seed in range(seed, seed + users):
        scenario = simdata.user_scenario(user_seed, ranges, 3, statics=False,
                                         gestures=swipes)
        frames = list(SimulatedUser(scenario, 60.0).frames())
        segmenter = Segmenter(config)
        windows = [w for f in frames for w in segmenter.update(f.t, f.hands)]
        times = np.array([f.t for f in frames])
        truths = [simdata.truth_of(w, times, [f.label for f in frames]) for w in windows]
        rows = habits(windows, truths, CENTRE_MM, segmenter.config.roll_scale_mm_per_rad,
                      float(times[-1]))
        out += [row | {"person": next(iter(scenario.users))} for row in rows]
    return out


SHARE_HABITS = ("returned",)
"""Habits that are yes or no: printed and drawn as the share of swipes, not as percentiles."""


def known_values(rows: list[dict], name: str) -> np.ndarray:
    """Returns one habit's values over the swipes it is known for (NaN: unknown)."""
    values = np.array([r[name] for r in rows], dtype=float)
    return values[np.isfinite(values)]


def print_realism(real: list[dict], simulated: list[dict]) -> dict:
    """Prints the habits side by side (median [10th, 90th percentile]); returns them.

    A yes/no habit (`SHARE_HABITS`) is given as its share of the swipes it is known for and
    their number, in the places of the median and the 10th percentile (its percentiles would
    only say 0 or 1). Every other habit is followed by the number of swipes it is known for
    (a ratio to a return or a preparation only where the swipe has one).
    """
    table = {}
    print(f"\n{'swipe habit':<20}{'real (SHREC train)':>31}{'simulated':>31}")
    for name in HABITS:
        cells = []
        for rows in (real, simulated):
            values = known_values(rows, name)
            if name in SHARE_HABITS:
                cells.append([float(values.mean()) if len(values) else np.nan,
                              float(len(values)), np.nan])
            else:
                cells.append([float(np.median(values)), float(np.percentile(values, 10)),
                              float(np.percentile(values, 90)), float(len(values))]
                             if len(values) else [np.nan] * 3 + [0.0])
        table[name] = {"real": cells[0], "simulated": cells[1]}
        if name in SHARE_HABITS:
            print(f"{name + ' (share)':<20}" + "".join(f"{m:>10.2f} of {n:<18.0f}"
                                                        for m, n, _ in cells))
        else:
            print(f"{name:<20}" + "".join(f"{m:>10.2f} [{lo:6.2f},{hi:7.2f}] n {n:<3.0f}"
                                          for m, lo, hi, n in cells))
    print(f"{'strokes':<20}{len(real):>31}{len(simulated):>31}")
    return table


SPREAD_HABITS = ("length_mm", "duration_s", "peak_mm_s")
"""Habits whose spread is split between people and within a person (`person_spread`)."""


def person_spread(rows: list[dict], name: str) -> tuple[float, float]:
    """Returns how much a habit differs between people and from one swipe to the next.

    Both as standard deviations of its logarithm: between people, of each person's mean; within
    a person, pooled over people with two swipes or more. A simulated population can match the
    real one's overall spread with users who each swipe alike but differ from each other.
    """
    people: dict[str, list[float]] = {}
    for r in rows:
        if np.isfinite(r[name]) and r[name] > 0:
            people.setdefault(r.get("person", ""), []).append(float(np.log(r[name])))
    means = [np.mean(v) for v in people.values()]
    within = [np.var(v) for v in people.values() if len(v) > 1]
    return (float(np.std(means)) if len(means) > 1 else np.nan,
            float(np.sqrt(np.mean(within))) if within else np.nan)


def print_spread(real: list[dict], simulated: list[dict]) -> dict:
    """Prints `person_spread` of the `SPREAD_HABITS`, real beside simulated; returns them."""
    print(f"\n{'SD of the log':<20}{'real: between people, within':>31}{'simulated':>31}")
    table = {}
    for name in SPREAD_HABITS:
        table[name] = {"real": person_spread(real, name),
                       "simulated": person_spread(simulated, name)}
        print(f"{name:<20}" + "".join(f"{between:>21.3f}, {within:<8.3f}"
                                      for between, within in table[name].values()))
    return table


LENGTH_BANDS_MM = ((20, 70), (70, 100), (100, 140), (140, 200), (200, 400))
"""Swipe lengths (mm) over which `speed_by_length` compares peak speeds."""


def ungated(config):
    """Returns `config` with the speed gates off: every swipe counted, however slow.

    The realism table measures the swipes the service evaluates; whether a short swipe is too
    slow for the gates (`SegmenterConfig.min_peak_speed_mm_s`) is seen only with them off.
    """
    return replace(config, min_peak_speed_mm_s=0.0, mid_peak_speed_mm_s=0.0,
                   min_extent_mm=LENGTH_BANDS_MM[0][0])


def _band_speeds(rows: list[dict]) -> dict:
    """Returns, per `LENGTH_BANDS_MM` band, the share of swipes and their peak speeds."""
    length = np.array([r["length_mm"] for r in rows])
    peak = np.array([r["peak_mm_s"] for r in rows])
    out = {}
    for lo, hi in LENGTH_BANDS_MM:
        inside = (length >= lo) & (length < hi)
        if inside.any():
            out[f"{lo}-{hi}"] = {"share": float(inside.mean()),
                                 "peak_p10": float(np.percentile(peak[inside], 10)),
                                 "peak_p50": float(np.median(peak[inside])),
                                 "under_200": float(np.mean(peak[inside] < 200.0))}
    fit = (length >= LENGTH_BANDS_MM[0][0]) & (peak > 0)
    out["slope"] = float(np.polyfit(np.log(length[fit]), np.log(peak[fit]), 1)[0])
    return out


def print_speed_by_length(real: list[dict], simulated: list[dict]) -> dict:
    """Prints peak speed by swipe length, real beside simulated (habits of `ungated` runs).

    A short swipe is caught only if it is brisk enough for the segmenter's speed gate, so the
    benches' short simulated swipes must be as quick as real people's, not only their lengths
    and speeds apart. ``slope``: of log peak speed on log length, over all swipes.
    """
    table = {"real": _band_speeds(real), "simulated": _band_speeds(simulated)}
    def cell(c: dict | None) -> str:
        if c is None:
            return f"{'-':>36}"
        return (f"{c['share']:>12.2f}{c['peak_p10']:>8.0f}/{c['peak_p50']:<6.0f}"
                f"{c['under_200']:>9.2f}")

    print(f"\n{'peak speed by length':<26}{'real: share, p10/p50 mm/s, < 200':>36}"
          f"{'simulated':>36}")
    for band in (f"{lo}-{hi}" for lo, hi in LENGTH_BANDS_MM):
        print(f"{band + ' mm':<26}" + "".join(cell(table[k].get(band))
                                              for k in ("real", "simulated")))
    print(f"{'slope, log peak on log length':<26}{table['real']['slope']:>12.2f}"
          f"{table['simulated']['slope']:>36.2f}")
    return table


HABIT_WORDS = {"length_mm": "length along the swipe (mm)", "roll_deg": "palm roll (°)",
               "roll_across_deg": "palm roll, swiping across the body (°)",
               "start_along": "start along the swipe from the middle (lengths)",
               "duration_s": "duration (s)", "peak_mm_s": "peak speed (mm/s)",
               "peak_over_mean": "peak over mean speed", "bow": "bow (sideways / length)",
               "returned": f"followed by a stroke within {NEIGHBOUR_S:g} s",
               "return_speed_ratio": "return's peak speed / the swipe's",
               "return_length_ratio": "return's length / the swipe's",
               "over_preparation": "swipe's length / its preparation's"}
"""What each of `HABITS` is, as the realism figure labels it."""


def plot_realism(real: list[dict], simulated: list[dict], out: Path) -> Path:
    """Draws each habit's distribution, real beside simulated, as ``out/realism.png``.

    One panel per habit of `HABITS`: the two sets' histograms over common bins (each summing
    to 1, so sets of different sizes compare), their medians as lines; the yes/no habit
    (``returned``) as the two shares. What `print_realism` prints, to look at.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    sets = (("real (SHREC'17 train split)", real, "#4c72b0"),
            ("simulated users", simulated, "#dd8452"))
    fig, axes = plt.subplots(3, 4, figsize=(14, 9))
    for ax, name in zip(axes.flat, HABITS, strict=True):
        values = [known_values(rows, name) for _, rows, _ in sets]
        counts = [len(v) for v in values]
        partial = name not in SHARE_HABITS and counts != [len(real), len(simulated)]
        # a habit known for some swipes only (a return, a preparation) says for how many
        ax.set_title(HABIT_WORDS[name] + (f" (of {counts[0]} / {counts[1]})" if partial else ""),
                     fontsize=9)
        if name in SHARE_HABITS:
            shares = [float(v.mean()) if len(v) else 0.0 for v in values]
            ax.bar([0, 1], shares, color=[c for _, _, c in sets])
            ax.set_xticks([0, 1], [f"real\n(of {len(values[0])} swipes)",
                                   f"simulated\n(of {len(values[1])})"])
            ax.set_ylim(0, 1)
            continue
        both = np.concatenate(values)
        if not len(both):
            continue
        lo, hi = np.percentile(both, [1, 99])
        edges = np.linspace(lo, hi, 25) if hi > lo else np.linspace(lo - 0.5, lo + 0.5, 3)
        for (label, _, colour), v in zip(sets, values, strict=True):
            if len(v):
                ax.hist(np.clip(v, edges[0], edges[-1]), bins=edges, color=colour, alpha=0.5,
                        weights=np.full(len(v), 1.0 / len(v)), label=label)
                ax.axvline(float(np.median(v)), color=colour, lw=1.5)
        ax.tick_params(labelsize=8)
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(f"Swipe habits: real people ({len(real)} swipes) beside simulated users "
                 f"({len(simulated)}); lines: medians")
    fig.tight_layout()
    path = out / "realism.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
