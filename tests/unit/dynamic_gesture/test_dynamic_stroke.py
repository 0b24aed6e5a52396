"""Stroke segmentation on synthetic trajectories: where strokes start, end, and do not."""

import math

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.hands.model import HandShape, build_hand, neutral_pose
from cbgo.services.dynamic_gesture import stroke
from cbgo.services.dynamic_gesture.stroke import (
    DEFAULT_CENTRE_MM,
    ReturnFilter,
    Segmenter,
    SegmenterConfig,
    palm_roll,
    reported,
    roll_increment,
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


@pytest.mark.parametrize("origin", [1796550077.5206337, 1.7e9 + 0.123, 12345.678])
def test_a_stroke_is_sampled_the_same_whatever_the_clocks_origin(synth, origin):
    # A 30 Hz clock meets the 20 Hz bins every 0.1 s; stamped from an epoch origin, those
    # frames fell on either side of the bin's end by rounding, and the samples changed.
    traj = synth.trajectory([REST, ("move", 0.5, (180.0, 40.0, 0.0)), ("hold", 0.5)], rate=30.0)
    frames = [(i / 30.0, p, r) for i, (_, p, r) in enumerate(traj)]
    from_zero = synth.feed(Segmenter(), frames)
    from_origin = synth.feed(Segmenter(), [(origin + t, p, r) for t, p, r in frames])
    assert len(from_zero) == len(from_origin) > 2
    for a, b in zip(from_zero, from_origin, strict=True):
        assert np.allclose(a.obs, b.obs, atol=1e-6) and a.final == b.final
        assert abs(b.t_end - origin - a.t_end) < 1e-5


def reported_windows(windows, classify):
    """The windows a service reports; `classify(w)` is w's gesture probability (or a bool)."""
    def probs(w):  # one gesture, then none
        p = float(classify(w))
        p = 0.9 if p == 1.0 else 0.1 if p == 0.0 else p
        return np.array([p, 1.0 - p])

    return [w for w, _ in reported(windows, ReturnFilter(SegmenterConfig().return_s), probs)]


def test_a_running_stroke_is_reported_early_only_when_sure_and_always_at_its_end(synth):
    windows = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)]))
    assert len(finals(windows)) == 1 and len(windows) > 1
    unsure = stroke.PARTIAL_P - 0.05
    assert [w.final for w in reported_windows(windows, lambda w: unsure)] == [True]
    sure = reported_windows(windows, lambda w: stroke.PARTIAL_P)
    assert sure == windows[1:]  # the first one sure alone, not yet confirmed by the next


def test_a_running_window_is_reported_only_when_the_one_before_read_the_same_gesture(synth):
    # One sure window alone is often a blip: a curving move, a preparation's first window.
    windows = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)]))
    running = [id(w) for w in windows if not w.final]
    assert len(running) >= 3

    def flickering(w):  # sure every time, but of swipe_up and swipe_down in turn
        up = running.index(id(w)) % 2 == 0 if not w.final else True
        return np.array([0.8, 0.1, 0.1] if up else [0.1, 0.8, 0.1])

    kept = [w for w, _ in reported(windows, ReturnFilter(1.5), flickering)]
    assert [w.final for w in kept] == [True]

    def settling(w):  # unsure swipe_down first, then sure swipe_up: confirmed from the third
        first = id(w) == running[0]
        return np.array([0.3, 0.6, 0.1] if first else [0.8, 0.1, 0.1])

    kept = [w for w, _ in reported(windows, ReturnFilter(1.5), settling)]
    assert kept == windows[2:]


def test_a_final_window_answers_for_its_stroke_with_its_surest_published_window(synth):
    # A final window that ends on the slowing hand often reads less sure than the stroke read
    # while it ran; a consumer taking one answer per stroke must not lose what it was told.
    windows = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)]))
    running = [id(w) for w in windows if not w.final]
    assert len(running) >= 3
    sure = {id(windows[1]): [0.95, 0.03, 0.02], id(windows[2]): [0.8, 0.1, 0.1]}

    def fading(w):  # swipe_up, surest in its second window; the final window reads none
        return np.array([0.2, 0.1, 0.7] if w.final else sure.get(id(w), [0.7, 0.1, 0.2]))

    answers = list(reported(windows, ReturnFilter(1.5), fading))
    assert answers[-1][0] is windows[-1] and answers[-1][0].final
    assert np.allclose(answers[-1][1], [0.95, 0.03, 0.02])
    assert [w for w, _ in answers] == windows[1:]  # still one final window, when it ends

    def surer_at_the_end(w):  # a final window surer than any before keeps its own answer
        return np.array([0.02, 0.97, 0.01] if w.final else sure.get(id(w), [0.7, 0.1, 0.2]))

    answers = list(reported(windows, ReturnFilter(1.5), surer_at_the_end))
    assert np.allclose(answers[-1][1], [0.02, 0.97, 0.01])

    def never_published(w):  # sure only in windows never published (unconfirmed): its own
        first = id(w) == running[0]
        return np.array([0.2, 0.1, 0.7] if not first else [0.95, 0.03, 0.02])

    answers = list(reported(windows, ReturnFilter(1.5), never_published))
    assert [w.final for w, _ in answers] == [True]
    assert np.allclose(answers[-1][1], [0.2, 0.1, 0.7])


