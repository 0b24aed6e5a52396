"""Unit tests of cbgo.recording: MCAP record/read-back and the gesture toolbox JSON reader."""

from __future__ import annotations

import copy
import json
import re
import threading
from pathlib import Path

import msgpack
import numpy as np
import pytest
from mcap.reader import make_reader

from cbgo import wire
from cbgo.errors import CbgoError, RecordingError
from cbgo.examples import example
from cbgo.recording import (
    MESSAGE_ENCODING,
    PROFILE,
    Recorder,
    load_toolbox_json,
    read_recording,
    recording_info,
)

ARTIFACTS = Path(__file__).parents[2] / "artifacts"
TOOLBOX = ARTIFACTS / "toolbox" / "two_hands.json"
T0 = 1_763_765_460_000_000_000  # a receive time, ns since the Unix epoch
KEYS = ["cbgo/hands/frame", "cbgo/gaze", "cbgo/user", "cbgo/episode/event"]


def messages(n: int = 60) -> list[tuple[str, bytes, int]]:
    """(key, payload, receive time) for n messages on the four KEYS, 1-19 ms apart."""
    out, t = [], T0
    for i in range(n):
        key = KEYS[i % 4] if i % 7 else KEYS[0]
        suffix = key.removeprefix("cbgo/")
        message = {**example(suffix, ts=1_763_765_400.0 + i * 0.01), "n": i}
        out.append((key, wire.encode(message), t))
        t += 1_000_000 * (1 + (i * 7) % 19)
    return out


@pytest.fixture
def recorded(tmp_path) -> tuple[Path, list[tuple[str, bytes, int]]]:
    sent = messages()
    path = tmp_path / "rec.mcap"
    with Recorder(path, prefix="cbgo", keys=["cbgo/**"], chunk_bytes=2048) as rec:
        for key, payload, t in sent:
            rec.write(key, payload, t)
    return path, sent


# --------------------------------------------------------------------------- record and read


def test_a_recording_reads_back_the_same_keys_payloads_and_order(recorded):
    path, sent = recorded
    back = list(read_recording(path))
    assert [(m.key, m.payload, m.log_time_ns) for m in back] == sent
    assert [m.message["n"] for m in back] == list(range(len(sent)))


def test_publish_time_is_the_message_ts_and_log_time_the_receive_time(recorded):
    path, sent = recorded
    for m, (_key, payload, t) in zip(read_recording(path), sent, strict=True):
        assert m.log_time_ns == t
        ts = msgpack.unpackb(payload)["ts"]
        assert abs(m.publish_time_ns - ts * 1e9) < 1e3


def test_publish_time_falls_back_to_the_receive_time_without_a_usable_ts(tmp_path):
    path = tmp_path / "rec.mcap"
    with Recorder(path) as rec:
        rec.write("cbgo/robot/stop", b"", T0)
        rec.write("cbgo/robot/stop", b"\xc1not msgpack", T0 + 1)
        rec.write("cbgo/robot/stop", msgpack.packb({"ts": float("nan")}), T0 + 2)
        rec.write("cbgo/robot/stop", msgpack.packb({"ts": -5.0}), T0 + 3)
        rec.write("cbgo/robot/stop", msgpack.packb([1, 2]), T0 + 4)
    assert [m.publish_time_ns for m in read_recording(path)] == [T0 + i for i in range(5)]


def test_sequence_counts_the_messages_of_each_key(recorded):
    path, sent = recorded
    seen: dict[str, int] = {}
    for m in read_recording(path):
        assert m.sequence == seen.get(m.key, 0)
        seen[m.key] = m.sequence + 1


def test_messages_come_back_in_log_time_order_even_if_written_out_of_order(tmp_path):
    path = tmp_path / "rec.mcap"
    with Recorder(path, chunk_bytes=64) as rec:
        for t in (5, 1, 4, 2, 3):
            rec.write("cbgo/user", wire.encode(example("user")), T0 + t)
    assert [m.log_time_ns - T0 for m in read_recording(path)] == [1, 2, 3, 4, 5]


