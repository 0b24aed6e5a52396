"""Benchmark the wire library and the Zenoh path every message takes.

1. Per message type: msgpack encode, decode and contract validation, in microseconds
   (median of repeated runs), and the payload size.
2. Through a real router (started here on a free loopback port, as a separate process):
   one-way latency of hand frames from a publisher session to a subscriber session, both
   clients of the router, p50/p90/p99 over --count frames at --rate Hz, and the round trip of a
   service status query.

Examples::

    cbgo bench wire
    cbgo bench wire --count 2000 --rate 120
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cbgo import client, keys, wire
from cbgo.examples import EXAMPLE_KEYS, example


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark's flags."""
    parser.add_argument("--repeat", type=int, default=2000, help="runs per codec figure [2000]")
    parser.add_argument("--count", type=int, default=1000, help="frames sent through the router")
    parser.add_argument("--rate", type=float, default=120.0, help="frame rate, Hz [120]")


def _median_us(fn, repeat: int) -> float:
    samples = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(repeat // 5):
            fn()
        samples.append((time.perf_counter() - t0) / (repeat // 5))
    return statistics.median(samples) * 1e6


def codec_table(repeat: int) -> list[dict]:
    """Returns encode/decode/validate microseconds and size per example message."""
    rows = []
    for suffix, role in EXAMPLE_KEYS:
        message = example(suffix, role)
        spec = wire.schema_for(suffix, role)
        payload = wire.encode(message)
        limit = wire.max_bytes_for(suffix)
        rows.append({
            "key": suffix, "role": role, "bytes": len(payload),
            "encode_us": _median_us(lambda m=message: wire.encode(m), repeat),
            "decode_us": _median_us(lambda p=payload, lim=limit: wire.decode(p, lim), repeat),
            "validate_us": _median_us(lambda m=message, s=spec: wire.validate(m, s), repeat),
        })
    return rows


def router_latency(count: int, rate: float) -> dict:
    """Returns one-way hand-frame latency through a router process and a status round trip."""
    from cbgo.testing import Stack

    with tempfile.TemporaryDirectory() as tmp, Stack(Path(tmp)) as stack:
        stack.start_router()
        stack.wait_alive(["router"])
        return _measure(stack, count, rate)


def _measure(stack, count: int, rate: float) -> dict:
    import zenoh

    from cbgo.config import ZenohOptions

    key = stack.keys.of(keys.HANDS_FRAME)
    delays: list[float] = []
    done = threading.Event()

    def on_sample(sample) -> None:
        sent = wire.decode(sample.payload.to_bytes())["ts"]
        delays.append(time.time() - sent)
        if len(delays) >= count:
            done.set()

    with client.open_session(ZenohOptions(connect=[stack.endpoint]), "bench-sub") as sub_session:
        sub_session.declare_subscriber(key, on_sample)
        pub = stack.session().declare_publisher(
            key, congestion_control=zenoh.CongestionControl.DROP, express=True)
        client.wait_matched(pub, timeout_s=None)
        frame = example("hands/frame")
        for seq in range(count):
            frame["seq"], frame["ts"] = seq, time.time()
            pub.put(wire.encode(frame))
            time.sleep(1.0 / rate)
        done.wait(5.0)
    status_rtt = []
    for _ in range(50):
        t0 = time.perf_counter()
        stack.status("router")
        status_rtt.append(time.perf_counter() - t0)
    ms = np.asarray(delays) * 1e3
    return {"frames_sent": count, "frames_received": len(delays),
            "p50_ms": float(np.percentile(ms, 50)), "p90_ms": float(np.percentile(ms, 90)),
            "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()),
            "status_rtt_p50_ms": float(np.median(status_rtt) * 1e3)}


def run(args: argparse.Namespace) -> int:
    """Prints the codec table and the router latency."""
    print(f"{'key':<18} {'role':<8} {'bytes':>7} {'encode µs':>10} {'decode µs':>10} "
          f"{'validate µs':>12}")
    for r in codec_table(args.repeat):
        print(f"{r['key']:<18} {r['role']:<8} {r['bytes']:>7} {r['encode_us']:>10.1f} "
              f"{r['decode_us']:>10.1f} {r['validate_us']:>12.1f}")
    lat = router_latency(args.count, args.rate)
    print(f"\nhand frames through a Python router (one-way, {lat['frames_received']}/"
          f"{lat['frames_sent']} received at {args.rate:g} Hz): p50 {lat['p50_ms']:.3f} ms, "
          f"p90 {lat['p90_ms']:.3f} ms, p99 {lat['p99_ms']:.3f} ms, max {lat['max_ms']:.3f} ms")
    print(f"status query round trip to the router: p50 {lat['status_rtt_p50_ms']:.3f} ms")
    return 0
