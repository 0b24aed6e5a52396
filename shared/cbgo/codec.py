r"""msgpack <-> JSON text, for people and for the third-party `zenoh` CLI (zenoh-cli).

zenoh-cli loads codecs through the entry points ``zenoh_cli.codecs.decoders`` and
``zenoh_cli.codecs.encoders`` (declared in pyproject.toml under the name ``msgpack``), so::

    zenoh --mode client --connect tcp/127.0.0.1:7447 subscribe -k 'cbgo/**' --decoder msgpack
    zenoh --mode client --connect tcp/127.0.0.1:7447 put -k cbgo/user \\
        --encoder msgpack -v '{"v": 1, "ts": 1763765460.0, "user": "alice"}'

print and send our messages. Bytes (a PNG render) show as ``"<bytes: N>"``; non-finite floats
as the strings ``"NaN"``/``"Infinity"`` so the output stays valid JSON.
"""

from __future__ import annotations

import json
import math
from typing import Any

import msgpack


def jsonable(value: Any) -> Any:
    """Returns a JSON-safe copy of a decoded msgpack value."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bytes, bytearray)):
        return f"<bytes: {len(value)}>"
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else ("Infinity" if value > 0 else "-Infinity")
    return value


def unpack_any(payload: bytes) -> Any:
    """Returns the decoded msgpack value of a payload, whatever its top-level type.

    Raises:
        ValueError: the payload is not exactly one msgpack value.
    """
    try:
        return msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except (msgpack.ExtraData, msgpack.UnpackException, ValueError) as e:
        raise ValueError(f"not a msgpack payload: {e}") from None


def decode_to_json(key: str, value: bytes) -> str:
    """zenoh-cli decoder: msgpack payload -> one line of JSON."""
    return json.dumps(jsonable(unpack_any(value)), separators=(",", ":"))


def encode_from_json(key: str, value: str) -> bytes:
    """zenoh-cli encoder: JSON text -> msgpack payload."""
    return msgpack.packb(json.loads(value), use_bin_type=True)


def pretty(value: Any, indent: int = 0) -> str:
    """Returns a readable multi-line rendering: maps one field a line, short lists inline."""
    pad = "  " * indent
    if isinstance(value, dict):
        if not value:
            return "{}"
        lines = []
        for k, v in value.items():
            body = pretty(v, indent + 1)
            sep = "\n" if isinstance(v, (dict, list)) and "\n" in body else " "
            lines.append(f"{pad}{k}:{sep}{body}")
        return "\n".join(lines)
    if isinstance(value, list):
        flat = json.dumps(jsonable(value))
        if len(flat) <= 100 and not any(isinstance(v, (dict, list)) for v in value):
            return flat
        return "\n".join(f"{pad}- " + pretty(v, indent + 1).lstrip() for v in value)
    return json.dumps(jsonable(value))
