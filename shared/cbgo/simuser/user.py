"""The simulated user: a scenario performed with a kinematic hand, frame by frame.

Each episode follows how people use a Leap Motion for gestures (the paper's episode and stroke
notions): the hand is out of view, enters from the user's side, settles in the centre of the
field (preparation), performs its gestures — static poses are formed, held and released; a swipe
starts before the middle of the field (`UserStyle.stroke_lead`), after a short rest or none,
crosses the middle with the palm rolling as real palms do, and comes back a little more slowly,
often without stopping; rotate rolls the palm, the palm drifting a little — and leaves. The
stroke habits are fitted to real people's swipes (`cbgo bench dynamic --realism DIR`).
Everything random — the user's hand size, pose spread, stroke bow, tremor, gaze noise — derives
from the scenario's seed and the user's name, so a scenario is reproducible frame by frame.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from cbgo.hands.model import HandShape, blend, build_hand, neutral_pose
from cbgo.hands.poses import curl_pose, gesture_pose
from cbgo.simuser.motion import (
    CENTRE_MM,
    ENTRY_MM,
    EXIT_MM,
    Timeline,
    TimelineBuilder,
)
from cbgo.simuser.scenario import Episode, GestureStep, Scenario, UserStyle
from cbgo.transform import base_to_leap

STROKE_MM = 160.0  # swipe length of an average user
SWIPE_DIRECTIONS = {
    "swipe_up": np.array([0.0, 1.0, 0.0]), "swipe_down": np.array([0.0, -1.0, 0.0]),
    "swipe_left": np.array([-1.0, 0.0, 0.0]), "swipe_right": np.array([1.0, 0.0, 0.0]),
}
# How long a swipe is each way (`swipe_way`), relative to the user's amplitude: real people
# swipe farther across the body (a right hand to the left) than outward, and up and down shorter
# still (`cbgo bench dynamic --realism DIR --users 24`'s "by way" table, SHREC'17 train split,
# medians: 235, 194, 153 and 131 mm; simulated 235, 195, 158, 127).
SWIPE_WAY_LENGTH = {"across": 1.35, "outward": 1.13, "up": 0.96, "down": 0.64}


def swipe_way(swipe: str, side: str) -> str:
    """Returns which way of `SWIPE_WAY_LENGTH` a swipe made by a `side` hand goes.

    A horizontal swipe goes across the body (a right hand's to the left, a left hand's to the
    right) or outward.
    """
    if swipe in ("swipe_up", "swipe_down"):
        return swipe.removeprefix("swipe_")
    return "across" if (swipe == "swipe_left") == (side == "right") else "outward"


# How far a return comes back, as a share of its swipe: log-normal, median and spread fitted to
# the SHREC'17 train split's returns (`cbgo bench dynamic --realism DIR`: 0.98 [0.58, 1.42],
# 10th and 90th percentiles). Real people stop short of where they started or overshoot it.
RETURN_REACH = 0.98
RETURN_REACH_LOG_SD = 0.33
RETURN_REACH_RANGE = (0.4, 1.8)

# How long a 160 mm swipe (`STROKE_MM`) of a user of speed 1 takes (log-normal around it, one
# swipe to the next), fitted to the SHREC'17 train split's swipes by the speed the service reads
# (`cbgo bench dynamic --realism DIR --users 24`): peak speed 476 [307, 700] mm/s against
# real 474 [283, 734] (median [10th, 90th percentile]). Real swipes last longer (0.80 s
# against 0.55): their paths wander 1.5 times their length, simulated ones 1.2.
SWIPE_S = 0.78
SWIPE_S_LOG_SD = 0.25

# How much a swipe's length differs from the user's amplitude: log-normal with SD
# `UserStyle.length_spread`, clipped to this range, fitted with the users' amplitudes to the
# SHREC'17 train split (`cbgo bench dynamic --realism DIR --users 24`: SD of the log length
# within a person 0.38, between people 0.20; simulated 0.39 and 0.19): a person's swipes
# differ from one to the next far more than people differ from each other.
SWIPE_LENGTH_RANGE = (0.45, 2.2)
# A swipe's duration grows as its length ** this, whether it is short because the person makes
# small strokes or because this one is: a real short swipe is quick (the same bench's "peak
# speed by length": log peak speed grows 0.53 per log length, real; 0.50 simulated; swipes of
# 20-70 mm under 200 mm/s: real 5 %, simulated 33 % of only 11). A smaller exponent makes
# short swipes too slow for the segmenter's speed gate, which real people's are not.
SWIPE_S_LENGTH_EXPONENT = 0.55
SWIPE_MM_MAX = 330.0  # the field's width less a margin: longer swipes would leave it

STROKE_BOX = (np.array([-190.0, 100.0, -150.0]), np.array([190.0, 470.0, 150.0]))


def _inside(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Returns `start` shifted so that a stroke from it to `end` stays well inside the field."""
    low, high = STROKE_BOX
    shift = np.maximum(low - np.minimum(start, end), 0) - np.maximum(np.maximum(start, end)
                                                                       - high, 0)
    return start + shift