def test_a_stroke_under_way_when_its_hand_appears_is_reported_early_only_when_very_sure(synth):
    # What a hand does first is often the move that brings it into the field, or a wind-up.
    windows = synth.feed(Segmenter(), synth.trajectory([SWIPE_UP, ("hold", 0.5)]))
    assert len(windows) > 1 and all(w.seen_s <= stroke.NEW_HAND_S for w in windows)
    fairly_sure = reported_windows(windows, lambda w: stroke.PARTIAL_P)
    assert [w.final for w in fairly_sure] == [True]
    assert reported_windows(windows, lambda w: stroke.NEW_HAND_P) == windows[1:]
    rested = synth.feed(Segmenter(), synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)]))
    assert all(w.seen_s > stroke.NEW_HAND_S for w in rested)
    assert reported_windows(rested, lambda w: stroke.PARTIAL_P) == rested[1:]


def test_the_slower_return_move_after_a_gesture_is_not_reported(synth):
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.4), ("move", 0.9, (0, -160, 0)),
                             ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert {w.stroke for w in finals(windows)} == {1, 2}  # the segmenter sees both moves
    kept = reported_windows(windows, classify=lambda w: w.stroke == 1)
    assert {w.stroke for w in kept} == {1}


def test_the_return_after_an_unsure_gesture_is_not_reported_even_when_it_looks_surer(synth):
    # Real swipes often come out unsure ("none" a little ahead); their return, never trained
    # as "none", looks like a sure swipe the other way.
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.4), ("move", 0.9, (0, -160, 0)),
                             ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    kept = reported_windows(windows, classify=lambda w: 0.35 if w.stroke == 1 else 0.9)
    assert {w.stroke for w in kept} == {1}


def test_the_return_after_a_gesture_reported_only_mid_stroke_is_not_reported(synth):
    # A real swipe often reads surest mid-stroke and "none" at its end (the end of a swipe
    # looks like the end of a return); the consumer was told of the swipe all the same.
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.4), ("move", 0.9, (0, -160, 0)),
                             ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert len([w for w in windows if w.stroke == 1 and not w.final]) > 1

    def swipe_sure_until_its_end(w):
        return (0.1 if w.final else stroke.PARTIAL_P) if w.stroke == 1 else 0.9

    kept = reported_windows(windows, classify=swipe_sure_until_its_end)
    assert {w.stroke for w in kept} == {1}
    # Mid-stroke windows too unsure to be reported do not make the stroke a gesture.
    kept = reported_windows(windows, classify=lambda w: 0.1 if w.stroke == 1 else 0.9)
    assert {w.stroke for w in kept} == {1, 2}


