"""Labelled stroke windows from simulated users, for training, calibration and the benchmark.

Every window is produced exactly as the service produces it: a simulated user
(`cbgo.simuser`) performs episodes frame by frame (the kinematic hand, tremor, its palm normal
and direction), and the `stroke.Segmenter` cuts the frames into windows. Ground truth comes from
the simulator's per-frame label: a window is gesture g when most of its frames are labelled g
(a stroke of g), else ``none`` (a static pose being formed, a roll back after rotate, ...).
Strokes that the segmenter never closes are counted as missed.

Users differ in style (speed, stroke size, curvature, tremor, hand size, side, roll angle),
drawn from `StyleRanges`. `TRAIN` is the range the default templates are learned and calibrated
in; `HELD_OUT` lies outside it on every axis (slower and faster, smaller and larger, more bowed,
shakier), for the benchmark. Each user's episodes mix the dynamic gestures in random order with
static poses, so that the non-gesture motions a real session has are there too.
"""

from __future__ import annotations

import multiprocessing
from dataclasses import dataclass, field

import numpy as np

from cbgo.services.dynamic_gesture.stroke import (
    DT,
    ReturnFilter,
    Segmenter,
    SegmenterConfig,
    Window,
)
from cbgo.simuser.scenario import IDLE_MOTIONS, Episode, GestureStep, Scenario, UserStyle
from cbgo.simuser.user import SimulatedUser
from cbgo.wire import DYNAMIC_GESTURES, STATIC_GESTURES

Interval = tuple[float, float]


@dataclass(frozen=True)
class StyleRanges:
    """Where user styles are drawn from: each field a tuple of intervals (one is picked)."""

    speed: tuple[Interval, ...]
    amplitude: tuple[Interval, ...]
    curvature: tuple[Interval, ...]
    tremor_mm: tuple[Interval, ...]
    hand_scale: tuple[Interval, ...]
    angle_deg: tuple[Interval, ...]
    left_share: float = 0.3
    # Stroke habits (`UserStyle`), spread around what the real train split's people do.
    stroke_lead: tuple[Interval, ...] = ((0.2, 0.8),)
    rest_s: tuple[Interval, ...] = ((0.0, 0.3),)
    swipe_roll_deg: tuple[Interval, ...] = ((15.0, 60.0),)
    medial_roll_deg: tuple[Interval, ...] = ((30.0, 70.0),)
    return_slowdown: tuple[Interval, ...] = ((0.6, 1.4),)
    length_spread: tuple[Interval, ...] = ((0.25, 0.5),)
    rotate_drift_mm: tuple[Interval, ...] = ((0.0, 40.0),)

    def draw(self, rng: np.random.Generator, name: str) -> tuple[UserStyle, tuple[float, float]]:
        """Returns a user style and the (low, high) roll angles of its rotate strokes."""
        def pick(intervals: tuple[Interval, ...]) -> float:
            lo, hi = intervals[rng.integers(len(intervals))]
            return float(rng.uniform(lo, hi))

        style = UserStyle(hand_scale=pick(self.hand_scale),
                          side="left" if rng.random() < self.left_share else "right",
                          speed=pick(self.speed), amplitude=pick(self.amplitude),
                          curvature=pick(self.curvature), tremor_mm=pick(self.tremor_mm),
                          stroke_lead=pick(self.stroke_lead), rest_s=pick(self.rest_s),
                          swipe_roll_deg=pick(self.swipe_roll_deg),
                          medial_roll_deg=pick(self.medial_roll_deg),
                          return_slowdown=pick(self.return_slowdown),
                          length_spread=pick(self.length_spread))
        angle = pick(self.angle_deg)
        style.rotate_drift_mm = pick(self.rotate_drift_mm)
        return style, (angle * 0.93, angle * 1.07)

    def quarter(self, style: UserStyle) -> str:
        """Returns "small" or "large", "slow" or "fast": a user's stroke size and speed.

        Each against the middle of the span these ranges draw it from. The users of the
        extremes fail for different reasons, so the benches score them apart.
        """
        def half(value: float, intervals: tuple[Interval, ...], low: str, high: str) -> str:
            lowest, highest = min(lo for lo, _ in intervals), max(hi for _, hi in intervals)
            if lowest == highest:
                return "typical"  # one value drawn (`default_style_ranges`)
            return low if value < (lowest + highest) / 2 else high

        return (f"{half(style.amplitude, self.amplitude, 'small', 'large')}/"
                f"{half(style.speed, self.speed, 'slow', 'fast')}")


