"""The dynamic-gesture service through FakeBus: valid messages, bad frames, reload, teaching."""

import argparse

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.errors import ConfigError
from cbgo.services.dynamic_gesture.classifier import NONE
from cbgo.services.dynamic_gesture.demonstrate import TakeRecorder
from cbgo.services.dynamic_gesture.library import save_user_template, user_dir
from cbgo.services.dynamic_gesture.main import DynamicGesture, DynamicGestureSettings
from cbgo.testing import FakeBus

T0 = 1000.0
SWIPE_UP = [("hold", 0.5), ("move", 0.45, (0.0, 160.0, 0.0)), ("hold", 0.5)]


@pytest.fixture
def bus(tmp_path):
    service = DynamicGesture(DynamicGestureSettings(user_dir=str(tmp_path), watch_s=1.0))
    bus = FakeBus(service)
    yield bus
    bus.stop()


def play(bus, synth, segments, hand_id=1, **kw):
    out = []
    for i, (t, p, r) in enumerate(synth.trajectory(segments, **kw)):
        out += bus.feed(keys.HANDS_FRAME, synth.frame(T0 + t, [synth.hand(p, r, hand_id)], i))
    return out


def winner(msg):
    return msg["names"][int(np.argmax(msg["probs"]))]


def test_a_swipe_publishes_valid_windows_and_its_final_window_names_it(bus, synth):
    out = play(bus, synth, SWIPE_UP)
    assert out and {topic for topic, _ in out} == {"gestures/dynamic"}
    for _, msg in out:
        wire.validate(msg, wire.GESTURES_DYNAMIC, "cbgo/gestures/dynamic")
        assert msg["names"][-1] == NONE and abs(sum(msg["probs"]) - 1) < 1e-6
        assert msg["hand_id"] == 1 and msg["side"] == "right" and msg["model"]
    assert [m["seq"] for _, m in out] == list(range(len(out)))
    final = out[-1][1]
    assert winner(final) == "swipe_up" and max(final["probs"]) > 0.8
    assert T0 < final["window"][0] < final["window"][1] < T0 + 1.2
    assert bus.counters.published == len(out)
    # one stroke: every window evaluated mid-stroke says so, and the last one is final
    assert [m["final"] for _, m in out] == [False] * (len(out) - 1) + [True]


def test_a_still_hand_publishes_nothing(bus, synth):
    assert play(bus, synth, [("hold", 4.0)], tremor=1.5) == []


def test_a_tracking_jump_mid_swipe_is_counted_and_the_swipe_still_named(bus, synth):
    out = []
    refit = synth.jumped(synth.trajectory(SWIPE_UP, rate=30.0), 0.7, (110.0, 0.0, -90.0))
    for i, (t, p, r) in enumerate(refit):
        out += bus.feed(keys.HANDS_FRAME, synth.frame(T0 + t, [synth.hand(p, r)], i))
    final = out[-1][1]
    assert winner(final) == "swipe_up" and max(final["probs"]) > 0.9  # 0.6 read as a bent stroke
    ok, status = bus.query("status", None)
    assert ok and status["tracking_jumps"] == 1


def test_bad_frames_are_rejected_and_the_service_keeps_working(bus, synth):
    bus.feed_raw(keys.HANDS_FRAME, b"not msgpack")
    bad = synth.frame(T0, [synth.hand(synth.CENTRE, 0.0)])
    bad["hands"][0]["palm_position"] = [0.0, float("nan"), 0.0]
    assert bus.feed(keys.HANDS_FRAME, bad) == []
    assert bus.counters.rejected == 2 and bus.counters.errors == 0
    assert winner(play(bus, synth, SWIPE_UP)[-1][1]) == "swipe_up"


def test_reload_and_polling_pick_up_a_taught_gesture(bus, synth, tmp_path):
    recorder = TakeRecorder(takes=2)
    for take in range(2):
        for t, p, r in synth.trajectory(SWIPE_UP, seed=take):
            recorder.feed(10.0 * take + t, [synth.hand(p, r, hand_id=10 + take)])
        recorder.feed(10.0 * take + 2.0, [])  # the hand leaves between takes
    assert recorder.done
    save_user_template(tmp_path, recorder.template("lift", "alice"))
    ok, reply = bus.query("reload", {"v": 1})
    assert ok and reply["gestures"][-1] == "lift"
    assert "lift" in play(bus, synth, SWIPE_UP)[-1][1]["names"]
    (tmp_path / "lift.json").unlink()
    bus.tick(1.5)  # the poll timer notices the removal
    ok, status = bus.query("status", None)
    assert ok and "lift" not in [g["name"] for g in status["gestures"]]
    assert status["reloads"] == 2


def test_a_reload_mid_stroke_publishes_the_strokes_end_over_the_new_names(bus, synth,
                                                                          tmp_path):
    # A final message may carry a surer window of its stroke published before: not one whose
    # probabilities were over the library's old names.
    recorder = TakeRecorder(takes=2)
    for take in range(2):
        for t, p, r in synth.trajectory(SWIPE_UP, seed=take):
            recorder.feed(10.0 * take + t, [synth.hand(p, r, hand_id=10 + take)])
        recorder.feed(10.0 * take + 2.0, [])
    frames = [synth.frame(T0 + t, [synth.hand(p, r)], i)
              for i, (t, p, r) in enumerate(synth.trajectory(SWIPE_UP))]
    out, reloaded = [], False
    for frame in frames:
        out += bus.feed(keys.HANDS_FRAME, frame)
        if not reloaded and out:  # the stroke was published mid-stroke: now a new gesture
            save_user_template(tmp_path, recorder.template("lift", "alice"))
            assert bus.query("reload", {"v": 1})[0]
            reloaded = True
    assert reloaded and out[-1][1]["final"] and "lift" in out[-1][1]["names"]
    for _, msg in out:
        wire.validate(msg, wire.GESTURES_DYNAMIC, "cbgo/gestures/dynamic")


