"""Show the planner's live behaviour tree (``cbgo plan show``).

Subscribes to ``plan/status`` and draws the newest one: the intent, the action sequence with
each step's state, the plan's state and error, and the behaviour tree as py-trees draws it. On a
terminal the screen is redrawn in place; otherwise (a pipe, a file) each status is printed in
turn, separated by a line of dashes.

Examples::

    cbgo plan show                       # live view until Ctrl-C
    cbgo plan show --once                # print the next status and exit
    cbgo plan show --once --timeout 60 --no-tree > plan.txt
"""

from __future__ import annotations

import argparse
import queue
import sys
import time

from cbgo import keys, wire
from cbgo.cli.common import add_network_arguments, session
from cbgo.errors import RejectedMessage

CLEAR = "\x1b[2J\x1b[H"  # clear the screen, cursor home


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds plan's flags."""
    parser.add_argument("what", choices=["show"], help="show: draw plan/status as it changes")
    parser.add_argument("--once", action="store_true", help="print the next status and exit")
    parser.add_argument("--timeout", type=float, default=0.0, metavar="S",
                        help="exit with code 1 if no status arrives within S seconds "
                             "(0: wait forever)")
    parser.add_argument("--no-tree", action="store_true", help="leave the tree out")
    add_network_arguments(parser)


def render(status: dict, tree: bool = True) -> str:
    """Returns a ``plan/status`` message as text for people."""
    intent = status["intent"]
    goal = f"{intent.get('action')}({intent.get('object') or '-'})"
    lines = [f"plan {goal}: {status['state']}   (episode {intent.get('episode') or '-'}, "
             f"confidence {intent.get('confidence', 0.0):.2f}, "
             f"{time.strftime('%H:%M:%S', time.localtime(status['ts']))})"]
    for i, step in enumerate(status["sequence"], 1):
        params = f" {step['params']}" if step["params"] else ""
        lines.append(f"  {i:2d}. {step['state']:<8} {step['action']}({step['object'] or '-'})"
                     f"{params}")
    if not status["sequence"]:
        lines.append("      (no action)")
    if status["error"]:
        lines.append(f"error: {status['error']}")
    if tree and status["tree"]:
        lines += ["", status["tree"].rstrip()]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Subscribes to plan/status and draws each status until Ctrl-C, --once or --timeout."""
    inbox: queue.Queue = queue.Queue()
    with session(args, "cbgo-plan") as (sess, k):
        key = k.of(keys.PLAN_STATUS)
        sess.declare_subscriber(key, lambda s: inbox.put(s.payload.to_bytes()))
        print(f"listening on {key}", file=sys.stderr)
        return _draw_loop(inbox, key, args)


def _draw_loop(inbox: queue.Queue, key: str, args: argparse.Namespace) -> int:
    tty = sys.stdout.isatty()
    deadline = time.monotonic() + args.timeout if args.timeout else None
    seen = 0
    while True:
        if deadline is not None and seen == 0 and time.monotonic() > deadline:
            print(f"cbgo: no {key} within {args.timeout:g} s (is the planner up?)",
                  file=sys.stderr)
            return 1
        try:
            payload = inbox.get(timeout=0.1)
        except queue.Empty:
            continue
        try:
            status = wire.decode_checked(payload, wire.PLAN_STATUS, key)
        except RejectedMessage as e:
            print(f"invalid: {e}", file=sys.stderr)
            continue
        seen += 1
        text = render(status, tree=not args.no_tree)
        print(CLEAR + text if tty else text + "\n" + "-" * 40, flush=True)
        if args.once:
            return 0