TRAIN = StyleRanges(speed=((0.85, 1.6),), amplitude=((0.75, 1.5),), curvature=((0.0, 0.3),),
                    tremor_mm=((0.3, 1.2),), hand_scale=((0.85, 1.15),),
                    angle_deg=((75.0, 105.0),))
HELD_OUT = StyleRanges(speed=((0.7, 0.85), (1.6, 1.9)), amplitude=((0.55, 0.75), (1.5, 1.8)),
                       curvature=((0.3, 0.4),), tremor_mm=((1.2, 2.0),),
                       hand_scale=((0.75, 0.85), (1.15, 1.25)),
                       angle_deg=((60.0, 75.0), (105.0, 120.0)))


def default_style_ranges() -> StyleRanges:
    """Returns ranges that draw only `UserStyle()`, a right hand.

    What a scenario file's user is unless it says otherwise; its swipes still vary in length,
    and its rotates in angle, as any user's.
    """
    typical = UserStyle()

    def only(name: str) -> tuple[Interval, ...]:
        value = float(getattr(typical, name))
        return ((value, value),)

    habits = ("stroke_lead", "rest_s", "swipe_roll_deg", "medial_roll_deg", "return_slowdown",
              "length_spread", "rotate_drift_mm")
    return StyleRanges(speed=only("speed"), amplitude=only("amplitude"),
                       curvature=only("curvature"), tremor_mm=only("tremor_mm"),
                       hand_scale=only("hand_scale"), angle_deg=TRAIN.angle_deg,
                       left_share=0.0, **{name: only(name) for name in habits})


RANGES = {"train": TRAIN, "held-out": HELD_OUT, "default": default_style_ranges()}


@dataclass
class Labelled:
    """A window and its ground truth."""

    window: Window
    truth: str  # a dynamic gesture or "none"


@dataclass
class UserData:
    """What one simulated user produced."""

    user: str
    style: dict
    windows: list[Labelled] = field(default_factory=list)
    strokes: list[tuple[str, float, float]] = field(default_factory=list)  # true strokes
    missed: list[tuple[str, float, float]] = field(default_factory=list)  # not caught


def user_scenario(seed: int, ranges: StyleRanges, reps: int, statics: bool = True,
                  gestures: tuple[str, ...] = DYNAMIC_GESTURES, idle: bool = True) -> Scenario:
    """Returns one user's session: `reps` episodes, each every gesture once, shuffled.

    With `statics`, each episode also holds one or two static poses between the strokes; with
    `idle`, one or two idle motions (drift, wobble, slow re-positioning, a slow palm turn).
    """
    rng = np.random.default_rng(seed)
    name = f"user{seed}"
    style, (angle_lo, angle_hi) = ranges.draw(rng, name)
    episodes = []
    for _ in range(reps):
        steps = [GestureStep(g, angle_deg=float(rng.uniform(angle_lo, angle_hi)))
                 for g in rng.permutation(gestures)]
        if statics:
            for pose in rng.choice(STATIC_GESTURES, size=int(rng.integers(1, 3)), replace=False):
                steps.insert(int(rng.integers(len(steps) + 1)), GestureStep(str(pose)))
        if idle:
            for motion in rng.choice(IDLE_MOTIONS, size=int(rng.integers(1, 3)), replace=False):
                steps.insert(int(rng.integers(len(steps) + 1)), GestureStep(str(motion)))
        episodes.append(Episode(gestures=steps, pause_s=0.3))
    return Scenario(episodes=episodes, users={name: style}, name=name, seed=seed)


