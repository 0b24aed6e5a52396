"""Replay an MCAP recording onto the network: each payload on its original key, in its rhythm.

Messages go out in log-time order, each at the recorded time since the first message divided by
``--speed`` (absolute deadlines on a monotonic clock, so timing errors do not add up over a long
file). Before the first message the replay waits up to ``--wait`` seconds for a subscriber on
every key, since a put made before any subscriber is known is lost. Known topics keep the
contract's delivery policy (hand frames: dropped under congestion, express; events, intents,
plans: never dropped). ``--keys`` replays only some keys (relative to the recording's prefix,
wildcards allowed). ``--restamp`` sets each message's ``ts`` to the time it is sent and leaves
every other field and byte of meaning as recorded; without it payloads are sent byte for byte.
Both encodings play: a msgpack recording's payloads as stored, a JSON one's (``cbgo record
--encoding json``, ``cbgo export``) re-encoded to the msgpack they came from; its derived
``foxglove/*`` channels are not wire messages and are not replayed.

Examples::

    cbgo replay session.mcap
    cbgo replay session.mcap --speed 2 --keys hands/frame gaze
    cbgo replay hands.mcap --loop --restamp        # a live-looking hand stream, until Ctrl-C
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time

from tqdm import tqdm

from cbgo import client, wire
from cbgo.cli.common import add_network_arguments, fail, session
from cbgo.errors import ConfigError, RecordingError, RejectedMessage
from cbgo.keys import Keys
from cbgo.recording import KeyFilter, RecordedMessage, read_recording, recording_info

# No busy-waiting before a deadline: on a 2-core machine a spinning replay takes a core from
# the router and the subscribers, which then deliver late. A timed wait wakes ~0.1-0.3 ms late,
# about equally for every message, so the intervals barely change.
MAX_WAIT_S = 0.1  # longest single wait, so a stop request is seen quickly


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds replay's flags."""
    parser.add_argument("file", metavar="FILE.mcap",
                        help="a recording (cbgo record or cbgo export; any MCAP file of msgpack "
                             "or JSON channels)")
    parser.add_argument("--speed", type=float, default=1.0, metavar="X",
                        help="play X times faster than recorded [1]")
    parser.add_argument("--loop", action="store_true", help="start again at the end, until "
                                                            "Ctrl-C")
    parser.add_argument("--keys", nargs="+", metavar="KEY",
                        help="replay only these keys (relative to the recording's prefix; "
                             "wildcards allowed)")
    parser.add_argument("--restamp", action="store_true",
                        help="set each message's ts to the time it is sent")
    parser.add_argument("--wait", type=float, default=2.0, metavar="S",
                        help="wait up to S seconds for subscribers before the first message [2]")
    add_network_arguments(parser)


def _file_keys(prefix: str | None, fallback: Keys) -> Keys:
    """Keys under the recording's own prefix (its metadata), else under --prefix."""
    try:
        return Keys(prefix) if prefix else fallback
    except ConfigError:
        return fallback


def _declare(sess, keys: Keys, key: str):
    """Returns a publisher on key with its topic's delivery policy (BLOCK for unknown keys)."""
    import zenoh

    topic = keys.topic_of(key)
    reliable = topic is None or topic.reliable
    return sess.declare_publisher(
        key, express=bool(topic and topic.express),
        congestion_control=(zenoh.CongestionControl.BLOCK if reliable
                            else zenoh.CongestionControl.DROP))


def _declare_all(sess, keys: Keys, chosen: list[str]) -> dict:
    import zenoh

    publishers = {}
    for key in chosen:
        try:
            publishers[key] = _declare(sess, keys, key)
        except zenoh.ZError as e:  # a foreign file's topic need not be a key expression
            print(f"cbgo: warning: skipping {key!r}: not a Zenoh key ({e})", file=sys.stderr)
    if not publishers:
        fail("no key of the recording can be published", 2)
    return publishers


