"""Record a new gesture by demonstration and retrain; list the gestures recorded so far.

``record`` captures the gesture from the live ``hands/frame`` stream (any source: a Leap, a
replay, the simulated user), stores it in the user's gesture set under the data directory,
retrains the model and asks the running service to reload it — no code change. ``--static`` is
handled by ``cbgo.services.static_gesture.demonstrate``, ``--dynamic`` by
``cbgo.services.dynamic_gesture.demonstrate`` (each imported only when used).
``cbgo gestures record --help`` says how, with examples. ``calibrate`` fits the recognisers to
one person from a few takes of the gestures they already know (``--help`` says how).

Examples::

    cbgo gestures record horns --static --simulate 1,0,1,1,0 --takes 3   # no sensor needed
    cbgo gestures record horns --static                  # 60 frames of one take, retrain
    cbgo gestures record ok --static --takes 3 --frames 40 --user alice
    cbgo gestures record circle --dynamic --takes 5
    cbgo gestures calibrate --user alice --takes 3       # a slow swiper is heard
    cbgo gestures list
    cbgo gestures list --json
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import socket
import sys
from pathlib import Path

from cbgo import registry
from cbgo.cli.common import add_network_arguments, fail
from cbgo.client import ConnectError
from cbgo.config import data_dir
from cbgo.errors import ConfigError

# kind -> (module, what is demonstrated), from the services' manifests (``demonstrate``)
DEMONSTRATIONS = registry.tools("demonstrate")
MODULES = {kind: module for kind, (module, _) in DEMONSTRATIONS.items()}
# kind -> module of each service's calibration to one person, from the manifests (``calibrate``)
CALIBRATE_MODULES = {kind: module for kind, (module, _) in registry.tools("calibrate").items()}
STATUS_TIMEOUT_S = 2.0

CALIBRATE_DESCRIPTION = """\
Fit the recognisers to one person: a few takes of each gesture they already know, made at the
person's own pace, so that a person who swipes slowly (a line drawn in the air) is heard.

The person makes each swipe --takes times: rest the hand, swipe once, take the hand away. The
takes' speeds are stored as <data dir>/calibration/NAME.json; the running dynamic-gesture
re-reads it and judges strokes by it whenever cbgo/user names the person.

A static pose the tracker bends for this person (a thumbs-up read as grab) is taught with
`cbgo gestures record thumbsup --static --takes 3 --user NAME --personal`: a model of the
person's own (the shipped data and their takes), which the running static-gesture serves
whenever cbgo/user names them. Without --personal the takes join the model of every user of
the data directory."""

CALIBRATE_EXAMPLES = """\
examples:
  cbgo gestures calibrate --user alice            # live, 3 takes of each swipe
  cbgo gestures calibrate --user alice --takes 5
  cbgo gestures calibrate --user alice --file alice-swipes.mcap
  cbgo status dynamic-gesture                    # lines_mm_s: the lines in use"""

RECORD_DESCRIPTION = """\
Record a gesture by showing it, store it in the data directory and retrain, so that the
running service recognises it: no code change.

Frames come from cbgo/hands/frame, whatever sends them: a person at a Leap Motion, a replay,
or leap-bridge's simulated user (what `cbgo up` starts). Without a sensor, --simulate makes
the simulated user show the pose once per take: a static gesture's name, or any hand pose as
five finger curls thumb,index,middle,ring,pinky, each 0 (straight) to 1 (curled). The hand
enters, holds the pose, leaves; frames count once it has settled.

Static: before anything is stored, the model served now reads the takes; when half of their
frames or more are answered as one other gesture (a "peace" shown as the two pose), the new
name would lose to it, so nothing is stored or swapped unless --force.

The data directory must be the running service's: this command asks its status for it and
uses it (--data-dir or CBGO_DATA_DIR that differ are an error naming both)."""

