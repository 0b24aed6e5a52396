"""Plain strokes (`plainstrokes`): textbook swipes and rotates through the service's logic."""

import numpy as np
import pytest

from cbgo.services.dynamic_gesture.library import DEFAULT_PATH, Library
from cbgo.services.dynamic_gesture.stroke import SegmenterConfig
from cbgo_tools.dynamic_gesture import bench, plainstrokes, scoring


def test_a_plain_stroke_goes_its_way_from_where_it_starts_and_comes_back():
    rng = np.random.default_rng(3)
    stroke = plainstrokes.draw("swipe_right", 3, 0.4, False, rng)  # 180 mm in 0.4 s
    assert np.linalg.norm(stroke.displacement) == pytest.approx(180.0)
    frames = plainstrokes.frames(stroke)
    palms = np.array([hands[0]["palm_position"] for _, hands in frames])
    low, high = plainstrokes.FIELD
    assert np.all(palms >= low - 60) and np.all(palms <= high + 60)
    far = palms[np.argmax(palms[:, 0])]
    assert far[0] - palms[0, 0] > 150  # it went right, drifting in before
    assert abs(palms[-1, 0] - palms[0, 0]) < 80  # and came back most of the way
    assert frames[1][0] - frames[0][0] == 1 / plainstrokes.RATE_HZ


def test_a_brisk_swipe_is_heard_and_a_small_slow_one_is_not():
    classifier = Library(DEFAULT_PATH, None).load().classifier()
    rng = np.random.default_rng(0)
    brisk = plainstrokes.draw("swipe_up", 3, 0.4, True, rng)  # 180 mm, peak 840 mm/s
    slow = plainstrokes.draw("swipe_up", 0, 1.0, True, rng)  # 60 mm, peak 112 mm/s
    rows = plainstrokes.score([brisk, slow], classifier, SegmenterConfig(), bench.replay_trial)
    assert [r["dynamic"] for r in rows] == ["swipe_up", scoring.NOTHING]
    figures = plainstrokes.report(rows, log=lambda *_: None)
    assert figures["cells"]["swipes 180 0.4"] == [1, 1]
    assert figures["cells"]["swipes 60 1"] == [0, 1]
    assert figures["missed"] == 1 and figures["miss_answers"] == {"nothing": 1}


def test_a_left_hands_plain_swipe_is_scored_as_its_mirror_image_and_heard():
    classifier = Library(DEFAULT_PATH, None).load().classifier()
    stroke = plainstrokes.draw("swipe_right", 3, 0.4, True, np.random.default_rng(1))
    (row,) = plainstrokes.score([stroke], classifier, SegmenterConfig(), bench.replay_trial,
                                mirror=True)
    assert row["truth"] == "swipe_left" and row["dynamic"] == "swipe_left"
