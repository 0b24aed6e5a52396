"""Real data sets (list, fetch, convert) and the paper's intent data sets: offline tools.

Examples::

    cbgo data list
    cbgo data fetch shrec17
    cbgo data convert mmhgr
    cbgo data intent make D4 -n 4000 -o d4.npz
"""

from __future__ import annotations

import argparse
import importlib

from cbgo.cli.common import offline_registry


def _command():
    offline_registry()  # says how to install the tools where they are missing
    return importlib.import_module("cbgo_tools.data.command")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the data command's sub-commands (`cbgo_tools.data.command`)."""
    command = _command()
    parser.description = command.__doc__
    command.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Runs the chosen sub-command."""
    return _command().run(args)
