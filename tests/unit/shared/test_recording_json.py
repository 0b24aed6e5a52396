"""Unit tests of JSON recordings: Recorder(encoding="json"), read-back, export of bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import jsonschema
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from cbgo import json_schema, wire
from cbgo.errors import RecordingError
from cbgo.examples import example
from cbgo.recording import Recorder, read_recording, recording_info

CLI = [sys.executable, "-m", "cbgo.cli.main"]
T0 = 1_763_765_460_000_000_000
SUFFIXES = ["hands/frame", "gaze", "scene/state", "intent", "episode/event", "robot/state"]


def session(n: int = 3) -> list[tuple[str, bytes, int]]:
    out = []
    for i in range(n * len(SUFFIXES)):
        suffix = SUFFIXES[i % len(SUFFIXES)]
        ns = T0 + i * 10_000_000
        out.append((f"cbgo/{suffix}", wire.encode(example(suffix, ts=ns / 1e9)), ns))
    return out


def test_a_json_recording_has_only_json_channels_whose_messages_fit_their_schemas(tmp_path):
    path = tmp_path / "j.mcap"
    with Recorder(path, encoding="json") as rec:
        for key, payload, ns in session():
            rec.write(key, payload, ns)
    with open(path, "rb") as f:
        seen = set()
        for schema, channel, message in make_reader(f).iter_messages():
            assert (channel.message_encoding, schema.encoding) == ("json", "jsonschema")
            jsonschema.validate(json.loads(message.data), json.loads(schema.data))
            seen.add(schema.name)
    assert {"cbgo.hands.frame", "foxglove.SceneUpdate", "foxglove.FrameTransforms",
            "foxglove.Log"} <= seen
    info = recording_info(path)
    assert info.metadata["cbgo"]["encoding"] == "json"
    assert set(info.derived) == {"foxglove/scene", "foxglove/transforms", "foxglove/log"}
    assert info.message_count == len(session()) == rec.message_count


def test_reading_a_json_recording_gives_back_the_recorded_payloads_and_times(tmp_path):
    path = tmp_path / "j.mcap"
    sent = session()
    with Recorder(path, encoding="json") as rec:
        for key, payload, ns in sent:
            rec.write(key, payload, ns)
    back = list(read_recording(path))
    assert [(m.key, m.payload, m.log_time_ns) for m in back] == sent
    assert [m.key for m in read_recording(path, "cbgo/gaze")] == ["cbgo/gaze"] * 3


def test_a_message_that_breaks_the_contract_is_left_out_and_counted(tmp_path):
    path = tmp_path / "j.mcap"
    bad_gaze = wire.encode({**example("gaze", ts=1.0), "point": [0.1, 0.2]})
    with Recorder(path, encoding="json") as rec:
        assert rec.write("cbgo/gaze", bad_gaze, T0)
        assert rec.write("cbgo/gaze", b"\xc1", T0 + 1)
        rec.write("cbgo/user", wire.encode(example("user", ts=1.0)), T0 + 2)
    count, reason = rec.rejected["cbgo/gaze"]
    assert count == 2 and "not a msgpack payload" in reason
    assert [m.key for m in read_recording(path)] == ["cbgo/user"]


def test_an_unknown_encoding_is_refused_with_the_choices(tmp_path):
    with pytest.raises(RecordingError, match="use one of msgpack, json"):
        Recorder(tmp_path / "x.mcap", encoding="cbor")


def test_an_unreadable_json_message_is_skipped_and_the_rest_read(tmp_path, caplog):
    path = tmp_path / "foreign.mcap"
    schema = json.dumps(json_schema.for_key("user")).encode()
    good = json.dumps(example("user", ts=1.0)).encode()
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        sid = writer.register_schema("cbgo.user", "jsonschema", schema)
        cid = writer.register_channel("cbgo/user", "json", sid)
        for i, data in enumerate([good, b"{not json", good]):
            writer.add_message(cid, log_time=T0 + i, data=data, publish_time=T0 + i)
        writer.finish()
    back = list(read_recording(path))
    assert [wire.decode(m.payload) for m in back] == [example("user", ts=1.0)] * 2
    assert "skipped 1 unreadable JSON message on cbgo/user" in caplog.text


def test_export_refuses_a_truncated_file_and_an_existing_output(tmp_path):
    source = tmp_path / "s.mcap"
    with Recorder(source) as rec:
        for key, payload, ns in session(1):
            rec.write(key, payload, ns)
    out = tmp_path / "o.mcap"
    out.write_bytes(b"keep")
    done = subprocess.run([*CLI, "export", str(source), "-o", str(out)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 2 and "use --force" in done.stderr
    assert out.read_bytes() == b"keep"
    truncated = tmp_path / "t.mcap"
    truncated.write_bytes(source.read_bytes()[:-200])
    done = subprocess.run([*CLI, "export", str(truncated), "-o", str(tmp_path / "t2.mcap")],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "not a complete MCAP file" in done.stderr
    done = subprocess.run([*CLI, "export", str(source), "-o", str(out), "--force"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert len(list(read_recording(out))) == len(SUFFIXES)


def test_export_of_a_file_damaged_mid_way_keeps_what_came_before_and_exits_1(tmp_path):
    source = tmp_path / "s.mcap"
    sent = session(40)
    with Recorder(source, chunk_bytes=2048, compression="none") as rec:
        for key, payload, ns in sent:
            rec.write(key, payload, ns)
    data = bytearray(source.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = bytes(64)  # zeroes over a chunk's records: its CRC fails
    source.write_bytes(bytes(data))
    out = tmp_path / "o.mcap"
    done = subprocess.run([*CLI, "export", str(source), "-o", str(out)], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 1, done.stderr
    assert "corrupt" in done.stderr and "the messages before it are exported" in done.stderr
    kept = list(read_recording(out))  # a complete file
    assert 0 < len(kept) < len(sent)
    assert [(m.key, m.payload) for m in kept] == [(k, p) for k, p, _ in sent[:len(kept)]]
