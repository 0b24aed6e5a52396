"""Run the Zenoh router of a cbgo network (Python, ``mode: router``, admin space on).

Examples::

    cbgo router                                   # listen on tcp/0.0.0.0:7447
    cbgo router --listen tcp/127.0.0.1:7448       # another port, loopback only
    cbgo router --connect tcp/robot-pc:7447       # join another site's router

All flags are the service runtime's; see `cbgo router --help`.
"""

from __future__ import annotations

import argparse


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The router's flags are parsed by the runtime (`cbgo.cli.main` hands them over)."""
    parser.add_argument("args", nargs=argparse.REMAINDER, help="router flags (see --help)")


def run(args: argparse.Namespace) -> int:
    """Runs the router (only reached through `cbgo.cli.main`, which short-cuts it)."""
    from cbgo.router import Router
    from cbgo.runtime import run as run_service

    return run_service(Router, args.args)
