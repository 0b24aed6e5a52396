"""Strokes cut out of the hand motion: the 20 Hz observation and the per-hand segmenter.

Observation (what a dynamic gesture is compared on):

- each hand's palm centre (mm, Leap frame) and palm **roll** are resampled to 20 Hz, as the
  paper does, by averaging the frames that fall in each 50 ms bin (this also averages out most of
  the 8–12 Hz physiological tremor); a bin without frames repeats the last sample;
- the roll is the angle of ``palm_normal`` about ``direction``, measured from the "palm down"
  reference (−y projected onto the plane across ``direction``), unwrapped, and negated for a
  left hand so that it is anatomical (the same rotation of either hand gives the same sign);
- a stroke's observation is ``[x, y, z, k·roll]`` per sample, translation-normalised to the
  stroke's first sample (``k`` = ``roll_scale_mm_per_rad``: a 90° roll weighs like a 157 mm
  swipe), so that rotate — a roll that barely moves the palm — is as visible as a swipe.

Segmentation, per hand id (the paper's stroke: it starts in the centre of the sensor's field):

- speed is the palm displacement over the last two samples (100 ms), roll rate likewise;
- a hand is **armed** once it has rested (slow: below both start thresholds) inside the centre
  region (a sphere of ``centre_radius_mm`` around ``centre_mm``) for ``rest_s``;
- an armed hand whose speed or roll rate rises above the start thresholds starts a stroke; its
  first sample is back-dated to the last sample at rest, so the observation holds the whole
  motion. A hand that reaches the centre while moving (entering the field, returning from a
  swipe) is not armed, so preparation and retraction moves are never strokes;
- the stroke ends when speed and roll rate stay below the end thresholds for ``end_hold_s``
  (the hand slowed down); the observation ends at the first slow sample. A stroke longer than
  ``max_stroke_s`` ends there;
- while it runs, a window is evaluated every ``eval_period_s`` once it has ``min_samples``
  samples, and once more at its end (``final``);
- a hand that disappears (or is not seen for ``max_gap_s``) ends its stroke with what was seen
  (a long swipe may leave the sensor's field); the move that takes a resting hand out of the
  field is cut the same way and is classified, normally as "no gesture";
- after a stroke the hand must rest in the centre again before the next one; the rest time
  counts from the end of the stroke's slow hold, so strokes can follow each other closely.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from cbgo.errors import ConfigError

RATE_HZ = 20.0  # the paper's resampling rate of the palm trajectory
DT = 1.0 / RATE_HZ
DEFAULT_CENTRE_MM = (0.0, 230.0, 0.0)  # the field centre; cbgo.simuser.motion.CENTRE_MM agrees
DIMS = 4  # x, y, z, k·roll
SPEED, RATE = 7, 8  # a sample: t, x, y, z, roll, grab, pinch, speed (mm/s), roll rate (°/s)


def _help(text: str) -> dict:
    return {"help": text}


@dataclass
class SegmenterConfig:
    """Where strokes start and end; every field is also a service setting (``--centre-mm``...).

    Attributes:
        centre_mm: centre of the region where strokes start (mm, Leap frame).
        centre_radius_mm: radius of that region.
        start_speed_mm_s: palm speed that starts a stroke.
        start_roll_deg_s: roll rate that starts a stroke.
        end_speed_mm_s: palm speed below which the hand counts as slowed down.
        end_roll_deg_s: roll rate below which the hand counts as slowed down.
        end_hold_s: how long the hand must stay slow to end a stroke.
        rest_s: how long a hand must rest in the centre before a stroke can start.
        eval_period_s: period of the windows evaluated while a stroke runs.
        min_samples: 20 Hz samples a window needs before it is evaluated.
        max_stroke_s: a stroke ends after this long whatever the hand does.
        max_gap_s: a hand not seen for this long has disappeared.
        roll_scale_mm_per_rad: k, the weight of the roll against the palm position.
    """

    centre_mm: list[float] = field(default_factory=lambda: list(DEFAULT_CENTRE_MM),
                                   metadata=_help("centre of the region where strokes start, "
                                                  "mm in the Leap frame (x,y,z)"))
    centre_radius_mm: float = field(default=70.0, metadata=_help(
        "radius of the centre region, mm"))
    start_speed_mm_s: float = field(default=150.0, metadata=_help(
        "palm speed that starts a stroke, mm/s"))
    start_roll_deg_s: float = field(default=60.0, metadata=_help(
        "palm roll rate that starts a stroke, deg/s"))
    end_speed_mm_s: float = field(default=70.0, metadata=_help(
        "palm speed below which the hand has slowed down, mm/s"))
    end_roll_deg_s: float = field(default=30.0, metadata=_help(
        "roll rate below which the hand has slowed down, deg/s"))
    end_hold_s: float = field(default=0.1, metadata=_help(
        "how long the hand stays slow to end a stroke, s"))
    rest_s: float = field(default=0.1, metadata=_help(
        "how long a hand rests in the centre before a stroke can start, s"))
    eval_period_s: float = field(default=0.1, metadata=_help(
        "period of the windows evaluated while a stroke runs, s"))
    min_samples: int = field(default=5, metadata=_help(
        "20 Hz samples a window needs before it is evaluated"))
    max_stroke_s: float = field(default=3.0, metadata=_help("longest stroke, s"))
    max_gap_s: float = field(default=0.3, metadata=_help(
        "a hand not seen for this long has disappeared, s"))
    roll_scale_mm_per_rad: float = field(default=100.0, metadata=_help(
        "weight of the palm roll against the palm position in the observation, mm/rad"))

    def __post_init__(self):
        if len(self.centre_mm) != 3:
            raise ConfigError("centre_mm needs 3 numbers (mm, Leap frame), e.g. 0,230,0")
        positive = ("centre_radius_mm", "start_speed_mm_s", "start_roll_deg_s", "end_speed_mm_s",
                    "end_roll_deg_s", "eval_period_s", "max_stroke_s", "max_gap_s",
                    "roll_scale_mm_per_rad")
        for name in positive:
            if not float(getattr(self, name)) > 0:
                raise ConfigError(f"{name}={getattr(self, name)} must be positive")
        for name in ("end_hold_s", "rest_s"):
            if float(getattr(self, name)) < 0:
                raise ConfigError(f"{name}={getattr(self, name)} must not be negative")
        if self.end_speed_mm_s > self.start_speed_mm_s:
            raise ConfigError("end_speed_mm_s must not exceed start_speed_mm_s")
        if self.end_roll_deg_s > self.start_roll_deg_s:
            raise ConfigError("end_roll_deg_s must not exceed start_roll_deg_s")
        if self.min_samples < 3:
            raise ConfigError(f"min_samples={self.min_samples} must be at least 3")
        if self.max_stroke_s < self.min_samples * DT:
            raise ConfigError("max_stroke_s is shorter than min_samples at 20 Hz")


@dataclass
class Window:
    """One evaluated stroke window.

    Attributes:
        hand_id: the tracking id of the hand.
        side: "left" or "right".
        stroke: a per-segmenter counter of strokes (windows of one stroke share it).
        times: (n,) sample times, s (the frames' clock).
        obs: (n, 4) observation ``[x, y, z, k·roll]`` relative to the first sample.
        final: True for the window at the stroke's end.
        pose_change: how much the hand's shape changed in the window: the largest
            ``|Δgrab_strength| + |Δpinch_strength|`` from the first sample (0..2).
        ended: why a final window's stroke ended: "slowed", "too long" or "lost" (the hand
            disappeared); "" while the stroke runs.
    """

    hand_id: int
    side: str
    stroke: int
    times: np.ndarray
    obs: np.ndarray
    final: bool
    pose_change: float = 0.0
    ended: str = ""

    @property
    def t_start(self) -> float:
        """Time of the first sample."""
        return float(self.times[0])

    @property
    def t_end(self) -> float:
        """Time of the last sample."""
        return float(self.times[-1])


def palm_roll(normal, direction, side: str = "right") -> float:
    """Returns the palm roll (rad) of one hand, anatomical sign; see the module docstring.

    Args:
        normal: the palm normal (unit vector).
        direction: from the palm towards the fingers (unit vector).
        side: "left" negates the angle, so either hand rolls the same way.
    """
    n = np.asarray(normal, dtype=float)
    d = np.asarray(direction, dtype=float)
    d = d / (np.linalg.norm(d) or 1.0)
    ref = np.array([0.0, -1.0, 0.0])
    ref = ref - ref.dot(d) * d
    if np.linalg.norm(ref) < 1e-3:  # fingers point straight up or down: use "towards the user"
        ref = np.array([0.0, 0.0, 1.0]) - d[2] * d
    ref /= np.linalg.norm(ref)
    angle = math.atan2(float(np.cross(ref, n).dot(d)), float(ref.dot(n)))
    return -angle if side == "left" else angle


def observation(positions: np.ndarray, rolls: np.ndarray, roll_scale: float) -> np.ndarray:
    """Returns the (n, 4) observation of samples, relative to the first one."""
    obs = np.column_stack([positions, roll_scale * np.asarray(rolls)])
    return obs - obs[0]


class _Resampler:
    """Averages one hand's frames into 50 ms bins (the 20 Hz samples)."""

    def __init__(self, t0: float):
        self.bin_end = t0 + DT
        self.acc = np.zeros(7)  # t, x, y, z, roll, grab, pinch sums
        self.count = 0
        self.last: np.ndarray | None = None

    def add(self, t: float, pos, roll: float, grab: float, pinch: float) -> list[np.ndarray]:
        out = []
        while t > self.bin_end:
            if self.count:
                self.last = self.acc / self.count
            elif self.last is not None:
                self.last = np.concatenate([[self.bin_end - DT / 2], self.last[1:]])
            if self.last is not None:
                out.append(self.last.copy())
            self.acc[:] = 0.0
            self.count = 0
            self.bin_end += DT
        self.acc += (t, *pos, roll, grab, pinch)
        self.count += 1
        return out

    def flush(self) -> np.ndarray | None:
        """Returns the sample of the bin in progress, if it has frames."""
        return self.acc / self.count if self.count else None


