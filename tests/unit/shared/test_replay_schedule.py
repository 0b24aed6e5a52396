"""`cbgo replay`'s schedule: each message waits for its recorded time / speed, counted from the
first, and is then put as recorded, marked ``replayed: true`` (or restamped too). The clock is
replaced, so nothing here depends on how busy the machine is; `cbgo bench replay` measures the
real rhythm through a router."""

from __future__ import annotations

import argparse
import threading

import pytest
from tqdm import tqdm

from cbgo import wire
from cbgo.cli import replay
from cbgo.examples import example
from cbgo.keys import Keys
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


def replayed(payload):
    """What the replay sends for a recorded payload: the same message, marked."""
    return {**wire.decode(payload), "replayed": True}


def decoded(sent):
    return [(k, wire.decode(p)) for k, p in sent]


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
    assert decoded(sent) == [(k, replayed(p)) for k, p, _n in written]  # in order, marked


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
    assert [wire.decode(p) for p in sent] == [replayed(p) for p, _n in gaze]
    assert deadlines == pytest.approx([origin + (n - gaze[0][1]) / 1e9 for _p, n in gaze])


def test_restamp_changes_ts_alone(monkeypatch, recording):
    path, written = recording
    monkeypatch.setattr(replay.time, "time", lambda: 42.5)
    _deadlines, _origin, sent = play_with_clock(monkeypatch, path, restamp=True)
    for (key, payload), (_k, original, _n) in zip(sent, written, strict=True):
        got, old = wire.decode(payload), replayed(original)
        assert got["ts"] == 42.5 != old["ts"]
        assert {k: v for k, v in got.items() if k != "ts"} == {
            k: v for k, v in old.items() if k != "ts"}, key


def test_a_stop_while_waiting_ends_the_pass_before_that_message(monkeypatch, recording):
    path, written = recording
    deadlines, _origin, sent = play_with_clock(monkeypatch, path, stop_after=2)
    assert len(deadlines) == 3
    assert decoded(sent) == [(k, replayed(p)) for k, p, _n in written[:2]]


def test_a_hand_frame_says_it_is_replayed_and_a_payload_that_is_no_map_goes_out_as_recorded(
        tmp_path):
    path = tmp_path / "mixed.mcap"
    frame = wire.encode(example("hands/frame", ts=1.0))
    with Recorder(path) as rec:
        rec.write("cbgo/hands/frame", frame, 1_000_000_000)
        rec.write("cbgo/gaze", b"\xc1", 1_001_000_000)  # not msgpack: cannot be marked
    sent = []
    puts = {k: (lambda payload, k=k: sent.append((k, payload)))
            for k in ("cbgo/hands/frame", "cbgo/gaze")}
    with tqdm(disable=True) as bar:
        replay.play(str(path), None, puts, argparse.Namespace(speed=1000.0, restamp=True),
                    threading.Event(), bar, hands_key="cbgo/hands/frame")
    (key, payload), raw = sent
    got = wire.decode(payload)
    assert key == "cbgo/hands/frame" and got["replayed"] is True
    assert got["source"] == "replay" and example("hands/frame")["source"] == "simulated"
    wire.validate(got, wire.HANDS_FRAME, key)  # still a valid frame: the mark is an extra field
    assert raw == ("cbgo/gaze", b"\xc1")


# ---------------------------------------------------------------- what goes out, and whether

KEYS = Keys("cbgo")
RECORDED = ["cbgo/hands/frame", "cbgo/gaze", "cbgo/user", "cbgo/episode/event", "cbgo/intent",
            "cbgo/scene/state", "cbgo/robot/stop", "cbgo/plan/status", "other/topic"]


def test_only_sensor_and_person_keys_go_out_without_derived():
    chosen, held_back = replay.choose_keys(RECORDED, KEYS, derived=False)
    assert chosen == ["cbgo/hands/frame", "cbgo/gaze", "cbgo/user"]
    assert held_back == RECORDED[3:]
    assert replay.choose_keys(RECORDED, KEYS, derived=True) == (RECORDED, [])


@pytest.mark.parametrize("alive", [{"planner"}, {"dry-robot"}, {"mujoco-sim", "router"}])
def test_derived_keys_while_a_planner_or_robot_is_alive_are_a_risk(alive):
    (risk,) = replay.robot_risks(RECORDED, KEYS, alive, planner_refuses_replayed=True)
    assert "intent" in risk and sorted(alive - {"router"})[0] in risk


def test_hand_frames_are_a_risk_only_where_a_planner_may_act_on_what_they_lead_to():
    sensors = RECORDED[:3]
    pipeline = {"episode", "intent", "planner"}
    assert replay.robot_risks(sensors, KEYS, {"router", "episode", "intent", "dry-robot"},
                              False) == []
    assert replay.robot_risks(sensors, KEYS, {"planner", "dry-robot"}, False) == []
    assert replay.robot_risks(sensors, KEYS, pipeline | {"dry-robot"}, True) == []
    (risk,) = replay.robot_risks(sensors, KEYS, pipeline, False)
    assert "--accept-replayed" in risk and "execute" in risk
    assert replay.robot_risks(["cbgo/gaze", "cbgo/user"], KEYS, pipeline | {"dry-robot"},
                              False) == []
    assert replay.robot_risks(RECORDED, KEYS, {"router", "web", "episode"}, False) == []


def test_a_second_hand_source_is_reported_once_and_counted():
    said = []
    watch = replay.SecondSource("cbgo/hands/frame", say=said.append)
    assert watch.summary() is None
    watch.on_frame()
    watch.on_frame()
    assert watch.foreign == 2 and len(said) == 1 and "another publisher" in said[0]
    assert "2 hand frames from another publisher" in watch.summary()
