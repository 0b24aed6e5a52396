"""Correct the last intent: tell the intent service what you meant, so it learns your gestures.

Publishes ``cbgo/intent/feedback``. Unless ``--episode`` and ``--user`` are both given, the
intent service is asked for its last intent (control verb ``@ctl/intent/last``, of ``--user``
if given) and that one is corrected. The intent service stores the correction for that user and
refits the user's model (see docs/design/intent.md, "Personalisation").

Examples::

    cbgo feedback --action move_right                 # the last intent was meant as move_right
    cbgo feedback --action pick_up --object cup2
    cbgo feedback --action place --user alice --episode ep-0042
"""

from __future__ import annotations

import argparse
import sys
import time

from cbgo import client, wire
from cbgo import keys as topics
from cbgo.cli.common import add_network_arguments, fail, session
from cbgo.errors import QueryError, RejectedMessage


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds feedback's flags."""
    parser.add_argument("--action", required=True, choices=wire.ACTIONS,
                        help="the action you meant")
    parser.add_argument("--object", default=None, help="the object you meant (if it matters)")
    parser.add_argument("--user", default=None, help="who corrects [the last intent's user]")
    parser.add_argument("--episode", default=None,
                        help="the episode to correct [the last intent's]")
    parser.add_argument("--timeout", type=float, default=5.0,
                        help="seconds to wait for the intent service [5]")
    add_network_arguments(parser)


def _last(sess, keys, user: str | None, timeout: float) -> dict:
    message = {"v": wire.SCHEMA_VERSION, **({"user": user} if user else {})}
    try:
        return client.query(sess, keys.ctl("intent", "last"), message, timeout_s=timeout)
    except QueryError as e:
        print(f"cbgo: intent: {e}", file=sys.stderr)
    fail("the intent service did not answer @ctl/intent/last; is it running? (or give "
         "--user and --episode)")
    return {}


def run(args: argparse.Namespace) -> int:
    """Publishes the correction; returns 0, or 1 when there is nothing to correct."""
    import zenoh

    with session(args, "cbgo-feedback") as (sess, keys):
        user, episode = args.user, args.episode
        if user is None or episode is None:
            last = _last(sess, keys, user, args.timeout)
            if not last.get("intent"):
                fail("the intent service has no intent to correct yet")
            user = user or last["user"]
            episode = episode if episode is not None else last.get("episode")
            shown = last["intent"]
            print(f"correcting {shown.get('action')}({shown.get('object')}) of {user}"
                  + (f", episode {episode}" if episode else ""))
        message = topics.INTENT_FEEDBACK.message(ts=time.time(), episode=episode,
                   user=user, action=args.action, object=args.object)
        key = keys.of(topics.INTENT_FEEDBACK)
        try:
            wire.validate(message, wire.INTENT_FEEDBACK, key)
        except RejectedMessage as e:
            fail(str(e), 2)
        pub = sess.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
        try:
            client.put_when_matched(pub, wire.encode(message), args.timeout)
        except TimeoutError:
            fail(f"no subscriber on {key}: is the intent service running?")
        time.sleep(0.1)  # let the put leave before the session closes
    print(f"sent: {args.action}" + (f"({args.object})" if args.object else "") + f" for {user}")
    return 0
