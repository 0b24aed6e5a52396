"""Calibrate the swipes to one person: ``cbgo gestures calibrate --user NAME``.

The person makes each swipe ``--takes`` times (rest the hand, swipe once, take the hand away);
each appearance of the hand gives one take: its stroke that goes farthest the asked way
(`pace.swipe_take`), found by the service's segmenter with no slow-move line, so that a slow
swipe is caught. An appearance with no stroke the asked way is refused and asked again. The
takes' peak speeds go to ``<data dir>/calibration/NAME.json``; a running dynamic-gesture
re-reads it within its ``--watch-s`` and judges the person's strokes by it whenever
``cbgo/user`` names them (`pace`).

Frames come live from ``cbgo/hands/frame`` or, with ``--file``, from an MCAP recording.

Examples::

    cbgo gestures calibrate --user alice --takes 3
    cbgo gestures calibrate --user alice --file alice-swipes.mcap
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from cbgo.config import data_dir
from cbgo.errors import ConfigError
from cbgo.services.dynamic_gesture import demonstrate
from cbgo.services.dynamic_gesture.pace import (
    SWIPES,
    calibration_path,
    pace_of,
    save_pace,
    swipe_take,
)
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig, Window

DEFAULT_TAKES = 3


def unlined(config: SegmenterConfig | None = None) -> SegmenterConfig:
    """Returns the segmenter settings with no slow-move line: every stroke is seen."""
    return replace(config or SegmenterConfig(), min_peak_speed_mm_s=0.0,
                   mid_peak_speed_mm_s=0.0, first_peak_speed_mm_s=0.0)


class SwipeRecorder:
    """Takes of each swipe in turn: one per appearance of the hand, the asked way.

    Args:
        takes: takes of each swipe.
        gestures: the swipes, in the order asked.
    """

    def __init__(self, takes: int, gestures: tuple[str, ...] = SWIPES):
        self.gestures, self.per_gesture = gestures, takes
        self.wanted = takes * len(gestures)
        self.segmenter = Segmenter(unlined())
        self.takes: list[Window] = []
        self.refused = 0
        self._windows: dict[int, list[Window]] = {}  # per hand id in view: its final windows

    @property
    def done(self) -> bool:
        """Whether every take was captured."""
        return len(self.takes) >= self.wanted

    @property
    def asked(self) -> str:
        """The swipe asked for now."""
        return self.gestures[min(len(self.takes), self.wanted - 1) // self.per_gesture]

    def prompt(self) -> str:
        """What the person does for the next take."""
        k = len(self.takes) % self.per_gesture + 1
        return (f"{self.asked.replace('_', ' ')} ({k}/{self.per_gesture}): rest the hand, "
                "swipe once at your own pace, take the hand away")

    def feed(self, t: float, hands: list[dict]) -> Window | None:
        """Feeds one frame; returns the take captured when a hand just left with one."""
        for window in self.segmenter.update(t, hands):
            if window.final:
                self._windows.setdefault(window.hand_id, []).append(window)
        for hand in hands:
            self._windows.setdefault(int(hand["id"]), [])
        present = {int(hand["id"]) for hand in hands}
        new = None
        for hand_id in [h for h in self._windows if h not in present]:
            windows = self._windows.pop(hand_id)
            if self.done or not windows:
                continue
            take = swipe_take(windows, self.asked)
            if take is None:
                self.refused += 1
                demonstrate.say(f"no {self.asked.replace('_', ' ')} seen; again: "
                                 + self.prompt())
            else:
                self.takes.append(take)
                new = take
        return new

    def peaks(self) -> dict[str, list[float]]:
        """Returns each swipe's takes' peak speeds (mm/s)."""
        out: dict[str, list[float]] = {g: [] for g in self.gestures}
        for i, take in enumerate(self.takes):
            out[self.gestures[i // self.per_gesture]].append(round(take.peak_mm_s, 1))
        return out


def run(args: argparse.Namespace) -> int:
    """Records the takes and writes the user's calibration (``cbgo gestures calibrate``).

    Args:
        args: ``user``, ``takes``, ``timeout``, optionally ``file``, and the Zenoh flags of
            `cbgo.client.add_network_arguments`.

    Returns:
        0 on success, 1 if the takes were not all captured in time, 2 for a bad user or file.
    """
    from cbgo.services.dynamic_gesture.library import check_name

    try:
        user = check_name(args.user)
    except ConfigError:
        print(f"cbgo: user name {args.user!r} is not valid: letters, digits, '_', '.', '-'",
              file=sys.stderr)
        return 2
    recorder = SwipeRecorder(int(args.takes or DEFAULT_TAKES))  # the CLI checked: ≥ 1
    if getattr(args, "file", None):
        try:
            demonstrate.record_from_file(recorder, args.file)
        except ConfigError as e:
            print(f"cbgo: {e}", file=sys.stderr)
            return 2
    else:
        from cbgo.client import session

        with session(args, "cbgo-gestures-calibrate") as (sess, prefix_keys):
            demonstrate.record_live(recorder, sess, prefix_keys, float(args.timeout))
    return finish(recorder, user)


def finish(recorder: SwipeRecorder, user: str) -> int:
    """Writes the calibration of a complete recording; returns the exit code."""
    if not recorder.done:
        print(f"cbgo: only {len(recorder.takes)} of {recorder.wanted} takes captured; nothing "
              "saved", file=sys.stderr)
        return 1
    pace = pace_of(user, recorder.takes)
    path = calibration_path(data_dir(), user)
    save_pace(path, pace, recorder.peaks())
    lines = pace.applied(SegmenterConfig())
    demonstrate.say(f"saved {user}'s calibration to {path}: typical swipe "
                    f"{pace.typical_mm_s:.0f} mm/s, strokes heard from "
                    f"{lines.min_peak_speed_mm_s:.0f} mm/s while cbgo/user names {user}")
    return 0
