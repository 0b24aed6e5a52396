"""Strokes cut out of the hand motion: the 20 Hz observation and the per-hand segmenter.

Observation (what a dynamic gesture is compared on):

- each hand's palm centre (mm, Leap frame) and palm **roll** are resampled to 20 Hz, as the
  paper does, by averaging the frames that fall in each 50 ms bin (this also averages out most of
  the 8–12 Hz physiological tremor); a bin without frames repeats the last sample;
- a **tracking jump** (the palm landing far away in one frame, faster than ``jump_mm_s`` and
  `JUMP_RATIO` times each of its last `JUMP_HISTORY` steps: the tracker re-fitted the hand) is
  taken out of the palm's path before resampling (`Segmenter._palm`), so it is neither a
  stroke nor part of one;
- the roll is the twist of ``palm_normal`` about ``direction`` summed frame by frame
  (`roll_increment`; the first frame's absolute `palm_roll` is the start), unwrapped, and
  negated for a left hand so that it is anatomical (the same rotation of either hand gives the
  same sign): measured whichever way the fingers point;
- a stroke's observation is ``[x, y, z, k·roll]`` per sample, translation-normalised to the
  stroke's first sample (``k`` = ``roll_scale_mm_per_rad``: a 90° roll weighs like a 79 mm
  swipe), so that rotate — a roll that barely moves the palm — is visible, while the 50–100°
  that real palms roll during a swipe leave it a swipe.

Segmentation, per hand id (the paper's strokes, found where real people make them):

- speed is the palm displacement over the last two samples (100 ms), roll rate likewise;
- a hand is **armed** once it has been slow (below both start thresholds: resting, or moving
  slowly) for ``rest_s``, anywhere in the field. With ``centre_rule`` (the paper's rule, an
  option) it must rest inside the centre region (a sphere of ``centre_radius_mm`` around
  ``centre_mm``), and a hand that reaches the centre while moving is not armed;
- an armed hand whose speed or roll rate rises above the start thresholds starts a stroke; its
  first sample is back-dated to the last sample at rest in the slow motion just before (at
  most `ONSET_S`, never into the previous stroke), so the observation holds the whole motion;
- the stroke ends when speed and roll rate stay below the end thresholds (or ``end_fraction``
  of the stroke's peak, if more: a tracker's jitter never reaches the absolute ones) for
  ``end_hold_s`` (the hand slowed down); the observation ends at the first slow sample. It
  also ends where the hand turns back (its excursion from the start drops ``turn_back_mm``, or
  a quarter of the farthest, below the farthest): the stroke stops at its farthest sample and
  the move back is a new stroke from there. A stroke longer than ``max_stroke_s`` ends there;
- while it runs, a window is evaluated every ``eval_period_s`` once it has ``min_samples``
  samples, and once more at its end (``final``);
- a hand that disappears (or is not seen for ``max_gap_s``) ends its stroke with what was seen
  (a long swipe may leave the sensor's field); a move mostly towards the person (+z) is held
  back while it runs and dropped if the hand is lost on its way: it is the hand leaving;
- after a stroke the hand must be slow again (for ``rest_s``, counted from the end of the
  stroke's slow hold) before the next one, except after a turn back;
- a hand's first stroke since it came into view is judged by ``first_peak_speed_mm_s``
  instead of the slow-move line below (when lower); a final window that passed by it alone is
  held back until the hand rests `PENDING_S`, leaves, or makes its next stroke, which drops it
  when `PREPARATION_FASTER` times as fast (it was that stroke's preparation);
- a window that has not moved ``min_extent_mm`` from its start is a twitch, and one that
  never went faster than ``min_peak_speed_mm_s`` (in a tenth of its samples: `FAST_PERCENTILE`)
  nor rolled faster than ``min_peak_roll_deg_s`` with the roll most of its motion (a rotate)
  is a slow move (a preparation, re-positioning, a return with the palm rolling back, drift):
  neither is evaluated; while the stroke runs, its windows wait for ``mid_peak_speed_mm_s``
  (or that roll rate) instead;
- whether a stroke is reported is the service's call: `ReturnFilter` drops the return move
  after a gesture.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace

import numpy as np

from cbgo.errors import ConfigError

EXIT_SHARE = 0.7  # a lost stroke going this much towards the person is the hand leaving
REVERSE_MIN_MM = 20.0  # both moves must go this far in space for a spatial reversal to count
# A window's palm speed for the slow-move lines: the speed a tenth of its samples exceed, not its
# top speed, which one tremor-lifted sample of a slow move (a re-positioning, the move to a
# swipe's start) can push past the line, while a real swipe is brisk over more of its samples
# (`cbgo bench dynamic --realism DIR` prints real and simulated peak speeds by swipe length).
FAST_PERCENTILE = 90.0
ONSET_S = 0.3  # how far back a stroke's start may be placed into the slow motion before it
GESTURE_P = 0.5  # a reported window whose top gesture is this probable is a gesture
# A final window whose top gesture is this probable might have been one: the reverse move after
# it is its return. Real swipes are often unsure (p 0.3-0.5, "none" a little ahead) while their
# return, which is never trained as "none", comes out surer and would win. The held-out real
# people's trials and streams measure it: `cbgo train dynamic --real DIR --folds 4`.
MIGHT_P = 0.25
# A running stroke's window is reported only when its top gesture is this probable: an early
# answer must be a sure one. Weaker early windows are mostly the first windows of a preparation
# that moves against the swipe to come, read as the opposite swipe: false triggers of the
# held-out real people's streams (`cbgo train dynamic --real DIR --folds 4 --streams 24`).
PARTIAL_P = 0.65
# ...and the window before it in its stroke must have read the same top gesture, whatever its p:
# one sure window alone is often a blip (a curving move's one window read as a swipe, a
# preparation's first sure window). The same command measures it; an early answer so comes one
# window (`eval_period_s`) later.
# A stroke that began within NEW_HAND_S of its hand's first frame was under way when the hand
# appeared: often the move that brings the hand into the field, or a wind-up, before the
# gesture (a Leap hand rising into view before a swipe right reads as a swipe up; SHREC'17's
# recordings start with the hand's appearance). Its running windows younger than
# NEW_HAND_WAIT_S are reported only from NEW_HAND_P. The first reported gesture of the
# held-out real people measures it (`cbgo train dynamic --real DIR --folds 4`; live, `cbgo
# bench dynamic --real ~/.cache/cbgo/leapmotion-swipes --per-class 0`).
# A hand's first stroke heard only by the first-stroke line (a slow move) is held back until the
# hand has rested PENDING_S after it, has left, or makes its next stroke: a next stroke
# PREPARATION_FASTER times as fast or more makes it that stroke's preparation (the slow move to
# a swipe's start, which reads as the opposite swipe: `cbgo bench dynamic --replay-sim 100`),
# and it is dropped; a slower next stroke (a slow swiper's return) lets it out first. The same
# ratio tells a preparation from a gesture in `ReturnFilter`.
PENDING_S = 1.0
PREPARATION_FASTER = 1.5
# The settings a person's pace sets (`pace.Pace.applied`, `Segmenter.retune`).
PACE_FIELDS = ("min_peak_speed_mm_s", "mid_peak_speed_mm_s", "first_peak_speed_mm_s",
               "start_speed_mm_s")
NEW_HAND_S = 0.15
NEW_HAND_WAIT_S = 0.5
NEW_HAND_P = 0.9
RATE_HZ = 20.0  # the paper's resampling rate of the palm trajectory
DT = 1.0 / RATE_HZ
DEFAULT_CENTRE_MM = (0.0, 230.0, 0.0)  # the field centre; cbgo.simuser.motion.CENTRE_MM agrees
DIMS = 4  # x, y, z, k·roll
BIN_TOLERANCE_S = 1e-6  # a frame this little past a 50 ms bin's end is stamped on it
SPEED, RATE = 7, 8  # a sample: t, x, y, z, roll, grab, pinch, speed (mm/s), roll rate (°/s)
# A tracking jump is also this many times faster than each of the palm's last JUMP_HISTORY
# frame-to-frame steps: a hand speeds up over a tenth of a second, a tracker that re-fits its
# skeleton jumps at once, and a jittery tracker's fast steps are never three times all three.
JUMP_RATIO = 3.0
JUMP_HISTORY = 3
# A re-fit lands within a few frames (a spike out and back is two); a step as fast after that
# many in a row is the hand's own motion, not a jump.
JUMP_FRAMES = 3


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
    end_fraction: float = field(default=0.25, metadata=_help(
        "the hand has also slowed down below this fraction of the stroke's peak speed (and "
        "roll rate): a tracker's jitter never reaches the absolute end thresholds"))
    rest_s: float = field(default=0.1, metadata=_help(
        "how long a hand rests in the centre before a stroke can start, s"))
    eval_period_s: float = field(default=0.1, metadata=_help(
        "period of the windows evaluated while a stroke runs, s"))
    min_samples: int = field(default=5, metadata=_help(
        "20 Hz samples a window needs before it is evaluated"))
    min_extent_mm: float = field(default=40.0, metadata=_help(
        "a window that has not moved this far from its start (mm, roll as k*roll) is a "
        "twitch, and is not evaluated"))
    min_peak_speed_mm_s: float = field(default=200.0, metadata=_help(
        "a window whose palm moved this fast in fewer than a tenth of its samples and never "
        "rolled min_peak_roll_deg_s is a slow move (a preparation, re-positioning, drift), not "
        "evaluated (real swipes of the SHREC'17 train split: 9 in 10 have a fifth of their "
        "samples above 280 mm/s, `cbgo bench dynamic --realism DIR`)"))
    min_peak_roll_deg_s: float = field(default=120.0, metadata=_help(
        "the roll rate that makes a slow-moving window a possible rotate, deg/s, when the "
        "roll (as k*roll) is most of its motion"))
    mid_peak_speed_mm_s: float = field(default=250.0, metadata=_help(
        "a window of a running stroke is evaluated only once the palm moved this fast (in a "
        "tenth of its samples) or rolled min_peak_roll_deg_s; its final window from "
        "min_peak_speed_mm_s: the early windows of a brisk preparation or re-positioning look "
        "like a small swipe"))
    first_peak_speed_mm_s: float = field(default=140.0, metadata=_help(
        "min_peak_speed_mm_s for a hand's first stroke since it came into view, when lower: a "
        "hand raised and held still is about to gesture, and a slow swiper's first swipe (a "
        "line drawn in the air) is heard; later strokes of the hand, among which "
        "re-positioning, keep the higher line (`cbgo bench dynamic --sets`)"))
    max_stroke_s: float = field(default=3.0, metadata=_help("longest stroke, s"))
    max_gap_s: float = field(default=0.3, metadata=_help(
        "a hand not seen for this long has disappeared, s"))
    roll_scale_mm_per_rad: float = field(default=50.0, metadata=_help(
        "weight of the palm roll against the palm position in the observation, mm/rad"))
    centre_rule: bool = field(default=False, metadata=_help(
        "strokes start only from rest inside the centre region (the paper's rule); off: "
        "from rest or slow motion anywhere in the field"))
    turn_back_mm: float = field(default=30.0, metadata=_help(
        "a stroke ends where the hand turns back by this much (or a quarter of its "
        "excursion, if more) from its farthest point, mm (roll as k*roll)"))
    jump_mm_s: float = field(default=1200.0, metadata=_help(
        f"a palm that moves faster than this from one frame to the next, and {JUMP_RATIO:g} "
        f"times faster than in any of its last {JUMP_HISTORY} steps, jumped: the tracker "
        "re-fitted the hand; the jump is taken out of the palm's path, not read as motion, "
        "mm/s (0: off)"))
    return_s: float = field(default=1.5, metadata=_help(
        "a stroke that reverses the gesture just made and starts within this time of its "
        "end is its return move, and is not reported, s (0: report every stroke)"))

    def __post_init__(self):
        if len(self.centre_mm) != 3:
            raise ConfigError("centre_mm needs 3 numbers (mm, Leap frame), e.g. 0,230,0")
        positive = ("centre_radius_mm", "start_speed_mm_s", "start_roll_deg_s", "end_speed_mm_s",
                    "end_roll_deg_s", "eval_period_s", "max_stroke_s", "max_gap_s",
                    "roll_scale_mm_per_rad", "turn_back_mm")
        for name in positive:
            if not float(getattr(self, name)) > 0:
                raise ConfigError(f"{name}={getattr(self, name)} must be positive")
        for name in ("end_hold_s", "rest_s", "return_s", "jump_mm_s", "min_extent_mm",
                     "min_peak_speed_mm_s", "min_peak_roll_deg_s", "mid_peak_speed_mm_s"):
            if float(getattr(self, name)) < 0:
                raise ConfigError(f"{name}={getattr(self, name)} must not be negative")
        if self.end_speed_mm_s > self.start_speed_mm_s:
            raise ConfigError("end_speed_mm_s must not exceed start_speed_mm_s")
        if self.end_roll_deg_s > self.start_roll_deg_s:
            raise ConfigError("end_roll_deg_s must not exceed start_roll_deg_s")
        if not 0 <= self.end_fraction < 1:
            raise ConfigError(f"end_fraction={self.end_fraction} must be in [0, 1)")
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
        pose_change: how much the hand's shape changed over the window:
            ``|Δgrab_strength| + |Δpinch_strength|`` from its start to its end, each the median
            of three samples (0..2).
        ended: why a final window's stroke ended: "slowed", "turned" (the hand turned back),
            "too long" or "lost" (the hand disappeared); "" while the stroke runs.
        peak_speed: the 80th percentile of the stroke's speeds so far (a glitch does not
            count), mm/s, the roll counted as k·roll (swipes are fast, drift and
            re-positioning slow).
        origin: the palm position of the first sample (mm, Leap frame).
        peak_mm_s: the palm's speed alone that a tenth of the window's samples exceed
            (90th percentile), mm/s: a tremor or a tracking glitch of a frame or two does
            not make a slow move fast.
        peak_roll_deg_s: the highest roll rate alone, deg/s.
        seen_s: how long the hand had been seen when the stroke began, s (`NEW_HAND_S`).
    """

    hand_id: int
    side: str
    stroke: int
    times: np.ndarray
    obs: np.ndarray
    final: bool
    pose_change: float = 0.0
    ended: str = ""
    peak_speed: float = 0.0
    origin: np.ndarray | None = None
    peak_mm_s: float = 0.0
    peak_roll_deg_s: float = 0.0
    seen_s: float = math.inf

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


