"""Talk to the simulator (mujoco-sim): snapshots, resets and single actions.

``snapshot`` queries ``cbgo/sim/render`` and writes the PNG; ``reset`` queries ``cbgo/sim/reset``
with a seed or a scene file (JSON or YAML: ``{objects: [...], robot: {...}}``) and prints the
settled scene; ``act`` queries ``cbgo/robot/act`` and prints the outcome.

Examples::

    cbgo sim snapshot -o scene.png
    cbgo sim snapshot -o top.png --camera top --width 1024 --height 768
    cbgo sim reset --seed 7
    cbgo sim reset --scene tests/artifacts/scenes/put_into.json
    cbgo sim act pick_up cup1
    cbgo sim act pour cup2 --params '{"angle_deg": 100}'
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cbgo import client, keys
from cbgo.cli.common import add_network_arguments, fail, read_json_argument, session
from cbgo.codec import pretty
from cbgo.errors import ConfigError, QueryError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the sub-verbs snapshot, reset and act."""
    sub = parser.add_subparsers(dest="sim_verb", metavar="VERB", required=True)
    snap = sub.add_parser("snapshot", help="render the scene to a PNG file")
    snap.add_argument("-o", "--output", required=True, help="PNG file to write")
    snap.add_argument("--camera", help="camera: overview, workspace, front, side, top or robot "
                                       "[the simulator's default, overview]")
    snap.add_argument("--width", type=int, help="pixels [the simulator's default, 640]")
    snap.add_argument("--height", type=int, help="pixels [the simulator's default, 480]")
    reset = sub.add_parser("reset", help="load a random scene (seed) or a scene file")
    which = reset.add_mutually_exclusive_group()
    which.add_argument("--seed", type=int, help="the world model's random scene of this seed")
    which.add_argument("--scene", help="a scene file, JSON or YAML")
    act = sub.add_parser("act", help="execute one action and print the outcome")
    act.add_argument("action", help="e.g. pick_up, put_into, move_left")
    act.add_argument("object", nargs="?", help="the target object, if the action has one")
    act.add_argument("--params", default="{}", help="JSON parameters, e.g. '{\"angle_deg\": 90}'")
    for p in (snap, reset, act):
        p.add_argument("--timeout", type=float, default=60.0, help="seconds to wait [60]")
        p.add_argument("--json", action="store_true", help="print the reply as JSON")
        add_network_arguments(p)


def _query(args: argparse.Namespace, topic, message: dict) -> dict:
    with session(args, "cbgo-sim") as (sess, k):
        try:
            return client.query(sess, k.of(topic), message, timeout_s=args.timeout,
                                hint="is a robot up? `cbgo up mujoco-sim` or `cbgo up dry-robot`")
        except QueryError as e:
            fail(str(e))
    raise AssertionError("unreachable")


def _scene_file(path: str) -> dict:
    from cbgo.world import read_scene_file

    try:
        return read_scene_file(path)
    except ConfigError as e:
        fail(str(e), 2)


def _print(reply: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(reply))
    else:
        print(pretty(reply))


def run(args: argparse.Namespace) -> int:
    """Runs the sub-verb; returns 0 on success, 1 when the simulator said no."""
    if args.sim_verb == "snapshot":
        message = keys.SIM_RENDER.message()
        for name in ("camera", "width", "height"):
            if getattr(args, name) is not None:
                message[name] = getattr(args, name)
        reply = _query(args, keys.SIM_RENDER, message)
        if not reply.get("ok") or "png" not in reply:
            fail(f"render failed: {reply.get('error')}")
        Path(args.output).parent.mkdir(parents=True, exist_ok=True)
        Path(args.output).write_bytes(reply["png"])
        print(f"wrote {args.output} ({len(reply['png'])} bytes)")
        return 0
    if args.sim_verb == "reset":
        message = keys.SIM_RESET.message()
        if args.seed is not None:
            message["seed"] = args.seed
        if args.scene is not None:
            message["scene"] = _scene_file(args.scene)
        reply = _query(args, keys.SIM_RESET, message)
    else:
        params = read_json_argument(args.params)
        if not isinstance(params, dict):
            fail("--params must be a JSON object", 2)
        reply = _query(args, keys.ROBOT_ACT, keys.ROBOT_ACT.message(action=args.action,
                                              object=args.object, params=params))
    if reply["ok"] or args.json:
        _print(reply, args.json)
    if not reply["ok"]:  # the world did not change: the reason is the news, not the scene
        print(f"cbgo: {reply['error']}", file=sys.stderr)
    return 0 if reply["ok"] else 1
