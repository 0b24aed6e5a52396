"""Say what your gestures mean: show, set or unset a user's gesture mapping.

The mapping is the file ``<personal dir>/<user>/mapping.yaml`` (``--personal-dir``, else
``CBGO_PERSONAL_DIR``, else ``<data dir>/intent``, the intent service's default), beside the
user's model and corrections. A running intent service reloads it within ``--watch-s`` (1 s)
and refits that user's model, which takes about 10 s; from then on the stated meaning is
followed wherever the scene allows it. The mapping is a prior of the user's model, not a
lookup: the scene's feasibility and the gesture evidence still decide, and corrections
(`cbgo feedback`) keep refining it. A rule names a gesture, an action, and optionally an object
type (``--on``) and its state (``--state``); the more precise rule wins.

Examples::

    cbgo mapping show --user alice
    cbgo mapping set --user alice swipe_left put_into           # swipe_left means put_into
    cbgo mapping set --user alice thumbsup pour --on cup        # ... on a cup, pour
    cbgo mapping set --user alice grab open --on drawer --state closed
    cbgo mapping unset --user alice thumbsup --on cup
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from cbgo.cli.common import fail
from cbgo.config import data_dir
from cbgo.services.intent import mapping as mp
from cbgo.services.intent.personal import safe_dirname
from cbgo.wire import ACTIONS, OBJECT_TYPES, PAPER_GESTURES

STATES = sorted({s for names in mp.STATE_NAMES.values() for s in names})


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the show, set and unset sub-commands."""
    verbs = parser.add_subparsers(dest="what", metavar="show|set|unset", required=True)
    show = verbs.add_parser("show", help="print the user's rules and where the file is")
    set_ = verbs.add_parser("set", help="state that a gesture means an action (replaces the "
                                        "rule of the same gesture, type and state)")
    unset = verbs.add_parser("unset", help="remove the rule of a gesture, type and state")
    for sub in (show, set_, unset):
        sub.add_argument("--user", required=True, help="whose mapping")
        sub.add_argument("--personal-dir", default=None,
                         help="where users' models live [CBGO_PERSONAL_DIR, else "
                              "<data dir>/intent]")
    for sub in (set_, unset):
        sub.add_argument("gesture", choices=PAPER_GESTURES, metavar="GESTURE",
                         help=f"one of {', '.join(PAPER_GESTURES)}")
    set_.add_argument("action", choices=ACTIONS, metavar="ACTION",
                      help=f"one of {', '.join(ACTIONS)}")
    for sub in (set_, unset):
        sub.add_argument("--on", choices=OBJECT_TYPES, default=None,
                         help="only on objects of this type [any]")
        sub.add_argument("--state", choices=STATES, default=None,
                         help="only in this state of the --on type (cup empty|full, drawer "
                              "closed|open, box free|blocked) [either]")


def mapping_path(user: str, personal_dir: str | None) -> Path:
    """Returns the file of a user's mapping (where the intent service reads it)."""
    root = personal_dir or os.environ.get("CBGO_PERSONAL_DIR")
    return (Path(root) if root else data_dir() / "intent") / safe_dirname(user) / mp.FILE_NAME


def run(args: argparse.Namespace) -> int:
    """Shows or edits the file; returns 0, or exits 1 with the reason."""
    path = mapping_path(args.user, args.personal_dir)
    try:
        mapping = mp.load(path, PAPER_GESTURES)
    except mp.MappingError as e:
        fail(f"{e}\nfix or delete the file; the intent service keeps the mapping it had")
    if args.what == "show":
        print(f"mapping of {args.user} ({path}{'' if path.exists() else ', no file yet'}):")
        for rule in mapping.rules:
            print(f"  {rule.label}")
        if not mapping:
            print("  no rules: the model's default reading of the gestures")
        return 0
    try:
        if args.what == "set":
            mapping = mapping.with_rule(mp.parse_rule(
                {"gesture": args.gesture, "action": args.action, "on": args.on,
                 "state": args.state}, "rule", PAPER_GESTURES))
            done = f"set: {mapping.rules[-1].label}"
        else:
            mapping, removed = mapping.without(args.gesture, args.on, args.state)
            if not removed:
                fail(f"{args.user} has no rule for {args.gesture}"
                     + (f" on {args.on}" if args.on else "")
                     + (f" ({args.state})" if args.state else "")
                     + "; `cbgo mapping show --user NAME` lists them")
            done = f"unset: {args.gesture}" + (f" on {args.on}" if args.on else "")
    except mp.MappingError as e:
        fail(str(e), 2)
    mp.save(path, mapping)
    print(f"{done} for {args.user} ({path}); a running intent service refits the user's "
          f"model within seconds")
    return 0
