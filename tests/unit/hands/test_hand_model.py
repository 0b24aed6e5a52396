"""The kinematic hand model builds valid, anatomically consistent contract hands."""

from __future__ import annotations

import numpy as np
import pytest

from cbgo import wire
from cbgo.hands import features as F
from cbgo.hands.features import quaternion_z_axis
from cbgo.hands.model import (
    JOINT_LIMITS,
    N_JOINT_PARAMS,
    PARAM_NAMES,
    HandPose,
    HandShape,
    blend,
    build_hand,
    build_hands,
    mirrored_hand,
    neutral_pose,
)
from cbgo.hands.poses import STATIC_GESTURES, gesture_mean, gesture_pose

PALM = (10.0, 220.0, -5.0)


def frame_of(hands: list[dict]) -> dict:
    return {"v": 1, "ts": 1.0, "seq": 1, "source": "simulated", "device": "test",
            "hands": hands}


def joints(hand: dict) -> np.ndarray:
    """(5, 4, 2, 3): finger, bone, prev/next, xyz."""
    return np.array([[[b["prev_joint"], b["next_joint"]] for b in f["bones"]]
                     for f in hand["fingers"]])


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("scale", [0.85, 1.0, 1.15])
def test_every_gesture_builds_a_frame_that_passes_the_wire_schema(side, scale):
    rng = np.random.default_rng(0)
    shape = HandShape.sample(rng, scale=scale, side=side)
    hands = [build_hand(shape, gesture_pose(g, rng), PALM, (1.0, -2.0, 3.0), hand_id=i)
             for i, g in enumerate(STATIC_GESTURES)]
    hands.append(build_hand(shape, neutral_pose(), PALM))
    wire.validate(frame_of(hands), wire.HANDS_FRAME)
    assert all(h["side"] == side and h["palm_position"] == list(PALM) for h in hands)
    assert hands[0]["palm_velocity"] == [1.0, -2.0, 3.0]


def test_bone_lengths_equal_the_shape_and_the_thumb_metacarpal_has_zero_length():
    shape = HandShape.sample(np.random.default_rng(4), side="left")
    hand = build_hand(shape, gesture_pose("pinch", np.random.default_rng(5)), PALM)
    j = joints(hand)
    lengths = np.linalg.norm(j[:, :, 1] - j[:, :, 0], axis=-1)
    assert lengths == pytest.approx(shape.bone_lengths, abs=1e-9)
    assert lengths[0, 0] == 0.0
    assert np.all(j[:, 1:, 0] == j[:, :-1, 1])  # each bone starts where the previous ends
    assert hand["fingers"][0]["bones"][0]["rotation"] is not None


def test_every_bone_rotation_is_a_unit_quaternion_whose_minus_z_is_the_bone_direction():
    hand = build_hand(HandShape.default(side="right"), gesture_mean("thumbsup"), PALM)
    for f, finger in enumerate(hand["fingers"]):
        for b, bone in enumerate(finger["bones"]):
            q = np.array(bone["rotation"])
            assert np.linalg.norm(q) == pytest.approx(1.0)
            if (f, b) == (0, 0):
                continue  # zero length: its rotation is all there is
            d = np.subtract(bone["next_joint"], bone["prev_joint"])
            assert -quaternion_z_axis(q) == pytest.approx(d / np.linalg.norm(d), abs=1e-9)


def test_palm_normal_and_direction_are_orthonormal_and_follow_the_orientation():
    ref = build_hand(HandShape.default(), HandPose(), PALM)
    assert ref["palm_normal"] == pytest.approx([0.0, -1.0, 0.0])
    assert ref["direction"] == pytest.approx([0.0, 0.0, -1.0])
    lifted = build_hand(HandShape.default(), HandPose().rotated(pitch=0.4), PALM)
    assert lifted["direction"] == pytest.approx([0.0, np.sin(0.4), -np.cos(0.4)])
    hand = build_hand(HandShape.default(), gesture_mean("four"), PALM)
    n, d = np.array(hand["palm_normal"]), np.array(hand["direction"])
    assert np.linalg.norm(n) == pytest.approx(1.0) and np.linalg.norm(d) == pytest.approx(1.0)
    assert n @ d == pytest.approx(0.0, abs=1e-12)


def test_negative_roll_raises_the_thumb_side_on_both_hands():
    for side in ("left", "right"):
        hand = build_hand(HandShape.default(side=side), HandPose(roll=-np.pi / 2), PALM)
        thumb_tip = np.array(hand["fingers"][0]["bones"][3]["next_joint"])
        pinky_tip = np.array(hand["fingers"][4]["bones"][3]["next_joint"])
        assert thumb_tip[1] > PALM[1] + 20.0 > pinky_tip[1] + 20.0


def test_a_left_hand_is_the_mirror_image_of_the_right_hand():
    pose = gesture_pose("three", np.random.default_rng(2))
    right = build_hand(HandShape.default(side="right"), pose, PALM)
    left = build_hand(HandShape.default(side="left"), pose, PALM)
    mirrored = joints(right).copy()
    mirrored[..., 0] = 2 * PALM[0] - mirrored[..., 0]
    assert joints(left) == pytest.approx(mirrored)
    assert F.hand_features(left) == pytest.approx(F.mirror_features(F.hand_features(right)))
    assert left["grab_strength"] == right["grab_strength"]