def roll_increment(prev_normal, normal, direction, side: str = "right") -> float:
    """Returns how far (rad) the palm rolled about ``direction`` since ``prev_normal``.

    The twist of the palm normal about the hand's current direction, anatomical sign (negated
    for a left hand, as `palm_roll`). Summed frame by frame it gives the roll whatever way the
    hand points: an absolute roll angle needs a reference across the direction, and that
    reference swings wildly when the fingers point up or down (a hand held upright before a
    camera, a Leap in front of the user).
    """
    d = np.asarray(direction, dtype=float)
    d = d / (np.linalg.norm(d) or 1.0)
    a = np.asarray(prev_normal, dtype=float)
    a = a - a.dot(d) * d
    if np.linalg.norm(a) < 1e-6:
        return 0.0
    n = np.asarray(normal, dtype=float)
    angle = math.atan2(float(np.cross(a, n).dot(d)), float(a.dot(n)))
    return -angle if side == "left" else angle


def observation(positions: np.ndarray, rolls: np.ndarray, roll_scale: float) -> np.ndarray:
    """Returns the (n, 4) observation of samples, relative to the first one."""
    obs = np.column_stack([positions, roll_scale * np.asarray(rolls)])
    return obs - obs[0]


class _Resampler:
    """Averages one hand's frames into 50 ms bins (the 20 Hz samples).

    The bins are counted from the hand's first frame, and a frame stamped on a bin's end (a
    30, 60 or 120 Hz clock meets the 20 Hz bins every 0.1 s or 0.05 s) belongs to that bin
    whatever the clock's origin: up to `BIN_TOLERANCE_S` past it. Compared as they come, an
    epoch stamp's rounding (about 2·10⁻⁷ s) put such frames on either side, so the same
    recording gave other samples, and other answers, at another time of day.
    """

    def __init__(self, t0: float):
        self.t0 = t0
        self.bins = 1  # the bin in progress ends at t0 + bins·DT
        self.acc = np.zeros(7)  # t − t0, x, y, z, roll, grab, pinch sums
        self.count = 0
        self.last: np.ndarray | None = None

    def add(self, t: float, pos, roll: float, grab: float, pinch: float) -> list[np.ndarray]:
        out = []
        since = t - self.t0
        while since > self.bins * DT + BIN_TOLERANCE_S:
            if self.count:
                self.last = self.acc / self.count
            elif self.last is not None:
                self.last = np.concatenate([[(self.bins - 0.5) * DT], self.last[1:]])
            if self.last is not None:
                out.append(self._sample(self.last))
            self.acc[:] = 0.0
            self.count = 0
            self.bins += 1
        self.acc += (since, *pos, roll, grab, pinch)
        self.count += 1
        return out

    def flush(self) -> np.ndarray | None:
        """Returns the sample of the bin in progress, if it has frames."""
        return self._sample(self.acc / self.count) if self.count else None

    def _sample(self, mean: np.ndarray) -> np.ndarray:
        """Returns a bin's mean with its time on the frames' clock again."""
        return np.concatenate([[self.t0 + mean[0]], mean[1:]])


