"""web's replay: a recording becomes the live page's views; what breaks the contract is left out."""

import pytest

from cbgo import wire
from cbgo.errors import RecordingError
from cbgo.examples import example
from cbgo.recording import Recorder
from cbgo.services.web.replay import load


def test_a_recording_becomes_views_in_time_order_with_the_bad_ones_counted(tmp_path):
    path = tmp_path / "s.mcap"
    with Recorder(path, prefix="cell2") as recorder:
        t0 = 1_800_000_000 * 10**9
        for i in range(120):  # one second of 120 Hz hand frames
            frame = example("hands/frame", ts=1_800_000_000 + i / 120, seq=i)
            recorder.write("cell2/hands/frame", wire.encode(frame), t0 + i * 10**9 // 120)
        recorder.write("cell2/intent", wire.encode(example("intent")), t0 + 10**9)
        bad = example("intent", status="maybe")
        recorder.write("cell2/intent", wire.encode(bad), t0 + 10**9 + 1)
        recorder.write("cell2/robot/stop", b"\xc1", t0 + 10**9 + 2)  # not msgpack: still a stop
    replay = load(path, rate_hz=30.0)
    assert replay.prefix == "cell2"
    topics = [topic for _, topic, _ in replay.items]
    assert topics.count("hands/frame") == 30 and topics.count("intent") == 1
    assert topics[-1] == "robot/stop"
    times = [t for t, _, _ in replay.items]
    assert times == sorted(times)
    assert sum(replay.skipped.values()) == 1 and "breaks the contract" in replay.skipped


def test_a_file_that_is_not_a_recording_is_refused(tmp_path):
    path = tmp_path / "x.mcap"
    path.write_bytes(b"not mcap")
    with pytest.raises(RecordingError):
        load(path)
