"""Benchmark the episode service: how soon the summary follows the end of an episode.

Starts a router and the episode service as real processes on a free loopback port; this
process drives them like a leap-bridge and a static-gesture service would: per episode it
publishes hand frames at ``--rate-hz`` for ``--visible-s`` (each followed by a static gesture
message), then lets the hand disappear, and waits for the summary. Two ways to disappear:

- ``frames``: empty frames keep coming at the rate (a sensor with nobody in view), the usual
  case;
- ``stall``: no frame at all after the last hand (a sensor unplugged); only the service's
  timer can end the episode.

Figures per mode, over ``--episodes`` episodes (arrival times taken in this process's
subscriber callback, time stamps on the same host's clock):

- end condition → summary: summary arrival − (last hand frame's ts + debounce), the latency the
  contract bounds (20 ms); in ``stall`` the condition is the clock's, ``clock_slack_s`` later;
- disappearance → summary: summary arrival − the first empty frame's ts (``frames`` only);
- last hand frame → summary: includes the debounce itself.

Examples::

    cbgo bench episode
    cbgo bench episode --episodes 200 --rate-hz 120 --json episode-bench.json
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import client, keys, wire
from cbgo.examples import example, open_hand
from cbgo.transform import default_to_base

MODES = ("frames", "stall")
SUMMARY_TIMEOUT_S = 5.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--episodes", type=int, default=100, help="episodes per mode [100]")
    parser.add_argument("--rate-hz", type=float, default=60.0, help="frame rate, Hz [60]")
    parser.add_argument("--visible-s", type=float, default=0.4,
                        help="how long the hand is seen per episode, s [0.4]")
    parser.add_argument("--debounce-s", type=float, default=0.15,
                        help="the service's debounce, s [0.15]")
    parser.add_argument("--modes", nargs="+", choices=MODES, default=list(MODES),
                        help="how the hand disappears [frames stall]")
    parser.add_argument("--json", metavar="FILE", help="also write the figures as JSON")


class Driver:
    """Publishes frames and gesture messages; collects summaries with their arrival time."""

    def __init__(self, stack, rate_hz: float):
        import zenoh as z

        session = stack.session()
        self.period = 1.0 / rate_hz
        self.frames = session.declare_publisher(
            stack.keys.of(keys.HANDS_FRAME), congestion_control=z.CongestionControl.DROP,
            express=True)
        self.static = session.declare_publisher(
            stack.keys.of(keys.GESTURES_STATIC), congestion_control=z.CongestionControl.DROP,
            express=True)
        self.summaries: list[tuple[float, dict]] = []
        self.cond = threading.Condition()
        session.declare_subscriber(stack.keys.of(keys.EPISODE_SUMMARY), self._on_summary)
        self.seq = 0
        self.to_base = default_to_base().reshape(-1).tolist()
        self.hand = open_hand()
        self.gesture = example("gestures/static")

    def _on_summary(self, sample) -> None:
        arrival = time.time()
        with self.cond:
            self.summaries.append((arrival, wire.decode(sample.payload.to_bytes())))
            self.cond.notify_all()

    def wait_matching(self, timeout: float = 10.0) -> None:
        """Waits until the episode service subscribes to the frames."""
        if not client.wait_matched(self.frames, self.static, timeout_s=timeout):
            raise TimeoutError("the episode service did not subscribe to the frames")

    def frame(self, with_hand: bool) -> float:
        """Publishes one frame (and its static message); returns its ts."""
        ts = time.time()
        hands = [self.hand] if with_hand else []
        self.frames.put(wire.encode({"v": 1, "ts": ts, "seq": self.seq, "source": "simulated",
                                     "device": "bench", "hands": hands,
                                     "to_base": self.to_base}))
        if with_hand:
            self.static.put(wire.encode({**self.gesture, "ts": ts, "seq": self.seq}))
        self.seq += 1
        return ts

    def episode(self, visible_s: float, mode: str, gap_s: float) -> dict:
        """Runs one episode; returns its time stamps and the summary's arrival."""
        with self.cond:
            before = len(self.summaries)
        start = time.perf_counter()
        n = max(1, round(visible_s / self.period))
        for i in range(n):
            _sleep_until(start + i * self.period)
            last_hand = self.frame(True)
        first_empty, i = None, n
        deadline = time.monotonic() + SUMMARY_TIMEOUT_S
        while time.monotonic() < deadline:
            with self.cond:
                if len(self.summaries) > before:
                    break
                if mode == "stall":
                    self.cond.wait(0.05)
                    continue
            _sleep_until(start + i * self.period)
            ts = self.frame(False)
            first_empty = first_empty or ts
            i += 1
        with self.cond:
            got = self.summaries[before:]
        gap_end = time.perf_counter() + gap_s
        while mode == "frames" and time.perf_counter() < gap_end:
            _sleep_until(start + i * self.period)
            self.frame(False)
            i += 1
        time.sleep(max(0.0, gap_end - time.perf_counter()))
        return {"last_hand": last_hand, "first_empty": first_empty,
                "arrival": got[0][0] if got else None, "summary": got[0][1] if got else None,
                "extra": len(got) - 1 if got else 0}


