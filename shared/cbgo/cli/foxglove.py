"""Serve the live cbgo traffic to Foxglove (a WebSocket server; the foxglove-bridge service).

Runs the foxglove-bridge service in this process: a Foxglove WebSocket server (default
ws://127.0.0.1:8765) with one JSON channel per data key (topic = the key, with its JSON
Schema), plus ``foxglove/scene`` (3D hands, objects, TCP, focus ray, the target highlighted),
``foxglove/transforms`` (robot base and Leap frame) and ``foxglove/log`` (episode, intent and
plan events). High-rate keys are thinned to ``--stream-hz``. In Foxglove: *Open connection*,
*Foxglove WebSocket*, the URL; the layout ``deploy/foxglove/layout.json`` shows the 3D scene,
gesture probabilities and the log.

Examples::

    cbgo foxglove                                  # ws://127.0.0.1:8765, router on localhost
    cbgo foxglove --ws-host 0.0.0.0 --ws-port 9000 --connect tcp/10.0.0.5:7447
    cbgo up --robot dry --foxglove                 # the same, started with the other services

All flags are the service's and the runtime's; see `cbgo foxglove --help`.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The bridge's flags are parsed by the runtime (`cbgo.cli.main` hands them over)."""
    parser.add_argument("args", nargs=argparse.REMAINDER, help="bridge flags (see --help)")


def run(args: argparse.Namespace) -> int:
    """Runs the bridge (only reached through `cbgo.cli.main`, which short-cuts it)."""
    from cbgo.runtime import run as run_service
    from cbgo.services.foxglove_bridge.main import FoxgloveBridge

    return run_service(FoxgloveBridge, args.args)
