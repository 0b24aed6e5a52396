"""Train a model and write it where its service loads it.

Examples::

    cbgo train static               # the static-gesture classifier
    cbgo train static --help        # a trainer's own options
"""

from __future__ import annotations

import argparse

from cbgo.cli.common import run_module
from cbgo.train import TRAINERS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer name; its own options are parsed by the trainer (lazy import)."""
    parser.add_argument("trainer", choices=sorted(TRAINERS), metavar="TRAINER",
                        help="; ".join(f"{name}: {text}" for name, (_, text) in TRAINERS.items()))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the trainer's own options")


def run(args: argparse.Namespace) -> int:
    """Imports the chosen trainer, parses its options and runs it."""
    return run_module(TRAINERS[args.trainer][0], f"cbgo train {args.trainer}", args.args)
