"""Measure the rate of messages on a key: frequency, interval jitter, size and bandwidth.

Prints one line per key every second (or at the end with --duration). Intervals are measured
at arrival on this machine, so they include network jitter.

Examples::

    cbgo hz hands/frame
    cbgo hz 'gestures/*' --window 200
    cbgo hz hands/frame --duration 10 --json
"""

from __future__ import annotations

import argparse
import json
import threading
import time
from collections import defaultdict, deque

import numpy as np

from cbgo.cli.common import add_network_arguments, listened_key, session


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds hz's flags."""
    parser.add_argument("key", help="key expression (relative to the prefix); wildcards allowed")
    parser.add_argument("--window", type=int, default=100,
                        help="number of recent intervals to compute statistics over [100]")
    parser.add_argument("--duration", type=float, default=0.0,
                        help="measure for S seconds, print once and exit (0: until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="print JSON lines")
    add_network_arguments(parser)


class RateMeter:
    """Arrival statistics of one key over a sliding window."""

    def __init__(self, window: int):
        self.stamps: deque[float] = deque(maxlen=window + 1)
        self.sizes: deque[int] = deque(maxlen=window + 1)
        self.total = 0

    def add(self, stamp: float, size: int) -> None:
        """Records one arrival."""
        self.stamps.append(stamp)
        self.sizes.append(size)
        self.total += 1

    def stats(self) -> dict | None:
        """Returns the statistics over the window, or None with fewer than two messages.

        Rate in Hz, interval mean/min/max/std in ms, mean size in B, bandwidth in B/s.
        """
        if len(self.stamps) < 2:
            return None
        dt = np.diff(np.asarray(self.stamps))
        mean = float(dt.mean())
        return {"rate_hz": 1.0 / mean if mean > 0 else float("inf"), "mean_ms": mean * 1e3,
                "min_ms": float(dt.min()) * 1e3, "max_ms": float(dt.max()) * 1e3,
                "std_ms": float(dt.std()) * 1e3, "size_b": float(np.mean(self.sizes)),
                "bandwidth_bps": float(np.mean(self.sizes)) / mean if mean > 0 else 0.0,
                "count": self.total, "window": len(dt)}


def _line(key: str, s: dict) -> str:
    return (f"{key}: {s['rate_hz']:.2f} Hz  interval {s['mean_ms']:.2f} ms "
            f"(min {s['min_ms']:.2f}, max {s['max_ms']:.2f}, std {s['std_ms']:.2f})  "
            f"{s['size_b']:.0f} B  {s['bandwidth_bps'] / 1024:.1f} KiB/s  n={s['count']}")


def run(args: argparse.Namespace) -> int:
    """Subscribes and reports until --duration or Ctrl-C."""
    meters: dict[str, RateMeter] = defaultdict(lambda: RateMeter(args.window))
    lock = threading.Lock()

    def on_sample(sample) -> None:
        with lock:
            meters[str(sample.key_expr)].add(time.perf_counter(), len(sample.payload))

    _, key = listened_key(args)
    with session(args, "cbgo-hz") as (sess, _):
        sess.declare_subscriber(key, on_sample)
        end = time.monotonic() + args.duration if args.duration else None
        while end is None or time.monotonic() < end:
            time.sleep(min(1.0, max(0.0, end - time.monotonic())) if end else 1.0)
            if end is None or time.monotonic() >= end:
                _report(meters, lock, args.json)
    return 0


def _report(meters: dict[str, RateMeter], lock: threading.Lock, as_json: bool) -> None:
    with lock:
        stats = {key: m.stats() for key, m in sorted(meters.items())}
    if not stats:
        print("no messages yet", flush=True)
    for key, s in stats.items():
        if s is None:
            print(f"{key}: 1 message so far", flush=True)
        else:
            print(json.dumps({"key": key, **s}) if as_json else _line(key, s), flush=True)