RECORD_EXAMPLES = """\
examples:
  cbgo up                                   # router, services, leap-bridge's simulated user
  cbgo gestures record horns --static --simulate 1,0,1,1,0 --takes 3
  cbgo gestures record peace --static --simulate two  # refused: its frames are read as two
  cbgo gestures record horns --static --takes 3 # at a Leap: hand in, hold, hand out, x3
  cbgo gestures record circle --dynamic --takes 5
  cbgo gestures list

  The simulated user holds any pose on request too, e.g. to try a taught gesture:
  cbgo get @ctl/leap-bridge/play --payload \\
    '{"episodes": [{"gestures": [{"gesture": "horns", "curls": [1,0,1,1,0], "hold_s": 4}]}]}'
  cbgo echo gestures/static"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the ``record`` and ``list`` sub-commands."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    record = actions.add_parser("record", help="record a gesture by demonstration and retrain",
                                description=RECORD_DESCRIPTION, epilog=RECORD_EXAMPLES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    record.add_argument("name", metavar="NAME", help="the gesture's name (a new or known one)")
    kind = record.add_mutually_exclusive_group(required=True)
    for name, (_, what) in DEMONSTRATIONS.items():
        kind.add_argument(f"--{name}", dest="kind", action="store_const", const=name, help=what)
    record.add_argument("--simulate", default=None, metavar="POSE",
                        help="static: leap-bridge's simulated user shows POSE for each take: a "
                             "static gesture (two) or finger curls thumb,index,middle,ring,"
                             "pinky, 0 straight .. 1 curled (horns: 1,0,1,1,0)")
    record.add_argument("--frames", type=int, default=None, metavar="N",
                        help="frames per take (static default: 60)")
    record.add_argument("--takes", type=int, default=1, metavar="N",
                        help="renditions to record; the hand leaves the view between them [1]")
    record.add_argument("--user", default=None, metavar="U",
                        help="who demonstrates (default: the operator on cbgo/user)")
    record.add_argument("--personal", action="store_true",
                        help="static: retrain the demonstrator's own model (their takes only), "
                             "served while cbgo/user names them, instead of the model of "
                             "every user of the data directory")
    record.add_argument("--timeout", type=float, default=60.0, metavar="S",
                        help="give up if the takes are not complete within S seconds [60]")
    record.add_argument("--settle", type=float, default=None, metavar="S",
                        help="static: seconds a hand is in view before its frames count "
                             "[0.5; 1 with --simulate]")
    record.add_argument("--epochs", type=int, default=None, metavar="N",
                        help="retraining epochs (fewer: faster, rougher)")
    record.add_argument("--replace", action="store_true",
                        help="drop earlier recordings of NAME instead of adding to them")
    record.add_argument("--no-train", action="store_true",
                        help="only store the recording; retrain later")
    record.add_argument("--force", action="store_true",
                        help="static: teach NAME even when the served model reads its takes "
                             "as another gesture")
    record.add_argument("--data-dir", default=None, metavar="DIR",
                        help="where gestures and models live (default: the running service's, "
                             "else CBGO_DATA_DIR, else ~/.local/share/cbgo)")
    add_network_arguments(record)
    calibrate = actions.add_parser(
        "calibrate", help="fit the recognisers to one person from a few demonstrations",
        description=CALIBRATE_DESCRIPTION, epilog=CALIBRATE_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    calibrate.add_argument("--user", required=True, metavar="NAME",
                           help="who is calibrated, as cbgo/user names them")
    calibrate.add_argument("--takes", type=int, default=3, metavar="N",
                           help="takes of each gesture [3]")
    calibrate.add_argument("--file", default=None, metavar="MCAP",
                           help="read the takes from a recording instead of the live stream")
    calibrate.add_argument("--timeout", type=float, default=180.0, metavar="S",
                           help="give up if the takes are not complete within S seconds [180]")
    calibrate.add_argument("--data-dir", default=None, metavar="DIR",
                           help="where calibrations live (default: the running service's, "
                                "else CBGO_DATA_DIR, else ~/.local/share/cbgo)")
    add_network_arguments(calibrate)
    listing = actions.add_parser("list", help="list the recorded gestures")
    listing.add_argument("--json", action="store_true", help="one JSON object per gesture")


def _module(kind: str, modules: dict[str, str] = MODULES):
    try:
        return importlib.import_module(modules[kind])
    except ModuleNotFoundError as e:
        if e.name and modules[kind].startswith(e.name):
            fail(f"{kind} gestures by demonstration are not available in this installation "
                 f"({modules[kind]} is missing)")
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


def service_of(kind: str) -> str:
    """Returns the service that serves the gestures of a kind (``static``: static-gesture)."""
    for manifest in registry.SERVICES:
        tool = manifest.demonstrate
        if tool is not None and tool.name == kind:
            return manifest.name
    raise KeyError(kind)


def _service_statuses(args: argparse.Namespace, service: str) -> list[dict]:
    """Returns the status replies of the running `service` (none running: empty)."""
    from cbgo.client import query_all, session

    with session(args, "cbgo-gestures") as (sess, k):
        replies = query_all(sess, k.ctl(service, "status"), timeout_s=STATUS_TIMEOUT_S)
    return [answer for ok, answer in replies if ok]


def _same_dir(a: str | Path, b: str | Path) -> bool:
    return Path(a).expanduser().resolve() == Path(b).expanduser().resolve()


def resolve_data_dir(args: argparse.Namespace, statuses: list[dict], service: str,
                     env=None) -> Path:
    """Returns the data directory to record into: the running service's.

    Args:
        args: ``data_dir`` (``--data-dir``), if given.
        statuses: the service's status replies (their ``data_dir``, when they say it).
        service: its name, for the messages.
        env: the environment (``os.environ`` by default).

    Raises:
        ValueError: the service reads another directory than the one asked for, several
            services read different ones, or the service runs on another machine and its
            directory is not here; the message names both and the fix.
    """
    env = os.environ if env is None else env
    asked = args.data_dir or env.get("CBGO_DATA_DIR")
    own = Path(asked).expanduser() if asked else data_dir(env)
    theirs = sorted({s["data_dir"] for s in statuses if isinstance(s.get("data_dir"), str)})
    if not theirs:
        return own
    if len(theirs) > 1:
        raise ValueError(f"{len(theirs)} {service} services answer, reading different data "
                         f"directories ({', '.join(theirs)}); stop all but one, or give them "
                         "one CBGO_DATA_DIR")
    if _same_dir(theirs[0], own):
        return own
    if asked:
        flag = "--data-dir" if args.data_dir else "CBGO_DATA_DIR"
        raise ValueError(f"the running {service} reads its gestures and model from "
                         f"{theirs[0]}, not {own} ({flag}): what this records there would "
                         f"never be served. Rerun with --data-dir {theirs[0]}, or restart "
                         f"{service} with CBGO_DATA_DIR={own}")
    here = any(s.get("host") == socket.gethostname() for s in statuses)
    if not here and not Path(theirs[0]).is_dir():
        raise ValueError(f"the running {service} reads its gestures and model from "
                         f"{theirs[0]} on another machine, which is not here: run this "
                         f"command where {service} runs, or share that directory and give it "
                         "with --data-dir")
    return Path(theirs[0])


def _calibrate(args: argparse.Namespace) -> int:
    """Runs each service's calibration for the user, in turn."""
    if args.takes < 1:
        fail("--takes must be at least 1", 2)
    if args.file and not Path(args.file).is_file():
        fail(f"no recording at {args.file}", 2)
    if args.file and args.data_dir:  # no service asked: the directory given is the one
        os.environ["CBGO_DATA_DIR"] = str(Path(args.data_dir).expanduser())
    for kind in CALIBRATE_MODULES:
        args.kind = kind
        try:
            if not args.file:
                _use_running_service(args)
            code = _module(kind, CALIBRATE_MODULES).run(args)
        except ConnectError as e:
            fail(str(e), e.code)
            raise
        if code:
            return code
    return 0


