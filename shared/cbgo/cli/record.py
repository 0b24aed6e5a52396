"""Record the traffic on keys into an MCAP file (one channel per key, payloads as received).

KEYs are relative to the prefix unless they start with it; the default ``**`` records every data
key (``cbgo/**``). Control keys (``cbgo/@alive/...``, ``cbgo/@ctl/...``) are never recorded:
Zenoh's ``**`` does not match chunks starting with ``@``. A message matching several KEYs is
recorded once. The recorder prints ``recording ...`` once subscribed, a live progress line on
stderr, and a per-key summary at the end. Ctrl-C or SIGTERM stops it and closes the file
properly; the file is valid only once closed (SIGKILL leaves it truncated). Read a file back
with ``cbgo replay`` or any MCAP tool (``mcap info``).

``--encoding json`` writes what Foxglove opens: each key's messages as JSON with the key's JSON
Schema, plus the derived channels ``foxglove/scene`` (3D hands, objects, TCP, focus ray),
``foxglove/transforms`` and ``foxglove/log``. Messages that break the contract are then not
written; they are counted and listed at the end. ``cbgo export`` converts an existing file.

Examples::

    cbgo record -o session.mcap                          # everything under cbgo/, until Ctrl-C
    cbgo record --encoding json -o foxglove.mcap --duration 30   # open it in Foxglove
    cbgo record -o hands.mcap hands/frame gaze --duration 30
    cbgo record -o one.mcap 'gestures/*' --count 100 --force
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

from cbgo.cli.common import add_network_arguments, fail, key_expression, keys_of, session
from cbgo.errors import RecordingError
from cbgo.foxglove.derive import DERIVED_TOPICS
from cbgo.recording import COMPRESSIONS, ENCODINGS, KeyFilter, Recorder

PROGRESS_PERIOD_S = 0.5  # how often the progress line is refreshed on a terminal
LOG_PERIOD_S = 5.0  # how often a progress line is printed when stderr is not a terminal


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds record's flags."""
    parser.add_argument("keys", nargs="*", default=["**"], metavar="KEY",
                        help="key expressions to record, relative to the prefix; wildcards "
                             "allowed [default: ** = every data key]")
    parser.add_argument("-o", "--output", required=True, metavar="FILE.mcap",
                        help="the MCAP file to write")
    parser.add_argument("-f", "--force", action="store_true",
                        help="overwrite the output file if it exists")
    parser.add_argument("--duration", type=float, default=0.0, metavar="S",
                        help="stop after S seconds (0: until Ctrl-C)")
    parser.add_argument("--count", type=int, default=0, metavar="N",
                        help="stop after N messages (0: no limit)")
    parser.add_argument("--compression", choices=list(COMPRESSIONS), default="zstd",
                        help="chunk compression [zstd]")
    parser.add_argument("--encoding", choices=list(ENCODINGS), default=ENCODINGS[0],
                        help="msgpack: payloads as received; json: JSON with schemas and "
                             "derived Foxglove channels, for Foxglove [msgpack]")
    add_network_arguments(parser)


def _progress(recorder: Recorder, started: float) -> str:
    stats = recorder.stats()
    count = sum(s.count for s in stats.values())
    size = sum(s.bytes for s in stats.values())
    return (f"recording: {count} messages, {size / 1024:.1f} KiB, {len(stats)} keys, "
            f"{time.monotonic() - started:.1f} s")


def summary(recorder: Recorder) -> str:
    """Returns the end-of-recording table: count, rate and size per key, then the totals."""
    stats = recorder.stats()
    width = max([len(k) for k in stats] + [3])
    lines = [f"{'key':<{width}}  {'count':>7}  {'rate Hz':>8}  {'KiB':>9}"]
    for key, s in stats.items():
        lines.append(f"{key:<{width}}  {s.count:>7}  {s.rate_hz:>8.2f}  {s.bytes / 1024:>9.1f}")
    wire_keys = [k for k in stats if k not in DERIVED_TOPICS]
    total = sum(stats[k].count for k in wire_keys)
    plural = "s" if len(wire_keys) != 1 else ""
    derived = sum(s.count for k, s in stats.items() if k in DERIVED_TOPICS)
    lines.append(f"{total} messages on {len(wire_keys)} key{plural}"
                 + (f" and {derived} derived Foxglove messages" if derived else "")
                 + f" written to {recorder.path}")
    lines += rejected_lines(recorder.rejected)
    return "\n".join(lines)


