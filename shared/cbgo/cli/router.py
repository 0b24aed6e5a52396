"""Run the Zenoh router of a cbgo network (Python, ``mode: router``, admin space on).

Examples::

    cbgo router                                   # listen on tcp/127.0.0.1:7447 (this host)
    cbgo router --listen tcp/127.0.0.1:7448       # another port, still loopback only
    cbgo router --listen tcp/10.0.0.5:7447        # the cell's network: other hosts may join
    cbgo router --connect tcp/robot-pc:7447       # join another site's router

Loopback by default: other hosts reach the router only where ``--listen`` names an address
they can reach. Listening there without TLS is logged as a warning naming the secured
deployment (`cbgo certs make`, deploy/compose.tls.yaml, deploy/tls/). A port in use ends the
router at once (exit code 2) with a message naming the port and ``--listen``.

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
