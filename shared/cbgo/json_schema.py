"""JSON Schemas of the contract's messages, generated from `cbgo.wire` (one source of truth).

Tools that read JSON rather than msgpack (Foxglove's MCAP decoders, a web page, any language's
validator) get the same contract from these: one schema per key and role (message, query,
reply), JSON Schema draft 2020-12. What a schema cannot say is checked by `cbgo.wire` only:
its whole-object rules (probabilities summing to one, names and probs of equal length, ordered
windows) and nodes with checks of their own (the metric parameters, which only carry their
description here); unknown fields are tolerated as on the wire.

JSON has no bytes: a msgpack bin (`wire.Bytes`, e.g. a rendered image) is a base64 string in a
JSON message, as Foxglove's JSON encoding writes it. `to_json` writes a wire message that way and
`from_json` reads it back with the message's schema, which marks those strings
(``contentEncoding: base64``), so a message survives msgpack -> JSON -> msgpack unchanged.

``make docs`` writes them as ``docs/schemas/<key with / as .>.<role>.json``; the
copies in ``docs/schemas/`` are checked against this module by the tests.
"""

from __future__ import annotations

import base64
import binascii
import json
from pathlib import Path
from typing import Any

from cbgo import wire

DIALECT = "https://json-schema.org/draft/2020-12/schema"
ROLES = ("message", "query", "reply")
STATUS_KEY = "@ctl/status"  # every service's status reply (not a contract key of its own)


def of(spec: wire.Spec | None) -> dict[str, Any]:
    """Returns the JSON Schema of one `wire` node (None, a raw payload: no constraint)."""
    if spec is None or isinstance(spec, wire.AnyValue):
        return {}
    if isinstance(spec, wire.Obj):
        return _object(spec)
    if isinstance(spec, wire.Nullable):
        return {"anyOf": [{"type": "null"}, of(spec.inner)]}
    if isinstance(spec, wire.ListOf):
        return _bounded({"type": "array", "items": of(spec.item)}, spec.lo or None, spec.hi,
                        "minItems", "maxItems")
    if isinstance(spec, wire.Vec):
        return {"type": "array", "items": {"type": "number"}, "minItems": spec.n,
                "maxItems": spec.n}
    if isinstance(spec, wire.MapOf):
        return {"type": "object", "propertyNames": {"minLength": 1},
                "additionalProperties": of(spec.value)}
    return _scalar(spec)


def _object(spec: wire.Obj) -> dict[str, Any]:
    properties = {name: of(s) for name, s in {**spec.fields, **spec.optional}.items()}
    return {"type": "object", "properties": properties, "required": list(spec.fields)}


def _scalar(spec: wire.Spec) -> dict[str, Any]:
    if isinstance(spec, wire.Num):
        return _bounded({"type": "number"}, spec.lo, spec.hi, "minimum", "maximum")
    if isinstance(spec, wire.Int):
        return _bounded({"type": "integer"}, spec.lo, spec.hi, "minimum", "maximum")
    if isinstance(spec, wire.Str):
        out: dict[str, Any] = {"type": "string"}
        if spec.choices:
            out["enum"] = list(spec.choices)
        elif spec.nonempty:
            out["minLength"] = 1
        return out
    if isinstance(spec, wire.Bool):
        return {"type": "boolean"}
    if isinstance(spec, wire.Bytes):
        return {"type": "string", "contentEncoding": "base64"}
    # A node with its own check (the metric parameters): described, checked by cbgo.wire.
    return {"description": spec.description}


def _bounded(out: dict, lo, hi, lo_name: str, hi_name: str) -> dict[str, Any]:
    if lo is not None:
        out[lo_name] = lo
    if hi is not None:
        out[hi_name] = hi
    return out


def to_json(value: Any) -> Any:
    """Returns a decoded wire message as JSON-ready data: bytes become base64 strings."""
    if isinstance(value, bytes):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, list):
        return [to_json(v) for v in value]
    return value


def from_json(value: Any, schema: dict[str, Any]) -> Any:
    """Returns JSON data as the wire message it came from: base64 strings back to bytes.

    Args:
        value: the parsed JSON.
        schema: its JSON Schema (a key's schema from `for_key`, or one read from a file); only
            its ``contentEncoding: base64`` nodes matter, the rest is walked through.

    Raises:
        ValueError: a string marked base64 is not base64.
    """
    branches = [b for b in schema.get("anyOf", []) if b.get("type") != "null"]
    if branches:  # the wire's Nullable: null or one kind of value
        schema = branches[0]
    if isinstance(value, str) and schema.get("contentEncoding") == "base64":
        try:
            return base64.b64decode(value, validate=True)
        except binascii.Error as e:
            raise ValueError(f"not base64: {e}") from None
    if isinstance(value, dict):
        properties = schema.get("properties", {})
        extra = schema.get("additionalProperties", {})
        return {k: from_json(v, properties.get(k, extra)) for k, v in value.items()}
    if isinstance(value, list):
        return [from_json(v, schema.get("items", {})) for v in value]
    return value


def for_key(suffix: str, role: str = "message") -> dict[str, Any]:
    """Returns the titled JSON Schema of a key's message, query or reply.

    Raises:
        KeyError: the key has no schema for that role.
    """
    spec = wire.SERVICE_STATUS if (suffix, role) == (STATUS_KEY, "reply") else \
        wire.schema_for(suffix, role)
    return {"$schema": DIALECT, "title": f"cbgo/{suffix} {role}", **of(spec)}


def every_schema() -> dict[tuple[str, str], dict[str, Any]]:
    """Returns every key's schemas by (suffix, role), the status reply included."""
    tables = {"message": wire.SCHEMAS, "query": wire.QUERY_SCHEMAS, "reply": wire.REPLY_SCHEMAS}
    out = {(suffix, role): for_key(suffix, role)
           for role, table in tables.items() for suffix in table}
    out[(STATUS_KEY, "reply")] = for_key(STATUS_KEY, "reply")
    return out


def file_name(suffix: str, role: str) -> str:
    """Returns the file a key's schema is written to, e.g. ``hands.frame.message.json``."""
    return f"{suffix.replace('/', '.').lstrip('@')}.{role}.json"


def write_all(folder: Path) -> list[Path]:
    """Writes every schema into `folder` (created); returns the files."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for (suffix, role), schema in sorted(every_schema().items()):
        path = folder / file_name(suffix, role)
        path.write_text(json.dumps(schema, indent=2) + "\n")
        paths.append(path)
    return paths
