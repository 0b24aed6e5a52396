"""Benchmark `cbgo replay`'s rhythm: how closely messages arrive at their recorded times.

Writes a recording of ``--count`` messages on four keys, ``--min-ms``..``--max-ms`` apart at
random (seeded), starts a router on a free loopback port, subscribes to every key and runs
``cbgo replay`` on the file as a separate process, as a user would. For each message it
compares the arrival time with the recorded time:

- **interval error**: |arrival interval − recorded interval| between consecutive messages;
- **offset from schedule**: |lag − median lag|, where lag = arrival − recorded time (the
  schedule's origin is arbitrary). The replay keeps absolute deadlines, so errors do not add up
  over a long file: the offset stays near the interval error.

The figures include the router hop and the subscriber's Zenoh callback, and depend on how busy
the machine is: on a quiet host both stay within a few milliseconds. A test checks what does not
depend on load (every message, in order, never early); this bench measures how late.

Examples::

    cbgo bench replay
    cbgo bench replay --count 2000 --speed 2
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import wire
from cbgo.examples import example
from cbgo.recording import Recorder

KEYS = ["hands/frame", "gaze", "user", "episode/event"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the bench's flags."""
    parser.add_argument("--count", type=int, default=500, help="messages to replay [500]")
    parser.add_argument("--min-ms", type=float, default=2.0, help="shortest gap [2]")
    parser.add_argument("--max-ms", type=float, default=18.0, help="longest gap [18]")
    parser.add_argument("--speed", type=float, default=1.0, help="replay speed [1]")
    parser.add_argument("--seed", type=int, default=3, help="seed of the gaps and keys [3]")


def write_recording(path: Path, prefix: str, count: int, gaps_ms: tuple[float, float],
                    seed: int) -> list[tuple[str, bytes, int]]:
    """Writes count example messages at random gaps; returns [(key, payload, log ns)]."""
    rng = random.Random(seed)
    keys = [f"{prefix}/{k}" for k in KEYS]
    written, now_ns = [], time.time_ns()
    with Recorder(path, prefix=prefix, keys=[f"{prefix}/**"]) as rec:
        for i in range(count):
            key = rng.choice(keys)
            payload = wire.encode({**example(key.split("/", 1)[1], ts=now_ns / 1e9), "n": i})
            rec.write(key, payload, now_ns)
            written.append((key, payload, now_ns))
            now_ns += int(rng.uniform(*gaps_ms) * 1e6)
    return written


def replay_arrivals(path: Path, count: int, speed: float) -> tuple[list, str]:
    """Runs `cbgo replay` through a fresh router; returns [(arrival s, key, payload)], stderr."""
    from cbgo.testing import Stack

    arrivals, done = [], threading.Event()

    def on_sample(sample) -> None:
        arrivals.append((time.perf_counter(), str(sample.key_expr), sample.payload.to_bytes()))
        if len(arrivals) >= count:
            done.set()

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.wait_alive(["router"])
        sub = stack.session().declare_subscriber(f"{stack.prefix}/**", on_sample)
        replay = subprocess.run(
            [sys.executable, "-m", "cbgo.cli.main", "replay", str(path), "--derived",
             "--speed", str(speed),
             "--wait", "10", "--connect", stack.endpoint],
            capture_output=True, text=True, env=stack.env())
        done.wait(5.0)
        sub.undeclare()
    if replay.returncode != 0:
        raise RuntimeError(f"cbgo replay failed: {replay.stderr.strip()}")
    return arrivals, replay.stderr


def as_replayed(key: str, payload: bytes) -> dict:
    """The message `cbgo replay` sends for a recorded payload: marked ``replayed: true``."""
    message = {**wire.decode(payload), "replayed": True}
    if key.endswith("/hands/frame"):
        message["source"] = "replay"
    return message


def timing_errors(arrived_s: np.ndarray, logged_ns: np.ndarray, speed: float) -> dict:
    """Returns interval and offset errors (ms) of arrivals against the recorded schedule."""
    due = (logged_ns - logged_ns[0]) / 1e9 / speed
    interval_ms = np.abs(np.diff(arrived_s) - np.diff(due)) * 1e3
    lag = arrived_s - due
    offset_ms = np.abs(lag - np.median(lag)) * 1e3
    return {name: {"median": float(np.median(v)), "p99": float(np.percentile(v, 99)),
                   "max": float(v.max())}
            for name, v in (("interval", interval_ms), ("offset", offset_ms))}


def run(args: argparse.Namespace) -> int:
    """Prints how closely replayed messages keep their recorded rhythm."""
    if args.count < 2 or args.speed <= 0 or not 0 <= args.min_ms <= args.max_ms:
        print("error: needs --count >= 2, --speed > 0 and 0 <= --min-ms <= --max-ms",
              file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rhythm.mcap"
        written = write_recording(path, "cbgo", args.count, (args.min_ms, args.max_ms),
                                  args.seed)
        arrivals, stderr = replay_arrivals(path, args.count, args.speed)
    in_order = ([(k, wire.decode(p)) for _t, k, p in arrivals]
                == [(k, as_replayed(k, p)) for k, p, _n in written])
    print(f"replayed {len(written)} messages over "
          f"{(written[-1][2] - written[0][2]) / 1e9 / args.speed:.2f} s at speed "
          f"{args.speed:g}: {len(arrivals)} arrived, "
          + ("all in order, as recorded (plus the replay mark)" if in_order
             else "NOT the recorded sequence"))
    if not in_order:
        print(stderr.strip(), file=sys.stderr)
        return 1
    errors = timing_errors(np.array([t for t, _k, _p in arrivals]),
                           np.array([n for _k, _p, n in written], dtype=np.float64),
                           args.speed)
    for name, label in (("interval", "|interval error|"), ("offset", "|offset from schedule|")):
        e = errors[name]
        print(f"  {label:<24} median {e['median']:.3f} ms, p99 {e['p99']:.3f} ms, "
              f"max {e['max']:.3f} ms")
    return 0
