"""Plain strokes: a grid of textbook swipes and rotates, no simulated person's habits.

The simulated users are fitted to real people, so a bench of them is confirmed by the same
assumptions the library learned. These strokes assume nothing of the kind: each is one
minimum-jerk move of a right hand held palm down (`HandShape.default`, `neutral_pose`), of a
length and a duration taken from a grid, from a random place in the field, tilted off its
direction, bowed in and out of the sensor's plane, the palm rolling on the way. Before it the
hand drifts in slowly or rests; after it the hand holds, comes back more slowly and holds
again. A rotate rolls the palm by an angle from the grid while the palm drifts up to
`ROTATE_DRIFT_MM` any way, as a person's palm does when it turns. Each trial goes through the
service's segmenter, return filter and library offline (`bench.replay_trial`), as the live
service answers it.

What it shows is where, in length and duration, a stroke stops being heard: the slow-move
line (`SegmenterConfig.min_peak_speed_mm_s`) and the size below which a stroke is a twitch
or `none`. A minimum-jerk stroke of length L in T seconds peaks at 1.875 L / T.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections import Counter

import numpy as np

from cbgo.hands.model import HandShape, build_hand, neutral_pose
from cbgo.simuser.motion import min_jerk
from cbgo.simuser.user import SWIPE_DIRECTIONS
from cbgo_tools.dynamic_gesture import scoring, trials

RATE_HZ = 60.0
LENGTHS_MM = (60.0, 90.0, 130.0, 180.0, 250.0)
DURATIONS_S = (0.25, 0.4, 0.6, 0.8, 1.0)
ROTATE_DEG = (40.0, 60.0, 80.0, 100.0, 130.0)
"""A rotate's angle, one per `LENGTHS_MM` column (the grid's size axis)."""
TILT_DEG = 25.0  # a swipe's direction is off by up to this, in the sensor's plane
BOW = 0.2  # its middle bows up to this share of its length, sideways and in depth
ROLL_DEG = 45.0  # its palm rolls up to this and back on the way
ROTATE_DRIFT_MM = 40.0  # a rotate's palm drifts up to this far, any way, while it turns
DRIFT_MM_S = 60.0  # the hand drifting in before a stroke without rest ...
DRIFT_S = 0.4  # ... for this long
FIELD = (np.array([-160.0, 130.0, -90.0]), np.array([160.0, 370.0, 90.0]))
"""Where a stroke starts and ends: inside the field with a margin (Leap frame, mm)."""
GESTURES = (*SWIPE_DIRECTIONS, "rotate")


@dataclasses.dataclass(frozen=True)
class Stroke:
    """One plain stroke: what it is and how it goes (mm, s, rad)."""

    gesture: str
    size: float  # its length (mm) or, for a rotate, its angle (degrees)
    seconds: float
    start: np.ndarray
    displacement: np.ndarray
    bow: np.ndarray
    roll: float  # a rotate's angle, or how far a swipe's palm rolls on the way and back
    rest: bool  # rests before it, else drifts in


def draw(gesture: str, column: int, seconds: float, rest: bool, rng: np.random.Generator
         ) -> Stroke:
    """Returns a stroke of the grid's `column` size and `seconds`, the rest drawn at random."""
    if gesture == "rotate":
        start = rng.uniform(*FIELD)
        way = rng.normal(size=3)
        drift = rng.uniform(0.0, ROTATE_DRIFT_MM) * way / np.linalg.norm(way)
        return Stroke(gesture, ROTATE_DEG[column], seconds, start, drift, np.zeros(3),
                      float(np.radians(ROTATE_DEG[column])), rest)
    length = LENGTHS_MM[column]
    way = SWIPE_DIRECTIONS[gesture]
    across = np.array([way[1], -way[0], 0.0])
    tilt = np.radians(rng.uniform(-TILT_DEG, TILT_DEG))
    displacement = length * (np.cos(tilt) * way + np.sin(tilt) * across)
    bow = length * (rng.uniform(-BOW, BOW) * across + rng.uniform(-BOW, BOW) * np.array([0, 0, 1]))
    low, high = FIELD[0] - np.minimum(displacement, 0), FIELD[1] - np.maximum(displacement, 0)
    start = rng.uniform(low, np.maximum(high, low))
    return Stroke(gesture, length, seconds, start, displacement, bow,
                  float(np.radians(rng.uniform(-ROLL_DEG, ROLL_DEG))), rest)