def test_a_swipe_the_hand_slowed_in_is_one_gesture_whose_return_comes_back_over_both(synth):
    # Up 100 mm, a slowing (50 ms still), on up 60 mm (two strokes), then back down 150 mm:
    # the return of the whole swipe, not a swipe down "twice as far" as the second stroke.
    traj = synth.trajectory([REST, ("move", 0.35, (0, 100, 0)), ("hold", 0.05),
                             ("move", 0.3, (0, 60, 0)), ("hold", 0.3),
                             ("move", 0.6, (0, -150, 0)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    ups = [w for w in finals(windows) if w.obs[-1, 1] > 0]
    assert len(ups) == 2 and ups[1].t_start - ups[0].t_end <= stroke.CONTINUE_GAP_S
    back = max(w.stroke for w in windows)
    kept = reported_windows(windows, classify=lambda w: 0.9)
    assert back not in {w.stroke for w in kept}
    # Had the first stroke been no gesture, the second alone is the gesture it reverses.
    kept = reported_windows(windows, classify=lambda w: 0.1 if w.stroke == ups[0].stroke
                            else 0.9)
    assert back in {w.stroke for w in kept}


def test_a_move_that_reverses_a_non_gesture_is_reported(synth):
    # A slow preparation downwards (classified "none"), then the swipe up.
    traj = synth.trajectory([REST, ("move", 1.0, (0, -80, 0)), ("hold", 0.2), SWIPE_UP,
                             ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    kept = reported_windows(windows, classify=lambda w: w.obs[-1, 1] > 100)
    assert any(w.final and w.obs[-1, 1] > 140 for w in kept)


def test_a_fast_stroke_from_anywhere_in_the_field_is_a_stroke(synth):
    start = synth.CENTRE + [150, -60, 80]
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.4)], start=start)
    (final,) = finals(synth.feed(Segmenter(), traj))
    assert 140 < final.obs[-1, 1] < 170


def test_with_the_centre_rule_a_motion_that_starts_outside_the_centre_is_not_a_stroke(synth):
    traj = synth.trajectory([REST, ("move", 0.45, (0, 0, 0))], start=synth.CENTRE + [150, 0, 0])
    traj += synth.trajectory([("move", 0.45, (0, 160, 0)), ("hold", 0.4)],
                             start=synth.CENTRE + [150, 0, 0])
    assert synth.feed(Segmenter(SegmenterConfig(centre_rule=True)), traj) == []


def test_with_the_centre_rule_a_hand_that_reaches_the_centre_while_moving_is_not_armed(synth):
    enter = synth.trajectory([("move", 0.6, -np.array([40.0, -40.0, 300.0])), ("hold", 1.0)],
                             start=synth.CENTRE + [40.0, -40.0, 300.0])
    assert synth.feed(Segmenter(SegmenterConfig(centre_rule=True)), enter) == []


def test_a_hand_that_turns_back_without_stopping_ends_the_stroke_at_its_farthest_point(synth):
    traj = synth.trajectory([REST, ("move", 0.4, (0, 160, 0)), ("move", 0.4, (0, -160, 0)),
                             ("hold", 0.5)])
    # A long end hold: the brief stop at the top does not end the stroke, the turn does.
    windows = synth.feed(Segmenter(SegmenterConfig(end_hold_s=0.3, end_fraction=0.0)), traj)
    first, second = finals(windows)
    assert first.ended == "turned" and 140 < first.obs[-1, 1] <= 161
    assert second.obs[-1, 1] < -120  # the move back is a stroke of its own, from the top


def test_the_roll_of_an_upright_hand_is_measured_about_its_direction():
    # Fingers up, palm towards -z (a hand held before a camera): turned 30° about +y.
    up = [0.0, 1.0, 0.0]
    before, after = [0.0, 0.0, -1.0], [-math.sin(math.radians(30)), 0.0, -math.cos(
        math.radians(30))]
    assert abs(abs(roll_increment(before, after, up)) - math.radians(30)) < 1e-6
    assert roll_increment(before, after, up, "left") == -roll_increment(before, after, up)


def test_a_stroke_ends_when_the_hand_falls_well_below_its_peak_speed_despite_jitter(synth):
    # Depth-camera skeletons jitter at 100-200 mm/s: the absolute end threshold is never met.
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 1.5)], tremor=10.0, seed=2)
    assert finals(synth.feed(Segmenter(SegmenterConfig(end_fraction=0.0)), traj)) == []
    first = finals(synth.feed(Segmenter(), traj))[0]
    assert first.ended == "slowed" and first.t_end - first.t_start < 1.0
    assert 130 < first.obs[-1, 1] < 180


BRISK_FIRST = [REST, ("move", 0.4, (150, 0, 0)), ("hold", 0.5)]  # a swipe: the hand's first
ONE_LINE = SegmenterConfig(first_peak_speed_mm_s=200.0)  # every stroke judged as a later one


def test_a_slow_move_after_the_hands_first_stroke_is_not_evaluated(synth):
    slow = synth.trajectory([*BRISK_FIRST, ("move", 1.0, (0, 100, 0)), ("hold", 0.5)])
    windows = finals(synth.feed(Segmenter(), slow))  # the slow move: 182 mm/s in a tenth
    assert [w.stroke for w in windows] == [1]
    lower = SegmenterConfig(min_peak_speed_mm_s=50.0)
    assert [w.stroke for w in finals(synth.feed(Segmenter(lower), slow))] == [1, 2]


