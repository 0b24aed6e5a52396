"""One episode being collected: frames' geometry, gesture messages, gaze; then its summary.

The service opens an `EpisodeBuilder` at the episode's start, feeds it every message that
belongs to the episode, and asks for the summary at the end. Which messages belong:

- hand frames: every frame from the start to the end decision (with or without a hand);
- ``gestures/static``: messages whose ``seq`` (the frame's seq) is one of the episode's frames
  or later than its first frame; their time is the frame's ``ts`` when the frame is known;
- ``gestures/dynamic``: windows that end at or after the episode's first hand frame (a stroke
  window published just after the hand left still counts, as long as it arrives before the end
  decision);
- gaze: points received while the episode is open, plus those of a short look-back before it.

The summary's g lists the contract's vocabulary (8 static, 5 dynamic gestures) plus any other
gesture name seen, so every summary has the same names whatever was observed.

Pure logic (dicts and numpy); no Zenoh, no clock.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from cbgo import keys, wire
from cbgo.evidence import Evidence, EvidenceSettings, Trigger, gesture_vector
from cbgo.services.episode import focus as focus_mod
from cbgo.services.episode.params import (
    HandSample,
    aperture,
    hand_sample,
    rotate_angle,
    stroke_length,
)
from cbgo.wire import DYNAMIC_GESTURES, STATIC_GESTURES

SWIPES = ("swipe_up", "swipe_down", "swipe_left", "swipe_right")


@dataclass
class BuilderSettings:
    """What an episode needs to know beyond its messages.

    Attributes:
        evidence: the evidence model.
        focus: focus sources in order of preference (``gaze``, ``pointing``).
        min_gaze_points: fewer gaze points count as no gaze.
        max_ray_m: the longest pointing ray to the table considered, m.
        max_frames: frames kept per episode (the oldest are forgotten beyond this).
    """

    evidence: EvidenceSettings = field(default_factory=EvidenceSettings)
    focus: tuple[str, ...] = ("gaze", "pointing")
    min_gaze_points: int = 3
    max_ray_m: float = 3.0
    max_frames: int = 36_000


@dataclass
class Window:
    """One dynamic window of the episode."""

    t0: float
    t1: float
    side: str
    probs: dict[str, float]


class EpisodeBuilder:
    """Collects one episode.

    Args:
        episode: the episode id.
        started: the first hand frame's time.
        first_seq: the first hand frame's seq.
        settings: see `BuilderSettings`.
        gaze: gaze points (base frame) seen just before the start.
    """

    def __init__(self, episode: str, started: float, first_seq: int,
                 settings: BuilderSettings | None = None, gaze: list | None = None):
        self.episode, self.started, self.first_seq = episode, started, first_seq
        self.settings = settings or BuilderSettings()
        self.evidence = Evidence(self.settings.evidence)
        self.frames: OrderedDict[int, tuple[float, list[HandSample]]] = OrderedDict()
        self.labels: dict[tuple[int, str], str] = {}
        self.windows: list[Window] = []
        self.gaze: list[list[float]] = list(gaze or [])
        self.replayed = False  # it has frames of a recording (`cbgo replay`)

    # ------------------------------------------------------------------ input

    def add_frame(self, frame: dict, to_base: np.ndarray | None) -> None:
        """Keeps the geometry of a frame's hands, and whether the frame was replayed."""
        self.replayed |= frame.get(wire.REPLAYED) is True
        samples = [hand_sample(frame["ts"], frame["seq"], h, to_base) for h in frame["hands"]]
        self.frames[frame["seq"]] = (frame["ts"], samples)
        while len(self.frames) > self.settings.max_frames:
            seq, (_, old) = self.frames.popitem(last=False)
            for s in old:
                self.labels.pop((seq, s.side), None)

    def owns_static(self, msg: dict) -> bool:
        """Returns whether a static message is about one of this episode's frames."""
        return msg["seq"] in self.frames or msg["seq"] >= self.first_seq

    def add_static(self, msg: dict) -> list[Trigger]:
        """Takes a static message of this episode; returns the triggers it causes."""
        known = self.frames.get(msg["seq"])
        t = known[0] if known else msg["ts"]
        names, probs = msg["names"], msg["probs"]
        self.labels[(msg["seq"], msg["side"])] = names[int(np.argmax(probs))]
        return self.evidence.static(t, msg["side"], names, probs)

    def owns_dynamic(self, msg: dict) -> bool:
        """Returns whether a dynamic window overlaps this episode."""
        return msg["window"][1] >= self.started

    def add_dynamic(self, msg: dict) -> list[Trigger]:
        """Takes a dynamic message of this episode; returns the triggers it causes."""
        t0, t1 = msg["window"]
        self.windows.append(Window(t0, t1, msg["side"], dict(zip(msg["names"], msg["probs"],
                                                                  strict=True))))
        return self.evidence.dynamic((t0, t1), msg["side"], msg["names"], msg["probs"])

    def add_gaze(self, point: list[float]) -> None:
        """Keeps one gaze point (base frame, m)."""
        if len(self.gaze) < self.settings.max_frames:
            self.gaze.append(point)

    # ------------------------------------------------------------------ output

    def _samples(self, label: str | None = None) -> list[HandSample]:
        out = []
        for seq, (_, samples) in self.frames.items():
            out += [s for s in samples if label is None or self.labels.get((seq, s.side)) == label]
        return out

    def _labelled(self) -> list[HandSample]:
        return [s for seq, (_, samples) in self.frames.items() for s in samples
                if self.evidence.is_gesture(self.labels.get((seq, s.side), wire.NO_GESTURE))]

    def _window_for(self, gestures: tuple[str, ...]) -> tuple[Window, str] | None:
        """The stroke window of a gesture of `gestures`: the triggered one's, or any's.

        Of the windows whose most probable gesture is a triggered one of `gestures` (any of
        `gestures` when none triggered), the most confident stroke's: a pose released just
        before a rotate rolls the palm too, and may trigger first, but is less rotate-like.
        A dynamic classifier evaluates growing windows of one stroke (same start): the longest
        of them covers the whole stroke.
        """
        triggered = {t.gesture for t in self.evidence.triggers
                     if t.gesture in gestures and t.window is not None}
        wanted = triggered or set(gestures)
        best = None
        for w in self.windows:
            top = max(w.probs, key=w.probs.get)
            if top in wanted and (best is None or w.probs[top] > best[0].probs[best[1]]):
                best = (w, top)
        if best is None:
            return None
        stroke = [w for w in self.windows if w.side == best[0].side and w.t0 == best[0].t0]
        return max(stroke, key=lambda w: w.t1 - w.t0), best[1]

    def _in_window(self, w: Window) -> list[HandSample]:
        inside = [s for _, (ts, samples) in self.frames.items() if w.t0 <= ts <= w.t1
                  for s in samples]
        same_side = [s for s in inside if s.side == w.side]
        return same_side or inside

    def params(self) -> dict:
        """Returns the auxiliary metric parameters (see `cbgo.services.episode.params`)."""
        out: dict = {}
        distance = aperture(self._samples("pinch") or self._labelled())
        if distance is not None:
            out["distance"] = distance
        rotate = self._window_for(("rotate",))
        if rotate is not None and (angle := rotate_angle(self._in_window(rotate[0]))) is not None:
            out["angle_deg"] = angle
        swipe = self._window_for(SWIPES)
        if swipe is not None and (length := stroke_length(self._in_window(swipe[0]))) is not None:
            out["move_distance"] = length
        return out

    def focus(self) -> tuple[list[float] | None, str | None]:
        """Returns (focus, focus_source) (see `cbgo.services.episode.focus`)."""
        rays = [s.ray for s in self._samples("point") if s.ray is not None]
        return focus_mod.choose_focus(self.settings.focus, self.gaze, rays,
                                      self.settings.min_gaze_points, self.settings.max_ray_m)

    def summary(self, ended: float, user: str, now: float) -> dict:
        """Returns the ``episode/summary`` message.

        Args:
            ended: the last hand frame's time.
            user: the operator.
            now: the wall-clock time of the summary (its ``ts``).
        """
        triggers = self.evidence.triggers
        vocabulary = [n for n in (*STATIC_GESTURES, *DYNAMIC_GESTURES, *self.evidence.names)
                      if self.evidence.is_gesture(n)]
        names, probs = gesture_vector([t.snapshot for t in triggers], vocabulary)
        focus, source = self.focus()
        summary = keys.EPISODE_SUMMARY.message(ts=now, episode=self.episode, user=user,
            started=self.started, ended=max(ended, self.started),
            gestures={"names": names, "probs": probs},
            triggers=[{"gesture": t.gesture, "ts": t.ts, "prob": t.prob} for t in triggers],
            params=self.params(), focus=focus, focus_source=source)
        if self.replayed:  # made of recorded hands: what follows from it is marked too
            summary[wire.REPLAYED] = True
        return summary