def without_returns(windows: list[Labelled], within_s: float) -> list[Labelled]:
    """Returns the windows the service reports: those of return moves dropped.

    The service's `stroke.ReturnFilter` judges "the gesture just made" by its classification;
    here the truth stands in for it.
    """
    returns = ReturnFilter(within_s)
    kept = []
    for lw in windows:
        if not returns.is_return(lw.window):
            returns.observe(lw.window, 1.0 if lw.truth != "none" else 0.0)
            kept.append(lw)
    return kept


def truth_of(window: Window, times: np.ndarray, labels: list[str | None]) -> str:
    """Returns the majority label of the frames in a window (non-dynamic labels are none)."""
    lo = np.searchsorted(times, window.t_start - DT / 2)
    hi = np.searchsorted(times, window.t_end, side="right")
    names = [lab if lab in DYNAMIC_GESTURES else "none" for lab in labels[lo:hi]]
    if not names:
        return "none"
    values, counts = np.unique(names, return_counts=True)
    return str(values[counts.argmax()])


def true_strokes(times: np.ndarray, labels: list[str | None], gap_s: float = 0.5
                 ) -> list[tuple[str, float, float]]:
    """Returns (gesture, t_start, t_end) of each stroke in per-frame labels.

    A stroke is a run of frames labelled with one dynamic gesture; runs of the same gesture
    less than `gap_s` apart are one stroke (the hand flickering at the field's border).
    """
    out: list[list] = []
    for t, lab in zip(times, labels, strict=True):
        if lab not in DYNAMIC_GESTURES:
            continue
        if out and out[-1][0] == lab and t - out[-1][2] <= gap_s:
            out[-1][2] = t
        else:
            out.append([lab, t, t])
    return [tuple(run) for run in out]


def run_user(seed: int, ranges: StyleRanges, reps: int, rate_hz: float = 60.0,
             statics: bool = True, config: SegmenterConfig | None = None) -> UserData:
    """Simulates one user's session and segments it; returns labelled windows."""
    scenario = user_scenario(seed, ranges, reps, statics)
    segmenter = Segmenter(config)
    frames = list(SimulatedUser(scenario, rate_hz).frames())
    times = np.array([f.t for f in frames])
    labels = [f.label for f in frames]
    windows = [w for f in frames for w in segmenter.update(f.t, f.hands)]
    style = vars(next(iter(scenario.users.values())))
    data = UserData(scenario.name, dict(style))
    data.windows = without_returns([Labelled(w, truth_of(w, times, labels)) for w in windows],
                                   segmenter.config.return_s)
    data.strokes = true_strokes(times, labels)
    finals = [lw for lw in data.windows if lw.window.final]
    for gesture, t0, t1 in data.strokes:
        if not any(lw.truth == gesture and lw.window.t_start <= t1 and lw.window.t_end >= t0
                   for lw in finals):
            data.missed.append((gesture, t0, t1))
    return data


def _run_user_args(args: tuple) -> UserData:
    return run_user(*args)


def generate(seeds: list[int], ranges: StyleRanges, reps: int, jobs: int = 1,
             rate_hz: float = 60.0, statics: bool = True,
             config: SegmenterConfig | None = None) -> list[UserData]:
    """Simulates several users, in `jobs` processes (spawned, so safe next to Zenoh)."""
    work = [(seed, ranges, reps, rate_hz, statics, config) for seed in seeds]
    if jobs <= 1:
        return [_run_user_args(w) for w in work]
    with multiprocessing.get_context("spawn").Pool(jobs) as pool:
        return pool.map(_run_user_args, work)