def test_the_standard_mcap_reader_sees_one_msgpack_channel_per_key(recorded):
    path, sent = recorded
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == PROFILE
        summary = reader.get_summary()
        channels = {c.topic: c for c in summary.channels.values()}
        assert sorted(channels) == sorted(KEYS)
        for channel in channels.values():
            assert channel.message_encoding == MESSAGE_ENCODING == "msgpack"
            assert channel.schema_id == 0
        counts = {summary.channels[cid].topic: n
                  for cid, n in summary.statistics.channel_message_counts.items()}
        assert counts == {k: sum(1 for s in sent if s[0] == k) for k in KEYS}
        assert summary.statistics.message_count == len(sent)
        assert len(summary.chunk_indexes) > 1
        assert {ci.compression for ci in summary.chunk_indexes} == {"zstd"}
        payloads = [msg.data for _s, _c, msg in reader.iter_messages()]
    assert payloads == [p for _k, p, _t in sent]


def test_the_recording_carries_cbgo_metadata(recorded):
    path, sent = recorded
    info = recording_info(path)
    assert info.profile == "cbgo"
    assert info.library.startswith("cbgo/")
    assert info.prefix == "cbgo"
    start = info.metadata["cbgo"]
    assert json.loads(start["keys"]) == ["cbgo/**"]
    assert {"cbgo_version", "start_time_ns", "start_time", "host"} <= set(start)
    assert info.metadata["cbgo.end"]["message_count"] == str(len(sent))
    assert info.message_count == len(sent)
    assert (info.start_ns, info.end_ns) == (sent[0][2], sent[-1][2])


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_other_compressions_read_back_too(tmp_path, compression):
    path = tmp_path / "rec.mcap"
    sent = messages(10)
    with Recorder(path, compression=compression, chunk_bytes=512) as rec:
        for key, payload, t in sent:
            rec.write(key, payload, t)
    assert [m.payload for m in read_recording(path)] == [p for _k, p, _t in sent]


def test_an_empty_recording_is_valid_and_has_no_messages(tmp_path):
    path = tmp_path / "empty.mcap"
    Recorder(path).close()
    assert list(read_recording(path)) == []
    assert recording_info(path).message_count == 0


def test_writes_from_many_threads_are_all_kept(tmp_path):
    path = tmp_path / "rec.mcap"
    with Recorder(path, chunk_bytes=4096) as rec:
        def worker(k: int) -> None:
            for i in range(250):
                rec.write(f"cbgo/t{k}", wire.encode({"v": 1, "ts": 1.0, "i": i}))
        threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    back = list(read_recording(path))
    assert len(back) == 1000
    for k in range(4):
        assert [m.message["i"] for m in back if m.key == f"cbgo/t{k}"] == list(range(250))


def test_writes_after_close_are_dropped_and_close_is_idempotent(tmp_path):
    rec = Recorder(tmp_path / "rec.mcap")
    assert rec.write("cbgo/user", b"\x80", T0)
    rec.close()
    assert rec.closed
    assert not rec.write("cbgo/user", b"\x80", T0 + 1)
    rec.close()
    assert len(list(read_recording(tmp_path / "rec.mcap"))) == 1


def test_recorder_stats_give_count_bytes_and_rate_per_key(tmp_path):
    with Recorder(tmp_path / "rec.mcap") as rec:
        for i in range(11):
            rec.write("cbgo/gaze", b"\x80" * 10, T0 + i * 10_000_000)
        stats = rec.stats()["cbgo/gaze"]
    assert (stats.count, stats.bytes) == (11, 110)
    assert stats.rate_hz == pytest.approx(100.0)


# --------------------------------------------------------------------------- key filters


