"""Playback through the live services: real or simulated trials and streams, in real time.

Trials and streams (`trials`, `streams`) are played as ``cbgo/hands/frame`` at their recorded
rate, in real time, to a router, dynamic-gesture and episode running as processes with their
default settings (`play_live`). Collected, on ``gestures/dynamic`` and on the episode summary:

- **Trials**: each trial is one episode, the hand then leaving the field. The dynamic answer
  of a trial is its most probable reported gesture with p ≥ 0.5 (else "nothing"), its most
  probable final window (one answer per stroke), and its first reported gesture; the
  episode's is the dynamic gesture with the largest g (`run_trials`).
- **Continuous streams**: one stream played without the hand leaving, scored by
  `scoring.stream_figures` (`run_stream`).
- **Latency**: from a stroke's last sample (``window[1]``) to the arrival of its last window
  (`stroke_latencies`).
- **Messages no summary holds**: gesture messages that reached the episode service after their
  episode had ended, or about no episode (its status' ``stray``): a summary that misses a
  gesture its ``gestures/dynamic`` messages carried is explained there.

`report.report_live` scores and prints what `play_live` returns.
"""

from __future__ import annotations

import shutil
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.services.dynamic_gesture.library import trained_path
from cbgo.services.dynamic_gesture.stroke import GESTURE_P
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.data import shrec
from cbgo_tools.dynamic_gesture.scoring import NOTHING, latency_figures, stream_figures
from cbgo_tools.dynamic_gesture.streams import split_spans
from cbgo_tools.dynamic_gesture.trials import Trial

LEAVE_S = 0.6  # empty frames after each play: the hand has left


class _Player:
    """Publishes hand frames in real time and collects what the services say."""

    def __init__(self, stack):
        self.stack = stack
        self.pub = stack.publisher(keys.HANDS_FRAME.suffix)
        self.lock = threading.Lock()
        self.dynamic: list[tuple[float, dict]] = []
        self.summaries: list[dict] = []
        session = stack.session()
        self.subs = [
            session.declare_subscriber(stack.keys.of(keys.GESTURES_DYNAMIC), self._on_dynamic),
            session.declare_subscriber(stack.keys.of(keys.EPISODE_SUMMARY), self._on_summary)]
        self.seq, self.hand_id = 0, 0

    def _on_dynamic(self, sample) -> None:
        with self.lock:
            self.dynamic.append((time.time(), wire.decode(sample.payload.to_bytes())))

    def _on_summary(self, sample) -> None:
        with self.lock:
            self.summaries.append(wire.decode(sample.payload.to_bytes()))

    def play(self, frames: list[tuple[float, list[dict]]], device: str
             ) -> tuple[float, float]:
        """Plays (time, hands) frames at their recorded times, then empty frames.

        Each play is a new appearance of its hands, with new tracking ids as a real sensor
        gives them (the service keeps each hand's last gesture to tell its return). A frame is
        stamped with the time it was due, as a sensor stamps its capture time: when this
        process falls behind (a busy machine), its frames go out late but keep their spacing,
        instead of showing a gap that ends the episode mid-gesture. Returns the ts span of
        the recording.
        """
        ids: dict[int, int] = {}
        t_first = time.time()
        last = frames[-1][0] if frames else 0.0
        leave = [(last + (i + 1) / shrec.RATE_HZ, []) for i in range(int(LEAVE_S * shrec.RATE_HZ))]
        for t, hands in [*frames, *leave]:
            time.sleep(max(0.0, t_first + t - time.time()))
            for hand in hands:
                if hand["id"] not in ids:
                    self.hand_id += 1
                    ids[hand["id"]] = self.hand_id
            hands = [{**hand, "id": ids[hand["id"]]} for hand in hands]
            self.pub.put(wire.encode(keys.HANDS_FRAME.message(ts=t_first + t, seq=self.seq,
                                                              source="replay", device=device,
                                                              hands=hands)))
            self.seq += 1
        return t_first, t_first + last

    def wait_summaries(self, count: int, timeout: float = 5.0) -> None:
        deadline = time.time() + timeout
        while time.time() < deadline:
            with self.lock:
                if len(self.summaries) >= count:
                    return
            time.sleep(0.02)


