"""Stroke segmentation on synthetic trajectories: where strokes start, end, and do not."""

import math

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.hands.model import HandShape, build_hand, neutral_pose
from cbgo.services.dynamic_gesture.stroke import (
    DEFAULT_CENTRE_MM,
    Segmenter,
    SegmenterConfig,
    palm_roll,
)
from cbgo.simuser.motion import CENTRE_MM

REST = ("hold", 0.5)
SWIPE_UP = ("move", 0.45, (0.0, 160.0, 0.0))


def finals(windows):
    return [w for w in windows if w.final]


def test_the_default_centre_is_where_the_simulated_user_starts_strokes():
    assert np.allclose(DEFAULT_CENTRE_MM, CENTRE_MM)


def test_a_swipe_from_rest_in_the_centre_is_one_stroke_evaluated_during_and_at_its_end(synth):
    windows = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)]))
    (final,) = finals(windows)
    assert len(windows) > 1 and all(not w.final for w in windows[:-1])
    assert final.ended == "slowed"
    assert np.allclose(final.obs[0], 0.0)  # translation-normalised to the stroke start
    assert 140 < final.obs[-1, 1] < 170 and abs(final.obs[-1, 0]) < 5
    assert 0.3 < final.t_end - final.t_start < 0.7
    starts = {w.t_start for w in windows}
    assert starts == {final.t_start}  # every window of a stroke starts where it started


def test_the_return_move_from_outside_the_centre_is_not_a_stroke(synth):
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.4), ("move", 0.9, (0, -160, 0)),
                             ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert len(finals(windows)) == 1
    assert {w.stroke for w in windows} == {1}


def test_a_motion_that_starts_outside_the_centre_is_not_a_stroke(synth):
    traj = synth.trajectory([REST, ("move", 0.45, (0, 0, 0))], start=synth.CENTRE + [150, 0, 0])
    traj += synth.trajectory([("move", 0.45, (0, 160, 0)), ("hold", 0.4)],
                             start=synth.CENTRE + [150, 0, 0])
    assert synth.feed(Segmenter(), traj) == []


def test_a_hand_that_reaches_the_centre_while_moving_is_not_armed(synth):
    enter = synth.trajectory([("move", 0.6, -np.array([40.0, -40.0, 300.0])), ("hold", 1.0)],
                             start=synth.CENTRE + [40.0, -40.0, 300.0])
    assert synth.feed(Segmenter(), enter) == []


def test_a_still_hand_with_tremor_never_starts_a_stroke(synth):
    still = synth.trajectory([("hold", 6.0)], tremor=1.5, seed=3)
    assert synth.feed(Segmenter(), still) == []


def test_a_palm_roll_in_place_is_a_stroke_seen_in_the_roll_dimension(synth):
    windows = synth.feed(Segmenter(), synth.trajectory([REST, ("roll", 0.6, math.radians(90)),
                                                        ("hold", 0.5)]))
    (final,) = finals(windows)
    assert np.abs(final.obs[-1, :3]).max() < 2.0
    assert abs(abs(final.obs[-1, 3]) - 100 * math.radians(90)) < 15  # k = 100 mm/rad


def test_a_hand_that_disappears_mid_stroke_ends_it_with_what_was_seen(synth):
    segmenter = Segmenter()
    traj = synth.trajectory([REST, SWIPE_UP])
    windows = synth.feed(segmenter, traj[:-12])
    windows += segmenter.update(traj[-12][0], [])
    (final,) = finals(windows)
    assert final.ended == "lost" and final.obs[-1, 1] > 60
    assert segmenter.tracks == {}


def test_two_hands_are_segmented_independently(synth):
    segmenter = Segmenter()
    moving = synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)])
    still = synth.trajectory([("hold", 1.45)], start=synth.CENTRE + [30, 0, 0])
    windows = []
    for (t, p, r), (_, q, s) in zip(moving, still, strict=True):
        windows += segmenter.update(t, [synth.hand(p, r, 1), synth.hand(q, s, 2, "left")])
    assert {w.hand_id for w in windows} == {1}


def test_frames_at_120_hz_are_resampled_to_20_hz(synth):
    windows = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)],
                                                       rate=120.0))
    final = finals(windows)[0]
    assert np.allclose(np.diff(final.times), 0.05, atol=0.01)


@pytest.mark.parametrize("side", ["right", "left"])
def test_the_palm_roll_has_the_anatomical_sign_on_either_hand(side):
    shape = HandShape.sample(np.random.default_rng(0), side=side)
    rolled = build_hand(shape, neutral_pose().rotated(roll=math.radians(40)), [0, 230, 0])
    flat = build_hand(shape, neutral_pose(), [0, 230, 0])
    delta = (palm_roll(rolled["palm_normal"], rolled["direction"], side)
             - palm_roll(flat["palm_normal"], flat["direction"], side))
    assert abs(abs(delta) - math.radians(40)) < 0.02
    assert delta < 0  # the same anatomical roll gives the same sign on both hands


def test_invalid_settings_name_the_fix():
    with pytest.raises(ConfigError, match="centre_mm needs 3 numbers"):
        SegmenterConfig(centre_mm=[0.0, 1.0])
    with pytest.raises(ConfigError, match="must not exceed"):
        SegmenterConfig(end_speed_mm_s=500.0)