@pytest.mark.parametrize(("keys", "expected"), [
    (["cbgo/gaze"], {"cbgo/gaze"}),
    ("cbgo/gaze", {"cbgo/gaze"}),
    (["cbgo/hands/*"], {"cbgo/hands/frame"}),
    (["cbgo/*"], {"cbgo/gaze", "cbgo/user"}),
    (["cbgo/**"], set(KEYS)),
    (["**/frame", "cbgo/user"], {"cbgo/hands/frame", "cbgo/user"}),
    (["cbgo/episode/**"], {"cbgo/episode/event"}),
    (["cbgo/nothing"], set()),
    ([], set()),
])
def test_key_filters_take_exact_keys_and_zenoh_wildcards(recorded, keys, expected):
    path, sent = recorded
    back = list(read_recording(path, keys=keys))
    assert {m.key for m in back} == expected
    assert [m.payload for m in back] == [p for k, p, _t in sent if k in expected]


def test_an_invalid_key_expression_is_a_recording_error(recorded):
    path, _ = recorded
    with pytest.raises(RecordingError, match="invalid key expression"):
        read_recording(path, keys=["cbgo//x"])


# --------------------------------------------------------------------------- bad files


def test_a_missing_file_is_a_recording_error(tmp_path):
    with pytest.raises(RecordingError, match="cannot open recording"):
        read_recording(tmp_path / "nope.mcap")
    assert issubclass(RecordingError, CbgoError)


def test_a_file_that_is_not_mcap_is_a_recording_error(tmp_path):
    path = tmp_path / "junk.mcap"
    path.write_bytes(b"this is not an mcap file at all, just text" * 10)
    with pytest.raises(RecordingError, match="not a complete MCAP file"):
        read_recording(path)


@pytest.mark.parametrize("keep", [0, 8, 100, 0.5, 0.9, -9, -1])
def test_a_truncated_file_is_a_recording_error(recorded, tmp_path, keep):
    path, _ = recorded
    data = path.read_bytes()
    cut = keep if isinstance(keep, int) and keep >= 0 else (
        int(len(data) * keep) if isinstance(keep, float) else len(data) + keep)
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(data[:cut])
    with pytest.raises(RecordingError):
        list(read_recording(bad))
    with pytest.raises(RecordingError):
        recording_info(bad)


def test_corrupt_bytes_give_a_recording_error_or_the_intact_messages(recorded, tmp_path):
    path, sent = recorded
    data = path.read_bytes()
    rng = np.random.default_rng(7)
    errors = 0
    for _ in range(200):
        corrupt = bytearray(data)
        for pos in rng.integers(0, len(data), 3):
            corrupt[pos] ^= 0xFF
        bad = tmp_path / "bad.mcap"
        bad.write_bytes(bytes(corrupt))
        try:
            back = [m.payload for m in read_recording(bad)]
        except RecordingError:
            errors += 1
            continue
        assert back == [p for _k, p, _t in sent]  # corruption outside the data is harmless
    assert errors > 150


def test_the_message_of_a_non_msgpack_payload_is_rejected_lazily(tmp_path):
    path = tmp_path / "rec.mcap"
    with Recorder(path) as rec:
        rec.write("cbgo/robot/stop", b"\xc1", T0)
    (m,) = read_recording(path)
    assert m.payload == b"\xc1"
    with pytest.raises(wire.RejectedMessage):
        _ = m.message


def test_an_unknown_compression_is_a_recording_error(tmp_path):
    with pytest.raises(RecordingError, match="unknown compression"):
        Recorder(tmp_path / "x.mcap", compression="bzip2")


def test_an_uncreatable_file_is_a_recording_error(tmp_path):
    with pytest.raises(RecordingError, match="cannot create"):
        Recorder(tmp_path / "no" / "such" / "dir" / "x.mcap")


# --------------------------------------------------------------------------- toolbox JSON


def toolbox_frames() -> list[dict]:
    return json.loads(TOOLBOX.read_text())