class _Track:
    """One hand's samples and stroke state."""

    def __init__(self, hand_id: int, side: str, t0: float, history: int):
        self.hand_id, self.side = hand_id, side
        self.first_t = t0  # when the hand was first seen
        self.resampler = _Resampler(t0)
        self.samples: deque[np.ndarray] = deque(maxlen=history)  # see SPEED, RATE
        self.last_t = t0
        self.last_roll: float | None = None
        self.last_normal: np.ndarray | None = None
        self.rest = 0  # consecutive samples at rest inside the centre
        self.stroke: list[np.ndarray] | None = None
        self.slow = 0  # consecutive slow samples inside the stroke
        self.far = 0  # index in the stroke of its farthest sample from the start
        self.far_mm = 0.0  # and that excursion (mm, roll as k·roll)
        self.since_eval = 0
        self.stroke_id = 0
        self.evaluated = 0  # strokes of this hand whose final window was evaluated
        self.pending: Window | None = None  # a slow first stroke's final window, held back
        self.ready: list[Window] = []  # windows released, to go out with the next ones
        self.raw_palm: np.ndarray | None = None  # the palm as the tracker last reported it
        self.jumped = np.zeros(3)  # the tracker's jumps so far, taken out of the palm's path
        self.steps: deque[float] = deque(maxlen=JUMP_HISTORY)  # last frame-to-frame speeds
        self.velocity = np.zeros(3)  # the palm's velocity over the last of them, mm/s
        self.jump_run = 0  # frames in a row taken for a jump


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
        self.onset_samples = max(self.rest_samples, round(ONSET_S * RATE_HZ))
        self.pending_samples = max(1, round(PENDING_S * RATE_HZ))
        self.tracks: dict[int, _Track] = {}
        self.strokes = 0
        self.jumps = 0

    def reset(self) -> None:
        """Forgets every hand (e.g. when the frame clock jumps back)."""
        self.tracks.clear()

    def retune(self, config: SegmenterConfig) -> None:
        """Takes the `PACE_FIELDS` of `config` (a person's pace: `pace.Pace.applied`).

        They are read afresh on each sample; the other settings stay as built.
        """
        self.config = replace(self.config, **{name: getattr(config, name)
                                              for name in PACE_FIELDS})

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
        """Ends the stroke of a hand that disappeared with what was seen of it.

        A slow first stroke still held back goes out: the hand left after it, so it prepared
        nothing.
        """
        self.tracks.pop(track.hand_id, None)
        window = None
        if track.stroke is not None:
            sample = track.resampler.flush()
            if sample is not None:
                track.stroke.append(self._rates(track, sample))
            window = self._finish(track, len(track.stroke), "lost")
        if window is None:
            self._release(track)
        return self._settle(track, window)

    def _release(self, track: _Track) -> None:
        """Sends the held-back window of a slow first stroke out (it counts as evaluated)."""
        if track.pending is not None:
            track.ready.append(track.pending)
            track.pending = None
            track.evaluated += 1

    def _settle(self, track: _Track, window: Window | None) -> list[Window]:
        """Returns the windows ready to go out, deciding a held-back slow first stroke.

        The next stroke's first window decides it: a move `PREPARATION_FASTER` times as fast
        or more made it a preparation (dropped); anything else lets it out first.
        """
        out, track.ready = track.ready, []
        if window is None:
            return out
        held = track.pending
        if held is not None and window.stroke != held.stroke:
            track.pending = None
            if window.peak_mm_s < PREPARATION_FASTER * held.peak_mm_s:
                track.evaluated += 1
                out.append(held)
        out.append(window)
        return out

    def _palm(self, track: _Track, t: float, hand: dict) -> np.ndarray:
        """Returns the palm position with the tracker's jumps taken out of its path.

        A depth camera's or a Leap's hand model sometimes re-fits in one frame, and the palm
        lands 50-150 mm away: read as motion, that is a stroke nobody made, or it bends the
        swipe it falls in (SHREC'17 train split: 148 of 1257 recordings hold a frame-to-frame
        step above 2000 mm/s). A step faster than ``jump_mm_s`` and `JUMP_RATIO` times the
        fastest of the last `JUMP_HISTORY` steps that were no jump is such a jump, for at most
        `JUMP_FRAMES` frames in a row. The palm goes on at its last velocity instead, and every
        later position is shifted by the jump (a stroke is read relative to its start, so only
        its ``origin`` stays shifted). A hand's first step is never a jump: there is nothing to
        compare it with.
        """
        raw = np.asarray(hand["palm_position"], dtype=float)
        dt = t - track.last_t  # a frame stamped like the one before has no speed to judge
        if track.raw_palm is not None and self.config.jump_mm_s > 0 and dt > 0:
            step = raw - track.raw_palm
            speed = float(np.linalg.norm(step)) / dt
            usual = max(track.steps, default=math.inf)
            if (speed > self.config.jump_mm_s and speed > JUMP_RATIO * usual
                    and track.jump_run < JUMP_FRAMES):
                track.jumped = track.jumped + step - track.velocity * dt
                track.jump_run += 1
                self.jumps += 1
            else:
                track.steps.append(speed)
                track.velocity, track.jump_run = step / dt, 0
        track.raw_palm = raw
        return raw - track.jumped

    def _add_frame(self, track: _Track, t: float, hand: dict) -> list[Window]:
        palm = self._palm(track, t, hand)
        normal = np.asarray(hand["palm_normal"], dtype=float)
        if track.last_roll is None:
            roll = palm_roll(normal, hand["direction"], track.side)
        else:
            roll = track.last_roll + roll_increment(track.last_normal, normal,
                                                    hand["direction"], track.side)
        track.last_roll, track.last_normal, track.last_t = roll, normal, t
        out = []
        for sample in track.resampler.add(t, palm, roll,
                                          hand["grab_strength"], hand["pinch_strength"]):
            out += self._settle(track, self._add_sample(track, sample))
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
        track.rest = track.rest + 1 if (self._in_centre(sample) and not moving) else 0
        if track.pending is not None and track.rest >= self.pending_samples:
            self._release(track)  # the hand rested after its slow first stroke
        return None

    def _in_centre(self, sample: np.ndarray) -> bool:
        """Whether a sample may arm a stroke: anywhere, unless the centre rule is on."""
        return (not self.config.centre_rule
                or np.linalg.norm(sample[1:4] - self.centre) <= self.config.centre_radius_mm)

    def _start(self, track: _Track) -> Window | None:
        history = list(track.samples)
        start = self._onset(history, track.rest)
        if not self._in_centre(history[start]):
            track.rest = 0
            return None
        return self._begin(track, history[start:])

    def _onset(self, history: list[np.ndarray], slow_run: int) -> int:
        """Returns the index in `history` where a stroke starting at its last sample began.

        The last sample at rest (below the end thresholds) among the slow samples just before,
        or the slowest of them if none is (a jittery tracker): never further back than that
        slow run, whose start is where the previous motion ended.
        """
        c = self.config
        last = len(history) - 1
        run = range(max(0, last - min(slow_run, self.onset_samples)), last)
        resting = [i for i in run if history[i][SPEED] < c.end_speed_mm_s
                   and history[i][RATE] < c.end_roll_deg_s]
        if resting:
            return resting[-1]
        if not run:
            return last
        return min(run, key=lambda i: (history[i][SPEED], history[i][RATE]))

    def _begin(self, track: _Track, samples: list[np.ndarray]) -> Window | None:
        track.stroke = list(samples)
        track.rest, track.slow, track.since_eval = 0, 0, 0
        track.far, track.far_mm = 0, 0.0
        for i in range(len(track.stroke)):
            self._reach(track, i)
        self.strokes += 1
        track.stroke_id = self.strokes
        return self._maybe_partial(track)

    def _reach(self, track: _Track, i: int) -> float:
        """Updates the stroke's farthest sample with sample i; returns i's excursion."""
        k = self.config.roll_scale_mm_per_rad
        delta = track.stroke[i][1:5] - track.stroke[0][1:5]
        excursion = float(np.linalg.norm(np.append(delta[:3], k * delta[3])))
        if excursion > track.far_mm:
            track.far, track.far_mm = i, excursion
        return excursion

    def _continue(self, track: _Track, sample: np.ndarray) -> Window | None:
        c = self.config
        track.stroke.append(sample)
        excursion = self._reach(track, len(track.stroke) - 1)
        peak_speed, peak_rate = self._peaks(track.stroke)
        slow = (sample[SPEED] < max(c.end_speed_mm_s, c.end_fraction * peak_speed)
                and sample[RATE] < max(c.end_roll_deg_s, c.end_fraction * peak_rate))
        track.slow = track.slow + 1 if slow else 0
        if track.slow >= self.end_samples:
            return self._finish(track, len(track.stroke) - track.slow + 1, "slowed")
        if track.far_mm - excursion > max(c.turn_back_mm, 0.25 * track.far_mm):
            return self._turn(track)
        if len(track.stroke) >= self.max_samples:
            return self._finish(track, len(track.stroke), "too long")
        return self._maybe_partial(track)

    @staticmethod
    def _peaks(stroke: list[np.ndarray]) -> tuple[float, float]:
        """Returns the stroke's second highest speed and roll rate (one glitch is no peak)."""
        speeds = sorted(sample[SPEED] for sample in stroke[1:])
        rates = sorted(sample[RATE] for sample in stroke[1:])
        pick = -2 if len(speeds) > 1 else -1
        return (speeds[pick], rates[pick]) if speeds else (0.0, 0.0)

    def _turn(self, track: _Track) -> Window | None:
        """Ends the stroke at its farthest point; the move back is a new stroke from there.

        The hand turned back without stopping (a return, or a preparation followed by the
        gesture): whether the new stroke is reported is `ReturnFilter`'s call.
        """
        far, samples = track.far, track.stroke
        window = self._finish(track, far + 1, "turned")
        self._begin(track, samples[far:])
        return window

    def _maybe_partial(self, track: _Track) -> Window | None:
        track.since_eval += 1
        if len(track.stroke) < self.config.min_samples or track.since_eval < self.eval_every:
            return None
        window = self._window(track, track.stroke, final=False)
        if not self._worth_evaluating(window, track):
            return None  # not yet more than a twitch or a slow move: try at the next sample
        track.since_eval = 0
        return window

    def _finish(self, track: _Track, end: int, reason: str) -> Window | None:
        samples = track.stroke[:max(end, 2)]
        # The slow hold that ended the stroke already counts as rest (if in the centre).
        track.rest = track.slow if self._in_centre(track.stroke[-1]) else 0
        track.stroke = None
        if len(samples) < self.config.min_samples:
            return None  # too short to be a gesture (a twitch)
        window = self._window(track, samples, final=True, reason=reason)
        if not self._worth_evaluating(window, track):
            return None
        if self._slow_first(window, track):
            track.pending = window
            return None
        track.evaluated += 1
        return window

    def _slow_first(self, window: Window, track: _Track) -> bool:
        """Whether a final window passed only by its hand's first-stroke line (no roll)."""
        return (track.evaluated == 0 and window.peak_mm_s < self.config.min_peak_speed_mm_s
                and window.peak_roll_deg_s < self.config.min_peak_roll_deg_s)

    def _worth_evaluating(self, window: Window, track: _Track) -> bool:
        """Whether a window is more than a twitch, faster than a slow move and no exit.

        A running stroke's windows must be faster (`mid_peak_speed_mm_s`) than its final one:
        the early windows of a slow move just past the final line (a re-positioning, the move
        to a swipe's start) look like a small swipe. A slow window that rolls fast is a
        possible rotate only when the roll is most of its motion: a palm rolling back while
        the hand moves back slowly (a return, a re-positioning) is a slow move. The false
        triggers of continuous streams measure both (`cbgo bench dynamic --streams-sim 48`;
        `cbgo train dynamic --real DIR --folds 4 --streams 24`).
        """
        c = self.config
        space = float(np.linalg.norm(window.obs[:, :3], axis=1).max())
        moved = float(np.linalg.norm(window.obs, axis=1).max()) >= c.min_extent_mm
        final_line, mid_line = self._lines(track)
        speed = final_line if window.final else max(final_line, mid_line)
        rolling = (window.peak_roll_deg_s >= c.min_peak_roll_deg_s
                   and float(np.abs(window.obs[:, 3]).max()) >= space)
        return moved and (window.peak_mm_s >= speed or rolling) and not self._exit(window)

    def _lines(self, track: _Track) -> tuple[float, float]:
        """Returns the slow-move lines (final window, running window) for a hand's stroke.

        A hand's first stroke since it came into view and rested is judged by
        ``first_peak_speed_mm_s`` instead (when lower).
        """
        c = self.config
        final = c.min_peak_speed_mm_s
        if track.evaluated == 0:
            final = min(c.first_peak_speed_mm_s, final)
        return final, c.mid_peak_speed_mm_s

    @staticmethod
    def _exit(window: Window) -> bool:
        """Whether a window may be the hand leaving the field towards the person.

        The usual way out of a sensor's field, and no default gesture goes mostly along
        depth: such a window is held back while its stroke runs and dropped if the hand is
        lost on its way; a stroke along depth that ends in view (a gesture taught by a user)
        is evaluated at its end.
        """
        if window.final and window.ended != "lost":
            return False
        delta = window.obs[-1, :3] - window.obs[0, :3]
        return bool(delta[2] > 0 and delta[2] > EXIT_SHARE * np.linalg.norm(delta))

    def _window(self, track: _Track, samples: list[np.ndarray], final: bool,
                reason: str = "") -> Window:
        arr = np.asarray(samples)
        obs = observation(arr[:, 1:4], arr[:, 4], self.config.roll_scale_mm_per_rad)
        pose = arr[:, 5:7]
        # Net change, start to end, each a median of three samples: fingers that relax or a
        # tracker that flickers during a swipe are no pose being formed.
        change = float(np.abs(np.median(pose[-3:], 0) - np.median(pose[:3], 0)).sum())
        k_deg = self.config.roll_scale_mm_per_rad * math.pi / 180.0
        # Not maxima: a tracking glitch (a skeleton that jumps for a frame or two) must not
        # make a slow move fast.
        def peak(values: np.ndarray) -> float:
            return float(np.percentile(values, 80)) if len(values) else 0.0

        def top(values: np.ndarray) -> float:
            return float(values.max()) if len(values) else 0.0

        def fast(values: np.ndarray) -> float:
            return float(np.percentile(values, FAST_PERCENTILE)) if len(values) else 0.0

        return Window(track.hand_id, track.side, track.stroke_id, arr[:, 0].copy(), obs, final,
                      change, reason, peak(np.hypot(arr[1:, SPEED], k_deg * arr[1:, RATE])),
                      arr[0, 1:4].copy(), fast(arr[1:, SPEED]), top(arr[1:, RATE]),
                      float(arr[0, 0]) - track.first_t)


