"""``cbgo data``: list, fetch and convert the real data sets; make the paper's intent sets.

Examples::

    cbgo data list                           # every set: what, where cached, present or not
    cbgo data fetch shrec17                  # git sparse checkout of its folder into the cache
    cbgo data convert mmhgr                  # the fetched copy -> the file the trainer reads
    cbgo data convert leapmotion-all --help  # a converter's own options
    cbgo data intent make D4 -n 4000 -o d4.npz   # the paper's synthetic intent data sets
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from cbgo.cli.common import fail, run_module
from cbgo.config import cache_dir
from cbgo_tools.data import DATASETS, DataSet, intent_sets


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the sub-commands list, fetch, convert and intent."""
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    sub.add_parser("list", help="every data set, where it is cached and whether it is there")
    fetch = sub.add_parser("fetch", help="copy a set's folder from its repository (git)")
    fetch.add_argument("name", choices=sorted(DATASETS), metavar="NAME")
    fetch.add_argument("--from", dest="source", default=None, metavar="URL",
                       help="clone this repository URL instead of GitHub's (a mirror, a path)")
    fetch.add_argument("--force", action="store_true", help="replace a copy already there")
    convert = sub.add_parser("convert", help="convert a fetched set (its own options follow)")
    convert.add_argument("name", choices=sorted(n for n, d in DATASETS.items() if d.converter),
                         metavar="NAME")
    convert.add_argument("args", nargs=argparse.REMAINDER, help="the converter's own options")
    intent = sub.add_parser("intent", help="the paper's synthetic intent data sets D1-D5",
                            description=intent_sets.__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    intent_sets.add_arguments(intent)


def run(args: argparse.Namespace) -> int:
    """Runs the chosen sub-command; returns the exit code."""
    if args.command == "list":
        return list_sets()
    if args.command == "fetch":
        return fetch(DATASETS[args.name], args.source, args.force)
    if args.command == "convert":
        module = DATASETS[args.name].converter
        return run_module(module, f"cbgo data convert {args.name}", args.args)
    return intent_sets.run(args)


def list_sets() -> int:
    """Prints every data set: name, what, its use, and its cache folder (present or not)."""
    print(f"cache: {cache_dir()} (CBGO_CACHE_DIR, else $XDG_CACHE_HOME/cbgo)")
    for d in DATASETS.values():
        there = "fetched" if d.path.is_dir() else "not fetched"
        print(f"\n{d.name}: {d.summary}\n  from {d.repo}:{d.folder}"
              f"{'@' + d.commit if d.commit else ''}\n  use: {d.use}\n  {there}: {d.path}"
              + (f"\n  convert: cbgo data convert {d.name}" if d.converter else ""))
    return 0


def fetch(data: DataSet, source: str | None = None, force: bool = False) -> int:
    """Copies ``data.folder`` of its repository into the cache with a sparse git checkout.

    Where the checkout fails or leaves files out (a mirror or partial clone that lacks some
    of the folder's file contents), the files are copied one by one instead
    (`copy_readable`): those that can be read are kept, and the ones that cannot are named.
    """
    if shutil.which("git") is None:
        fail("cbgo data fetch needs git", 2)
    if data.path.exists() and not force:
        print(f"{data.name} is already at {data.path} (--force replaces it)")
        return 0
    url = source or f"https://github.com/{data.repo}.git"
    commit = data.commit or "HEAD"
    data.path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=data.path.parent, prefix=f".{data.name}-") as tmp:
        clone = Path(tmp) / "repo"
        steps = [["git", "clone", "--filter=blob:none", "--no-checkout", "--quiet", url,
                  str(clone)],
                 ["git", "-C", str(clone), "sparse-checkout", "set", "--no-cone", data.folder]]
        for step in steps:
            _git(step, f"fetching {data.name} from {url} failed (see git's message above)")
        checkout = ["git", "-C", str(clone), "checkout", "--quiet", commit]
        print("$ " + " ".join(checkout), file=sys.stderr)
        checked_out = subprocess.run(checkout).returncode == 0
        listed = list_files(clone, commit, data.folder)
        if not listed:
            fail(f"{url} has no folder {data.folder}", 1)
        folder = clone / data.folder
        if not checked_out or not all((clone / path).is_file() for path in listed):
            print(f"the checkout left files of {data.folder} out; copying them one by one",
                  file=sys.stderr)
            folder = Path(tmp) / "files"
            copied, unreadable = copy_readable(clone, commit, data.folder, listed, folder)
            if not copied:
                fail(f"{url}: none of the files of {data.folder} could be read "
                     f"({len(unreadable)} listed); fetch from GitHub (no --from) or a complete "
                     "clone", 1)
            if unreadable:
                print(f"{data.name}: kept {copied} files; {len(unreadable)} could not be read "
                      "from this source (their contents are missing there): "
                      + ", ".join(unreadable), file=sys.stderr)
        if data.path.exists():
            shutil.rmtree(data.path)
        folder.rename(data.path)
    print(f"fetched {data.name} into {data.path}")
    return 0


def _git(step: list[str], error: str) -> None:
    print("$ " + " ".join(step), file=sys.stderr)
    if subprocess.run(step).returncode != 0:
        fail(error, 1)


def list_files(clone: Path, commit: str, folder: str) -> list[str]:
    """Returns the repository paths of every file under ``folder`` at ``commit``."""
    listing = subprocess.run(["git", "-C", str(clone), "ls-tree", "-r", "-z", "--name-only",
                              commit, "--", folder], capture_output=True)
    if listing.returncode != 0:
        fail(f"git cannot list {folder} at {commit}: "
             f"{listing.stderr.decode(errors='replace').strip()}", 1)
    return list(filter(None, listing.stdout.decode().split("\0")))


def copy_readable(clone: Path, commit: str, folder: str, paths: list[str], dest: Path
                  ) -> tuple[int, list[str]]:
    """Copies each of ``paths`` (under ``folder``) at ``commit`` that git can read to ``dest``.

    Returns:
        (files copied, the paths whose contents could not be read).
    """
    copied, unreadable = 0, []
    for path in paths:
        blob = subprocess.run(["git", "-C", str(clone), "cat-file", "blob", f"{commit}:{path}"],
                              capture_output=True)
        if blob.returncode != 0:
            unreadable.append(path)
            continue
        target = dest / Path(path).relative_to(folder)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(blob.stdout)
        copied += 1
    return copied, unreadable