def load_edited(tmp_path, frames: list[dict]) -> list[tuple[float, dict]]:
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(frames))
    return load_toolbox_json(path)


def test_the_toolbox_fixture_converts_to_valid_hand_frames():
    frames = load_toolbox_json(TOOLBOX)
    assert len(frames) == 3
    for t, message in frames:
        wire.validate(message, wire.HANDS_FRAME, "hands/frame")
        assert message["ts"] == t
        assert (message["source"], message["device"]) == ("replay", "toolbox-json")
    assert [len(m["hands"]) for _t, m in frames] == [1, 2, 0]
    assert [m["seq"] for _t, m in frames] == [802211, 802212, 802213]
    assert frames[0][0] == pytest.approx(5291.734512)
    assert frames[1][0] - frames[0][0] == pytest.approx(0.008333)


def test_toolbox_hands_keep_the_recorded_fields():
    raw = toolbox_frames()[1]
    (_t, message) = load_toolbox_json(TOOLBOX)[1]
    left, right = message["hands"]
    assert (left["side"], left["id"], right["side"], right["id"]) == ("left", 42, "right", 41)
    src = raw["l"]
    assert left["grab_strength"] == src["grab_strength"] == 1.0
    assert left["pinch_strength"] == src["pinch_strength"]
    assert left["confidence"] == src["confidence"]
    assert left["palm_width"] == src["palm_width"]
    assert left["palm_position"] == [src["palm_position"][a] for a in "xyz"]
    assert left["wrist_position"] == [src["wrist_position"][a] for a in "xyz"]
    bone = src["fingers"][2]["bones"][3]
    out = left["fingers"][2]["bones"][3]
    assert out["type"] == "distal" and left["fingers"][2]["type"] == "middle"
    assert out["prev_joint"] == [bone["prev_joint"][a] for a in "xyz"]
    assert out["next_joint"] == [bone["next_joint"][a] for a in "xyz"]
    assert out["width"] == bone["width"]


def test_the_thumb_metacarpal_stays_zero_length_with_its_direction_in_the_rotation():
    (_t, message) = load_toolbox_json(TOOLBOX)[0]
    thumb_meta = message["hands"][0]["fingers"][0]["bones"][0]
    assert thumb_meta["prev_joint"] == thumb_meta["next_joint"]
    assert "rotation" in thumb_meta


