"""Run a benchmark and print its figures (the offline tools of a cbgo checkout).

``--write FILE`` also writes what the benchmark printed as a results document (Markdown, with
the command that produced it), so a README's figures are regenerated, never hand-edited.

Examples::

    cbgo bench wire
    cbgo bench hands --per-gesture 200
    cbgo bench sim --write docs/results/mujoco_sim.md
    cbgo bench wire --help          # a benchmark's own options
"""

from __future__ import annotations

import argparse
import sys

from cbgo.cli.common import fail, offline_registry, run_module


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the benchmark name and --write; its own options are parsed by the benchmark."""
    benches = offline_registry().BENCHES
    parser.add_argument("bench", choices=sorted(benches), metavar="BENCH",
                        help="; ".join(f"{name}: {text}" for name, (_, text) in benches.items()))
    parser.add_argument("--write", metavar="FILE", default=None,
                        help="also write the printed figures to FILE as a results document")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="the benchmark's own options")


def split_write(argv: list[str]) -> tuple[str | None, list[str]]:
    """Takes ``--write FILE`` (or ``--write=FILE``) out of the benchmark's own options.

    Options after the benchmark's name are the benchmark's, so ``--write`` there would reach
    it; it is cbgo bench's wherever it stands.
    """
    rest, write = [], None
    items = iter(argv)
    for item in items:
        if item == "--write":
            write = next(items, None)
            if write is None:
                fail("--write needs a file name", 2)
        elif item.startswith("--write="):
            write = item.partition("=")[2]
        else:
            rest.append(item)
    return write, rest


def run(args: argparse.Namespace) -> int:
    """Imports the chosen benchmark, parses its options and runs it."""
    module = offline_registry().BENCHES[args.bench][0]
    prog = f"cbgo bench {args.bench}"
    write, own = split_write(args.args)
    args.write, args.args = args.write or write, own
    if args.write is None:
        return run_module(module, prog, args.args)
    from cbgo_tools.results import written  # noqa: PLC0415 - only with --write

    with written(args.write, [*prog.split(), *args.args]):
        code = run_module(module, prog, args.args)
        if code:
            sys.exit(code)  # a failed run leaves the results document as it was
    return 0
