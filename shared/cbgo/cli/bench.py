"""Run a benchmark and print its figures.

Examples::

    cbgo bench wire
    cbgo bench hands --per-gesture 200
    cbgo bench wire --help          # a benchmark's own options
"""

from __future__ import annotations

import argparse

from cbgo.bench import BENCHES
from cbgo.cli.common import run_module


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark name; its own options are parsed by the benchmark (lazy import)."""
    parser.add_argument("bench", choices=sorted(BENCHES), metavar="BENCH",
                        help="; ".join(f"{name}: {text}" for name, (_, text) in BENCHES.items()))
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the benchmark's own options")


def run(args: argparse.Namespace) -> int:
    """Imports the chosen benchmark, parses its options and runs it."""
    return run_module(BENCHES[args.bench][0], f"cbgo bench {args.bench}", args.args)
