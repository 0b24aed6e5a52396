"""Fills the example payloads of docs/protocol.md from `cbgo.examples`, so they are exactly valid.

Every example in the doc is a ```json block preceded by a marker line
``<!-- example: <suffix> <role> -->`` (role: message, query or reply); this script rewrites the
body of each such block with `cbgo.examples.example(suffix, role)` at a fixed time stamp,
rendered as JSON (bytes as ``"<bytes: N>"``, as `cbgo.codec` shows them). The one marker that
is not a contract key, ``@ctl/status reply``, gets a service status built by the real
`cbgo.runtime.Context.status()` with the machine-specific fields pinned.

``make docs`` runs it (`cbgo_tools.docs`) after a change of `cbgo.examples` or of the
runtime's status reply.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from cbgo import keys, wire
from cbgo.codec import jsonable
from cbgo.config import NoSettings, resolve
from cbgo.errors import RejectedMessage
from cbgo.examples import example
from cbgo.runtime import Context, Service

DOC = Path(__file__).resolve().parents[3] / "docs" / "protocol.md"
TS = 1763765460.0  # a fixed time stamp (2025-11-21T22:51:00Z), so the doc does not churn
WIDTH = 128  # containers that fit in this many columns stay on one line
STATUS = "@ctl/status"
BLOCK = re.compile(r"(<!-- example: (\S+) (message|query|reply) -->\n(?:(?!<!-- example:).*\n)*?"
                   r"```json\n)(.*?)(^```)", re.MULTILINE | re.DOTALL)


def render(value: Any, indent: int = 0, lead: int = 0) -> str:
    """Returns JSON text: one field a line, but any container that fits in WIDTH on one line.

    Args:
        value: a JSON-safe value.
        indent: the nesting depth (two spaces each).
        lead: columns already taken on the first line (the key in front of the value).
    """
    flat = json.dumps(value)
    if not isinstance(value, (dict, list)) or not value or 2 * indent + lead + len(flat) <= WIDTH:
        return flat
    pad = "  " * (indent + 1)
    if isinstance(value, dict):
        items = [f"{pad}{json.dumps(k)}: " + render(v, indent + 1, len(json.dumps(k)) + 2)
                 for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + "  " * indent + "}"
    items = [pad + render(v, indent + 1) for v in value]
    return "[\n" + ",\n".join(items) + "\n" + "  " * indent + "]"


class _Episode(Service):
    """A stand-in with the episode service's name, for the status example."""

    name = "episode"


def status_example() -> dict:
    """Returns what ``@ctl/episode/status`` answers, from the real runtime, with fixed values."""
    config = resolve(NoSettings, [], prog="cbgo-episode", env={}).as_dict()
    ctx = Context(_Episode(NoSettings()), keys.Keys(), transport=None, config=config)
    ctx.inputs = [ctx.keys.of(t) for t in (keys.HANDS_FRAME, keys.GESTURES_STATIC,
                                          keys.GESTURES_DYNAMIC, keys.GAZE, keys.USER)]
    ctx.outputs = [ctx.keys.of(t) for t in (keys.EPISODE_EVENT, keys.EPISODE_SUMMARY)]
    ctx.queryables = [ctx.keys.ctl("episode", "status")]
    bad_frame = example("hands/frame", ts=TS)
    bad_frame["hands"][0]["confidence"] = 1.2
    try:
        wire.validate(bad_frame, wire.schema_for("hands/frame"),
                      ctx.keys.of(keys.HANDS_FRAME))
    except RejectedMessage as e:
        rejection = str(e)
    else:  # pragma: no cover - the example above must be rejected
        raise AssertionError("a confidence of 1.2 was accepted")
    for name, n in (("received", 18250), ("published", 37), ("rejected", 1)):
        ctx.counters.add(name, n)
    ctx.counters.last_error = {"ts": TS - 12.5, "where": "input", "message": rejection}
    status = ctx.status()
    status.update(ts=TS, version="0.1.0", pid=4242, host="cell-1",
                  zid="5c1e0b6e4a3f2d1c9b8a7f6e5d4c3b2a", started=TS - 300.0, uptime_s=300.0)
    return status


def example_for(suffix: str, role: str) -> Any:
    """Returns the JSON-safe example of one marker."""
    value = status_example() if suffix == STATUS else example(suffix, role, ts=TS)
    return jsonable(value)


def update(text: str) -> str:
    """Returns the doc text with every marked example block regenerated."""
    return BLOCK.sub(lambda m: m.group(1) + render(example_for(m.group(2), m.group(3))) + "\n"
                     + m.group(5), text)


def stale_protocol(write: bool) -> list[Path]:
    """Returns [docs/protocol.md] if its examples are out of step (rewritten if write), else []."""
    text = DOC.read_text()
    new = update(text)
    if new == text:
        return []
    if write:
        DOC.write_text(new)
    return [DOC]
