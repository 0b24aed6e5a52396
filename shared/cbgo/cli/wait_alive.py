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
from cbgo.cli.common import add_network_arguments, did_you_mean, session


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
            alive = client.alive(sess, keys, 0.5)
            missing = set(args.services) - alive
            if not missing:
                return 0
            if time.monotonic() > deadline:
                hints = "".join(did_you_mean(name, alive) for name in sorted(missing))
                print(f"not alive after {args.timeout:g} s: {', '.join(sorted(missing))}{hints}; "
                      f"alive: {', '.join(sorted(alive)) or 'none (is `cbgo up` running?)'}",
                      file=sys.stderr)
                return 1
            time.sleep(0.1)