def _reported(messages: list[dict]) -> list[tuple[str, float, dict]]:
    """Returns (gesture, p, message) of the messages whose top gesture has p ≥ `GESTURE_P`."""
    out = []
    for msg in messages:
        probs = np.asarray(msg["probs"][:-1])
        top = int(np.argmax(probs))
        if probs[top] >= GESTURE_P:
            out.append((msg["names"][top], float(probs[top]), msg))
    return out


def _summary_gesture(summary: dict) -> str:
    """Returns the dynamic gesture with the largest g of an episode summary ("nothing": none)."""
    block = summary.get("gestures", {})
    g = dict(zip(block.get("names", []), block.get("probs", []), strict=False))
    names = [n for n in DYNAMIC_GESTURES if g.get(n, 0.0) > 0.0]
    return max(names, key=lambda n: g[n]) if names else NOTHING


def run_trials(player: _Player, trials: list[Trial], device: str, log=print) -> dict:
    """Plays every trial as its own episode; returns the answers per trial."""
    rows = []
    for i, trial in enumerate(trials):
        with player.lock:
            first, n_sum = len(player.dynamic), len(player.summaries)
        player.play(trial.frames(), device)
        player.wait_summaries(n_sum + 1)
        with player.lock:
            messages = [m for _, m in player.dynamic[first:]]
            summary = player.summaries[n_sum] if len(player.summaries) > n_sum else {}
        reported = _reported(messages)
        dynamic = max(reported, key=lambda r: r[1])[0] if reported else NOTHING
        finals = [r for r in reported if r[2].get("final")]  # one answer per stroke
        rows.append(trial.row(dynamic=dynamic, first=reported[0][0] if reported else NOTHING,
                              finals=max(finals, key=lambda r: r[1])[0] if finals else NOTHING,
                              summary=_summary_gesture(summary),
                              reports=[r[0] for r in reported]))
        log(f"  [{i + 1}/{len(trials)}] {trial.gesture} (person {trial.person}): dynamic "
            f"{dynamic}, summary {rows[-1]['summary']}")
    return {"trials": rows}


def run_stream(player: _Player, frames: list[tuple], spans: list[tuple], device: str) -> dict:
    """Plays one continuous stream; returns swipe recall and false triggers."""
    with player.lock:
        first = len(player.dynamic)
    t0, t1 = player.play(frames, device)
    time.sleep(0.5)
    with player.lock:
        messages = [m for _, m in player.dynamic[first:]]
    swipes, others = split_spans(spans, t0)
    reports = [(name, *msg["window"], (msg["hand_id"], msg["window"][0]))
               for name, _, msg in _reported(messages)]
    return stream_figures(reports, swipes, t1 - t0, others)


def stroke_latencies(player: _Player) -> list[float]:
    """Stroke end → arrival of the stroke's last window (ms), over everything collected."""
    last: dict[tuple, tuple[float, dict]] = {}
    with player.lock:
        for arrival, msg in player.dynamic:
            last[(msg["hand_id"], msg["window"][0])] = (arrival, msg)
    return [1000.0 * (a - m["window"][1]) for a, m in last.values()]


def play_live(trials: list[Trial], streams: list[tuple], device: str, where: str,
              log=print, library: Path | None = None) -> dict:
    """Plays trials, then streams, through a router, dynamic-gesture and episode in real time.

    `library`: a library file the dynamic-gesture service uses instead of the installed one.
    """
    from cbgo.testing import Stack  # noqa: PLC0415 (test harness only when benching live)

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        if library is not None:  # where the service looks first (`library.trained_path`)
            used = trained_path(Path(tmp))
            used.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(library, used)
        stack.start_router()
        for name in ("dynamic-gesture", "episode"):
            stack.start_service(name, env={"CBGO_DATA_DIR": tmp})
        stack.wait_alive(["router", "dynamic-gesture", "episode"], timeout=90)
        player = _Player(stack)
        time.sleep(0.5)  # let the subscribers' declarations reach the router
        log(f"{len(trials)} trials of {where}, real time")
        result = run_trials(player, trials, device, log)
        result["streams"] = [run_stream(player, *stream, device) for stream in streams]
        result["stroke_latencies_ms"] = stroke_latencies(player)
        result["latency_ms"] = latency_figures(result["stroke_latencies_ms"])
        # Gesture messages the episode service could not place: a summary misses them.
        result["episode_stray"] = stack.status("episode").get("stray", {})
    return result
