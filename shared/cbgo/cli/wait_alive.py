"""Wait until services are alive (their ``<prefix>/@alive/<service>`` token is present).

Exit code 0 when all are alive, 1 on timeout; for scripts and container healthchecks.

Examples::

    cbgo wait-alive router episode --timeout 10
    ZENOH_CONNECT=tcp/router:7447 cbgo wait-alive intent --timeout 3
"""

from __future__ import annotations

import argparse
import sys
import time

from cbgo import client
from cbgo.cli.common import add_network_arguments, session


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds wait-alive's flags."""
    parser.add_argument("services", nargs="+", help="service names")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds to wait [10]")
    add_network_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Polls the liveliness tokens until all are present or the timeout passes."""
    args.connect_timeout = min(args.connect_timeout, args.timeout)
    deadline = time.monotonic() + args.timeout
    with session(args, "cbgo-wait-alive") as (sess, keys):
        while True:
            missing = set(args.services) - client.alive(sess, keys, 0.5)
            if not missing:
                return 0
            if time.monotonic() > deadline:
                print(f"not alive after {args.timeout:g} s: {', '.join(sorted(missing))}",
                      file=sys.stderr)
                return 1
            time.sleep(0.1)