@dataclass
class _Running:
    """What a hand's running stroke has said so far (`ReturnFilter.observe`)."""

    stroke: int
    seen: float = 0.0  # its windows' highest gesture p
    top: int = -1  # its last window's top gesture
    surest: np.ndarray | None = None  # its surest published window's probabilities (p: seen)


@dataclass
class _Gesture:
    t_end: float
    delta: np.ndarray
    peak_speed: float
    p: float
    returned_at: float = math.inf


# A stroke more than 102° from the one before reverses it: real returns come back on a curve
# (`ReturnFilter`'s choice of -0.2, and the realism bench's return and preparation ratios).
REVERSE_COS_MAX = -0.2
# A gesture has one return. Once a return has come back this share of the gesture's
# displacement, a later reversing stroke is still that return only if it starts within
# RETURN_GAP_S of the return's end (a return made in two parts); otherwise it is a new gesture
# (swipe right, come back, swipe left). Measured on the held-out real people (`cbgo train
# dynamic --real DIR --folds 4`) and the simulated streams, whose returns are fitted to real
# ones (`cbgo bench dynamic --users 2 --no-latency --streams-sim 48`).
RETURNED_SHARE = 0.7
RETURN_GAP_S = 0.3
# A gesture the hand slowed in mid-way is two strokes. The second one, a gesture too, that starts
# within CONTINUE_GAP_S of the first one's end and goes the same way (cosine ≥ CONTINUE_COS,
# within 60°), carries it on: the return comes back over both, and is not taken for the
# opposite swipe (a swipe_up made as 81 + 44 mm comes back about 140 mm: more than twice the
# second stroke, `ReturnFilter`'s ``farther``).
CONTINUE_GAP_S = 0.3
CONTINUE_COS = 0.5
ROLL_BACK = 2.0  # a turn after a move is that move's roll coming back up to this many times it


