"""Benchmark the leap-bridge's frame stream: rate and jitter as a subscriber sees them.

Starts a router and the leap-bridge (simulated user playing a looping scenario) as real
processes on a free loopback port, subscribes to ``hands/frame`` for ``--seconds`` at each rate,
and prints the measured rate, the interval mean/std/p99/max, the share of frames with a hand,
and how many frames failed validation. The subscriber is a separate process from the
publisher, so the figures include Zenoh and the router.

Examples::

    cbgo bench bridge
    cbgo bench bridge --rates 60 120 --seconds 20
"""

from __future__ import annotations

import argparse
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import keys, wire
from cbgo.errors import RejectedMessage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--rates", type=float, nargs="+", default=[30.0, 60.0, 120.0],
                        help="frame rates to measure, Hz [30 60 120]")
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring time per rate")
    parser.add_argument("--scenario", default="demo", help="scenario to loop [demo]")


def measure(rate: float, seconds: float, scenario: str) -> dict:
    """Returns the stream statistics of a leap-bridge at `rate` over `seconds`."""
    from cbgo.testing import Stack

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.start_service("leap-bridge", "--scenario", scenario, "--loop", "--rate-hz",
                            str(rate))
        stack.wait_alive(["router", "leap-bridge"])
        arrivals: list[tuple[float, bytes]] = []
        lock = threading.Lock()

        def on_sample(sample) -> None:
            with lock:
                arrivals.append((time.perf_counter(), sample.payload.to_bytes()))

        stack.session().declare_subscriber(stack.keys.of(keys.HANDS_FRAME), on_sample)
        time.sleep(1.0)  # let the stream settle
        with lock:
            arrivals.clear()
        time.sleep(seconds)
        with lock:
            got = list(arrivals)
    return _stats(rate, got)


def _stats(rate: float, got: list[tuple[float, bytes]]) -> dict:
    stamps = np.array([t for t, _ in got])
    dt = np.diff(stamps) * 1e3
    invalid, with_hand = 0, 0
    for _, payload in got:
        try:
            message = wire.decode_checked(payload, wire.HANDS_FRAME)
            with_hand += bool(message["hands"])
        except RejectedMessage:
            invalid += 1
    period = 1e3 / rate
    return {"rate_set": rate, "frames": len(got),
            "rate_hz": (len(stamps) - 1) / (stamps[-1] - stamps[0]),
            "interval_mean_ms": float(dt.mean()), "interval_std_ms": float(dt.std()),
            "jitter_p99_ms": float(np.percentile(np.abs(dt - period), 99)),
            "interval_max_ms": float(dt.max()), "with_hand": with_hand / len(got),
            "invalid": invalid}


def run(args: argparse.Namespace) -> int:
    """Measures every rate and prints one line each."""
    print(f"{'set Hz':>7} {'measured Hz':>12} {'error %':>8} {'mean ms':>8} {'std ms':>7} "
          f"{'|jitter| p99 ms':>16} {'max ms':>7} {'frames':>7} {'w/ hand':>8} {'invalid':>8}")
    for rate in args.rates:
        s = measure(rate, args.seconds, args.scenario)
        error = 100.0 * (s["rate_hz"] - rate) / rate
        print(f"{rate:>7.0f} {s['rate_hz']:>12.2f} {error:>8.2f} {s['interval_mean_ms']:>8.2f} "
              f"{s['interval_std_ms']:>7.2f} {s['jitter_p99_ms']:>16.2f} "
              f"{s['interval_max_ms']:>7.2f} {s['frames']:>7} {s['with_hand']:>8.0%} "
              f"{s['invalid']:>8}", flush=True)
    return 0
