"""leap-bridge: publishes hand frames from a Leap Motion, a recording or a simulated user.

Behaviour (the contract is services/leap_bridge/README.md):
- one source per process: ``leap`` (a live sensor), ``replay`` (an MCAP recording made by
  `cbgo record`, or a JSON recording of the paper's gesture toolbox) or ``simulated`` (a
  scenario performed by simulated users with a kinematic hand);
- a pacing thread publishes ``cbgo/hands/frame`` on absolute deadlines (``--rate-hz`` for the
  simulated user, the recorded timing ÷ ``--speed`` for replays, as frames arrive for a sensor),
  each scheduled frame stamped with its deadline (its capture time; a stall delays delivery
  but leaves no gap in the stamps);
  after a simulated scenario or a replay ends, frames with no hand keep coming at the rate, as
  from a sensor nobody is using;
- every frame carries the configured Leap→base transform (``to_base``);
- ``cbgo/user`` is published when the operator changes and every 2 s; the simulated user's
  ``cbgo/gaze`` follows its target (an object name resolved in the latest ``cbgo/scene/state``,
  or a point), with eye-tracking noise;
- control verb ``@ctl/leap-bridge/play`` starts a scenario on demand (simulated source); its
  static steps may hold any pose given as finger curls (`cbgo.simuser.scenario`), which is how
  ``cbgo gestures record NAME --static --simulate CURLS`` teaches a gesture without a sensor.
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from cbgo import keys, wire
from cbgo.config import described as _help
from cbgo.errors import ConfigError, DeviceError, QueryError
from cbgo.runtime import EXIT_DEVICE, Service, main_for
from cbgo.services.leap_bridge.sources import LiveSource, ReplaySource, SimulatedStream
from cbgo.simuser.scenario import Scenario, load_scenario, parse_scenario
from cbgo.simuser.user import SourceFrame
from cbgo.transform import default_to_base, parse_to_base

SOURCES = ("simulated", "replay", "leap")
USER_REPEAT_S = 2.0  # republish the user so that late joiners learn it


@dataclass
class LeapBridgeSettings:
    """Settings of the leap-bridge (flags ``--source`` ... or env ``CBGO_SOURCE`` ...)."""

    source: str = field(default="simulated", metadata=_help(
        "where hands come from: simulated, replay or leap"))
    scenario: str | None = field(default=None, metadata=_help(
        "simulated: scenario file or bundled name (e.g. demo) to play at start; without one "
        "the user waits for @ctl/leap-bridge/play"))
    file: str | None = field(default=None, metadata=_help(
        "replay: an MCAP recording (cbgo record) or a gesture-toolbox JSON recording"))
    rate_hz: float = field(default=60.0, metadata=_help(
        "simulated frame rate, Hz (30-120); also the rate of empty frames when idle"))
    speed: float = field(default=1.0, metadata=_help("replay/scenario speed factor"))
    loop: bool = field(default=False, metadata=_help("replay or scenario: start over at the end"))
    user: str = field(default="user1", metadata=_help(
        "operator id published on cbgo/user (scenarios name their own users)"))
    device: str = field(default="", metadata=_help("device label in frames (default: source)"))
    sensor_position: list[float] = field(default_factory=lambda: [1.0, 0.0, 0.0], metadata=_help(
        "sensor's top centre in the robot base frame, m (x,y,z)"))
    sensor_yaw_deg: float = field(default=0.0, metadata=_help(
        "sensor rotation about the vertical, degrees (0: user faces the robot along -x)"))
    to_base: list[float] | None = field(default=None, metadata=_help(
        "full Leap(mm)->base(m) transform, 16 numbers row-major; overrides sensor_*"))
    gaze_rate_hz: float = field(default=30.0, metadata=_help("simulated gaze rate, Hz"))
    wait_for: list[str] = field(default_factory=list, metadata=_help(
        "services whose liveliness to wait for before starting the scenario or replay"))
    seed: int | None = field(default=None, metadata=_help("override the scenario's seed"))

    def __post_init__(self):
        if self.source not in SOURCES:
            raise ConfigError(f"source {self.source!r} is not one of {', '.join(SOURCES)}")
        if not 30.0 <= self.rate_hz <= 120.0:
            raise ConfigError(f"rate_hz={self.rate_hz} must be within 30-120 Hz")
        if not 0.05 <= self.speed <= 20.0:
            raise ConfigError(f"speed={self.speed} must be within 0.05-20")
        if self.source == "replay" and not self.file:
            raise ConfigError("--source replay needs a recording: --source replay FILE")
        if len(self.sensor_position) != 3:
            raise ConfigError("sensor_position needs 3 numbers (m)")
        if not 0.5 <= self.gaze_rate_hz <= 240.0:
            raise ConfigError(f"gaze_rate_hz={self.gaze_rate_hz} must be within 0.5-240")

    def transform(self) -> np.ndarray:
        """Returns the 4×4 Leap(mm)→base(m) transform these settings describe."""
        if self.to_base is not None:
            return parse_to_base(self.to_base)
        return default_to_base(self.sensor_position, self.sensor_yaw_deg)


class PaceStats:
    """Publish-interval statistics of the frame stream (served in status)."""

    def __init__(self, window: int = 1200):
        self.stamps: deque[float] = deque(maxlen=window)
        self.lateness: deque[float] = deque(maxlen=window)

    def add(self, now: float, late_s: float) -> None:
        """Records one publication and how late it was against its deadline."""
        self.stamps.append(now)
        self.lateness.append(late_s)

    def summary(self) -> dict:
        """Returns rate, interval mean/std/max and lateness p99 (ms) over the window."""
        if len(self.stamps) < 3:
            return {}
        dt = np.diff(np.asarray(self.stamps)) * 1e3
        return {"rate_hz": 1e3 / float(dt.mean()), "interval_mean_ms": float(dt.mean()),
                "interval_std_ms": float(dt.std()), "interval_max_ms": float(dt.max()),
                "late_p99_ms": float(np.percentile(np.asarray(self.lateness) * 1e3, 99))}


class LeapBridge(Service):
    """The source of hand frames."""

    name = "leap-bridge"
    description = ("Publishes cbgo/hands/frame from a Leap Motion sensor, a recording or a "
                   "simulated user; also cbgo/user and (simulated) cbgo/gaze.")
    settings_class = LeapBridgeSettings

    def __init__(self, settings: LeapBridgeSettings):
        super().__init__(settings)
        self.to_base = settings.transform()
        self.objects: dict[str, list[float]] = {}
        self.seq = 0
        self.stats = PaceStats()
        self._last_user: tuple[str | None, float] = (None, 0.0)
        self._last_gaze = 0.0
        self._gaze_rng = np.random.default_rng(settings.seed)
        self._thread: threading.Thread | None = None

    def setup(self, ctx) -> None:
        """Opens the source, declares outputs, and starts the pacing thread."""
        self.ctx = ctx
        self.stream = self._open_source()
        ctx.subscribe(keys.SCENE_STATE, self.on_scene_state)
        ctx.publishes(keys.HANDS_FRAME, keys.GAZE, keys.USER)
        if isinstance(self.stream, SimulatedStream):
            ctx.control("play", self.on_play)
        self._thread = threading.Thread(target=self._pace, name="pacing", daemon=True)
        self._thread.start()

    def _open_source(self):
        s = self.settings
        if s.source == "leap":
            return LiveSource(s.device or "leap")
        if s.source == "replay":
            return ReplaySource(s.file, s.speed, s.loop, s.rate_hz, s.device)
        scenario = self._scenario(load_scenario(s.scenario)) if s.scenario else None
        return SimulatedStream(s.rate_hz, scenario, s.loop, s.device or "simulated", s.speed,
                               self.resolve_target, self.to_base)

    def resolve_target(self, target: str | list[float]) -> list[float] | None:
        """Returns a gaze target in the base frame: a point as is, an object by its name."""
        return self.objects.get(target) if isinstance(target, str) else target

    def _scenario(self, scenario: Scenario) -> Scenario:
        if self.settings.seed is not None:
            scenario.seed = self.settings.seed
        return scenario

    def on_scene_state(self, msg: dict) -> None:
        """Remembers where each object is, for gaze targets given by name."""
        self.objects = {o["name"]: o["position"] for o in msg["objects"]}

    def on_play(self, query: dict) -> dict:
        """Control verb: queue a scenario ({scenario: name|path} or an inline scenario)."""
        try:
            if "episodes" in query:
                scenario = parse_scenario(query, "inline scenario")
            elif isinstance(query.get("scenario"), str):
                scenario = load_scenario(query["scenario"])
            else:
                raise QueryError("give {scenario: NAME|PATH} or an inline scenario with "
                                 "'episodes'")
        except ConfigError as e:
            raise QueryError(str(e)) from None
        duration = self.stream.play(self._scenario(scenario))
        return {"v": wire.SCHEMA_VERSION, "ok": True, "scenario": scenario.name,
                "episodes": len(scenario.episodes), "duration_s": duration}

    # ------------------------------------------------------------ pacing thread

    def _pace(self) -> None:
        try:
            for name in self.settings.wait_for:
                self.ctx.log.info("waiting for %s", name)
                while not self.ctx.wait_for_service(name, 1.0):
                    if self.ctx.stopping.is_set():
                        return
            self._pace_frames()
        except DeviceError as e:
            self.ctx.request_exit(EXIT_DEVICE, f"device fault: {e}")

    def _pace_frames(self) -> None:
        start = time.perf_counter()
        for frame in self.stream.frames(self.ctx.stopping):
            if self.ctx.stopping.is_set():
                return
            late = 0.0
            if frame.t is not None:
                deadline = start + frame.t / self.stream.speed
                wait = deadline - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                late = max(0.0, time.perf_counter() - deadline)
            # A scheduled frame (simulated, replayed) is stamped when it was due, its capture
            # time, as a sensor stamps a frame when it captures it: a stall of this process
            # delays delivery but is not a gap in the hand's motion (which would end an
            # episode in the middle of a gesture).
            self._publish(frame, time.time() - late)
            self.stats.add(time.perf_counter(), late)

    def _publish(self, frame: SourceFrame, now: float) -> None:
        """Publishes one frame captured at `now` (and the user and gaze that go with it)."""
        self.ctx.publish(keys.HANDS_FRAME, keys.HANDS_FRAME.message(
            ts=now, seq=self.seq, source=self.stream.kind, device=self.stream.device,
            hands=frame.hands, to_base=self.to_base.reshape(-1).tolist()))
        self.seq += 1
        self._publish_user(frame.user or self.settings.user, now)
        if frame.gaze is not None:
            self._publish_gaze(frame.gaze, now)

    def _publish_user(self, user: str, now: float) -> None:
        last_user, last_time = self._last_user
        if user != last_user or now - last_time >= USER_REPEAT_S:
            self.ctx.publish(keys.USER, keys.USER.message(ts=now, user=user))
            self._last_user = (user, now)

    def _publish_gaze(self, target, now: float) -> None:
        if now - self._last_gaze < 1.0 / self.settings.gaze_rate_hz:
            return
        point = self.resolve_target(target)
        if point is None:
            self.ctx.rejects.warning(f"gaze:{target}", f"gaze target {target!r} is not in the "
                                                       "latest scene; no gaze published")
            return
        noise = self._gaze_rng.normal(0.0, self.stream.gaze_noise_m(), 3)
        self.ctx.publish(keys.GAZE, keys.GAZE.message(ts=now,
                                     point=(np.asarray(point) + noise).tolist(),
                                     source="simulated"))
        self._last_gaze = now

    def status_extra(self) -> dict:
        """Adds the source and the measured pacing of the frame stream."""
        return {"source": self.stream.kind, "device": self.stream.device,
                "frames": self.seq, "pacing": self.stats.summary(),
                "playing": self.stream.describe()}

    def shutdown(self) -> None:
        """Stops the pacing thread (the runtime has set `stopping`)."""
        if self._thread is not None:
            self._thread.join(timeout=1.0)


def _normalise_argv(argv: list[str]) -> list[str]:
    """Accepts ``--source replay FILE`` and ``--source simulated FILE``.

    The trailing value becomes ``--file FILE`` / ``--scenario FILE``.
    """
    out = list(argv)
    for i, arg in enumerate(out[:-2]):
        if arg == "--source" and not out[i + 2].startswith("-"):
            flag = {"replay": "--file", "simulated": "--scenario"}.get(out[i + 1])
            if flag:
                out.insert(i + 2, flag)
                break
    return out


_run = main_for(LeapBridge)


def main(argv: list[str] | None = None) -> None:
    """Entry point of ``cbgo-leap-bridge``."""
    _run(_normalise_argv(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    main()