def reverses(delta: np.ndarray, previous: np.ndarray, cos_max: float = REVERSE_COS_MAX) -> bool:
    """Whether displacement `delta` (``[x, y, z, k·roll]``) points back against `previous`.

    In space alone when both moved in space (a swipe's palm may roll one way and not back),
    or with the roll included when the two are moves of one kind: both mostly a move, or both
    mostly a turn (`_turns`). Across kinds, a return retraces what the gesture did: a turn
    after a move is that move's roll coming back only when it turns no more than `ROLL_BACK`
    times as far (a swipe that rolled the palm 20°, then a rotate of 110° the other way, is a
    rotate); a move after a turn moves where the turn did not, so it returns nothing (a swipe
    made soon after a rotate whose palm rolls back is a swipe).
    """
    spatial = min(np.linalg.norm(delta[:3]), np.linalg.norm(previous[:3])) >= REVERSE_MIN_MM
    if spatial and _cos(delta[:3], previous[:3]) < cos_max:
        return True
    if _turns(delta) == _turns(previous):
        same_kind = True
    elif _turns(delta):
        same_kind = abs(float(delta[3])) <= ROLL_BACK * abs(float(previous[3]))
    else:
        same_kind = False
    return same_kind and _cos(delta, previous) < cos_max


def continues(delta: np.ndarray, previous: np.ndarray) -> bool:
    """Whether displacement `delta` goes on the way `previous` went (`CONTINUE_COS`).

    Both must be moves, compared in space, or both turns, compared with the roll included.
    """
    if _turns(delta) != _turns(previous):
        return False
    if _turns(delta):
        return _cos(delta, previous) >= CONTINUE_COS
    return _cos(delta[:3], previous[:3]) >= CONTINUE_COS