class _Track:
    """One hand's samples and stroke state."""

    def __init__(self, hand_id: int, side: str, t0: float, history: int):
        self.hand_id, self.side = hand_id, side
        self.resampler = _Resampler(t0)
        self.samples: deque[np.ndarray] = deque(maxlen=history)  # see SPEED, RATE
        self.last_t = t0
        self.last_roll: float | None = None
        self.rest = 0  # consecutive samples at rest inside the centre
        self.stroke: list[np.ndarray] | None = None
        self.slow = 0  # consecutive slow samples inside the stroke
        self.since_eval = 0
        self.stroke_id = 0


class Segmenter:
    """Cuts strokes out of hand frames and returns the windows to evaluate.

    Args:
        config: thresholds and regions.
    """

    def __init__(self, config: SegmenterConfig | None = None):
        self.config = config or SegmenterConfig()
        c = self.config
        self.centre = np.asarray(c.centre_mm, dtype=float)
        self.rest_samples = max(1, round(c.rest_s * RATE_HZ))
        self.end_samples = max(1, round(c.end_hold_s * RATE_HZ))
        self.eval_every = max(1, round(c.eval_period_s * RATE_HZ))
        self.max_samples = max(c.min_samples, round(c.max_stroke_s * RATE_HZ))
        self.tracks: dict[int, _Track] = {}
        self.strokes = 0

    def reset(self) -> None:
        """Forgets every hand (e.g. when the frame clock jumps back)."""
        self.tracks.clear()

    def update(self, t: float, hands: list[dict]) -> list[Window]:
        """Feeds one frame; returns the windows that became ready.

        Args:
            t: the frame time, s.
            hands: contract hand dicts (``cbgo/hands/frame``'s ``hands``).
        """
        seen = set()
        out: list[Window] = []
        for hand in hands:
            hand_id = int(hand["id"])
            seen.add(hand_id)
            track = self.tracks.get(hand_id)
            if track is not None and (t - track.last_t > self.config.max_gap_s
                                      or t < track.last_t):
                out += self._lost(track)  # not seen for too long (or the clock went back)
                track = None
            if track is None:
                track = _Track(hand_id, hand["side"], t, 3 * self.rest_samples + 16)
                self.tracks[hand_id] = track
            out += self._add_frame(track, t, hand)
        for hand_id in list(self.tracks):
            if hand_id not in seen:
                out += self._lost(self.tracks.pop(hand_id))
        return out

    def _lost(self, track: _Track) -> list[Window]:
        """Ends the stroke of a hand that disappeared with what was seen of it."""
        self.tracks.pop(track.hand_id, None)
        if track.stroke is None:
            return []
        sample = track.resampler.flush()
        if sample is not None:
            track.stroke.append(self._rates(track, sample))
        window = self._finish(track, len(track.stroke), "lost")
        return [window] if window is not None else []

    def _add_frame(self, track: _Track, t: float, hand: dict) -> list[Window]:
        roll = palm_roll(hand["palm_normal"], hand["direction"], track.side)
        if track.last_roll is not None:  # unwrap against the previous frame
            roll = track.last_roll + (roll - track.last_roll + math.pi) % (2 * math.pi) - math.pi
        track.last_roll, track.last_t = roll, t
        out = []
        for sample in track.resampler.add(t, hand["palm_position"], roll,
                                          hand["grab_strength"], hand["pinch_strength"]):
            window = self._add_sample(track, sample)
            if window is not None:
                out.append(window)
        return out

    def _rates(self, track: _Track, sample: np.ndarray) -> np.ndarray:
        if len(track.samples) < 2:
            return np.concatenate([sample, [0.0, 0.0]])
        back = track.samples[-2]
        dt = max(sample[0] - back[0], 1e-3)
        speed = float(np.linalg.norm(sample[1:4] - back[1:4])) / dt
        rate = math.degrees(abs(sample[4] - back[4])) / dt
        return np.concatenate([sample, [speed, rate]])

    def _add_sample(self, track: _Track, raw: np.ndarray) -> Window | None:
        c = self.config
        sample = self._rates(track, raw)
        track.samples.append(sample)
        speed, rate = sample[SPEED], sample[RATE]
        if track.stroke is not None:
            return self._continue(track, sample)
        moving = speed >= c.start_speed_mm_s or rate >= c.start_roll_deg_s
        if moving and track.rest >= self.rest_samples:
            return self._start(track)
        in_centre = np.linalg.norm(sample[1:4] - self.centre) <= c.centre_radius_mm
        track.rest = track.rest + 1 if (in_centre and not moving) else 0
        return None

    def _start(self, track: _Track) -> Window | None:
        c = self.config
        history = list(track.samples)
        start = len(history) - 1
        while start > 0 and (history[start][SPEED] >= c.end_speed_mm_s
                             or history[start][RATE] >= c.end_roll_deg_s):
            start -= 1  # back-date to the last sample at rest
        if np.linalg.norm(history[start][1:4] - self.centre) > c.centre_radius_mm:
            track.rest = 0
            return None
        track.stroke = history[start:]
        track.rest, track.slow, track.since_eval = 0, 0, 0
        self.strokes += 1
        track.stroke_id = self.strokes
        return self._maybe_partial(track)

    def _continue(self, track: _Track, sample: np.ndarray) -> Window | None:
        c = self.config
        track.stroke.append(sample)
        slow = sample[SPEED] < c.end_speed_mm_s and sample[RATE] < c.end_roll_deg_s
        track.slow = track.slow + 1 if slow else 0
        if track.slow >= self.end_samples:
            return self._finish(track, len(track.stroke) - track.slow + 1, "slowed")
        if len(track.stroke) >= self.max_samples:
            return self._finish(track, len(track.stroke), "too long")
        return self._maybe_partial(track)

    def _maybe_partial(self, track: _Track) -> Window | None:
        track.since_eval += 1
        if len(track.stroke) < self.config.min_samples or track.since_eval < self.eval_every:
            return None
        track.since_eval = 0
        return self._window(track, track.stroke, final=False)

    def _finish(self, track: _Track, end: int, reason: str) -> Window | None:
        samples = track.stroke[:max(end, 2)]
        last = track.stroke[-1][1:4]
        in_centre = np.linalg.norm(last - self.centre) <= self.config.centre_radius_mm
        # The slow hold that ended the stroke already counts as rest if it is in the centre.
        track.rest = track.slow if in_centre else 0
        track.stroke = None
        if len(samples) < self.config.min_samples:
            return None  # too short to be a gesture (a twitch)
        return self._window(track, samples, final=True, reason=reason)

    def _window(self, track: _Track, samples: list[np.ndarray], final: bool,
                reason: str = "") -> Window:
        arr = np.asarray(samples)
        obs = observation(arr[:, 1:4], arr[:, 4], self.config.roll_scale_mm_per_rad)
        pose = arr[:, 5:7]
        change = float(np.abs(pose - pose[0]).sum(1).max())
        return Window(track.hand_id, track.side, track.stroke_id, arr[:, 0].copy(), obs, final,
                      change, reason)
