"""Record a new gesture by demonstration and retrain; list the gestures recorded so far.

``record`` captures the gesture from the live ``hands/frame`` stream (any source: a Leap, a
replay, the simulated user), stores it in the user's gesture set under ``data_dir()``
(``CBGO_DATA_DIR``), retrains the model and asks the running service to reload it — no code
change. ``--static`` is handled by ``cbgo.services.static_gesture.demonstrate``, ``--dynamic``
by ``cbgo.services.dynamic_gesture.demonstrate`` (each imported only when used).

Examples::

    cbgo gestures record horns --static                  # 60 frames of one take, retrain
    cbgo gestures record ok --static --takes 3 --frames 40 --user alice
    cbgo gestures record circle --dynamic --takes 5
    cbgo gestures list
    cbgo gestures list --json
"""

from __future__ import annotations

import argparse
import importlib
import json

from cbgo import registry
from cbgo.cli.common import add_network_arguments, fail
from cbgo.client import ConnectError

# kind -> (module, what is demonstrated), from the services' manifests (``demonstrate``)
DEMONSTRATIONS = registry.tools("demonstrate")
MODULES = {kind: module for kind, (module, _) in DEMONSTRATIONS.items()}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the ``record`` and ``list`` sub-commands."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    record = actions.add_parser("record", help="record a gesture by demonstration and retrain")
    record.add_argument("name", metavar="NAME", help="the gesture's name (a new or known one)")
    kind = record.add_mutually_exclusive_group(required=True)
    for name, (_, what) in DEMONSTRATIONS.items():
        kind.add_argument(f"--{name}", dest="kind", action="store_const", const=name, help=what)
    record.add_argument("--frames", type=int, default=None, metavar="N",
                        help="frames per take (static default: 60)")
    record.add_argument("--takes", type=int, default=1, metavar="N",
                        help="renditions to record; the hand leaves the view between them [1]")
    record.add_argument("--user", default=None, metavar="U",
                        help="who demonstrates (default: the operator on cbgo/user)")
    record.add_argument("--timeout", type=float, default=60.0, metavar="S",
                        help="give up if the takes are not complete within S seconds [60]")
    record.add_argument("--settle", type=float, default=None, metavar="S",
                        help="static: seconds a hand is in view before its frames count [0.5]")
    record.add_argument("--epochs", type=int, default=None, metavar="N",
                        help="retraining epochs (fewer: faster, rougher)")
    record.add_argument("--replace", action="store_true",
                        help="drop earlier recordings of NAME instead of adding to them")
    record.add_argument("--no-train", action="store_true",
                        help="only store the recording; retrain later")
    add_network_arguments(record)
    listing = actions.add_parser("list", help="list the recorded gestures")
    listing.add_argument("--json", action="store_true", help="one JSON object per gesture")


def _module(kind: str):
    try:
        return importlib.import_module(MODULES[kind])
    except ModuleNotFoundError as e:
        if e.name and MODULES[kind].startswith(e.name):
            fail(f"{kind} gestures by demonstration are not available in this installation "
                 f"({MODULES[kind]} is missing)")
        raise


def _list(as_json: bool) -> int:
    rows = []
    for module_name in MODULES.values():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError:
            continue
        if hasattr(module, "list_gestures"):
            rows += module.list_gestures()
    if as_json:
        for row in rows:
            print(json.dumps(row))
        return 0
    if not rows:
        print("no recorded gestures yet; record one with `cbgo gestures record NAME --static`")
        return 0
    print(f"{'kind':<8} {'name':<16} {'samples':>7} {'takes':>5}  {'users':<16} last recorded")
    for r in rows:
        print(f"{r['kind']:<8} {r['name']:<16} {r['samples']:>7} {r['takes']:>5}  "
              f"{','.join(r['users']):<16} {r['last']}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Dispatches ``record`` to the gesture kind's module, or lists recordings."""
    if args.action == "list":
        return _list(args.json)
    if args.frames is not None and args.frames < 1 or args.takes < 1:
        fail("--frames and --takes must be at least 1", 2)
    try:
        return _module(args.kind).run(args)
    except ConnectError as e:  # the demonstrate modules open their sessions with cbgo.client
        fail(str(e), e.code)
        raise