def rejected_lines(rejected: dict[str, tuple[int, str]]) -> list[str]:
    """Returns one line per key whose messages were left out, with the last reason."""
    return [f"left out {n} message{'s' if n != 1 else ''} on {key} that break the contract "
            f"(last: {reason})" for key, (n, reason) in rejected.items()]


def _check_output(args: argparse.Namespace) -> Path:
    path = Path(args.output)
    if path.exists() and not args.force:
        fail(f"{path} exists; use --force to overwrite it", 2)
    if args.count < 0 or args.duration < 0:
        fail("--count and --duration must be >= 0", 2)
    return path


def run(args: argparse.Namespace) -> int:
    """Subscribes, records until --duration, --count, Ctrl-C or SIGTERM, closes the file."""
    path = _check_output(args)
    keys = keys_of(args)  # what was typed is checked before the network is waited for
    exprs = [key_expression(keys, key) for key in args.keys]
    stop = threading.Event()
    with session(args, "cbgo-record") as (sess, _):
        try:
            recorder = Recorder(path, prefix=keys.prefix, keys=exprs,
                                compression=args.compression, encoding=args.encoding)
        except RecordingError as e:
            fail(str(e), 2)
        # From here on a signal only asks the loop to stop, so the file is always closed.
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        try:
            subscribers = [sess.declare_subscriber(e, cb) for e, cb in
                           zip(exprs, _callbacks(recorder, exprs, args.count, stop), strict=True)]
            print(f"recording {' '.join(exprs)} to {path} (Ctrl-C to stop)", file=sys.stderr,
                  flush=True)
            _wait(recorder, args, stop)
            for sub in subscribers:
                sub.undeclare()
        finally:
            recorder.close()
    print(summary(recorder), flush=True)
    return 0


def _callbacks(recorder: Recorder, exprs: list[str], count: int, stop: threading.Event):
    """Returns one subscriber callback per expression: write each sample, stop after `count`.

    A sample whose key matches several expressions reaches several subscribers; only the
    first expression's callback records it, so overlapping KEYs record each message once.
    """
    lock = threading.Lock()  # one lock for all callbacks, so --count is exact
    earlier = [KeyFilter(exprs[:i]) for i in range(len(exprs))]

    def callback_for(i: int):
        def callback(sample) -> None:
            received = time.time_ns()
            key = str(sample.key_expr)
            if i and earlier[i](key):
                return
            with lock:
                if count and recorder.message_count >= count:
                    stop.set()
                    return
                recorder.write(key, sample.payload.to_bytes(), received)
                if count and recorder.message_count >= count:
                    stop.set()
        return callback
    return [callback_for(i) for i in range(len(exprs))]


def _wait(recorder: Recorder, args: argparse.Namespace, stop: threading.Event) -> None:
    started = time.monotonic()
    deadline = started + args.duration if args.duration else None
    tty = sys.stderr.isatty()
    last_line = started
    while not stop.wait(PROGRESS_PERIOD_S if deadline is None
                        else max(0.0, min(PROGRESS_PERIOD_S, deadline - time.monotonic()))):
        now = time.monotonic()
        if deadline is not None and now >= deadline:
            break
        if tty:
            print("\r" + _progress(recorder, started), end="", file=sys.stderr, flush=True)
        elif now - last_line >= LOG_PERIOD_S:
            print(_progress(recorder, started), file=sys.stderr, flush=True)
            last_line = now
    if tty:
        print("\r" + _progress(recorder, started), file=sys.stderr, flush=True)