@dataclass
class SourceFrame:
    """One frame from any source, before it is stamped and published.

    Attributes:
        t: seconds on the source's own timeline (None: publish at once).
        hands: contract hand dicts (empty: no hand visible).
        user: the operator, when the source knows it.
        gaze: simulated gaze target: an object name or a base-frame point (m), or None.
        label: simulated ground truth: the gesture being performed, if any (not published).
    """

    t: float | None
    hands: list[dict]
    user: str | None = None
    gaze: str | list[float] | None = None
    label: str | None = None


def _angles(direction) -> tuple[float, float]:
    """Returns (pitch, yaw) of a Leap-frame direction in the hand model's convention."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    return float(np.arcsin(np.clip(d[1], -1, 1))), float(np.arctan2(-d[0], -d[2]))


def _seed(scenario_seed: int, *parts: str) -> int:
    return (scenario_seed * 1_000_003 + zlib.crc32("/".join(parts).encode())) % (2**32)


class SimulatedUser:
    """Turns a scenario into timed frames.

    Args:
        scenario: what to perform.
        rate_hz: frame rate of the simulated sensor.
        resolve: turns a gaze target (object name or point) into a base-frame point (m), or
            None if unknown; a pointing hand aims its index finger at it.
        to_base: the Leap(mm)→base(m) transform, needed for aiming.
    """

    def __init__(self, scenario: Scenario, rate_hz: float,
                 resolve: Callable[[str | list[float]], Any] | None = None,
                 to_base: np.ndarray | None = None):
        self.scenario = scenario
        self.rate_hz = rate_hz
        self.resolve, self.to_base = resolve, to_base
        self.shapes = {name: self._shape(name, style) for name, style in scenario.users.items()}
        self._next_hand_id = 1

    def _shape(self, name: str, style: UserStyle) -> HandShape:
        rng = np.random.default_rng(_seed(self.scenario.seed, "shape", name))
        return HandShape.sample(rng, scale=style.hand_scale, side=style.side)

    def episodes(self, loop_index: int = 0) -> Iterator[tuple[Episode, str, Timeline]]:
        """Yields (episode, user, timeline) in order; the same for the same loop index."""
        for index, episode in enumerate(self.scenario.episodes):
            user = self.scenario.user_of(episode)
            rng = np.random.default_rng(_seed(self.scenario.seed, "episode", str(loop_index),
                                              str(index)))
            yield episode, user, self.timeline(episode, self.scenario.users[user], rng)

    def duration(self) -> float:
        """Returns the scenario's length in seconds (without building any hand)."""
        return sum(len(timeline) for _, _, timeline in self.episodes()) / self.rate_hz

    def frames(self, loop_index: int = 0) -> Iterator[SourceFrame]:
        """Yields every frame of the scenario, t counting from 0."""
        t0 = 0.0
        for episode, user, timeline in self.episodes(loop_index):
            yield from self._render(timeline, user, episode, t0)
            t0 += len(timeline) / self.rate_hz

    def timeline(self, episode: Episode, style: UserStyle, rng: np.random.Generator
                 ) -> Timeline:
        """Returns the motion of one episode (no hand geometry yet)."""
        builder = TimelineBuilder(self.rate_hz, ENTRY_MM, neutral_pose())
        builder.hidden(episode.pause_s)
        builder.move_to(CENTRE_MM + rng.normal(0, 8, 3), 0.6 / style.speed, "enter")
        if episode.preparation:
            builder.hold(0.3 / style.speed, "prepare")
        bow_sign = 1.0 if rng.random() < 0.5 else -1.0
        dropout_at = None
        for step in episode.gestures:
            if step.idle:
                self._idle(builder, step.gesture, style, rng)
            elif step.dynamic:
                self._stroke(builder, step, style, rng, bow_sign)
            else:
                dropout_at = dropout_at or builder.frames + int(0.4 * self.rate_hz)
                self._static(builder, step, style, rng)
        builder.move_to(EXIT_MM, 0.6 / style.speed, "leave")
        builder.hold(0.2, "leave")
        if episode.dropout_frames:
            builder.hide_frames(dropout_at or builder.frames // 2, episode.dropout_frames)
        return builder.build(style.tremor_mm, rng)

    def _static(self, builder: TimelineBuilder, step: GestureStep, style: UserStyle,
                rng: np.random.Generator) -> None:
        if step.curls is not None:  # any pose, given as finger curls
            pose = curl_pose(step.curls, rng, style.pose_variation, step.spread)
        else:
            pose = gesture_pose(step.gesture, rng, variation=style.pose_variation)
        builder.move_to(CENTRE_MM + rng.normal(0, 10, 3), 0.25 / style.speed, "pose",
                        step.gesture)
        builder.key_pose(pose)
        builder.hold(step.hold_s or style.hold_s, "pose", step.gesture)
        builder.key_pose(pose)
        builder.hold(0.25 / style.speed, "return")
        builder.key_pose(neutral_pose())

    def _idle(self, builder: TimelineBuilder, kind: str, style: UserStyle,
              rng: np.random.Generator) -> None:
        """A motion that is no gesture (`IDLE_MOTIONS`), slow or small as people's are."""
        here = builder.position.copy()
        if kind == "drift":  # a slow wander, 20-40 mm over 1.5-2.5 s
            for _ in range(3):
                builder.move_to(_inside(here + rng.normal(0, 15, 3), here), rng.uniform(0.5, 0.8),
                                "idle")
        elif kind == "wobble":  # 2-4 Hz, 5-12 mm, for about a second
            freq, amp = rng.uniform(2.0, 4.0), rng.uniform(5.0, 12.0)
            axis = rng.normal(0, 1, 3)
            axis /= np.linalg.norm(axis)
            for i in range(int(rng.uniform(0.8, 1.5) * freq * 2)):
                builder.move_to(here + axis * amp * (1 if i % 2 == 0 else -1), 0.5 / freq, "idle")
            builder.move_to(here, 0.25 / freq, "idle")
        elif kind == "reposition":  # 80-180 mm at 60-150 mm/s mean speed
            distance = rng.uniform(80.0, 180.0)
            direction = rng.normal(0, 1, 3)
            direction /= np.linalg.norm(direction)
            target = _inside(here + direction * distance, here + direction * distance)
            builder.move_to(target, distance / rng.uniform(60.0, 150.0), "idle")
        else:  # "turn": a slow palm roll of 20-50° and back, at 10-35°/s
            angle = np.radians(rng.uniform(20.0, 50.0)) * rng.choice([-1.0, 1.0])
            rate = np.radians(rng.uniform(10.0, 35.0))
            builder.roll_to(builder.roll_angle + angle, abs(angle) / rate, "idle")
            builder.hold(rng.uniform(0.1, 0.4), "idle")
            builder.roll_to(builder.roll_angle - angle, abs(angle) / rate, "idle")
        builder.hold(rng.uniform(0.1, 0.3) / style.speed, "idle")

    def _stroke(self, builder: TimelineBuilder, step: GestureStep, style: UserStyle,
                rng: np.random.Generator, bow_sign: float) -> None:
        centre = CENTRE_MM + rng.normal(0, style.stroke_spread_mm, 3)  # wherever the hand is
        rest = style.rest_s * rng.uniform(0.0, 1.0)  # often next to no rest at all
        if step.gesture == "rotate":
            distance = float(np.linalg.norm(centre - builder.position))
            builder.move_to(centre, max(0.3, distance / rng.uniform(60.0, 100.0)), "return")
            builder.hold(max(rest, 0.05), "prepare")
            # roll > 0 raises the thumb side on either hand (the model keeps anatomy).
            way = rng.normal(0.0, 1.0, 3)
            drift = way / np.linalg.norm(way) * rng.uniform(0.0, style.rotate_drift_mm)
            builder.roll_to(np.radians(step.angle_deg), 0.6 / style.speed, "stroke", "rotate",
                            drift=drift)
            builder.hold(0.3 / style.speed, "stroke", "rotate")
            builder.roll_to(0.0, 1.0 / style.speed, "return")
            return
        direction = SWIPE_DIRECTIONS[step.gesture]
        horizontal = abs(direction[0]) > 0.5
        way = swipe_way(step.gesture, style.side)
        spread = float(np.clip(np.exp(rng.normal(0.0, style.length_spread)),
                               *SWIPE_LENGTH_RANGE))
        length = min(STROKE_MM * style.amplitude * SWIPE_WAY_LENGTH[way] * spread,
                     SWIPE_MM_MAX)
        sideways = np.array([direction[1], -direction[0], 0.0])
        bow = bow_sign * style.curvature * length * sideways
        # The swipe crosses the middle of the field: it starts a part of its length before.
        start = centre - direction * length * style.stroke_lead * rng.uniform(0.7, 1.3)
        start = _inside(start, start + direction * length)
        # Getting there is a slow preparation (60-100 mm/s on average, whatever the person's
        # stroke speed), unlike the stroke.
        distance = float(np.linalg.norm(start - builder.position))
        builder.move_to(start, max(0.3, distance / rng.uniform(60.0, 100.0)), "return")
        if rest >= 0.5 / builder.rate_hz:
            builder.hold(rest, "prepare")
        # A real palm turns to face where it swipes across the body (a right hand swiping left
        # rolls its thumb side down: median 57° over the SHREC'17 train split's swipes), and
        # hardly, on average, the other ways (0°); a left hand is the right one's mirror image.
        roll = np.radians(rng.normal(-style.medial_roll_deg if way == "across" else 0.0,
                                     style.swipe_roll_deg * (1.0 if horizontal else 0.5)))
        seconds = (SWIPE_S / style.speed * (length / STROKE_MM) ** SWIPE_S_LENGTH_EXPONENT
                   * float(np.exp(rng.normal(0.0, SWIPE_S_LOG_SD))))
        end = start + direction * length
        builder.move_to(end, seconds, "stroke", step.gesture, bow=bow, roll_to=roll)
        builder.hold(0.15 / style.speed * rng.uniform(0.0, 1.0), "stroke", step.gesture)
        reach = float(np.clip(np.exp(rng.normal(np.log(RETURN_REACH), RETURN_REACH_LOG_SD)),
                              *RETURN_REACH_RANGE))
        back = end - direction * length * reach
        builder.move_to(_inside(back, back),
                        seconds * reach * style.return_slowdown * rng.uniform(0.8, 1.1),
                        "return", roll_to=0.0)

    def _render(self, timeline: Timeline, user: str, episode: Episode, t0: float
                ) -> Iterator[SourceFrame]:
        shape = self.shapes[user]
        velocity = timeline.velocity()
        hand_id, was_visible, aim = self._next_hand_id, False, None
        for i in range(len(timeline)):
            t = t0 + i / self.rate_hz
            gaze = episode.gaze if timeline.phase[i] != "hidden" else None
            if not timeline.visible[i]:
                was_visible = False
                yield SourceFrame(t, [], user, gaze, None)
                continue
            if not was_visible:  # a hand (re)entering view gets a new id, as on a real sensor
                hand_id, self._next_hand_id = self._next_hand_id, self._next_hand_id + 1
                was_visible = True
            pose = timeline.pose_at(i, blend)
            if timeline.roll[i]:
                pose = pose.rotated(roll=timeline.roll[i])
            if timeline.label[i] == "point" and gaze is not None:
                # Aim with the fully formed pointing pose (the keyframe being blended towards),
                # not the half-formed first frame, so the hold points at the target.
                formed = timeline.next_pose(i)
                if aim is None or aim[0] is not formed:
                    aim = (formed, self._aim(shape, formed, timeline.palm[i], gaze))
                pose = pose.rotated(pitch=aim[1][0], yaw=aim[1][1])
            elif timeline.label[i] != "point":
                aim = None
            hand = build_hand(shape, pose, timeline.palm[i], velocity[i], hand_id=hand_id)
            yield SourceFrame(t, [hand], user, gaze, timeline.label[i])

    def _aim(self, shape: HandShape, pose, palm: np.ndarray, gaze) -> tuple[float, float]:
        """Returns the (pitch, yaw) change that points the index finger at the gaze target.

        The target is resolved to the base frame and brought into the Leap frame; three
        corrections of the built hand's knuckle-to-tip ray converge to within a degree.
        """
        target = self.resolve(gaze) if self.resolve else None
        if target is None or self.to_base is None:
            return (0.0, 0.0)
        target_leap = base_to_leap(self.to_base, target)
        mirror = 1.0 if shape.side == "right" else -1.0  # yaw > 0 turns towards the thumb
        d_pitch = d_yaw = 0.0
        for _ in range(3):
            hand = build_hand(shape, pose.rotated(pitch=d_pitch, yaw=d_yaw), palm)
            index = hand["fingers"][1]["bones"]
            knuckle = np.asarray(index[1]["prev_joint"])
            pitch_w, yaw_w = _angles(target_leap - knuckle)  # the ray starts at the knuckle
            pitch, yaw = _angles(np.subtract(index[3]["next_joint"], knuckle))
            d_pitch += pitch_w - pitch
            d_yaw += mirror * (yaw_w - yaw)
        return (d_pitch, d_yaw)
