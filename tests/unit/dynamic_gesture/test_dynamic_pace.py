"""A person's pace: calibration takes, the lines they set, the file, the recorder."""

import json
import os

import pytest

from cbgo.services.dynamic_gesture import pace, user_pace
from cbgo.services.dynamic_gesture.stroke import Segmenter, SegmenterConfig

REST = ("hold", 0.6)


def appearance(synth, move, t0=0.0, hand_id=1):
    """One appearance of the hand: rest, the move, rest; frames (t, hands) from t0."""
    traj = synth.trajectory([REST, ("move", *move), ("hold", 0.5)])
    return [(t0 + t, [synth.hand(p, r, hand_id)]) for t, p, r in traj]


def test_a_slow_persons_lines_and_start_lie_below_their_typical_swipe():
    slow = pace.Pace("ann", 180.0, 6).applied(SegmenterConfig())
    assert slow.min_peak_speed_mm_s == pytest.approx(pace.PACE_SHARE * 180.0)
    assert slow.start_speed_mm_s == pytest.approx(pace.PACE_SHARE * 180.0)
    assert slow.first_peak_speed_mm_s <= slow.min_peak_speed_mm_s
    assert slow.mid_peak_speed_mm_s < SegmenterConfig().mid_peak_speed_mm_s


def test_the_typical_speed_is_the_median_take_so_more_takes_do_not_lower_it(synth):
    windows = []
    for seconds in (0.5, 0.6, 0.7, 1.6):  # the last one much slower than the others
        segmenter = Segmenter(user_pace.unlined())
        frames = appearance(synth, (seconds, (-150, 0, 0)))
        windows += [w for t, hands in frames for w in segmenter.update(t, hands) if w.final]
    typical = pace.pace_of("ann", windows).typical_mm_s
    assert min(w.peak_mm_s for w in windows) < typical < max(w.peak_mm_s for w in windows)


def test_a_fast_persons_calibration_leaves_the_lines_as_configured():
    fast = pace.Pace("bob", 900.0, 6).applied(SegmenterConfig())
    assert fast == SegmenterConfig()


def test_no_line_goes_below_the_floor():
    crawling = pace.Pace("cy", 40.0, 6).applied(SegmenterConfig())
    assert crawling.min_peak_speed_mm_s == pace.PACE_FLOOR_MM_S
    assert crawling.start_speed_mm_s == pace.PACE_FLOOR_MM_S


def test_the_take_is_the_stroke_that_goes_farthest_the_asked_way(synth):
    frames = appearance(synth, (0.5, (-150, 0, 0)))
    segmenter = Segmenter(user_pace.unlined())
    windows = [w for t, hands in frames for w in segmenter.update(t, hands)]
    assert pace.swipe_take(windows, "swipe_left") is not None
    assert pace.swipe_take(windows, "swipe_right") is None
    assert pace.swipe_take(windows, "swipe_up") is None


def test_a_calibration_file_round_trips_and_a_broken_one_is_named(tmp_path):
    path = pace.calibration_path(tmp_path, "ann")
    pace.save_pace(path, pace.Pace("ann", 170.0, 4), {"swipe_left": [170.0, 190.0]})
    assert pace.read_pace(path) == pace.Pace("ann", 170.0, 4)
    path.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ValueError, match="not a calibration file"):
        pace.read_pace(path)


def test_paces_are_re_read_when_the_file_changes_and_broken_ones_are_listed(tmp_path):
    paces = pace.Paces(tmp_path)
    assert paces.get("ann") is None
    path = pace.calibration_path(tmp_path, "ann")
    pace.save_pace(path, pace.Pace("ann", 170.0, 4), {})
    assert paces.get("ann").typical_mm_s == 170.0
    path.write_text("{")
    os.utime(path, (1, 1))
    assert paces.get("ann") is None and "ann" in paces.skipped


def test_the_recorder_takes_one_swipe_per_appearance_and_asks_again_for_a_wrong_way(
        synth, monkeypatch):
    recorder = user_pace.SwipeRecorder(1, ("swipe_left", "swipe_right"))
    said = []
    monkeypatch.setattr(user_pace.demonstrate, "say", said.append)  # what the person is told
    t = 0.0
    for hand_id, move in enumerate([(0.8, (0, 120, 0)),      # up: not the asked swipe left
                                    (1.4, (-120, 0, 0)),     # a slow swipe left
                                    (1.4, (120, 0, 0))], 1):  # a slow swipe right
        frames = appearance(synth, move, t, hand_id)
        for ft, hands in frames:
            recorder.feed(ft, hands)
        recorder.feed(frames[-1][0] + 0.05, [])  # the hand leaves
        t = frames[-1][0] + 1.0
    assert recorder.done and recorder.refused == 1
    assert any("no swipe left seen" in line for line in said)
    assert set(recorder.peaks()) == {"swipe_left", "swipe_right"}
    slowest = min(w.peak_mm_s for w in recorder.takes)
    assert slowest < SegmenterConfig().min_peak_speed_mm_s  # caught, though a slow move


def test_a_calibration_is_saved_where_the_service_reads_it(tmp_path, monkeypatch, synth):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    monkeypatch.setattr(user_pace.demonstrate, "say", lambda text: None)
    recorder = user_pace.SwipeRecorder(1, ("swipe_left",))
    frames = appearance(synth, (1.0, (-120, 0, 0)))
    for t, hands in [*frames, (frames[-1][0] + 0.05, [])]:
        recorder.feed(t, hands)
    assert user_pace.finish(recorder, "ann") == 0
    saved = pace.read_pace(tmp_path / "calibration" / "ann.json")
    assert saved.takes == 1 and saved.typical_mm_s == pytest.approx(recorder.takes[0].peak_mm_s)
    assert user_pace.finish(user_pace.SwipeRecorder(1), "bob") == 1  # nothing captured
