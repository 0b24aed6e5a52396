"""JSON channels of cbgo data for Foxglove: which schema each channel has, and the encoding.

A wire key's channel keeps the key as its topic (``cbgo/hands/frame``), message encoding
``json`` and schema encoding ``jsonschema``; its schema is the key's schema from
`cbgo.json_schema`, named after the key (``cbgo.hands.frame``). A data key outside the contract
gets a schema that accepts any JSON object. The derived channels (`cbgo.foxglove.derive`) use
Foxglove's own schemas, vendored in ``schemas/`` and named ``foxglove.*``: readers tell a
derived channel from a wire channel by that name.

`JsonChannels` writes both kinds into an `mcap.writer.Writer`; `wire_payload` turns a JSON
message of a wire channel back into the msgpack payload it came from.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

from cbgo import json_schema, wire
from cbgo.errors import RejectedMessage
from cbgo.foxglove.derive import DERIVED_TOPICS, Derived, Deriver
from cbgo.keys import Keys

MESSAGE_ENCODING = "json"
SCHEMA_ENCODING = "jsonschema"
DERIVED_PREFIX = "foxglove."
SCHEMA_FOLDER = Path(__file__).parent / "schemas"


@functools.cache
def foxglove_schema(name: str) -> dict:
    """Returns Foxglove's JSON Schema of ``foxglove.<Name>`` (vendored, MIT).

    Raises:
        KeyError: cbgo ships no such schema.
    """
    path = SCHEMA_FOLDER / f"{name.removeprefix(DERIVED_PREFIX)}.json"
    if not name.startswith(DERIVED_PREFIX) or not path.is_file():
        raise KeyError(f"no vendored Foxglove schema {name!r}")
    return json.loads(path.read_text())


def wire_schema(keys: Keys, key: str) -> tuple[str, dict]:
    """Returns (schema name, JSON Schema) of the channel of a concrete data key."""
    topic = keys.topic_of(key)
    if topic is None or topic.query:
        return key.replace("/", "."), {"$schema": json_schema.DIALECT, "title": key,
                                       "type": "object"}
    return f"cbgo.{topic.suffix.replace('/', '.')}", json_schema.for_key(topic.suffix)


def is_derived(schema_name: str | None) -> bool:
    """Returns whether a channel of that schema is derived (not a wire key's)."""
    return bool(schema_name) and schema_name.startswith(DERIVED_PREFIX)


def encode(message: dict) -> bytes:
    """Returns the compact JSON bytes of a message (bytes as base64; NaN refused).

    Raises:
        ValueError: a value has no JSON form (NaN, inf).
    """
    return json.dumps(json_schema.to_json(message), separators=(",", ":"),
                      allow_nan=False).encode()


def wire_payload(data: bytes, schema_data: bytes | None) -> bytes:
    """Returns the msgpack payload of a wire channel's JSON message.

    Args:
        data: the JSON message.
        schema_data: the channel's JSON Schema as stored in the file (for the base64 fields).

    Raises:
        ValueError: the message or the schema is not JSON, or a base64 field is not base64.
    """
    schema = json.loads(schema_data) if schema_data else {}
    message = json_schema.from_json(json.loads(data), schema if isinstance(schema, dict) else {})
    return wire.encode(message)


def decode_valid(keys: Keys, key: str, payload: bytes, max_bytes: int) -> tuple[str, dict]:
    """Returns (topic suffix or '', message) of a payload, decoded and checked on its key.

    Raises:
        RejectedMessage: not a msgpack map, or it breaks the key's contract.
    """
    topic = keys.topic_of(key)
    if topic is None:
        return "", wire.decode_checked(payload, None, key, max_bytes)
    return topic.suffix, wire.decode_checked(payload, topic.schema, key,
                                             topic.max_bytes(max_bytes))


class JsonChannels:
    """Writes wire messages and their derived Foxglove messages as JSON channels into MCAP.

    Not thread-safe: the caller (`cbgo.recording.Recorder`) serialises the calls.

    Args:
        writer: a started `mcap.writer.Writer`.
        prefix: the key prefix, to find each key's contract.
        max_bytes: the payload size limit applied when decoding.
    """

    def __init__(self, writer, prefix: str, max_bytes: int = wire.DEFAULT_MAX_BYTES):
        self.writer, self.keys, self.max_bytes = writer, Keys(prefix), max_bytes
        self.deriver = Deriver()
        self._channels: dict[str, int] = {}
        self._sequence: dict[str, int] = {}

    def write(self, key: str, payload: bytes, log_ns: int, publish_ns: int
              ) -> list[tuple[str, int]]:
        """Writes one message and what it implies; returns [(topic, bytes written)].

        Raises:
            RejectedMessage: the payload is not a valid message of its key (nothing written).
        """
        suffix, message = decode_valid(self.keys, key, payload, self.max_bytes)
        try:
            data = encode(message)
        except ValueError as e:
            raise RejectedMessage(f"no JSON form: {e}", key=key) from None
        written = [(key, self._add(key, data, log_ns, publish_ns))]
        for derived in self.deriver.feed(suffix, message):
            written.append(self._add_derived(derived, log_ns))
        return written

    def _add_derived(self, derived: Derived, log_ns: int) -> tuple[str, int]:
        data = encode(derived.message)
        return derived.topic, self._add(derived.topic, data, log_ns,
                                        int(round(derived.ts * 1e9)))

    def _add(self, topic: str, data: bytes, log_ns: int, publish_ns: int) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            channel = self._register(topic)
        sequence = self._sequence[topic]
        self._sequence[topic] = sequence + 1
        self.writer.add_message(channel, log_time=log_ns, data=data, publish_time=publish_ns,
                                sequence=sequence % (1 << 32))
        return len(data)

    def _register(self, topic: str) -> int:
        if topic in DERIVED_TOPICS:
            name = DERIVED_TOPICS[topic]
            schema = foxglove_schema(name)
        else:
            name, schema = wire_schema(self.keys, topic)
        schema_id = self.writer.register_schema(name, SCHEMA_ENCODING,
                                                json.dumps(schema).encode())
        self._channels[topic] = self.writer.register_channel(topic, MESSAGE_ENCODING,
                                                             schema_id)
        self._sequence[topic] = 0
        return self._channels[topic]