def _wait_for_subscribers(publishers: dict, wait_s: float) -> None:
    client.wait_matched(*publishers.values(), timeout_s=wait_s)
    for key, pub in publishers.items():
        if not pub.matching_status.matching:
            print(f"cbgo: warning: no subscriber on {key}; publishing anyway", file=sys.stderr)


def _sleep_until(deadline: float, stop: threading.Event) -> bool:
    """Waits until perf_counter() reaches deadline; returns True if asked to stop first."""
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return stop.is_set()
        if stop.wait(min(remaining, MAX_WAIT_S)):
            return True


def restampable(recorded: RecordedMessage) -> dict | None:
    """Returns the decoded message if it is a map with a ``ts`` field, else None."""
    try:
        message = recorded.message
    except RejectedMessage:
        return None
    return message if "ts" in message else None


def play(path: str, filters: list[str] | None, puts: dict, args: argparse.Namespace,
         stop: threading.Event, bar: tqdm) -> int:
    """Publishes one pass over the recording with its timing; returns the messages sent.

    Args:
        path: the recording.
        filters: key expressions to replay (None: all).
        puts: the put function of each key to replay.
        args: the verb's flags (speed, restamp).
        stop: set by Ctrl-C or SIGTERM; the pass ends at the next message.
        bar: the progress bar to advance.

    Raises:
        RecordingError: the file turned out corrupt mid-way.
    """
    sent, origin = 0, None
    for recorded in read_recording(path, filters):
        put = puts.get(recorded.key)
        if put is None:
            continue
        if origin is None:
            origin = (time.perf_counter(), recorded.log_time_ns)
        deadline = origin[0] + (recorded.log_time_ns - origin[1]) / 1e9 / args.speed
        message = restampable(recorded) if args.restamp else None  # decoded ahead of time
        if _sleep_until(deadline, stop):
            break
        put(recorded.payload if message is None else wire.encode({**message, "ts": time.time()}))
        sent += 1
        bar.update(1)
    return sent


def run(args: argparse.Namespace) -> int:
    """Replays once (or until Ctrl-C with --loop); returns 0, or 2 for an unusable file."""
    if args.speed <= 0:
        fail("--speed must be > 0", 2)
    try:
        info = recording_info(args.file)
    except RecordingError as e:
        fail(str(e), 2)
    with session(args, "cbgo-replay") as (sess, net_keys):
        keys = _file_keys(info.prefix, net_keys)
        filters = [keys.resolve(k) for k in args.keys] if args.keys else None
        try:
            chosen = [k for k in info.counts if KeyFilter(filters)(k) and info.counts[k]]
        except RecordingError as e:
            fail(str(e), 2)
        if not chosen:
            fail(f"no messages in {args.file} match {filters or 'any key'}", 2)
        publishers = _declare_all(sess, keys, chosen)
        _wait_for_subscribers(publishers, args.wait)
        stop = threading.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        total = sum(info.counts[k] for k in chosen)
        puts = {k: p.put for k, p in publishers.items()}
        return _loop(args, filters, puts, total, stop)


def _loop(args: argparse.Namespace, filters, puts: dict, total: int,
          stop: threading.Event) -> int:
    started, sent, passes = time.monotonic(), 0, 0
    with tqdm(total=total, unit="msg", file=sys.stderr, disable=None, leave=False) as bar:
        while not stop.is_set():
            bar.reset(total)
            try:
                sent += play(args.file, filters, puts, args, stop, bar)
            except RecordingError as e:
                fail(f"{e} (after {sent} messages)", 2)
            passes += 1
            if not args.loop:
                break
    time.sleep(0.1)  # let the last puts leave before the session closes
    print(f"replayed {sent} messages on {len(puts)} key{'s' if len(puts) != 1 else ''} in "
          f"{time.monotonic() - started:.2f} s ({passes} pass{'es' if passes != 1 else ''}, "
          f"speed {args.speed:g})",
          file=sys.stderr)
    return 0