def frames(stroke: Stroke, hand_id: int = 1) -> list[tuple[float, list[dict]]]:
    """Returns (time, hands) frames at `RATE_HZ`: lead-in, the stroke, hold, return, hold."""
    shape, pose = HandShape.default(), neutral_pose()
    palms, rolls = [], []

    def add(palm, roll) -> None:
        palms.append(np.asarray(palm, dtype=float))
        rolls.append(float(roll))

    if stroke.rest:
        for _ in range(int(0.3 * RATE_HZ)):
            add(stroke.start, 0.0)
    else:  # drifting in slowly, along the stroke's way (or up to a rotate)
        way = stroke.displacement if stroke.displacement.any() else np.array([0.0, 1.0, 0.0])
        step = way / np.linalg.norm(way) * DRIFT_MM_S / RATE_HZ
        for i in range(int(DRIFT_S * RATE_HZ), 0, -1):
            add(stroke.start - i * step, 0.0)
    s = min_jerk(np.arange(1, int(stroke.seconds * RATE_HZ) + 1) / (stroke.seconds * RATE_HZ))
    rotate = stroke.gesture == "rotate"
    for v in s:
        add(stroke.start + v * stroke.displacement + np.sin(np.pi * v) * stroke.bow,
            v * stroke.roll if rotate else np.sin(np.pi * v) * stroke.roll)
    end, end_roll = palms[-1], rolls[-1]
    for _ in range(int(0.25 * RATE_HZ)):
        add(end, end_roll)
    back = min_jerk(np.arange(1, int(1.5 * stroke.seconds * RATE_HZ) + 1)
                    / (1.5 * stroke.seconds * RATE_HZ))
    for v in back:
        add(end - 0.9 * v * stroke.displacement, (1.0 - v) * end_roll)
    for _ in range(int(0.3 * RATE_HZ)):
        add(palms[-1], 0.0)
    return [(i / RATE_HZ, [build_hand(shape, dataclasses.replace(pose, roll=roll), palm,
                                      hand_id=hand_id)])
            for i, (palm, roll) in enumerate(zip(palms, rolls, strict=True))]


def grid(reps: int, seed: int) -> list[Stroke]:
    """Returns every gesture × size × duration × (rest, drift) `reps` times, drawn by `seed`."""
    rng = np.random.default_rng(seed)
    return [draw(g, column, seconds, rest, rng)
            for g, column, seconds, rest, _ in itertools.product(
                GESTURES, range(len(LENGTHS_MM)), DURATIONS_S, (True, False), range(reps))]


def score(strokes: list[Stroke], classifier, config, replay, mirror: bool = False
          ) -> list[dict]:
    """Returns one row per stroke: its grid cell and the service's answers (`replay`).

    With `mirror`, each stroke is made by a left hand (`trials.mirrored_trial`: a swipe
    right becomes a swipe left, and is scored so).
    """
    rows = []
    for k, stroke in enumerate(strokes):
        trial = trials.Trial(stroke.gesture, stroke.gesture, f"plain-{k}", frames(stroke))
        if mirror:
            trial = trials.mirrored_trial(trial)
        rows.append(replay(classifier, trial, config) | {
            "size": stroke.size, "seconds": stroke.seconds, "rest": stroke.rest})
    return rows


def report(rows: list[dict], log=print) -> dict:
    """Prints recall by size and duration, how the misses were answered; returns the figures."""
    table: dict = {}
    log(f"\nplain strokes heard right by gestures/dynamic (any window), of {len(rows)}; "
        "rows: length (mm) / rotate angle (°), columns: duration (s)")
    for gesture in ("swipes", "rotate"):
        mine = [r for r in rows if (r["truth"] == "rotate") == (gesture == "rotate")]
        sizes = ROTATE_DEG if gesture == "rotate" else LENGTHS_MM
        log(f"{gesture:<8}" + "".join(f"{s:>9g} s" for s in DURATIONS_S))
        for size in sizes:
            cells = []
            for seconds in DURATIONS_S:
                cell = [r for r in mine if r["size"] == size and r["seconds"] == seconds]
                right = sum(r["dynamic"] == r["truth"] for r in cell)
                table[f"{gesture} {size:g} {seconds:g}"] = [right, len(cell)]
                cells.append(f"{right:>5d}/{len(cell):<4d}")
            log(f"{size:>8g}" + " ".join(cells))
    misses = [r for r in rows if r["dynamic"] != r["truth"]]
    answers = Counter("nothing" if r["dynamic"] == scoring.NOTHING else "another gesture"
                      for r in misses)
    rests = {rest: [r["dynamic"] == r["truth"] for r in rows if r["rest"] == rest]
             for rest in (True, False)}
    log(f"missed {len(misses)} of {len(rows)}: answered {dict(answers) or 'nothing'}; "
        f"after a rest {sum(rests[True])}/{len(rests[True])} right, drifting in "
        f"{sum(rests[False])}/{len(rests[False])}")
    return {"cells": table, "missed": len(misses), "miss_answers": dict(answers),
            "strokes": len(rows)}
