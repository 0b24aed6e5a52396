"""What every `cbgo` verb shares: Zenoh flags, opening a session, reading keys and payloads.

CLI sessions are clients of the router like the services, but they give up after
``--connect-timeout`` seconds with a clear message instead of waiting forever. The session and
the flags are `cbgo.client`'s; this module turns its errors into a message and an exit code.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from cbgo.client import ConnectError, add_network_arguments, connect
from cbgo.errors import ConfigError
from cbgo.keys import Keys

__all__ = ["add_network_arguments", "fail", "offline_registry", "read_json_argument", "run_module",
           "session"]

OFFLINE_TOOLS = ("the offline tools (benchmarks, trainers, data-set converters) are not installed: "
                 "they live in a cbgo checkout's tools/ folder, outside the cbgo wheel; from the "
                 "checkout, `pip install -e tools/` (`make install` does)")


def fail(message: str, code: int = 1) -> None:
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
    """Returns the JSON value of an argument: inline JSON, ``@file.json``, or ``-`` (stdin)."""
    if text == "-":
        text = sys.stdin.read()
    elif text.startswith("@"):
        try:
            text = Path(text[1:]).read_text()
        except OSError as e:
            fail(f"cannot read {text[1:]}: {e}", 2)
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        fail(f"not valid JSON ({e}): {text[:80]!r}", 2)