def test_a_take_is_the_first_real_stroke_of_each_hand_appearance(synth):
    recorder = TakeRecorder(takes=3)
    twitch = [("hold", 0.5), ("move", 0.2, (0.0, 15.0, 0.0)), ("hold", 0.3)]
    segments = twitch + SWIPE_UP + [("move", 0.9, (0.0, -160.0, 0.0))] + SWIPE_UP
    for t, p, r in synth.trajectory(segments):
        recorder.feed(t, [synth.hand(p, r, hand_id=5)])
    assert len(recorder.takes) == 1 and recorder.takes[0].obs[-1, 1] > 140


def test_a_roll_scale_other_than_the_templates_is_refused(tmp_path):
    service = DynamicGesture(DynamicGestureSettings(user_dir=str(tmp_path),
                                                    roll_scale_mm_per_rad=100.0))
    with pytest.raises(ConfigError, match="roll_scale_mm_per_rad"):
        FakeBus(service)


def test_the_user_folder_defaults_to_the_data_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    service = DynamicGesture(DynamicGestureSettings())
    assert service.library.user_folder == user_dir(tmp_path)


def test_recording_from_a_file_adds_to_earlier_takes_unless_replaced(synth, tmp_path,
                                                                       monkeypatch):
    from cbgo.recording import Recorder
    from cbgo.services.dynamic_gesture import demonstrate

    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path / "data"))
    path = tmp_path / "takes.mcap"
    with Recorder(path) as recorder:
        seq = 0
        for take in range(2):
            t0 = T0 + 10.0 * take
            for t, p, r in synth.trajectory(SWIPE_UP, seed=take):
                msg = synth.frame(t0 + t, [synth.hand(p, r, hand_id=20 + take)], seq)
                recorder.write("cbgo/hands/frame", wire.encode(msg), int((t0 + t) * 1e9))
                seq += 1
            msg = synth.frame(t0 + 2.0, [], seq)
            recorder.write("cbgo/hands/frame", wire.encode(msg), int((t0 + 2.0) * 1e9))
            seq += 1
    args = dict(name="lift", takes=2, user="alice", timeout=5.0, file=str(path))
    assert demonstrate.run(argparse.Namespace(**args)) == 0
    assert demonstrate.run(argparse.Namespace(**args)) == 0
    (row,) = demonstrate.list_gestures()
    assert row["name"] == "lift" and row["takes"] == 4 and row["users"] == ["alice"]
    assert demonstrate.run(argparse.Namespace(**args, replace=True)) == 0
    assert demonstrate.list_gestures()[0]["takes"] == 2
    assert demonstrate.run(argparse.Namespace(**{**args, "name": "no gesture"})) == 2
    assert demonstrate.run(argparse.Namespace(**{**args, "takes": 3})) == 1


def test_status_names_the_gestures_the_trajectory_network_gives_an_opinion_on(bus):
    ok, status = bus.query("status", None)
    assert ok and status["second_opinion"] == ["swipe_up", "swipe_down", "swipe_left",
                                               "swipe_right", "rotate"]


def test_a_calibrated_user_is_judged_by_their_pace_and_others_by_the_settings(
        tmp_path, monkeypatch, synth):
    from cbgo.services.dynamic_gesture.pace import Pace, calibration_path, save_pace

    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    save_pace(calibration_path(tmp_path, "ann"), Pace("ann", 190.0, 12), {})
    bus = FakeBus(DynamicGesture(DynamicGestureSettings(user_dir=str(tmp_path / "g"))))
    try:
        # a brisk first stroke, then a slow swipe left (about 160 mm/s): a line drawn
        slow_after_first = [*SWIPE_UP, ("move", 1.3, (-130.0, 0.0, 0.0)), ("hold", 0.6)]
        finals = [m for _, m in play(bus, synth, slow_after_first) if m["final"]]
        assert len(finals) == 1  # the slow swipe is a slow move by the settings' lines
        bus.feed(keys.USER, {"v": 1, "ts": T0, "user": "ann"})
        ok, status = bus.query("status", None)
        assert ok and status["user"] == "ann" and status["lines_mm_s"]["final"] < 150.0
        assert status["lines_mm_s"]["start"] < DynamicGestureSettings().start_speed_mm_s
        finals = [m for _, m in play(bus, synth, slow_after_first, hand_id=2) if m["final"]]
        assert len(finals) == 2 and winner(finals[-1]) == "swipe_left"
        bus.feed(keys.USER, {"v": 1, "ts": T0, "user": "bob"})  # not calibrated
        ok, status = bus.query("status", None)
        assert status["lines_mm_s"]["final"] == DynamicGestureSettings().min_peak_speed_mm_s
    finally:
        bus.stop()
