"""`cbgo replay`'s schedule: each message waits for its recorded time / speed, counted from the
first, and is then put as recorded (or restamped). The clock is replaced, so nothing here depends
on how busy the machine is; `cbgo bench replay` measures the real rhythm through a router."""

from __future__ import annotations

import argparse
import threading

import pytest
from tqdm import tqdm

from cbgo import wire
from cbgo.cli import replay
from cbgo.examples import example
from cbgo.recording import Recorder

GAPS_MS = [0, 3, 17, 2, 11, 40]


@pytest.fixture
def recording(tmp_path):
    """Six messages on two keys at GAPS_MS; returns (path, [(key, payload, log ns)])."""
    path, written, now_ns = tmp_path / "six.mcap", [], 1_700_000_000_000_000_000
    with Recorder(path) as rec:
        for i, gap in enumerate(GAPS_MS):
            now_ns += gap * 1_000_000
            key = "cbgo/gaze" if i % 2 else "cbgo/user"
            payload = wire.encode({**example(key[5:], ts=now_ns / 1e9), "n": i})
            rec.write(key, payload, now_ns)
            written.append((key, payload, now_ns))
    return path, written


def play_with_clock(monkeypatch, path, speed=1.0, restamp=False, stop_after=None):
    """Plays path with a fake clock; returns (deadlines waited for, origin, [(key, payload)])."""
    origin, deadlines, sent = 100.0, [], []
    stop = threading.Event()
    monkeypatch.setattr(replay.time, "perf_counter", lambda: origin)

    def sleep_until(deadline, stop_event):
        deadlines.append(deadline)
        if stop_after is not None and len(deadlines) > stop_after:
            stop_event.set()
        return stop_event.is_set()

    monkeypatch.setattr(replay, "_sleep_until", sleep_until)
    puts = {k: (lambda payload, k=k: sent.append((k, payload))) for k in ("cbgo/gaze",
                                                                          "cbgo/user")}
    args = argparse.Namespace(speed=speed, restamp=restamp)
    with tqdm(disable=True) as bar:
        count = replay.play(str(path), None, puts, args, stop, bar)
    assert count == len(sent)
    return deadlines, origin, sent


@pytest.mark.parametrize("speed", [1.0, 4.0, 0.5])
def test_each_message_waits_for_its_recorded_time_over_speed(monkeypatch, recording, speed):
    path, written = recording
    deadlines, origin, sent = play_with_clock(monkeypatch, path, speed=speed)
    first_ns = written[0][2]
    assert deadlines == pytest.approx([origin + (n - first_ns) / 1e9 / speed
                                       for _k, _p, n in written], abs=1e-9)
    assert sent == [(k, p) for k, p, _n in written]  # byte for byte, in order


def test_only_the_chosen_keys_play_and_their_times_still_count_from_the_first_played(
        monkeypatch, recording):
    path, written = recording
    deadlines, origin, sent = [], 100.0, []
    monkeypatch.setattr(replay.time, "perf_counter", lambda: origin)
    monkeypatch.setattr(replay, "_sleep_until", lambda d, s: deadlines.append(d) or False)
    args = argparse.Namespace(speed=1.0, restamp=False)
    with tqdm(disable=True) as bar:
        replay.play(str(path), None, {"cbgo/gaze": lambda p: sent.append(p)}, args,
                    threading.Event(), bar)
    gaze = [(p, n) for k, p, n in written if k == "cbgo/gaze"]
    assert sent == [p for p, _n in gaze]
    assert deadlines == pytest.approx([origin + (n - gaze[0][1]) / 1e9 for _p, n in gaze])


def test_restamp_changes_ts_alone(monkeypatch, recording):
    path, written = recording
    monkeypatch.setattr(replay.time, "time", lambda: 42.5)
    _deadlines, _origin, sent = play_with_clock(monkeypatch, path, restamp=True)
    for (key, payload), (_k, original, _n) in zip(sent, written, strict=True):
        got, old = wire.decode(payload), wire.decode(original)
        assert got["ts"] == 42.5 != old["ts"]
        assert {k: v for k, v in got.items() if k != "ts"} == {
            k: v for k, v in old.items() if k != "ts"}, key


def test_a_stop_while_waiting_ends_the_pass_before_that_message(monkeypatch, recording):
    path, written = recording
    deadlines, _origin, sent = play_with_clock(monkeypatch, path, stop_after=2)
    assert len(deadlines) == 3
    assert sent == [(k, p) for k, p, _n in written[:2]]