def _use_running_service(args: argparse.Namespace) -> None:
    """Points this process at the running service's data directory (and served model)."""
    service = service_of(args.kind)
    statuses = _service_statuses(args, service)
    try:
        chosen = resolve_data_dir(args, statuses, service)
    except ValueError as e:
        fail(str(e), 2)
    if not _same_dir(chosen, data_dir()):
        print(f"data directory: {chosen} (the running {service}'s)")
    os.environ["CBGO_DATA_DIR"] = str(chosen)  # what the demonstrate modules read
    served = [s.get("model") for s in statuses if isinstance(s.get("model"), dict)]
    args.served_model = served[0].get("path") if served else None


def run(args: argparse.Namespace) -> int:
    """Dispatches ``record`` to the gesture kind's module, or lists recordings."""
    if args.action == "list":
        return _list(args.json)
    if args.action == "calibrate":
        return _calibrate(args)
    if args.frames is not None and args.frames < 1 or args.takes < 1:
        fail("--frames and --takes must be at least 1", 2)
    if args.personal and args.kind != "static":
        fail("--personal trains a person's own static-gesture model: it goes with --static", 2)
    if args.simulate and args.kind != "static":
        fail("--simulate shows a held pose: it goes with --static (a stroke is recorded from "
             "a scenario played with `cbgo get @ctl/leap-bridge/play`)", 2)
    module = _module(args.kind)
    try:  # the mistakes found without a network first
        module.check_name(args.name)
        if args.simulate:
            module.simulate_pose(args.simulate, args.name)
        if args.personal:
            module.check_personal(args.user)
    except (ValueError, ConfigError) as e:
        print(f"cbgo: {e}", file=sys.stderr)
        return 2
    try:
        _use_running_service(args)
        return module.run(args)
    except ConnectError as e:  # the demonstrate modules open their sessions with cbgo.client
        fail(str(e), e.code)
        raise
