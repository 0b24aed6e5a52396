"""Send a query and print every reply, decoded; error replies go to stderr.

SELECTOR is relative to the prefix unless it starts with it or with ``@/`` (Zenoh's admin
space); cbgo's control keys (``@ctl/...``, ``@alive/...``) are relative to the prefix too. The
payload is JSON, sent as msgpack. Exit code 0 if at least one reply was ok.

Examples::

    cbgo get '@ctl/*/status'
    cbgo get sim/reset --payload '{"v": 1, "seed": 3}'
    cbgo get intent/infer --payload @query.json --json
    cbgo get '@/*/router'                         # the router's admin space (JSON)
"""

from __future__ import annotations

import argparse
import json
import sys

from cbgo import client, wire
from cbgo.cli.common import add_network_arguments, read_json_argument, session
from cbgo.codec import jsonable, pretty, unpack_any
from cbgo.errors import RejectedMessage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds get's flags."""
    parser.add_argument("selector", help="key expression or selector to query")
    parser.add_argument("--payload", help="query payload: JSON, @file.json or - for stdin")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds to wait [10]")
    parser.add_argument("--json", action="store_true", help="one JSON object a line")
    add_network_arguments(parser)


def decode_reply(payload: bytes):
    """Returns a reply's value: msgpack if it decodes, else JSON (admin space), else text."""
    try:
        return unpack_any(payload)
    except ValueError:
        pass
    try:
        return json.loads(payload)
    except (json.JSONDecodeError, UnicodeDecodeError):
        return payload.decode("utf-8", "replace")


def run(args: argparse.Namespace) -> int:
    """Queries and prints; returns 0 if any reply was ok, 1 otherwise."""
    with session(args, "cbgo-get") as (sess, keys):
        selector = keys.resolve(args.selector)
        payload = None
        if args.payload is not None:
            message = read_json_argument(args.payload)
            topic = keys.topic_of(selector)
            if topic is not None and topic.query_schema is not None:
                try:
                    wire.validate(message, topic.query_schema, selector)
                except RejectedMessage as e:
                    print(f"cbgo: warning: the query breaks the contract: {e}", file=sys.stderr)
            payload = wire.encode(message)
        ok = 0
        for reply in client.replies(sess, selector, payload, args.timeout):
            if reply.ok:
                ok += 1
                _print_ok(reply.key, decode_reply(reply.payload), args.json)
            else:
                print(f"error: {reply.text}", file=sys.stderr)
    if not ok:
        print(f"no successful reply on {selector}", file=sys.stderr)
    return 0 if ok else 1


def _print_ok(key: str, value, as_json: bool) -> None:
    if as_json:
        print(json.dumps({"key": key, "reply": jsonable(value)}), flush=True)
    else:
        print(f"--- {key}\n{pretty(value)}", flush=True)