def test_a_hands_first_stroke_is_heard_down_to_the_first_line_once_the_hand_rests(synth):
    # A person raises a hand, holds it still and draws a line in the air: 100 mm in 1 s
    drawn = synth.trajectory([REST, ("move", 1.0, (100, 0, 0)), ("hold", 1.2)])
    (window,) = finals(synth.feed(Segmenter(), drawn))
    assert window.t_end < drawn[-1][0] - stroke.PENDING_S  # held back until the hand rested
    assert synth.feed(Segmenter(ONE_LINE), drawn) == []
    creeping = synth.trajectory([REST, ("move", 2.0, (100, 0, 0)), ("hold", 1.2)])  # 94 mm/s
    assert synth.feed(Segmenter(), creeping) == []


def test_a_slow_first_stroke_goes_out_when_the_hand_leaves(synth):
    drawn = synth.trajectory([REST, ("move", 1.0, (100, 0, 0)), ("hold", 0.3)])
    segmenter = Segmenter()
    assert synth.feed(segmenter, drawn) == []
    assert len(finals(segmenter.update(drawn[-1][0] + 0.05, []))) == 1


def test_a_slow_first_stroke_before_a_much_faster_one_was_its_preparation(synth):
    # the slow move to the swipe's start, a short rest, then the brisk swipe back
    moves = synth.trajectory([REST, ("move", 1.0, (100, 0, 0)), ("hold", 0.4),
                              ("move", 0.3, (-200, 0, 0)), ("hold", 1.2)])
    windows = finals(synth.feed(Segmenter(), moves))
    assert len(windows) == 1 and windows[0].obs[-1, 0] < -150


def test_a_slow_first_stroke_goes_out_before_a_slower_return(synth):
    moves = synth.trajectory([REST, ("move", 1.0, (100, 0, 0)), ("hold", 0.3),
                              ("move", 1.2, (-100, 0, 0)), ("hold", 1.2)])
    windows = finals(synth.feed(Segmenter(ONE_LINE), moves))
    assert windows == []  # neither is more than a slow move by the usual line
    windows = finals(synth.feed(Segmenter(), moves))
    assert windows and windows[0].obs[-1, 0] > 80  # the line drawn, out first


def test_a_brisk_move_below_the_running_threshold_is_evaluated_only_at_its_end(synth):
    brisk = synth.trajectory([REST, ("move", 0.75, (0, 100, 0)), ("hold", 0.5)])  # 250 mm/s
    windows = synth.feed(Segmenter(SegmenterConfig(mid_peak_speed_mm_s=300.0)), brisk)
    assert len(windows) == 1 and windows[0].final
    running = synth.feed(Segmenter(SegmenterConfig(mid_peak_speed_mm_s=200.0)), brisk)
    assert len(running) > 1 and not running[0].final


def test_a_slow_move_with_a_tremor_is_not_evaluated_though_its_top_speed_passes(synth,
                                                                                monkeypatch):
    # 190 mm in 2 s (178 mm/s at most), a tremor of 2 mm: a few samples pass 200 mm/s
    slow = synth.trajectory([REST, ("move", 2.0, (-190, 0, 0)), REST], tremor=2.0, seed=0)
    assert synth.feed(Segmenter(ONE_LINE), slow) == []
    monkeypatch.setattr(stroke, "FAST_PERCENTILE", 100.0)  # the top speed, as before
    assert finals(synth.feed(Segmenter(ONE_LINE), slow))


def test_a_slow_move_whose_palm_rolls_fast_is_a_rotate_candidate_only_if_mostly_roll(synth):
    # 120 mm at 188 mm/s peak, the palm rolling 90° back at 140°/s peak (k*roll 79 mm)
    back = synth.trajectory([REST, ("moveroll", 1.2, (-120, 0, 0), math.radians(90)),
                             ("hold", 0.5)])
    assert synth.feed(Segmenter(ONE_LINE), back) == []
    twist = synth.trajectory([REST, ("moveroll", 1.2, (-30, 0, 0), math.radians(90)),
                              ("hold", 0.5)])
    assert finals(synth.feed(Segmenter(), twist))


def test_a_still_hand_with_tremor_never_starts_a_stroke(synth):
    still = synth.trajectory([("hold", 6.0)], tremor=1.5, seed=3)
    assert synth.feed(Segmenter(), still) == []


