"""Publish a JSON message as msgpack on a key, checked against the contract first.

KEY is relative to the prefix unless it starts with it. The message is JSON, ``@file.json`` or
``-`` (stdin); ``--example`` publishes the contract's example message for that key instead.
``--stamp`` fills in ``v`` (if missing), ``ts`` (now) and, for streams, ``seq``.
A message that breaks the contract is refused unless ``--force`` (to test how services reject
bad input); the refusal names the field at fault and the fix (``--stamp`` when only ``v``,
``ts`` or ``seq`` is missing). The message is checked before the network is waited for. The
put waits up to ``--wait`` seconds for a subscriber, since a put made before any subscriber is
known is lost.

Examples::

    cbgo pub user '{"user": "alice"}' --stamp
    cbgo pub robot/stop '{}' --stamp
    cbgo pub gaze --example --count 100 --rate 30 --stamp
    cbgo pub user '{"v": 1, "ts": -1, "user": ""}' --force   # see it rejected
"""

from __future__ import annotations

import argparse
import sys
import time

from cbgo import client, examples, wire
from cbgo.cli.common import (
    add_network_arguments,
    fail,
    key_expression,
    keys_of,
    read_json_argument,
    session,
    unknown_key_note,
)
from cbgo.errors import RejectedMessage

STAMPED_FIELDS = ("v", "ts", "seq")  # what --stamp fills in


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds pub's flags."""
    parser.add_argument("key", help="key to publish on (relative to the prefix)")
    parser.add_argument("message", nargs="?", help="JSON message, @file.json, or - for stdin")
    parser.add_argument("--example", action="store_true",
                        help="publish the contract's example message for this key")
    parser.add_argument("--stamp", action="store_true", help="set v (if missing), ts and seq")
    parser.add_argument("--count", type=int, default=1, help="how many times to publish [1]")
    parser.add_argument("--rate", type=float, default=10.0, help="rate for --count > 1, Hz [10]")
    parser.add_argument("--force", action="store_true",
                        help="publish even if the message breaks the contract")
    parser.add_argument("--wait", type=float, default=2.0,
                        help="wait up to S seconds for a subscriber before the first put [2]")
    add_network_arguments(parser)


def _message(args: argparse.Namespace, suffix: str | None) -> dict:
    if args.example:
        try:
            return examples.example(suffix or "")
        except KeyError:
            fail(f"no example message for {args.key}; pass the message as JSON", 2)
    if args.message is None:
        fail("give a message (JSON, @file.json or -) or --example", 2)
    return read_json_argument(args.message)


def _stamped(message: dict, seq: int, stream: bool) -> dict:
    if not isinstance(message, dict):
        fail("--stamp needs a JSON object", 2)
    out = {"v": wire.SCHEMA_VERSION, **message, "ts": time.time()}
    if stream:
        out["seq"] = seq
    return out


def _problem(message, spec, key: str) -> RejectedMessage | None:
    try:
        wire.validate(message, spec, key)
    except RejectedMessage as e:
        return e
    return None


def _check(message, spec, key: str, args: argparse.Namespace, stream: bool) -> None:
    """Refuses a message that breaks the contract (unless --force), naming the fix.

    A message that lacks only what --stamp fills in is told to add --stamp; otherwise the
    field at fault is named, with the contract's example (``--example``).
    """
    sent = _stamped(message, 0, stream) if args.stamp else message
    problem = _problem(sent, spec, key)
    if problem is None:
        return
    if args.force:
        print(f"cbgo: warning: publishing a message that breaks the contract: {problem}",
              file=sys.stderr)
        return
    if not args.stamp and problem.path in STAMPED_FIELDS and isinstance(message, dict):
        stamped = _problem(_stamped(message, 0, stream), spec, key)
        if stamped is None:
            fail(f"refusing to publish: {problem}; add --stamp to fill in v, ts and seq", 2)
        problem = stamped
    fail(f"refusing to publish: {problem}. The contract's example: `cbgo pub {args.key} "
         f"--example`{'' if args.stamp else ' (with --stamp for v, ts and seq)'}; --force "
         "sends it anyway, to test how services reject it", 2)


def run(args: argparse.Namespace) -> int:
    """Validates and publishes; returns 0, or 2 for a refused message."""
    keys = keys_of(args)  # the message is checked before the network is waited for
    key = key_expression(keys, args.key)
    topic = keys.topic_of(key)
    base = _message(args, topic.suffix if topic else None)
    spec = topic.schema if topic else None
    stream = spec is not None and hasattr(spec, "fields") and "seq" in spec.fields
    _check(base, spec, key, args, stream)
    note = unknown_key_note(keys, key)
    if note:
        print(f"cbgo: warning: {note}; publishing it unchecked", file=sys.stderr)
    with session(args, "cbgo-pub") as (sess, _):
        pub = sess.declare_publisher(key)
        if not client.wait_matched(pub, timeout_s=args.wait):
            print(f"cbgo: warning: no subscriber on {key}; publishing anyway", file=sys.stderr)
        for i in range(args.count):
            message = _stamped(base, i, stream) if args.stamp else base
            pub.put(wire.encode(message))
            if i + 1 < args.count:
                time.sleep(1.0 / args.rate)
        time.sleep(0.1)  # let the last put leave before the session closes
    return 0
