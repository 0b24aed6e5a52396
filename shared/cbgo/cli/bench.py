"""Run a benchmark and print its figures (`cbgo bench --help` lists them).

Examples::

    cbgo bench wire
"""

from __future__ import annotations

import argparse
import importlib

from cbgo.bench import BENCHES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds one sub-command per benchmark."""
    benches = parser.add_subparsers(dest="bench", metavar="BENCH", required=True)
    for name, summary in BENCHES.items():
        module = importlib.import_module(f"cbgo.bench.{name}")
        sub = benches.add_parser(name, help=summary, description=module.__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(sub)
        sub.set_defaults(bench_run=module.run)


def run(args: argparse.Namespace) -> int:
    """Runs the chosen benchmark."""
    return args.bench_run(args)