def test_a_mirrored_hand_is_the_other_hand_built_in_the_mirrored_place():
    pose = gesture_pose("thumbsup", np.random.default_rng(3))
    right = build_hand(HandShape.default(side="right"), pose, PALM, (300.0, -20.0, 5.0))
    left = build_hand(HandShape.default(side="left"), pose, (-PALM[0], *PALM[1:]),
                      (-300.0, -20.0, 5.0))
    again = mirrored_hand(right)
    wire.validate(frame_of([again]), wire.HANDS_FRAME)
    twice = mirrored_hand(again)
    assert again["side"] == "left" and twice["side"] == "right"
    assert joints(twice) == pytest.approx(joints(right))
    for key in ("palm_position", "palm_velocity", "palm_normal", "direction",
                "wrist_position"):
        assert again[key] == pytest.approx(left[key]), key
    assert joints(again) == pytest.approx(joints(left))
    for f_again, f_left in zip(again["fingers"], left["fingers"], strict=True):
        for b_again, b_left in zip(f_again["bones"], f_left["bones"], strict=True):
            q, p = np.array(b_again["rotation"]), np.array(b_left["rotation"])
            assert min(np.abs(q - p).max(), np.abs(q + p).max()) < 1e-6  # q and -q: one turn


def test_grab_strength_is_high_for_grab_and_low_for_five_and_pinch_strength_high_for_pinch():
    rng = np.random.default_rng(7)
    built = {g: [build_hand(HandShape.sample(rng), gesture_pose(g, rng), PALM)
                 for _ in range(40)] for g in ("grab", "five", "pinch")}
    strength = {g: {k: np.array([h[f"{k}_strength"] for h in hands]) for k in ("grab", "pinch")}
                for g, hands in built.items()}
    assert strength["grab"]["grab"].min() > 0.55
    assert strength["five"]["grab"].max() < 0.15
    assert np.median(strength["pinch"]["pinch"]) > 0.8 and strength["pinch"]["pinch"].min() > 0.5
    assert strength["five"]["pinch"].max() < 0.1


def test_joint_angles_beyond_the_limits_are_clipped_before_building():
    wild = HandPose.from_vector(np.r_[np.full(N_JOINT_PARAMS, 3.0), 0.1, 0.2, 0.3])
    clipped = wild.clipped()
    v = clipped.to_vector()
    assert v[:N_JOINT_PARAMS] == pytest.approx(JOINT_LIMITS[:, 1])
    assert (v[-3:] == [0.1, 0.2, 0.3]).all()  # orientation is not a joint
    shape = HandShape.default()
    assert build_hand(shape, wild, PALM) == build_hand(shape, clipped, PALM)


def test_sampled_poses_respect_the_joint_limits_even_with_large_variation():
    rng = np.random.default_rng(11)
    for g in STATIC_GESTURES:
        for _ in range(30):
            v = gesture_pose(g, rng, variation=4.0).to_vector()[:N_JOINT_PARAMS]
            assert np.all(v >= JOINT_LIMITS[:, 0]) and np.all(v <= JOINT_LIMITS[:, 1])


def test_blend_returns_the_endpoints_and_interpolates_linearly_in_between():
    a, b = neutral_pose(), gesture_mean("grab")
    assert blend(a, b, 0.0) == a
    assert blend(a, b, 1.0).to_vector() == pytest.approx(b.to_vector())
    mid = blend(a, b, 0.25).to_vector()
    assert mid == pytest.approx(0.75 * a.to_vector() + 0.25 * b.to_vector())


def test_pose_vectors_round_trip_in_param_names_order():
    v = np.arange(len(PARAM_NAMES), dtype=float) / 100.0
    pose = HandPose.from_vector(v)
    assert pose.to_vector() == pytest.approx(v)
    assert pose.thumb[0] == v[PARAM_NAMES.index("thumb_cmc_flex")]
    assert pose.pip[2] == v[PARAM_NAMES.index("ring_pip")]
    assert pose.yaw == v[PARAM_NAMES.index("yaw")]


def test_sampled_users_vary_in_size_within_the_requested_range():
    rng = np.random.default_rng(3)
    base = HandShape.default().bone_lengths.sum()
    sizes = [HandShape.sample(rng).bone_lengths.sum() / base for _ in range(200)]
    assert 0.8 < min(sizes) < 0.9 and 1.1 < max(sizes) < 1.2
    assert HandShape.sample(rng, scale=1.0).scale == HandShape.default().scale
    with pytest.raises(ValueError, match="side"):
        HandShape(side="middle")


def test_building_many_hands_at_once_equals_building_them_one_by_one():
    rng = np.random.default_rng(9)
    shapes = [HandShape.sample(rng, side=s) for s in ("left", "right", "left")]
    poses = [gesture_pose(g, rng) for g in ("point", "two", "thumbsup")]
    palms = rng.uniform(-50, 50, size=(3, 3)) + [0, 200, 0]
    batch = build_hands(shapes, poses, palms, hand_ids=[4, 5, 6])
    for i in range(3):
        assert batch[i] == build_hand(shapes[i], poses[i], palms[i], hand_id=4 + i)
