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
from cbgo.cli.common import (
    add_network_arguments,
    key_expression,
    keys_of,
    read_json_argument,
    session,
    unknown_key_note,
)
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
    keys = keys_of(args)  # what was typed is checked before the network is waited for
    selector = _selector(keys, args.selector)
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
    ok = errors = 0
    with session(args, "cbgo-get") as (sess, _):
        for reply in client.replies(sess, selector, payload, args.timeout):
            if reply.ok:
                ok += 1
                _print_ok(reply.key, decode_reply(reply.payload), args.json)
            else:
                errors += 1
                print(f"error: {reply.text}", file=sys.stderr)
    if not ok and not errors:
        note = unknown_key_note(keys, selector.split("?", 1)[0])
        print(f"no reply on {selector} within {args.timeout:g} s"
              + (f"; {note}" if note else "; is the service that answers it up? (`cbgo ls`)"),
              file=sys.stderr)
    return 0 if ok else 1


def _selector(keys, typed: str) -> str:
    """Returns the full selector: its key expression checked, its parameters (``?...``) kept."""
    key, sep, parameters = typed.partition("?")
    return key_expression(keys, key) + sep + parameters


def _print_ok(key: str, value, as_json: bool) -> None:
    if as_json:
        print(json.dumps({"key": key, "reply": jsonable(value)}), flush=True)
    else:
        print(f"--- {key}\n{pretty(value)}", flush=True)
