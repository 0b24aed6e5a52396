"""Episode boundaries from hand visibility, with a debounce.

An episode starts with the first frame that shows a hand and ends once no hand has been seen for
``debounce_s`` (default 0.15 s), so a tracking dropout of a frame or two does not split it. The
end condition is met at *last hand frame + debounce*; it is detected by whichever comes first:

- **frame**: a frame without a hand whose ``ts`` is at least ``debounce_s`` after the last
  hand frame's. Sensors keep streaming empty frames when nobody is in view, so this is the
  usual path; it is exact on the frames' clock but waits for the next frame (up to one frame
  period late). Only such a frame shows the hand gone: a hand frame after a gap in which no
  frame came (frames lost on a busy network, seen as a jump in ``seq``) continues the episode,
  unless the gap is as long as the clock's wait below (``debounce_s + clock_slack_s``); then
  it ends the old episode and starts a new one.
- **clock**: the service's clock (monotonic, local) says ``debounce_s`` plus a slack
  (``clock_slack_s``) have passed since the last hand frame *arrived*: frames that come late in
  a burst (a stalled process, a busy network) must not end an episode whose hand is still
  there. It catches the end between frames, and when frames stop coming at
  all (a sensor unplugged, a replay at its end).

Each `Boundary` carries the local clock time at which the end condition was met (last hand
arrival + debounce, + the slack on the clock path), so the service can measure its end →
summary latency.

Pure logic: times are passed in, nothing here reads a clock or imports Zenoh.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Frame stamps are a sensor's (or a clock's) and jitter, and k frame periods add up to a hair
# less than k/rate in floating point: without a tolerance, at 60 Hz the 9th empty frame
# (0.15 s) would miss the default debounce and the 10th end the episode, 17 ms late.
STAMP_TOLERANCE_S = 0.002


@dataclass(frozen=True)
class Boundary:
    """The start or the end of an episode.

    Attributes:
        kind: ``start`` or ``end``.
        ts: the first (start) or last (end) hand frame's time, on the frames' clock.
        by: what detected it: ``frame`` (the frames' time stamps) or ``clock`` (the local
            clock: the service's timer, or an empty frame that arrived late).
        condition_at: local clock time the condition was met: the first hand frame's arrival
            (start), or the last hand frame's arrival + debounce (end by frame) or + debounce
            + clock slack (end by clock).
    """

    kind: str
    ts: float
    by: str
    condition_at: float


class Segmenter:
    """Follows hand visibility and reports episode boundaries.

    Args:
        debounce_s: how long no hand must be seen before the episode ends.
        clock_slack_s: how much longer the local clock waits: frames that arrive late (a
            loaded machine, a busy network) must not cut a gesture in two; the frames' own
            time stamps still end it after exactly `debounce_s`.
    """

    def __init__(self, debounce_s: float, clock_slack_s: float = 0.0):
        if not debounce_s > 0:
            raise ValueError(f"debounce_s must be positive, got {debounce_s}")
        if clock_slack_s < 0:
            raise ValueError(f"clock_slack_s must not be negative, got {clock_slack_s}")
        self.debounce_s = debounce_s
        self.clock_wait_s = debounce_s + clock_slack_s
        self.open = False
        self.started_ts = math.nan
        self.last_hand_ts = math.nan
        self.last_hand_at = math.nan

    def frame(self, ts: float, now: float, visible: bool) -> list[Boundary]:
        """Takes one frame; returns the boundaries it causes (end, start, or both).

        Args:
            ts: the frame's time stamp (frames' clock).
            now: the local clock when the frame is handled.
            visible: whether the frame shows at least one hand.
        """
        out = []
        # A frame without a hand is evidence the hand has gone; a gap without frames is not.
        wait = self.clock_wait_s if visible else self.debounce_s
        if self.open and ts - self.last_hand_ts >= wait - STAMP_TOLERANCE_S:
            out.append(self._end("frame"))
        if visible:
            if not self.open:
                self.open, self.started_ts = True, ts
                out.append(Boundary("start", ts, "frame", now))
            self.last_hand_ts, self.last_hand_at = ts, now
        elif self.open and now - self.last_hand_at >= self.clock_wait_s:
            out.append(self._end("clock"))  # the frame came late: the local clock decides
        return out

    def tick(self, now: float) -> Boundary | None:
        """Checks the end condition on the local clock (between frames, or without frames)."""
        if self.open and now - self.last_hand_at >= self.clock_wait_s:
            return self._end("clock")
        return None

    def _end(self, by: str) -> Boundary:
        self.open = False
        wait = self.clock_wait_s if by == "clock" else self.debounce_s
        return Boundary("end", self.last_hand_ts, by, self.last_hand_at + wait)