def _sleep_until(when: float) -> None:
    wait = when - time.perf_counter()
    if wait > 0:
        time.sleep(wait)


def _figures(values_s: list[float]) -> dict:
    ms = np.asarray(values_s) * 1e3
    if ms.size == 0:
        return {"n": 0}
    return {"n": int(ms.size), "p50": float(np.percentile(ms, 50)),
            "p90": float(np.percentile(ms, 90)), "p99": float(np.percentile(ms, 99)),
            "max": float(ms.max()), "min": float(ms.min())}


def measure(mode: str, runs: list[dict], wait_s: float) -> dict:
    """Returns the latency figures of one mode's episodes (`wait_s`: hand gone → condition)."""
    ok = [r for r in runs if r["arrival"] is not None]
    return {
        "mode": mode, "episodes": len(runs), "summaries": len(ok),
        "missing": len(runs) - len(ok), "duplicates": sum(r["extra"] for r in runs),
        "with_grab_trigger": sum(any(t["gesture"] == "grab" for t in r["summary"]["triggers"])
                                 for r in ok),
        "end_condition_to_summary_ms": _figures(
            [r["arrival"] - (r["last_hand"] + wait_s) for r in ok]),
        "disappearance_to_summary_ms": _figures(
            [r["arrival"] - r["first_empty"] for r in ok if r["first_empty"] is not None]),
        "last_hand_to_summary_ms": _figures([r["arrival"] - r["last_hand"] for r in ok]),
    }


def _line(name: str, f: dict) -> str:
    if not f.get("n"):
        return f"  {name:<32} -"
    return (f"  {name:<32} p50 {f['p50']:7.2f}  p90 {f['p90']:7.2f}  p99 {f['p99']:7.2f}  "
            f"max {f['max']:7.2f}  (n={f['n']})")


def run(args: argparse.Namespace) -> int:
    """Runs the episodes of every mode through real processes and prints the figures."""
    from cbgo.testing import Stack

    results = {"settings": {"episodes": args.episodes, "rate_hz": args.rate_hz,
                            "visible_s": args.visible_s, "debounce_s": args.debounce_s},
               "modes": {}}
    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.start_service("episode", "--debounce-s", str(args.debounce_s))
        stack.wait_alive(["router", "episode"])
        driver = Driver(stack, args.rate_hz)
        driver.wait_matching()
        print(f"episode bench: {args.episodes} episodes per mode, frames at {args.rate_hz:g} Hz, "
              f"hand seen {args.visible_s:g} s, debounce {args.debounce_s:g} s "
              "(router + episode as processes)", flush=True)
        slack_s = float(stack.status("episode")["config"]["settings"]["clock_slack_s"])
        for mode in args.modes:
            runs = [driver.episode(args.visible_s, mode, gap_s=0.1) for _ in range(args.episodes)]
            # Without frames the end condition is the clock's: the debounce plus the slack.
            wait_s = args.debounce_s + (slack_s if mode == "stall" else 0.0)
            fig = results["modes"][mode] = measure(mode, runs, wait_s)
            print(f"mode {mode}: {fig['summaries']}/{fig['episodes']} summaries, "
                  f"{fig['duplicates']} duplicates, {fig['with_grab_trigger']} with the grab "
                  "trigger; latency in ms:")
            for name in ("end_condition_to_summary_ms", "disappearance_to_summary_ms",
                         "last_hand_to_summary_ms"):
                print(_line(name.removesuffix("_ms").replace("_", " "), fig[name]), flush=True)
        service = {k: v for k, v in stack.status("episode").items()
                   if k in ("episodes", "ended_by", "end_latency_ms", "stray", "counters")}
        results["service"] = service
        lat = service["end_latency_ms"]
        print(f"service side: {service['episodes']} episodes, ended by {service['ended_by']}, "
              f"end condition -> summary built p50 {lat.get('p50', 0):.2f} ms, "
              f"p99 {lat.get('p99', 0):.2f} ms; counters {service['counters']}")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2))
        print(f"wrote {args.json}")
    return 0
