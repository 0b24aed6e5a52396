"""The key and settings tables of every service's README, generated from its manifest.

Each ``services/<svc>/README.md`` holds two generated blocks, between markers:

- ``keys``: every key the service reads, writes, answers and asks, with its delivery policy
  (`cbgo.keys`) and a link to its message in ``docs/protocol.md`` (from `cbgo.manifest`);
- ``settings``: every setting with its flag, environment variable, type, default and meaning,
  the same texts as ``--help`` (`cbgo.config.settings_rows`).

The prose around them (what each key is for, when it is sent) stays hand-written; a test
checks that the blocks are in step and that the prose tables name the same keys.

``make docs`` rewrites the blocks of every service README (`cbgo_tools.docs`).
"""

from __future__ import annotations

import re
from pathlib import Path

from cbgo import registry
from cbgo.config import settings_rows
from cbgo.keys import Topic
from cbgo.manifest import Manifest

REPO = Path(__file__).resolve().parents[3]
PROTOCOL = REPO / "docs" / "protocol.md"
BLOCKS = ("keys", "settings")
GENERATED = "generated from the manifest by `make docs`; edit the manifest"


def readme_of(manifest: Manifest) -> Path:
    """Returns the path of a service's README in this checkout."""
    return REPO / "services" / manifest.name.replace("-", "_") / "README.md"


def begin(block: str) -> str:
    """Returns the opening marker of a generated block."""
    return f"<!-- begin {block}: {GENERATED} -->"


def end(block: str) -> str:
    """Returns the closing marker of a generated block."""
    return f"<!-- end {block} -->"


def _anchors() -> dict[str, str]:
    """Returns topic suffix -> the anchor of its section in docs/protocol.md."""
    out = {}
    for line in PROTOCOL.read_text().splitlines():
        found = re.match(r"^### `cbgo/([^`]+)`(.*)$", line)
        if found:
            title = f"cbgo/{found.group(1)}{found.group(2)}".lower()
            out[found.group(1)] = re.sub(r"[^a-z0-9 -]", "", title).replace(" ", "-")
    return out


def _delivery(topic: Topic) -> str:
    if topic.query:
        return "query"
    text = "BLOCK" if topic.reliable else "DROP"
    return text + (", express" if topic.express else "")


def keys_table(manifest: Manifest) -> str:
    """Returns the markdown table of the keys a service reads, writes, answers and asks."""
    anchors = _anchors()
    lines = ["| key | the service | delivery | message |", "|---|---|---|---|"]
    for role, topics in (("subscribes", manifest.subscribes), ("publishes", manifest.publishes),
                         ("answers", manifest.answers), ("asks", manifest.asks)):
        for topic in topics:
            anchor = anchors.get(topic.suffix)
            message = f"[protocol](../../docs/protocol.md#{anchor})" if anchor else "—"
            lines.append(f"| `cbgo/{topic.suffix}` | {role} | {_delivery(topic)} | "
                         f"{message} |")
    for verb in ("status", *manifest.controls):
        lines.append(f"| `cbgo/@ctl/{manifest.name}/{verb}` | answers | query | "
                     + ("[status reply](../../docs/protocol.md#status-reply)" if verb == "status"
                        else "below") + " |")
    return "\n".join(lines)


def _cell(value) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        return ", ".join(str(v) for v in value) or "none"
    return f"`{value}`"


def settings_table(manifest: Manifest) -> str:
    """Returns the markdown table of a service's settings (as its ``--help`` gives them)."""
    lines = ["| flag | environment | type | default | meaning |", "|---|---|---|---|---|"]
    for row in settings_rows(manifest.settings_class()):
        meaning = row.meaning.replace("|", "\\|")
        lines.append(f"| `{row.flag}` | `{row.env}` | {row.type} | {_cell(row.default)} | "
                     f"{meaning} |")
    return "\n".join(lines)


def rendered(manifest: Manifest, block: str) -> str:
    """Returns one generated block, markers included."""
    table = keys_table(manifest) if block == "keys" else settings_table(manifest)
    return f"{begin(block)}\n{table}\n{end(block)}"


def updated(text: str, manifest: Manifest) -> str:
    """Returns a README's text with its generated blocks rewritten.

    Raises:
        ValueError: a block's markers are missing (add them where the table belongs).
    """
    for block in BLOCKS:
        pattern = re.compile(re.escape(begin(block)) + r".*?" + re.escape(end(block)), re.S)
        if not pattern.search(text):
            raise ValueError(f"{readme_of(manifest)} has no generated {block} block: add the "
                             f"lines\n{begin(block)}\n{end(block)}\nwhere the table belongs")
        text = pattern.sub(lambda _m, b=block: rendered(manifest, b), text, count=1)
    return text


def stale_readmes(write: bool) -> list[Path]:
    """Returns the service READMEs whose generated blocks are out of step (rewritten if write)."""
    stale = []
    for manifest in registry.SERVICES:
        path = readme_of(manifest)
        text = path.read_text()
        new = updated(text, manifest)
        if new != text:
            stale.append(path)
            if write:
                path.write_text(new)
    return stale
