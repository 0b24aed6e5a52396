"""docs/protocol.md: its example payloads are valid, complete and generated from cbgo.examples;
docs/schemas: the JSON Schemas generated from cbgo.wire, which the examples fit too.

An example is a ```json block preceded by a marker line ``<!-- example: <suffix> <role> -->``
(role: message, query or reply). Bytes cannot be JSON, so the doc writes them as
``"<bytes: N>"``; they are turned back into N bytes before validating.
"""

import base64
import json
import re
from pathlib import Path

import jsonschema
import pytest

from cbgo import json_schema, wire
from cbgo.examples import EXAMPLE_KEYS
from cbgo_tools.docs import protocol_examples

ROOT = Path(__file__).resolve().parents[3]
DOC = ROOT / "docs" / "protocol.md"
STATUS = "@ctl/status"  # the status reply of every service, not a contract key
MARKER = re.compile(r"^<!-- example: (\S+) (\S+) -->$")
BYTES = re.compile(r"^<bytes: (\d+)>$")


def doc_examples() -> list[tuple[str, str, str]]:
    """Returns (suffix, role, json text) of every marked example, in document order."""
    lines = DOC.read_text().splitlines()
    found = []
    for i, line in enumerate(lines):
        m = MARKER.match(line)
        if not m:
            continue
        assert lines[i + 1] == "```json", f"line {i + 2}: the marker must be followed by ```json"
        end = lines.index("```", i + 2)
        found.append((m.group(1), m.group(2), "\n".join(lines[i + 2:end])))
    return found


def placeholders_as(value, make):
    """Returns value with every "<bytes: N>" placeholder replaced by make(N zero bytes)."""
    if isinstance(value, dict):
        return {k: placeholders_as(v, make) for k, v in value.items()}
    if isinstance(value, list):
        return [placeholders_as(v, make) for v in value]
    if isinstance(value, str) and (m := BYTES.match(value)):
        return make(bytes(int(m.group(1))))
    return value


def with_bytes(value):
    """Returns value with its bytes placeholders as bytes (what msgpack carries)."""
    return placeholders_as(value, bytes)


def with_base64(value):
    """Returns value with its bytes placeholders as JSON carries bytes: base64 text."""
    return placeholders_as(value, lambda raw: base64.b64encode(raw).decode())


def schema_of(suffix: str, role: str) -> wire.Spec | None:
    return wire.SERVICE_STATUS if (suffix, role) == (STATUS, "reply") else wire.schema_for(
        suffix, role)


EXAMPLES = doc_examples()


@pytest.mark.parametrize(("suffix", "role", "text"), EXAMPLES,
                         ids=[f"{s} {r}" for s, r, _ in EXAMPLES])
def test_every_example_in_the_protocol_doc_is_valid(suffix, role, text):
    message = with_bytes(json.loads(text))
    assert wire.validate(message, schema_of(suffix, role), suffix) is message
    # It must also survive the wire: msgpack encoding, the size limit, decoding, validation.
    payload = wire.encode(message)
    wire.decode_checked(payload, schema_of(suffix, role), suffix, wire.max_bytes_for(suffix))


def test_every_key_and_role_has_an_example_in_the_protocol_doc():
    documented = [(s, r) for s, r, _ in EXAMPLES]
    missing = [k for k in EXAMPLE_KEYS if k not in documented]
    assert not missing, f"docs/protocol.md has no example for {missing}"
    assert (STATUS, "reply") in documented
    assert len(documented) == len(set(documented)), "an example is in the doc twice"


def test_every_key_of_the_contract_has_a_section_in_the_protocol_doc():
    text = DOC.read_text()
    suffixes = set(wire.SCHEMAS) | set(wire.QUERY_SCHEMAS)
    missing = sorted(s for s in suffixes if f"### `cbgo/{s}`" not in text)
    assert not missing, f"docs/protocol.md has no section for {missing}"


def test_a_wrong_example_in_the_protocol_doc_would_be_caught():
    suffix, role, text = next(e for e in EXAMPLES if e[0] == "gestures/static")
    message = with_bytes(json.loads(text))
    message["probs"][1] += 0.5
    with pytest.raises(wire.RejectedMessage, match="summing to 1"):
        wire.validate(message, schema_of(suffix, role), suffix)


def test_the_examples_in_the_protocol_doc_are_the_ones_cbgo_examples_generates():
    text = DOC.read_text()
    assert protocol_examples.update(text) == text, "docs/protocol.md is stale; run: make docs"


# --------------------------------------------------------------------- JSON Schemas (docs/schemas)

SCHEMA_DIR = ROOT / "docs" / "schemas"


@pytest.mark.parametrize(("suffix", "role", "text"), EXAMPLES,
                         ids=[f"{s} {r}" for s, r, _ in EXAMPLES])
def test_every_example_in_the_protocol_doc_fits_its_json_schema(suffix, role, text):
    schema = json_schema.for_key(suffix, role)
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(with_base64(json.loads(text)), schema,
                        cls=jsonschema.Draft202012Validator)


def test_the_json_schemas_in_docs_are_the_ones_generated_from_the_wire():
    generated = {json_schema.file_name(s, r): schema
                 for (s, r), schema in json_schema.every_schema().items()}
    on_disk = {p.name: json.loads(p.read_text()) for p in SCHEMA_DIR.glob("*.json")}
    assert on_disk == generated, "docs/schemas is stale; run: make docs"


@pytest.mark.parametrize(("change", "why"), [
    (lambda m: m.pop("probs"), "a required field is missing"),
    (lambda m: m.update(side="middle"), "not one of the choices"),
    (lambda m: m.update(seq=-1), "below the minimum"),
    (lambda m: m.update(window=[1.0]), "a list too short"),
    (lambda m: m.update(names="swipe_up"), "not a list"),
])
def test_a_json_schema_rejects_what_the_wire_rejects(change, why):
    (text,) = [t for s, r, t in EXAMPLES if (s, r) == ("gestures/dynamic", "message")]
    message = json.loads(text)
    change(message)
    with pytest.raises(wire.RejectedMessage):
        wire.validate(message, wire.schema_for("gestures/dynamic"), "gestures/dynamic")
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(message, json_schema.for_key("gestures/dynamic"),
                            cls=jsonschema.Draft202012Validator)