def test_a_palm_roll_in_place_is_a_stroke_seen_in_the_roll_dimension(synth):
    windows = synth.feed(Segmenter(), synth.trajectory([REST, ("roll", 0.6, math.radians(90)),
                                                        ("hold", 0.5)]))
    (final,) = finals(windows)
    assert np.abs(final.obs[-1, :3]).max() < 2.0
    k = SegmenterConfig().roll_scale_mm_per_rad
    assert abs(abs(final.obs[-1, 3]) - k * math.radians(90)) < 0.1 * k


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
    with pytest.raises(ConfigError, match="jump_mm_s=-1"):
        SegmenterConfig(jump_mm_s=-1.0)


def test_a_much_faster_move_back_after_an_unsure_gesture_is_reported(synth):
    # The first move was slow (a preparation the classifier half took for a gesture); the
    # second, much faster, is the real stroke.
    traj = synth.trajectory([REST, ("move", 0.7, (0, -120, 0)), ("hold", 0.3),
                             ("move", 0.2, (0, 160, 0)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    kept = reported_windows(windows, classify=lambda w: 0.6)
    assert any(w.final and w.obs[-1, 1] > 140 for w in kept)
    # after a sure gesture, the same move back is its return
    kept = reported_windows(windows, classify=lambda w: 0.95)
    assert not any(w.final and w.obs[-1, 1] > 140 for w in kept)


def test_a_move_back_much_farther_than_a_sure_gesture_is_reported_one_as_far_is_its_return(
        synth):
    # A quick 60 mm preparation down, taken for a sure swipe down, then the 160 mm swipe up at
    # the same pace: it goes farther than twice the preparation, so it is the gesture.
    traj = synth.trajectory([REST, ("move", 0.2, (0, -60, 0)), ("hold", 0.3),
                             ("move", 0.45, (0, 160, 0)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    kept = reported_windows(windows, classify=lambda w: 0.95)
    assert any(w.final and w.obs[-1, 1] > 140 for w in kept)
    # a move back as far as the swipe, as fast, after a sure swipe: its return
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.3), ("move", 0.45, (0, -160, 0)),
                             ("hold", 0.5)])
    kept = reported_windows(synth.feed(Segmenter(), traj), classify=lambda w: 0.95)
    assert [w.stroke for w in kept if w.final] == [1]


@pytest.mark.parametrize(("delta", "previous", "back"), [
    ((0, -70, 0, -15), (0, 80, 0, 20), True),      # a swipe's return, its roll coming back too
    ((0, 0, 0, 30), (0, 80, 0, -20), True),        # the swipe's roll alone coming back
    ((-3, -2, -3, -99), (0, 78, 0, 19), False),    # a rotate, five times the swipe's roll
    ((3, 2, 0, 85), (1, -4, 2, -85), True),        # a rotate's roll coming back
    ((71, -2, 0, 35), (-1, 4, -2, -85), False),    # a swipe after a rotate moves anew
    ((-60, 0, 0), (80, 0, 0), True),               # in space alone (no roll given)
])
def test_a_return_retraces_what_the_gesture_did(delta, previous, back):
    assert stroke.reverses(np.array(delta, float), np.array(previous, float)) is back


def test_a_rotate_soon_after_a_swipe_whose_palm_rolled_the_other_way_is_reported(synth):
    # The swipe up rolls the palm 30° as it goes; 0.5 s later the palm turns 110° back: more
    # than the swipe's roll could return, so it is a rotate, not the swipe's return (with the
    # roll counted in one vector with the move, the two pointed 105° apart).
    traj = synth.trajectory([REST, ("moveroll", 0.35, (0, 100, 0), math.radians(30)),
                             ("hold", 0.5), ("roll", 0.5, math.radians(-110)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert len(finals(windows)) == 2
    kept = reported_windows(windows, classify=lambda w: True)
    assert [w.stroke for w in kept if w.final] == [1, 2]
    # rolled back only as far as the swipe rolled, it is the swipe's return
    traj = synth.trajectory([REST, ("moveroll", 0.45, (0, 160, 0), math.radians(60)),
                             ("hold", 0.5), ("roll", 0.5, math.radians(-60)), ("hold", 0.5)])
    kept = reported_windows(synth.feed(Segmenter(), traj), classify=lambda w: True)
    assert [w.stroke for w in kept if w.final] == [1]


def test_a_stroke_cut_short_by_the_hand_leaving_after_a_gesture_is_its_return(synth):
    segmenter = Segmenter()
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.3), ("move", 0.2, (0, -160, 0))])
    windows = synth.feed(segmenter, traj[:-4])
    windows += segmenter.update(traj[-4][0], [])  # gone mid-way back, fast
    kept = reported_windows(windows, classify=lambda w: True)
    assert [w.stroke for w in kept if w.final] == [1]


def test_a_stroke_soon_after_another_never_reaches_back_into_it(synth):
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.15), ("move", 0.45, (160, 0, 0)),
                             ("hold", 0.5)], tremor=4.0, seed=1)
    first, second = finals(synth.feed(Segmenter(), traj))
    assert second.t_start >= first.t_end
    assert abs(second.obs[-1, 1]) < 30 and second.obs[-1, 0] > 130


