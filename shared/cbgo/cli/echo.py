"""Print the messages on a key, decoded from msgpack and checked against the contract.

KEY is relative to the prefix unless it starts with it (``hands/frame`` = ``cbgo/hands/frame``);
wildcards work (``'gestures/*'``, ``'**'``). Messages that break the contract are printed too,
with the reason on stderr.

Examples::

    cbgo echo episode/summary
    cbgo echo 'gestures/*' --count 10
    cbgo echo hands/frame --json | jq .message.hands[0].grab_strength
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import time

from cbgo import wire
from cbgo.cli.common import add_network_arguments, listened_key, session
from cbgo.codec import jsonable, pretty, unpack_any
from cbgo.errors import RejectedMessage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds echo's flags."""
    parser.add_argument("key", help="key expression, relative to the prefix unless it starts "
                                    "with it; wildcards allowed")
    parser.add_argument("--json", action="store_true",
                        help="one JSON object a line: {key, received, valid, message}")
    parser.add_argument("-n", "--count", type=int, default=0,
                        help="exit after N messages (0: run until Ctrl-C)")
    parser.add_argument("--timeout", type=float, default=0.0,
                        help="exit after S seconds (0: no limit)")
    add_network_arguments(parser)


def check(keys, key: str, message) -> str | None:
    """Returns why a message breaks the contract, or None if it is valid (or not ours)."""
    topic = keys.topic_of(key)
    if topic is None or topic.schema is None:
        return None
    try:
        wire.validate(message, topic.schema, key)
    except RejectedMessage as e:
        return str(e)
    return None


def run(args: argparse.Namespace) -> int:
    """Subscribes and prints until --count, --timeout or Ctrl-C."""
    inbox: queue.Queue = queue.Queue()
    keys, key = listened_key(args)
    with session(args, "cbgo-echo") as (sess, _):
        sess.declare_subscriber(key, lambda s: inbox.put((str(s.key_expr),
                                                          s.payload.to_bytes(), time.time())))
        print(f"listening on {key}", file=sys.stderr)
        return _print_loop(inbox, keys, args)


def _print_loop(inbox: queue.Queue, keys, args: argparse.Namespace) -> int:
    seen, deadline = 0, (time.monotonic() + args.timeout) if args.timeout else None
    while not args.count or seen < args.count:
        if deadline and time.monotonic() > deadline:
            break
        try:
            key, payload, received = inbox.get(timeout=0.1)
        except queue.Empty:
            continue
        seen += 1
        try:
            message = unpack_any(payload)
        except ValueError as e:
            print(f"{key}: {e} ({len(payload)} bytes)", file=sys.stderr)
            continue
        problem = check(keys, key, message)
        if problem:
            print(f"invalid: {problem}", file=sys.stderr)
        if args.json:
            print(json.dumps({"key": key, "received": received, "valid": problem is None,
                              "message": jsonable(message)}), flush=True)
        else:
            print(f"--- {key}  ({len(payload)} B)\n{pretty(message)}", flush=True)
    return 0
