"""Train a model and write it where its service loads it (the offline tools of a checkout).

Examples::

    cbgo train static               # the static-gesture classifier
    cbgo train static --help        # a trainer's own options
"""

from __future__ import annotations

import argparse

from cbgo.cli.common import offline_registry, run_module


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the trainer name; its own options are parsed by the trainer (lazy import)."""
    trainers = offline_registry().TRAINERS
    parser.add_argument("trainer", choices=sorted(trainers), metavar="TRAINER",
                        help="; ".join(f"{name}: {text}" for name, (_, text) in trainers.items()))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the trainer's own options")


def run(args: argparse.Namespace) -> int:
    """Imports the chosen trainer, parses its options and runs it."""
    module = offline_registry().TRAINERS[args.trainer][0]
    return run_module(module, f"cbgo train {args.trainer}", args.args)
