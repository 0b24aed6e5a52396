"""Generate the paper's synthetic intent datasets D1–D5 as documented ``.npz`` files.

D1–D4 follow the paper's decision tables (``cbgo/data/gesture_tables.json``); D5 is D4 with the
object order shuffled. ``--repairable`` also draws intents whose unmet preconditions the planner
repairs (put into a closed drawer, pick up while holding), not in the paper. The file format
and the rules are documented in ``cbgo.services.intent.datasets`` (NumPy arrays, no pickles:
``np.load(path, allow_pickle=False)``).

Examples::

    cbgo data intent make D4 -n 4000 --seed 0 -o d4.npz
    cbgo data intent make D4 -n 4000 --repairable -o d4-repairable.npz
    cbgo data intent make D5 -n 2000 --seed 1 -o /tmp/d5-test.npz
    cbgo data intent info d4.npz
"""

from __future__ import annotations

import argparse
import importlib
from collections import Counter
from pathlib import Path

from cbgo.cli.common import fail
from cbgo.errors import ConfigError

DATASET_NAMES = ("D1", "D2", "D3", "D4", "D5")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the sub-commands make and info."""
    sub = parser.add_subparsers(dest="intent_command", metavar="COMMAND", required=True)
    make = sub.add_parser("make", help="generate a dataset")
    make.add_argument("name", choices=DATASET_NAMES, help="which dataset")
    make.add_argument("-n", "--samples", type=int, default=4000, help="observations [4000]")
    make.add_argument("--seed", type=int, default=0, help="random seed [0]")
    make.add_argument("-o", "--out", type=Path, required=True, help="output file (.npz)")
    make.add_argument("--repairable", action="store_true",
                      help="also draw intents the planner makes feasible (not in the paper)")
    info = sub.add_parser("info", help="summarise a dataset file")
    info.add_argument("file", type=Path, help="a file written by `cbgo data intent make`")


def run(args: argparse.Namespace) -> int:
    """Makes or describes a dataset; returns the exit code."""
    datasets = importlib.import_module("cbgo.services.intent.datasets")  # numpy, the world
    if args.intent_command == "make":
        if args.samples < 1:
            fail("-n must be at least 1", 2)
        ds = datasets.make(args.name, args.samples, args.seed, progress=True,
                           repairable=args.repairable)
        path = ds.save(args.out)
        extra = f", {int(ds.repaired.sum())} needing repairs" if args.repairable else ""
        print(f"wrote {path}: {args.name}, {len(ds)} observations, seed {args.seed}{extra}")
        return 0
    try:
        ds = datasets.Dataset.load(args.file)
    except ConfigError as e:
        fail(str(e), 2)
    meta = ds.meta
    counts = Counter(meta["actions"][a] for a in ds.action)
    print(f"{args.file}: {meta.get('dataset')} ({meta.get('n')} observations, seed "
          f"{meta.get('seed')}, objects shuffled: {meta.get('shuffled_objects')}, repairable "
          f"intents: {meta.get('repairable', False)})")
    if "repaired" in ds.arrays:
        print(f"intents needing the planner's repairs: {int(ds.repaired.sum())}")
    print("actions: " + ", ".join(f"{a} {counts[a]}" for a in meta["actions"]))
    print("arrays: " + ", ".join(f"{k} {v.dtype}{list(v.shape)}" for k, v in ds.arrays.items()))
    return 0
