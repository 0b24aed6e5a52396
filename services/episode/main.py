"""episode: gesture episodes, their evidence, the gesture vector g, focus and metric parameters.

Behaviour (the contract is services/episode/README.md):
- an episode starts with the first ``cbgo/hands/frame`` showing a hand and ends once no hand has
  been seen for ``debounce_s`` (`segmenter`); ``cbgo/episode/event`` says ``start``, each
  ``trigger`` and ``end``;
- static and dynamic gesture probabilities accumulate evidence; a gesture passing E_t triggers
  and the current probability vector is saved (`evidence`);
- at the end, ``cbgo/episode/summary``: g (element-wise max of the saved vectors), the triggers,
  metric parameters from the hand (`params`), the focus from gaze or pointing (`focus`) and the
  user (last ``cbgo/user``, else ``--user``).

Timing: the end condition (last hand frame + debounce) is checked on every frame and on a 5 ms
timer (frames may stop coming), and the summary is built and returned by that same handler, so
it is published at once (measured: ``cbgo bench episode``; the service's own part is served in
status as ``end_latency_ms``).

Late messages: gesture messages are accepted while their episode is open, including the
debounce after the hand left (a stroke window published as the hand leaves still counts). The
summary is never held back for stragglers; a gesture message about a finished episode is
counted as ``late`` and dropped, one about no episode at all as ``outside``.
"""

from __future__ import annotations

import secrets
import time
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from cbgo import keys, wire
from cbgo.config import described as _help
from cbgo.errors import ConfigError
from cbgo.evidence import EvidenceSettings, Trigger
from cbgo.examples import example
from cbgo.runtime import Service, main_for
from cbgo.services.episode.builder import BuilderSettings, EpisodeBuilder
from cbgo.services.episode.segmenter import Boundary, Segmenter
from cbgo.transform import default_to_base, parse_to_base

FOCUS_SOURCES = ("gaze", "pointing")
LATENCY_WINDOW = 1000  # episodes kept for the status's latency figures


@dataclass
class EpisodeSettings:
    """Settings of the episode service (flags ``--debounce-s`` ... or env ``CBGO_DEBOUNCE_S``)."""

    debounce_s: float = field(default=0.15, metadata=_help(
        "an episode ends once no hand has been seen for this long, s (0.02-2)"))
    check_period_s: float = field(default=0.005, metadata=_help(
        "how often the end condition is checked between frames, s"))
    clock_slack_s: float = field(default=2.0, metadata=_help(
        "the local clock ends an episode only this long after the debounce (frames that "
        "arrive late must not split a gesture; frame time stamps end it on time), s"))
    evidence: EvidenceSettings = field(default_factory=EvidenceSettings, metadata=_help(
        "the evidence model (`evidence.EvidenceSettings`): --evidence.threshold ..."))
    user: str = field(default="user1", metadata=_help(
        "the operator until cbgo/user names one"))
    focus: list[str] = field(default_factory=lambda: list(FOCUS_SOURCES), metadata=_help(
        "focus sources in order of preference: gaze, pointing"))
    min_gaze_points: int = field(default=3, metadata=_help(
        "fewer gaze points in an episode count as no gaze"))
    gaze_lookback_s: float = field(default=0.5, metadata=_help(
        "gaze up to this long before the episode's start counts for its focus, s"))
    max_ray_m: float = field(default=3.0, metadata=_help(
        "pointing rays hitting the table farther than this are ignored, m"))
    max_frames: int = field(default=36_000, metadata=_help(
        "frames kept per episode (5 min at 120 Hz); older ones are forgotten"))

    def __post_init__(self):
        if not 0.02 <= self.debounce_s <= 2.0:
            raise ConfigError(f"debounce_s={self.debounce_s} must be within 0.02-2 s")
        if not 0.001 <= self.check_period_s <= self.debounce_s:
            raise ConfigError(f"check_period_s={self.check_period_s} must be within 0.001 s "
                              "and debounce_s")
        if not 0.0 <= self.clock_slack_s <= 5.0:
            raise ConfigError(f"clock_slack_s={self.clock_slack_s} must be within 0-5 s")
        if not self.max_ray_m > 0:
            raise ConfigError(f"max_ray_m={self.max_ray_m} must be positive")
        if self.gaze_lookback_s < 0:
            raise ConfigError(f"gaze_lookback_s={self.gaze_lookback_s} must not be negative")
        bad = [f for f in self.focus if f not in FOCUS_SOURCES]
        if bad or not self.focus:
            raise ConfigError(f"focus {self.focus}: use one or both of {', '.join(FOCUS_SOURCES)}")
        if not self.user:
            raise ConfigError("user must not be empty")
        if self.min_gaze_points < 1 or self.max_frames < 10:
            raise ConfigError("min_gaze_points must be >= 1 and max_frames >= 10")

    def builder(self) -> BuilderSettings:
        """Returns the settings of one episode's builder."""
        return BuilderSettings(self.evidence, tuple(self.focus), self.min_gaze_points,
                               self.max_ray_m, self.max_frames)