def _cos(a: np.ndarray, b: np.ndarray) -> float:
    return float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-9)


def _turns(delta: np.ndarray) -> bool:
    """Whether a displacement is mostly a turn: its k·roll beyond its distance in space."""
    return len(delta) > 3 and abs(float(delta[3])) > float(np.linalg.norm(delta[:3]))


class ReturnFilter:
    """Tells the return move after a gesture from a new stroke, per hand.

    People prepare, stroke and come back; the paper's centre rule kept the preparation and the
    return out by starting strokes only from the centre, which real people rarely rest in.
    Here a stroke is a **return** when it reverses the gesture just reported by this hand
    (its displacement points against the gesture's: cosine below ``cos_max``, roll included or
    in space alone) and starts within ``within_s`` of that gesture's end. Its windows are not
    reported. Two exceptions, judged when the stroke has ended, where the "gesture" was a
    preparation and this stroke is the gesture: the gesture was not a sure one (p below
    ``sure``) and the reversing stroke was much faster (more than ``faster`` times its peak
    speed); or the reversing stroke went much farther in space (more than ``farther`` times).
    People come back about as far as they swiped, while they swipe farther than they
    prepared (SHREC'17 train split, `cbgo bench dynamic --realism DIR --users 24`: a return
    goes 0.96 of the swipe's length, median [0.56, 1.42 at the 10th and 90th percentiles];
    a swipe goes 2.20 [1.39, 4.97] times as far as a preparation that reversed it). A stroke
    cut short by the hand leaving is always a return: it has neither speed nor length to
    judge. A stroke reversing a non-gesture (a preparation classified ``none``) is always
    reported. A gesture has one return: once one has come back `RETURNED_SHARE` of the way,
    only a stroke starting within `RETURN_GAP_S` of its end is still that return. A gesture
    made in two strokes (the hand slowed mid-way) is one gesture, whose return comes back
    over both (`observe`).
    It also remembers what each hand's running stroke said: the top gesture its next window
    must confirm (`confirms`) and its surest published window, which its final window answers
    with if surer (`stroke_answer`).

    Args:
        within_s: how soon after a gesture's end a reversing stroke counts as its return
            (0 turns the filter off).
        cos_max: the cosine between the displacements below which a stroke reverses: -0.2
            (more than 102° apart), as real returns come back on a curve, not straight
            (`cbgo train dynamic --real DIR --folds 4` measures it on the held-out real
            people's trials and streams).
        faster: how much faster than an unsure gesture its reversal must be to be reported.
        sure: the probability from which only a farther reversal is reported.
        farther: how much farther than a gesture its reversal must go to be reported.
    """

    def __init__(self, within_s: float, cos_max: float = REVERSE_COS_MAX, faster: float = 1.5,
                 sure: float = 0.8, farther: float = 2.0):
        self.within_s, self.cos_max, self.faster, self.sure = within_s, cos_max, faster, sure
        self.farther = farther
        self.last: dict[int, _Gesture] = {}
        self.running: dict[int, _Running] = {}  # hand → what its running stroke said
        self.returns = 0

    def is_return(self, window: Window) -> bool:
        """Whether a window belongs to the return move of the hand's last gesture."""
        last = self.last.get(window.hand_id)
        if last is None or self.within_s <= 0 or window.t_start - last.t_end > self.within_s:
            return False
        if window.t_start - last.returned_at > RETURN_GAP_S:
            return False
        delta = window.obs[-1] - window.obs[0]
        if float(np.linalg.norm(delta)) < 1e-6 or not reverses(delta, last.delta, self.cos_max):
            return False
        if not window.final:
            return True
        prepared = window.ended != "lost" and (
            (last.p < self.sure and window.peak_speed > self.faster * last.peak_speed)
            or np.linalg.norm(delta[:3]) > self.farther * np.linalg.norm(last.delta[:3]))
        self.returns += int(not prepared)
        if not prepared and np.linalg.norm(delta) >= RETURNED_SHARE * np.linalg.norm(last.delta):
            last.returned_at = window.t_end
        return not prepared

    def confirms(self, window: Window, top: int) -> bool:
        """Whether the window before `window` in its stroke read the same top gesture."""
        running = self.running.get(window.hand_id)
        return running is not None and running.stroke == window.stroke and running.top == top

    def stroke_answer(self, window: Window, probs: np.ndarray, top_p: float) -> np.ndarray:
        """Returns a final window's answer for its whole stroke (call before `observe`).

        The stroke's surest published window, this final one or one published mid-stroke:
        a final window that ends on the slowing hand often reads less sure than the stroke
        read while it ran, and a consumer that takes one answer per stroke (the final one)
        must not lose a gesture it was already told of. `top_p`: the final window's most
        probable gesture's p.
        """
        running = self.running.get(window.hand_id)
        if (running is None or running.stroke != window.stroke or running.surest is None
                or len(running.surest) != len(probs) or running.seen <= top_p):
            return probs
        return running.surest

    def forget_running(self) -> None:
        """Forgets what the running strokes said: a reloaded library names other gestures."""
        self.running.clear()

    def observe(self, window: Window, p_gesture: float, top: int = -1,
                probs: np.ndarray | None = None) -> None:
        """Records a classified window's top gesture probability (0 if it was no gesture).

        A stroke is recorded as a gesture when it ends, with the highest of these over its
        windows: a swipe reported mid-stroke whose end reads ``none`` was still reported. A
        gesture stroke that carries on the hand's last gesture (`continues`, within
        `CONTINUE_GAP_S`, before any return) extends it instead. `top`, the window's top
        gesture, is what the stroke's next window must read to be confirmed (`confirms`). A
        running window's `probs` are kept while it is the stroke's surest (`stroke_answer`):
        a running window's p_gesture is nonzero only when it was published.
        """
        running = self.running.get(window.hand_id)
        if running is None or running.stroke != window.stroke:
            running = self.running[window.hand_id] = _Running(window.stroke)
        surer = p_gesture > running.seen
        seen = running.seen = max(p_gesture, running.seen)
        if not window.final:
            running.top = top
            if surer and probs is not None:
                running.surest = probs
            return
        self.running.pop(window.hand_id, None)
        delta = window.obs[-1] - window.obs[0]
        if seen <= 0.0 or float(np.linalg.norm(delta)) <= 1e-6:
            return
        last = self.last.get(window.hand_id)
        carries_on = (last is not None and last.returned_at == math.inf
                      and window.t_start - last.t_end <= CONTINUE_GAP_S
                      and continues(delta, last.delta))
        if carries_on:  # one gesture in two strokes: its return comes back over both
            self.last[window.hand_id] = _Gesture(window.t_end, last.delta + delta,
                                                 max(last.peak_speed, window.peak_speed),
                                                 max(last.p, seen))
        else:
            self.last[window.hand_id] = _Gesture(window.t_end, delta, window.peak_speed, seen)


