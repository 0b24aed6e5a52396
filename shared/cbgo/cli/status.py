"""Show the status of one service, or a one-line summary of every live service.

Each service answers ``<prefix>/@ctl/<service>/status`` with its name, version, pid, host,
uptime, resolved configuration, counters (received, published, rejected, errors, dropped) and
last error.

Examples::

    cbgo status                 # every service, one line each
    cbgo status static-gesture  # everything one service reports
    cbgo status episode --json
"""

from __future__ import annotations

import argparse
import json
import sys

from cbgo import client
from cbgo.cli.common import add_network_arguments, did_you_mean, session
from cbgo.codec import jsonable, pretty


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds status's flags."""
    parser.add_argument("service", nargs="?", default="*", help="service name (default: all)")
    parser.add_argument("--timeout", type=float, default=3.0, help="seconds to wait [3]")
    parser.add_argument("--json", action="store_true", help="print the raw status as JSON")
    add_network_arguments(parser)


def format_uptime(seconds: float) -> str:
    """Returns an uptime like ``3h02m``, ``4m05s`` or ``12.3s``."""
    if seconds < 60:
        return f"{seconds:.1f}s"
    minutes, sec = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m" if hours else f"{minutes}m{sec:02d}s"


def summary_line(status: dict) -> str:
    """Returns the one-line summary of a status."""
    c = status.get("counters", {})
    err = status.get("last_error") or {}
    return (f"{status['name']:<16} {status.get('host', '?'):<14} {status.get('pid', '?'):>7} "
            f"{format_uptime(status.get('uptime_s', 0.0)):>8} {c.get('received', 0):>9} "
            f"{c.get('published', 0):>9} {c.get('rejected', 0):>8} {c.get('errors', 0):>6}  "
            f"{err.get('message', '')[:60]}")


HEADER = (f"{'SERVICE':<16} {'HOST':<14} {'PID':>7} {'UPTIME':>8} {'RECEIVED':>9} "
          f"{'PUBLISHED':>9} {'REJECTED':>8} {'ERRORS':>6}  LAST ERROR")


def no_answer(service: str, key: str, live: list[str]) -> str:
    """Returns why nothing answered a status query, and what to run instead.

    Args:
        service: the name asked for (``*``: all).
        key: the status key that was queried.
        live: the services whose liveliness token is present.
    """
    if not live:
        return (f"no service answered {key}, and none is alive under this prefix: start them "
                "with `cbgo up` (or check --prefix and --connect)")
    if service == "*":
        return f"no service answered {key}; alive: {', '.join(live)} (are they busy?)"
    if service in live:
        return f"{service} is alive but did not answer {key}; try a longer --timeout"
    return (f"no service named {service!r} is alive{did_you_mean(service, live)}; alive: "
            f"{', '.join(live)} (`cbgo ls` lists them with their keys)")


def run(args: argparse.Namespace) -> int:
    """Prints the status(es); returns 1 if no service answered."""
    with session(args, "cbgo-status") as (sess, keys):
        statuses = client.status(sess, keys, args.service, args.timeout)
        if not statuses:
            live = sorted(client.alive(sess, keys, 1.0))
            print(f"cbgo: {no_answer(args.service, keys.ctl(args.service, 'status'), live)}",
                  file=sys.stderr)
            return 1
    if args.json:
        for status in statuses.values():
            print(json.dumps(jsonable(status)))
    elif args.service != "*":
        for status in statuses.values():
            print(pretty(status))
    else:
        print(HEADER)
        for name in sorted(statuses):
            print(summary_line(statuses[name]))
    return 0