def test_a_spike_out_and_back_is_two_jumps_that_leave_the_path_where_it_was(synth):
    traj = synth.trajectory([("hold", 2.0)], rate=30.0)
    spike = [(t, p + ((0, 100, 0) if i == 30 else 0.0), r) for i, (t, p, r) in enumerate(traj)]
    segmenter = Segmenter()
    assert synth.feed(segmenter, spike) == []
    assert segmenter.jumps == 2
    assert np.abs(segmenter.tracks[1].jumped).max() < 1e-9  # the way back undid the way out


def test_a_jump_inside_a_swipe_is_taken_out_of_it(synth):
    traj = synth.jumped(synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)], rate=30.0), 0.7,
                  (100, 0, -80))
    segmenter = Segmenter()
    (final,) = finals(synth.feed(segmenter, traj))
    assert segmenter.jumps == 1 and 140 < final.obs[-1, 1] < 175
    assert np.abs(final.obs[-1, [0, 2]]).max() < 10  # the swipe as made, not bent by the jump
    bent = finals(synth.feed(Segmenter(SegmenterConfig(jump_mm_s=0)), traj))[0]
    assert np.abs(bent.obs[-1, [0, 2]]).max() > 50  # without the rule


@pytest.mark.parametrize("rate", [30.0, 60.0, 120.0])
def test_a_fast_swipe_is_no_jump(synth, rate):
    # 300 mm in 0.3 s: a peak of 1875 mm/s, faster than 99 % of SHREC'17's frame steps.
    traj = synth.trajectory([REST, ("move", 0.3, (300, 0, 0)), ("hold", 0.5)], rate=rate)
    segmenter = Segmenter()
    (final,) = finals(synth.feed(segmenter, traj))
    assert segmenter.jumps == 0 and 280 < final.obs[-1, 0] < 310


def test_a_hand_that_enters_fast_is_no_jump(synth):
    enter = synth.trajectory([("move", 0.4, (0, 0, -400)), ("hold", 0.5)], rate=60.0,
                             start=synth.CENTRE + [0, 0, 200])
    segmenter = Segmenter()
    synth.feed(segmenter, enter[5:])  # first seen while moving at full speed
    assert segmenter.jumps == 0


def test_a_frame_stamped_like_the_one_before_is_no_jump(synth):
    # A frame mid-swipe that moved with no time passed (a bridge that stamped it twice).
    traj = synth.trajectory([REST, SWIPE_UP, ("hold", 0.5)], rate=120.0)
    i = 86  # 0.72 s: the swipe at its fastest
    stamped = traj[:i] + [(traj[i - 1][0], *traj[i][1:])] + traj[i + 1:]
    segmenter = Segmenter()
    (final,) = finals(synth.feed(segmenter, stamped))
    assert segmenter.jumps == 0 and 140 < final.obs[-1, 1] < 170


def test_a_gesture_has_one_return_and_a_swipe_after_it_is_a_gesture(synth):
    # Swipe right, come back at once, then swipe left 0.4 s later: still within return_s of
    # the swipe right, but its return has already come back, so the swipe left is reported.
    swipe, back = ("move", 0.35, (160, 0, 0)), ("move", 0.35, (-150, 0, 0))
    traj = synth.trajectory([REST, swipe, ("hold", 0.15), back, ("hold", 0.4),
                             ("move", 0.35, (-160, 0, 0)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert len(finals(windows)) == 3
    kept = reported_windows(windows, classify=lambda w: 0.95)
    assert [w.stroke for w in kept if w.final] == [1, 3]
    # A return made in two parts, the second right after the first: both are the return.
    traj = synth.trajectory([REST, swipe, ("hold", 0.15), back, ("hold", 0.15),
                             ("move", 0.3, (-100, 0, 0)), ("hold", 0.5)])
    windows = synth.feed(Segmenter(), traj)
    assert len(finals(windows)) == 3
    kept = reported_windows(windows, classify=lambda w: 0.95)
    assert [w.stroke for w in kept if w.final] == [1]