@dataclass
class _Closed:
    """What is remembered of the last finished episode, to tell late messages apart."""

    episode: str
    first_seq: int
    started: float


class Episode(Service):
    """Segments episodes and publishes their events and summaries.

    Attributes:
        clock: the local monotonic clock of the end condition (tests replace it).
        wall: the wall clock of outgoing time stamps.
    """

    name = "episode"
    description = ("Groups the gesture stream into episodes and publishes cbgo/episode/event "
                   "and one cbgo/episode/summary per episode (gesture vector g, focus, params).")
    settings_class = EpisodeSettings

    def __init__(self, settings: EpisodeSettings):
        super().__init__(settings)
        self.clock, self.wall = time.monotonic, time.time
        self.segmenter = Segmenter(settings.debounce_s, settings.clock_slack_s)
        self.builder_settings = settings.builder()
        self.current: EpisodeBuilder | None = None
        self.closed: _Closed | None = None
        self.user = settings.user
        self.recent_gaze: deque[tuple[float, list[float]]] = deque(maxlen=1024)
        self.count = 0
        self.stray = Counter({"late": 0, "outside": 0})
        self.ended_by = Counter({"frame": 0, "clock": 0})
        self.latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._tag = secrets.token_hex(2)  # tells episodes of two service runs apart
        self._to_base: tuple[list[float] | None, np.ndarray | None] = (None, None)

    def setup(self, ctx) -> None:
        """Called once before the service is announced alive: inputs, outputs, the timer."""
        self.ctx = ctx
        ctx.subscribe(keys.HANDS_FRAME, self.on_frame)
        ctx.subscribe(keys.GESTURES_STATIC, self.on_static)
        ctx.subscribe(keys.GESTURES_DYNAMIC, self.on_dynamic)
        ctx.subscribe(keys.GAZE, self.on_gaze)
        ctx.subscribe(keys.USER, self.on_user)
        ctx.publishes(keys.EPISODE_EVENT, keys.EPISODE_SUMMARY)
        ctx.every(self.settings.check_period_s, self.on_tick)
        self._warm_up()

    def _warm_up(self) -> None:
        """Builds one summary from example messages, publishing nothing.

        The first real summary must not pay for lazy imports and first calls (numpy's median
        imports numpy.ma: ~50 ms), or the first episode of a run would be late.
        """
        to_base = default_to_base()
        frame = example("hands/frame", ts=1.0, seq=1, to_base=to_base.reshape(-1).tolist())
        ep = EpisodeBuilder("warm-up", 1.0, 1, self.builder_settings, [[0.5, 0.0, 0.0]] * 3)
        for seq, label in ((1, "point"), (2, "pinch")):
            ep.add_frame({**frame, "seq": seq, "ts": float(seq)}, to_base)
            names = [label, wire.NO_GESTURE]
            ep.add_static({**example("gestures/static"), "seq": seq, "ts": float(seq),
                           "names": names, "probs": [1.0, 0.0]})
        for name in ("rotate", "swipe_down"):
            ep.add_dynamic({**example("gestures/dynamic"), "names": [name, wire.NO_GESTURE],
                            "probs": [1.0, 0.0], "window": [1.0, 2.0]})
        wire.encode(wire.validate(ep.summary(2.0, "warm-up", 3.0), wire.EPISODE_SUMMARY))

    # ------------------------------------------------------------------ inputs

    def on_frame(self, msg: dict) -> list:
        """Follows hand visibility; keeps the frame's geometry for the open episode."""
        out = []
        for boundary in self.segmenter.frame(msg["ts"], self.clock(), bool(msg["hands"])):
            out += self._start(boundary, msg) if boundary.kind == "start" else self._end(boundary)
        if self.current is not None:
            self.current.add_frame(msg, self._transform(msg.get("to_base")))
        return out

    def on_static(self, msg: dict) -> list:
        """Adds static evidence to the open episode; returns trigger events."""
        if self.current is not None and self.current.owns_static(msg):
            return self._events(self.current.add_static(msg))
        late = self.closed is not None and msg["seq"] >= self.closed.first_seq
        self.stray["late" if late else "outside"] += 1
        return []

    def on_dynamic(self, msg: dict) -> list:
        """Adds dynamic evidence to the open episode; returns trigger events."""
        if self.current is not None and self.current.owns_dynamic(msg):
            return self._events(self.current.add_dynamic(msg))
        late = self.closed is not None and msg["window"][1] >= self.closed.started
        self.stray["late" if late else "outside"] += 1
        return []

    def on_gaze(self, msg: dict) -> None:
        """Keeps gaze for the open episode, and a short history for the next one."""
        self.recent_gaze.append((msg["ts"], msg["point"]))
        if self.current is not None:
            self.current.add_gaze(msg["point"])

    def on_user(self, msg: dict) -> None:
        """Remembers the operator."""
        self.user = msg["user"]

    def on_tick(self) -> list:
        """Timer: ends the episode when no hand frame came for the debounce."""
        boundary = self.segmenter.tick(self.clock())
        return self._end(boundary) if boundary is not None else []

    # ------------------------------------------------------------------ episodes

    def _start(self, boundary: Boundary, frame: dict) -> list:
        self.count += 1
        stamp = time.strftime("%Y%m%dT%H%M%S", time.gmtime(boundary.ts))
        episode = f"ep-{stamp}-{self._tag}-{self.count:04d}"
        horizon = boundary.ts - self.settings.gaze_lookback_s
        gaze = [p for ts, p in self.recent_gaze if ts >= horizon]
        self.current = EpisodeBuilder(episode, boundary.ts, frame["seq"], self.builder_settings,
                                      gaze)
        return [(keys.EPISODE_EVENT, keys.EPISODE_EVENT.message(ts=boundary.ts,
                                      episode=episode, kind="start"))]

    def _end(self, boundary: Boundary) -> list:
        ep = self.current
        if ep is None:
            return []
        self.current = None
        self.closed = _Closed(ep.episode, ep.first_seq, ep.started)
        now = self.wall()
        summary = ep.summary(boundary.ts, self.user, now)
        self.latencies.append(max(0.0, self.clock() - boundary.condition_at))
        self.ended_by[boundary.by] += 1
        self.ctx.log.info("%s: %.2f s, triggers %s, focus %s, params %s", ep.episode,
                          summary["ended"] - summary["started"],
                          [t["gesture"] for t in summary["triggers"]] or "none",
                          summary["focus_source"], summary["params"] or "none")
        end = keys.EPISODE_EVENT.message(ts=now, episode=ep.episode, kind="end")
        return [(keys.EPISODE_EVENT, end), (keys.EPISODE_SUMMARY, summary)]

    def _events(self, triggers: list[Trigger]) -> list:
        return [(keys.EPISODE_EVENT, keys.EPISODE_EVENT.message(
            ts=t.ts, episode=self.current.episode, kind="trigger", gesture=t.gesture,
            prob=t.prob)) for t in triggers]

    def _transform(self, values: list[float] | None) -> np.ndarray | None:
        """Returns the frame's to_base as a matrix (parsed once per distinct value)."""
        if values is None:
            return None
        if values != self._to_base[0]:
            try:
                matrix = parse_to_base(values)
            except ConfigError as e:
                self.ctx.rejects.warning("to_base", f"ignoring the frames' to_base: {e}")
                matrix = None
            self._to_base = (values, matrix)
        return self._to_base[1]

    def status_extra(self) -> dict:
        """Adds the open episode, episode counts, stray messages and end → summary latency."""
        lat = np.asarray(list(self.latencies)) * 1e3
        latency = {"n": int(lat.size)}
        if lat.size:
            latency.update(p50=float(np.percentile(lat, 50)), p99=float(np.percentile(lat, 99)),
                           max=float(lat.max()))
        current = self.current
        return {"episode": current.episode if current else None, "episodes": self.count,
                "user": self.user, "stray": dict(self.stray), "ended_by": dict(self.ended_by),
                "end_latency_ms": latency}


main = main_for(Episode)

if __name__ == "__main__":
    main()
