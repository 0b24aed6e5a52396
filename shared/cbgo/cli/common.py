"""What every `cbgo` verb shares: Zenoh flags, opening a session, reading keys and payloads.

CLI sessions are clients of the router like the services, but they give up after
``--connect-timeout`` seconds with a clear message instead of waiting forever. The session and
the flags are `cbgo.client`'s; this module turns its errors into a message and an exit code.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import json
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

from cbgo.client import ConnectError, add_network_arguments, connect
from cbgo.config import resolve_zenoh
from cbgo.errors import ConfigError, zenoh_reason
from cbgo.keys import TOPICS, Keys

__all__ = ["add_network_arguments", "did_you_mean", "fail", "key_expression", "keys_of",
           "listened_key", "offline_registry", "read_json_argument", "run_module", "session",
           "unknown_key_note"]

OFFLINE_TOOLS = ("the offline tools (benchmarks, trainers, data-set converters) are not installed: "
                 "they live in a cbgo checkout's tools/ folder, outside the cbgo wheel; from the "
                 "checkout, `pip install -e tools/` (`make install` does)")


def fail(message: str, code: int = 1) -> NoReturn:
    """Prints an error for the user and exits."""
    print(f"cbgo: {message}", file=sys.stderr)
    sys.exit(code)


def offline_registry() -> Any:
    """Returns `cbgo_tools.registry`, or ends the command saying how to install the tools."""
    try:
        return importlib.import_module("cbgo_tools.registry")
    except ModuleNotFoundError as e:
        if e.name not in ("cbgo_tools", "cbgo_tools.registry"):
            raise
        fail(OFFLINE_TOOLS, 2)


def run_module(module_name: str, prog: str, argv: list[str]) -> int:
    """Runs a module's own command line: its `add_arguments` and `run` (a bench, a trainer).

    A data folder or model that is not there (`ConfigError`, `FileNotFoundError`) ends the
    command with its message (exit code 2), not a traceback.
    """
    module = importlib.import_module(module_name)  # lazily: torch, MuJoCo...
    parser = argparse.ArgumentParser(prog=prog, description=module.__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    module.add_arguments(parser)
    options = parser.parse_args(argv)
    try:
        return module.run(options)
    except (ConfigError, FileNotFoundError) as e:
        fail(str(e), 2)
        return 2


@contextmanager
def session(args: argparse.Namespace, name: str = "cbgo-cli") -> Iterator[tuple[Any, Keys]]:
    """Opens a client session from the verb's flags and environment; yields (session, keys).

    A session that cannot be opened ends the command with the reason (exit code 2 for bad
    configuration, 1 for an unreachable network).
    """
    try:
        sess, keys = connect(args, name)
    except ConnectError as e:
        fail(str(e), e.code)
    with sess:
        yield sess, keys


def read_json_argument(text: str) -> Any:
    """Returns the JSON value of an argument: inline JSON, ``@file.json``, or ``-`` (stdin).

    Unreadable files and malformed JSON end the command (exit code 2) with where the problem
    is and how to write it.
    """
    source = "the argument"
    if text == "-":
        text, source = sys.stdin.read(), "stdin"
    elif text.startswith("@"):
        source = text[1:]
        try:
            text = Path(source).read_text()
        except OSError as e:
            fail(f"cannot read {source}: {e.strerror or e}", 2)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        where = f"line {e.lineno}, column {e.colno}" if "\n" in text.strip() else \
            f"column {e.colno}"
        shown = f": {text.strip()[:80]!r}" if source == "the argument" else ""
        fail(f"{source} is not valid JSON ({e.msg} at {where}){shown}; JSON needs double "
             "quotes, e.g. '{\"user\": \"alice\"}' (and single quotes around it in a shell)",
             2)


def keys_of(args: argparse.Namespace) -> Keys:
    """Returns the keys under the prefix of the flags and environment, without connecting.

    Lets a verb check what the user typed before it waits for the network.
    """
    try:
        return Keys(resolve_zenoh(vars(args)).prefix)
    except ConfigError as e:
        fail(f"configuration error: {e}", 2)


def key_expression(keys: Keys, typed: str) -> str:
    """Returns a typed key as a canonical key expression under the prefix, or ends the command.

    ``hands/frame`` becomes ``cbgo/hands/frame``; ``a//b`` is refused (exit code 2) with
    Zenoh's reason and the form keys have.
    """
    import zenoh

    try:
        return str(zenoh.KeyExpr.autocanonize(keys.resolve(typed)))
    except zenoh.ZError as e:
        fail(f"invalid key {typed!r}: {zenoh_reason(e)}; keys look like hands/frame or "
             "'gestures/*' (`cbgo ls` lists the keys in use)", 2)


def listened_key(args: argparse.Namespace) -> tuple[Keys, str]:
    """Returns (keys, key expression) of the KEY a verb listens on, checked before connecting.

    A concrete key under the prefix that no contract key matches is not an error (anything
    may be published), but a likely typo: a note on stderr says so, with the closest key.
    """
    keys = keys_of(args)
    key = key_expression(keys, args.key)
    note = unknown_key_note(keys, key)
    if note:
        print(f"cbgo: note: {note}", file=sys.stderr)
    return keys, key


def did_you_mean(typed: str, known: Iterable[str]) -> str:
    """Returns `` (did you mean X?)`` for the known name closest to a typo, or ``""``."""
    close = difflib.get_close_matches(typed, list(known), n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def unknown_key_note(keys: Keys, key: str) -> str | None:
    """Returns a note when a concrete key under the prefix is none of the contract's keys.

    Wildcards, control keys and keys outside the prefix are not judged (None).
    """
    head = keys.prefix + "/"
    if not key.startswith(head) or "*" in key or "/@" in key or keys.topic_of(key):
        return None
    suffix = key[len(head):]
    return (f"{key} is not one of the contract's keys{did_you_mean(suffix, TOPICS)}; "
            "`cbgo ls` lists the keys in use")
