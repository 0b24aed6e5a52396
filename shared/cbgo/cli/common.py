"""What every `cbgo` verb shares: Zenoh flags, opening a session, reading keys and payloads.

CLI sessions are clients of the router like the services, but they give up after
``--connect-timeout`` seconds with a clear message instead of waiting forever.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from cbgo.config import ConfigError, add_zenoh_arguments, resolve_zenoh, zenoh_config
from cbgo.keys import Keys


def add_network_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the Zenoh flags and --connect-timeout to a verb's parser."""
    add_zenoh_arguments(parser)
    parser.add_argument("--connect-timeout", type=float, default=5.0, metavar="S",
                        help="give up if the router cannot be reached within S seconds "
                             "[default: 5]")


def fail(message: str, code: int = 1) -> None:
    """Prints an error for the user and exits."""
    print(f"cbgo: {message}", file=sys.stderr)
    sys.exit(code)


@contextmanager
def session(args: argparse.Namespace, name: str = "cbgo-cli") -> Iterator[tuple[Any, Keys]]:
    """Opens a client session from the verb's flags and environment; yields (session, keys)."""
    import zenoh

    try:
        options = resolve_zenoh(vars(args))
        conf = zenoh_config(options, name)
    except ConfigError as e:
        fail(f"configuration error: {e}", 2)
    conf.insert_json5("connect/timeout_ms", str(int(args.connect_timeout * 1000)))
    try:
        sess = zenoh.open(conf)
    except zenoh.ZError as e:
        fail(f"cannot reach the Zenoh network at {', '.join(options.connect)} ({e}); is "
             "`cbgo up` or `cbgo router` running? Use --connect to point elsewhere.")
    with sess:
        yield sess, Keys(options.prefix)


def read_json_argument(text: str) -> Any:
    """Returns the JSON value of an argument: inline JSON, ``@file.json``, or ``-`` (stdin)."""
    if text == "-":
        text = sys.stdin.read()
    elif text.startswith("@"):
        try:
            text = Path(text[1:]).read_text()
        except OSError as e:
            fail(f"cannot read {text[1:]}: {e}", 2)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        fail(f"not valid JSON ({e}): {text[:80]!r}", 2)
