"""The three sources of hand frames, behind one interface the pacing thread consumes.

Each source has ``kind`` (the frame's ``source`` field), ``device``, ``speed`` and
``frames(stop)``: an iterator of `SourceFrame` whose ``t`` is seconds on the source's own
timeline (the pacer publishes it at ``start + t / speed``) or None (publish at once: a live
sensor). When a scenario or a recording is over, sources keep yielding frames with no hand at
the configured rate, like a sensor that nobody uses.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from pathlib import Path

from cbgo.errors import ConfigError, RecordingError
from cbgo.simuser.scenario import Scenario
from cbgo.simuser.user import SimulatedUser, SourceFrame


class SimulatedStream:
    """Simulated users performing scenarios, queued with `play`; idle frames in between.

    Args:
        rate_hz: frame rate.
        scenario: a scenario to play at start, or None.
        loop: play each scenario again when it ends.
        device: the device label in frames.
        speed: playback speed factor.
        resolve: gaze target -> base-frame point (see SimulatedUser).
        to_base: the Leap->base transform (for aiming a pointing hand).
    """

    kind = "simulated"

    def __init__(self, rate_hz: float, scenario: Scenario | None, loop: bool, device: str,
                 speed: float = 1.0, resolve=None, to_base=None):
        self.rate_hz, self.loop, self.device, self.speed = rate_hz, loop, device, speed
        self.resolve, self.to_base = resolve, to_base
        self._pending: queue.Queue = queue.Queue()
        self._playing: str | None = None
        self._gaze_noise = 0.0
        if scenario is not None:
            self.play(scenario)

    def play(self, scenario: Scenario) -> float:
        """Queues a scenario; returns its duration in seconds (at speed 1)."""
        duration = SimulatedUser(scenario, self.rate_hz).duration()
        self._pending.put(scenario)
        return duration

    def gaze_noise_m(self) -> float:
        """Eye-tracking noise of the user now performing (m)."""
        return self._gaze_noise

    def describe(self) -> str | None:
        """The scenario being played, if any."""
        return self._playing

    def frames(self, stop: threading.Event) -> Iterator[SourceFrame]:
        """Yields frames forever: queued scenarios, and empty frames while idle."""
        t, dt, loops = 0.0, 1.0 / self.rate_hz, 0
        while not stop.is_set():
            try:
                scenario = self._pending.get_nowait()
            except queue.Empty:
                self._playing = None
                yield SourceFrame(t, [])
                t += dt
                continue
            self._playing = scenario.name
            user = SimulatedUser(scenario, self.rate_hz, self.resolve, self.to_base)
            for frame in user.frames(loops):
                self._gaze_noise = scenario.users[frame.user].gaze_noise_m
                frame.t = t
                t += dt
                yield frame
                if stop.is_set():
                    return
            loops += 1
            if self.loop:
                self._pending.put(scenario)


class ReplaySource:
    """A recording played back at its recorded pace (÷ speed).

    Args:
        path: an MCAP file made by `cbgo record`, or a gesture-toolbox JSON recording.
        speed: playback speed factor.
        loop: start over at the end.
        idle_rate_hz: rate of empty frames after the end.
        device: device label (default: the file name).

    Raises:
        ConfigError: the file is missing, unreadable or holds no hand frames.
    """

    kind = "replay"

    def __init__(self, path: str, speed: float, loop: bool, idle_rate_hz: float,
                 device: str = ""):
        self.speed, self.loop, self.idle_rate_hz = speed, loop, idle_rate_hz
        self.device = device or Path(path).name
        try:
            self.frames_data = _load_replay(path)
        except RecordingError as e:
            raise ConfigError(f"cannot replay {path}: {e}") from None
        if not self.frames_data:
            raise ConfigError(f"{path} holds no hand frames")
        self._position = "start"

    def gaze_noise_m(self) -> float:
        """Replays carry no simulated gaze."""
        return 0.0

    def describe(self) -> str:
        """Where the replay is."""
        return self._position

    def frames(self, stop: threading.Event) -> Iterator[SourceFrame]:
        """Yields the recorded frames (looping if asked), then empty frames."""
        t0 = self.frames_data[0][0]
        span = self.frames_data[-1][0] - t0 + 1.0 / self.idle_rate_hz
        offset, passes = 0.0, 0
        while not stop.is_set():
            self._position = f"pass {passes + 1}"
            for t, hands, user in self.frames_data:
                yield SourceFrame(offset + t - t0, hands, user)
                if stop.is_set():
                    return
            offset += span
            passes += 1
            if not self.loop:
                break
        self._position = "finished"
        t = offset
        while not stop.is_set():
            yield SourceFrame(t, [])
            t += 1.0 / self.idle_rate_hz


def _load_replay(path: str) -> list[tuple[float, list[dict], str | None]]:
    """Returns (t seconds, hands, user) per recorded hand frame."""
    from cbgo.recording import read_recording
    from cbgo.toolbox import load_toolbox_json

    if path.endswith(".json"):
        return [(t, frame["hands"], None) for t, frame in load_toolbox_json(path)]
    out, user = [], None
    for record in read_recording(path):
        if record.key.endswith("/user"):
            user = record.message.get("user", user)
        elif record.key.endswith("/hands/frame"):
            out.append((record.log_time_ns / 1e9, record.message.get("hands", []), user))
    return out


class LiveSource:
    """A Leap Motion sensor: frames as the device delivers them."""

    kind = "leap"
    speed = 1.0

    def __init__(self, device: str):
        from cbgo.services.leap_bridge.leap_device import LeapSource

        self._sensor = LeapSource()  # raises ConfigError with install advice
        self.device = device

    def gaze_noise_m(self) -> float:
        """A sensor has no simulated gaze."""
        return 0.0

    def describe(self) -> str:
        """A live sensor."""
        return "live"

    def frames(self, stop: threading.Event) -> Iterator[SourceFrame]:
        """Yields each tracking frame at once (t is None)."""
        for hands in self._sensor.frames(stop):
            yield SourceFrame(None, hands)
