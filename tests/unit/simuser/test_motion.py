"""Palm trajectories: minimum-jerk moves, field visibility, tremor, dropouts, keyframes."""

import numpy as np

from cbgo.simuser.motion import (
    CENTRE_MM,
    ENTRY_MM,
    TimelineBuilder,
    in_field,
    min_jerk,
    tremor,
)


def test_minimum_jerk_starts_and_ends_at_rest():
    s = np.linspace(0, 1, 101)
    x = min_jerk(s)
    assert x[0] == 0 and x[-1] == 1
    v = np.gradient(x, s)
    assert abs(v[0]) < 1e-3 and abs(v[-1]) < 1e-3
    assert abs(v[50] - 1.875) < 1e-3  # peak speed of the minimum-jerk profile


def test_the_sensor_sees_only_hands_inside_its_field():
    points = np.array([CENTRE_MM, ENTRY_MM, [0, 30, 0], [0, 600, 0], [300, 200, 0]])
    assert in_field(points).tolist() == [True, False, False, False, False]


def test_tremor_has_the_requested_rms_amplitude():
    noise = tremor(6000, 100.0, 1.0, np.random.default_rng(0))
    rms = np.sqrt((noise**2).mean(axis=0))
    assert np.all((rms > 1.0) & (rms < 2.5))  # 1 mm tremor plus a 2 mm slow drift


def test_a_hand_entering_becomes_visible_at_the_field_border_and_reaches_the_centre():
    b = TimelineBuilder(60.0, ENTRY_MM, "neutral")
    b.hidden(0.5)
    b.move_to(CENTRE_MM, 0.6, "enter")
    b.hold(0.5, "prepare")
    tl = b.build(0.0, np.random.default_rng(0))
    assert len(tl) == 30 + 36 + 30
    assert not tl.visible[:30].any()
    first_seen = int(np.argmax(tl.visible))
    assert 30 < first_seen < 66
    assert tl.visible[first_seen:].all()
    assert np.allclose(tl.palm[-1], CENTRE_MM)


def test_a_swipe_is_bowed_sideways_and_ends_on_target():
    b = TimelineBuilder(100.0, CENTRE_MM, "neutral")
    target = CENTRE_MM + [160.0, 0, 0]
    b.move_to(target, 0.5, "stroke", "swipe_right", bow=[0.0, 12.0, 0.0])
    tl = b.build(0.0, np.random.default_rng(0))
    assert np.allclose(tl.palm[-1], target)
    assert abs(tl.palm[:, 1].max() - CENTRE_MM[1] - 12.0) < 0.2
    assert set(tl.label) == {"swipe_right"}
    speed = np.linalg.norm(tl.velocity(), axis=1)
    assert speed.argmax() in range(15, 35)  # bell-shaped: fastest mid-stroke


def test_dropout_frames_are_hidden_and_keyframes_blend_linearly():
    b = TimelineBuilder(10.0, CENTRE_MM, 0.0)
    b.hold(1.0, "pose")
    b.key_pose(10.0)
    b.hide_frames(3, 1)
    tl = b.build(0.0, np.random.default_rng(0))
    assert tl.visible.tolist() == [True, True, True, False] + [True] * 6
    assert tl.pose_at(5, lambda a, c, t: a + (c - a) * t) == 5.0