def _rotate(q: list[float], v: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    m = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    return m @ v


def test_bone_rotations_point_minus_z_along_the_recorded_bone_direction():
    raw = toolbox_frames()
    checked = 0
    for (_t, message), frame in zip(load_toolbox_json(TOOLBOX), raw, strict=True):
        for hand in message["hands"]:
            src = frame["l" if hand["side"] == "left" else "r"]
            for f, finger in enumerate(hand["fingers"]):
                for b, bone in enumerate(finger["bones"]):
                    d = src["fingers"][f]["bones"][b]["direction"]
                    direction = np.array([d["x"], d["y"], d["z"]])
                    got = _rotate(bone["rotation"], np.array([0.0, 0.0, -1.0]))
                    assert np.allclose(got, direction / np.linalg.norm(direction), atol=2e-3)
                    checked += 1
    assert checked == 60


def test_missing_toolbox_fields_are_derived_from_the_geometry(tmp_path):
    frames = toolbox_frames()
    given = load_toolbox_json(TOOLBOX)
    for frame in frames:
        for side in ("l", "r"):
            for name in ("palm_velocity", "palm_normal", "direction", "wrist_position",
                         "palm_width", "grab_strength", "pinch_strength", "confidence"):
                frame[side].pop(name, None)
            for finger in frame[side]["fingers"]:
                for bone in finger["bones"]:
                    bone.pop("width")
                    bone.pop("basis")
    derived = load_edited(tmp_path, frames)
    for (_t, got), (_t2, ref) in zip(derived, given, strict=True):
        wire.validate(got, wire.HANDS_FRAME, "hands/frame")
        for hand, ref_hand in zip(got["hands"], ref["hands"], strict=True):
            assert hand["confidence"] == 1.0
            assert np.allclose(hand["palm_normal"], ref_hand["palm_normal"], atol=0.02)
            assert np.allclose(hand["direction"], ref_hand["direction"], atol=0.06)
            assert np.allclose(hand["wrist_position"], ref_hand["wrist_position"], atol=5.0)
            assert hand["palm_width"] == pytest.approx(ref_hand["palm_width"], abs=15.0)
            assert all(b["width"] == 0.0 and "rotation" not in b
                       for f in hand["fingers"] for b in f["bones"])
    right0, right1 = derived[0][1]["hands"][0], derived[1][1]["hands"][1]
    # The right palm moves 0.5 mm in x in 8.333 ms: 60 mm/s, as the fixture's own velocity.
    assert np.allclose(right0["palm_velocity"], [60.0, 0.0, 0.0], atol=0.01)
    assert np.allclose(right1["palm_velocity"], [60.0, 0.0, 0.0], atol=0.01)
    left = derived[1][1]["hands"][0]
    assert left["palm_velocity"] == [0.0, 0.0, 0.0]  # seen in one frame only
    assert left["grab_strength"] > 0.5 > right1["grab_strength"]  # a fist and an open hand
    assert right1["pinch_strength"] < 0.2  # thumb and index tips ~67 mm apart


def test_toolbox_variants_left_right_keys_hands_lists_and_xyz_lists_are_accepted(tmp_path):
    frames = toolbox_frames()
    ref = load_toolbox_json(TOOLBOX)
    renamed = copy.deepcopy(frames)
    for frame in renamed:
        frame["left"], frame["right"] = frame.pop("l"), frame.pop("r")
        frame["secs"], frame["nsecs"] = frame.pop("sec"), frame.pop("nanosec")
    assert load_edited(tmp_path, renamed) == ref
    listed = copy.deepcopy(frames)
    for frame in listed:
        frame["hands"] = [h for h in (frame.pop("l"), frame.pop("r")) if h["visible"]]
        for hand in frame["hands"]:
            hand["palm_position"] = [hand["palm_position"][a] for a in "xyz"]
    assert load_edited(tmp_path, listed) == ref


@pytest.mark.parametrize(("edit", "where"), [
    (lambda f: f[1]["r"].pop("palm_position"), "frame 1: r.palm_position"),
    (lambda f: f[0]["r"]["fingers"].pop(), "frame 0: r.fingers"),
    (lambda f: f[1]["l"]["fingers"][2]["bones"].pop(), "frame 1: l.fingers[2].bones"),
    (lambda f: f[0]["r"]["fingers"][1]["bones"][2]["next_joint"].update(y="NaN"),
     "frame 0: r.fingers[1].bones[2].next_joint[1]"),
    (lambda f: f[2].pop("sec"), "frame 2: sec"),
    (lambda f: f[0]["r"].update(confidence=1.5), "frame 0: hands/frame: hands[0].confidence"),
    (lambda f: f.__setitem__(1, 7), "frame 1: expected a frame object"),
    (lambda f: f[1].update(l="left hand"), "frame 1: l: expected a hand object"),
])
def test_a_malformed_toolbox_frame_names_the_frame_and_field(tmp_path, edit, where):
    frames = toolbox_frames()
    edit(frames)
    with pytest.raises(RecordingError, match=re.escape(f"edited.json: {where}")):
        load_edited(tmp_path, frames)


@pytest.mark.parametrize(("content", "problem"), [
    (None, "cannot read toolbox recording"),
    ("{not json", "is not JSON"),
    ('{"frames": []}', "expected a JSON list of frames"),
])
def test_an_unreadable_toolbox_file_is_a_recording_error(tmp_path, content, problem):
    path = tmp_path / "t.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(RecordingError, match=problem):
        load_toolbox_json(path)