def reported(windows, returns: ReturnFilter, classify):
    """Yields (window, probabilities) of the windows a service reports, as it decides.

    A return (`ReturnFilter.is_return`) is skipped; every other window is classified
    (`classify(window)` → probabilities, ``none`` last). A final window is always reported. A
    running stroke's window is reported only when its top gesture has p ≥ `PARTIAL_P`, or
    `NEW_HAND_P` while it is younger than `NEW_HAND_WAIT_S` in a stroke under way when its
    hand appeared (`NEW_HAND_S`), and the stroke's window before it read the same top gesture
    (`ReturnFilter.confirms`). A stroke is recorded as a gesture, whose reversal is its
    return, if its final window's most probable gesture has p ≥ `MIGHT_P` or is more probable
    than ``none`` (what might have been a gesture is followed by what might be its return), or
    if one of its running windows was reported: a consumer was told of it. A final window
    is published with its stroke's answer (`ReturnFilter.stroke_answer`): its own
    probabilities, or those of a surer window of its stroke published mid-stroke.
    """
    for window in windows:
        if returns.is_return(window):
            continue
        probs = classify(window)
        best = int(np.argmax(probs[:-1]))
        top = float(probs[best])
        published = window.final or (top >= partial_p(window) and returns.confirms(window, best))
        # a final window that might be a gesture, or any published one, makes its stroke one
        gesture = (top >= MIGHT_P or top > probs[-1]) if window.final else published
        answer = returns.stroke_answer(window, probs, top) if window.final else probs
        returns.observe(window, top if gesture else 0.0, best, probs)
        if published:
            yield window, answer


def partial_p(window: Window) -> float:
    """Returns how probable a running stroke's window's top gesture must be to be reported."""
    young = window.t_end - window.t_start < NEW_HAND_WAIT_S
    return NEW_HAND_P if window.seen_s <= NEW_HAND_S and young else PARTIAL_P
