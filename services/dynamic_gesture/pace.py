"""A person's own pace: the slow-move lines calibrated on that person's demonstrations.

The segmenter's slow-move lines (``min_peak_speed_mm_s``, ``mid_peak_speed_mm_s``,
``first_peak_speed_mm_s``) stop slow re-positioning and drift from being read as gestures, and
so also stop a person who swipes slowly. ``cbgo gestures calibrate --user NAME`` records a few
of the person's swipes and writes their peak speeds to ``<data dir>/calibration/NAME.json``;
while ``cbgo/user`` names that person, the service judges strokes by lines at `PACE_SHARE` of
the person's typical swipe speed (the median take: the slowest of many takes falls with their
number, and a line at it lets in re-positioning), and starts strokes from that speed too
(never above the configured lines, never below `PACE_FLOOR_MM_S`). A fast swiper's calibration
leaves the lines as configured.

The share and the floor are measured with people kept apart: each held-out person's
calibration from k of their swipes, scored on their other swipes and their continuous streams
(``cbgo bench dynamic --calibration``).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from cbgo.services.dynamic_gesture.stroke import SegmenterConfig, Window

FORMAT = "cbgo-calibration"
# The lines lie at this share of the person's typical swipe speed. A lower share lowers the lines
# of more people, and those whose swipes are brisk enough already get re-positioning reported:
# at 0.5 the SHREC'17 people's streams read 1.7 false triggers per minute, at 0.75 0.8 (0.4
# uncalibrated), while GestureMidAir's slow swipers are all heard at either (`cbgo bench
# dynamic --calibration`).
PACE_SHARE = 0.75
PACE_FLOOR_MM_S = 100.0  # no line goes lower: below it, drift and tremor pass
SWIPES = ("swipe_left", "swipe_right", "swipe_up", "swipe_down")
DIRECTIONS = {"swipe_left": (-1.0, 0.0, 0.0), "swipe_right": (1.0, 0.0, 0.0),
              "swipe_up": (0.0, 1.0, 0.0), "swipe_down": (0.0, -1.0, 0.0)}


def calibration_path(data_dir: Path, user: str) -> Path:
    """Returns the file of a user's calibration: ``<data_dir>/calibration/<user>.json``."""
    return Path(data_dir) / "calibration" / f"{user}.json"


@dataclass(frozen=True)
class Pace:
    """A person's typical swipe speed, and the lines it sets.

    Attributes:
        user: who demonstrated.
        typical_mm_s: the median of the demonstrated swipes' palm speeds (`Window.peak_mm_s`).
        takes: how many swipes were demonstrated.
    """

    user: str
    typical_mm_s: float
    takes: int

    def applied(self, config: SegmenterConfig) -> SegmenterConfig:
        """Returns `config` with this person's lines and start speed (never above its own)."""
        line = max(PACE_FLOOR_MM_S, PACE_SHARE * self.typical_mm_s)
        final = min(config.min_peak_speed_mm_s, line)
        scale = final / config.min_peak_speed_mm_s if config.min_peak_speed_mm_s > 0 else 1.0
        start = max(config.end_speed_mm_s, min(config.start_speed_mm_s, line))
        return replace(config, min_peak_speed_mm_s=final,
                       mid_peak_speed_mm_s=config.mid_peak_speed_mm_s * scale,
                       first_peak_speed_mm_s=min(config.first_peak_speed_mm_s, final),
                       start_speed_mm_s=start)


def pace_of(user: str, takes: list[Window]) -> Pace:
    """Returns the pace of a person's demonstrated swipes (their final windows).

    Raises:
        ValueError: no take.
    """
    if not takes:
        raise ValueError("no swipe to calibrate on")
    return Pace(user, float(np.median([w.peak_mm_s for w in takes])), len(takes))


def swipe_take(windows: list[Window], gesture: str) -> Window | None:
    """Returns the final window that goes farthest along the swipe's direction (its take).

    None when no final window moves at least half its way along that direction: the person
    moved another way.
    """
    way = DIRECTIONS[gesture]
    best, best_mm = None, 0.0
    for window in windows:
        if not window.final:
            continue
        delta = window.obs[-1, :3] - window.obs[0, :3]
        along = float(sum(d * w for d, w in zip(delta, way, strict=True)))
        if along > best_mm and along >= 0.5 * math.hypot(*delta):
            best, best_mm = window, along
    return best


def save_pace(path: Path, pace: Pace, peaks: dict[str, list[float]]) -> None:
    """Writes a user's calibration file (the swipes' peak speeds by gesture, and the pace)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"format": FORMAT, "version": 1, "user": pace.user, "created": time.time(),
            "dynamic": {"typical_mm_s": pace.typical_mm_s, "takes": pace.takes,
                        "peak_mm_s": peaks}}
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)


def read_pace(path: Path) -> Pace:
    """Reads a user's calibration file.

    Raises:
        ValueError: unreadable, another format, or no usable speed in it.
    """
    try:
        data = json.loads(Path(path).read_text())
        block = data["dynamic"]
        typical, takes = float(block["typical_mm_s"]), int(block["takes"])
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: not a calibration file ({e})") from None
    if data.get("format") != FORMAT or not (math.isfinite(typical) and typical > 0):
        raise ValueError(f"{path}: not a {FORMAT} file with a positive typical_mm_s")
    return Pace(str(data.get("user", Path(path).stem)), typical, takes)


class Paces:
    """Each user's calibration under a data directory, re-read when its file changes."""

    def __init__(self, data_dir: Path):
        self.data_dir = Path(data_dir)
        self._cache: dict[str, tuple[float, Pace | None]] = {}
        self.skipped: dict[str, str] = {}

    def get(self, user: str) -> Pace | None:
        """Returns the user's pace, None without a (usable) calibration file."""
        path = calibration_path(self.data_dir, user)
        try:
            stamp = path.stat().st_mtime
        except OSError:
            self._cache.pop(user, None)
            return None
        cached = self._cache.get(user)
        if cached is not None and cached[0] == stamp:
            return cached[1]
        try:
            pace = read_pace(path)
            self.skipped.pop(user, None)
        except ValueError as e:
            pace = None
            self.skipped[user] = str(e)
        self._cache[user] = (stamp, pace)
        return pace
