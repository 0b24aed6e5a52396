"""The 57 features, pinned on tiny hands whose values are worked out by hand.

Conventions being pinned (cbgo.hands.features): pitch = asin(-d_y), yaw = atan2(d_x, d_z); a
bone's direction is unit(prev_joint - next_joint) (the recordings' tip-to-base convention);
feature = previous angles minus this bone's angles, yaw not unwrapped.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cbgo import wire
from cbgo.hands import features as F
from cbgo.hands.data import load_real_features

PI = math.pi


def straight_chain(x: float, length: float = 10.0) -> list[list[float]]:
    """Five joints (metacarpal start .. tip) along -z from (x, 0, 0)."""
    return [[x, 0.0, -length * k] for k in range(5)]


def tiny_hand(chains=None, direction=(0.0, 0.0, -1.0), wrist=(0.0, 0.0, 50.0), side="left",
              thumb_rotation=(0.0, 0.0, 0.0, 1.0)) -> dict:
    """A contract hand with the palm at the origin; the thumb's metacarpal has zero length."""
    if chains is None:
        chains = [straight_chain(20.0 * f) for f in range(5)]
    fingers = []
    for f, ftype in enumerate(wire.FINGER_TYPES):
        joints = [list(map(float, j)) for j in chains[f]]
        if f == 0:
            joints[1] = joints[0]  # zero-length thumb metacarpal, as in the Leap SDK
        bones = [{"type": b, "prev_joint": joints[i], "next_joint": joints[i + 1], "width": 15.0}
                 for i, b in enumerate(wire.BONE_TYPES)]
        if f == 0 and thumb_rotation is not None:
            bones[0]["rotation"] = list(thumb_rotation)
        fingers.append({"type": ftype, "bones": bones})
    return {"id": 1, "side": side, "confidence": 1.0, "palm_position": [0.0, 0.0, 0.0],
            "palm_velocity": [0.0, 0.0, 0.0], "palm_normal": [0.0, -1.0, 0.0],
            "direction": list(direction), "wrist_position": list(wrist), "palm_width": 80.0,
            "grab_strength": 0.0, "pinch_strength": 0.0, "fingers": fingers}


def bone(finger: int, bone_index: int) -> tuple[int, int]:
    """(pitch, yaw) feature indices of a bone: 2 + 2·(4·finger + bone)."""
    i = 2 + 2 * (4 * finger + bone_index)
    return i, i + 1


def test_the_tiny_hands_are_valid_contract_hands():
    frame = {"v": 1, "ts": 1.0, "seq": 0, "source": "simulated", "device": "test",
             "hands": [tiny_hand(), tiny_hand(thumb_rotation=None, side="right")]}
    wire.validate(frame, wire.HANDS_FRAME)


def test_feature_names_are_57_readable_names_in_definition_order():
    names = F.FEATURE_NAMES
    assert len(names) == 57 == len(set(names))
    assert names[:2] == ("wrist_dpitch", "wrist_dyaw")
    assert names[bone(1, 1)[1]] == "index_proximal_dyaw"
    assert names[bone(0, 0)[0]] == "thumb_metacarpal_dpitch"
    assert names[41] == "pinky_distal_dyaw"
    assert names[42] == "dist_thumb_index" and names[46] == "dist_thumb_palm"
    assert names[47] == "dist_index_middle" and names[56] == "dist_pinky_palm"


def test_a_flat_straight_hand_has_metacarpals_half_a_turn_from_the_hand_direction():
    f = F.hand_features(tiny_hand())
    # palm - wrist = (0,0,-50): pitch 0, yaw atan2(0,-1) = π, the same as the direction.
    assert f[0] == pytest.approx(0.0) and f[1] == pytest.approx(0.0)
    for finger in range(5):
        # A bone along -z has the tip-to-base direction (0,0,1): pitch 0, yaw 0, so
        # direction (0, π) minus (0, 0) is (0, π); the thumb's comes from its identity rotation.
        assert f[list(bone(finger, 0))] == pytest.approx([0.0, PI])
        for b in (1, 2, 3):
            assert f[list(bone(finger, b))] == pytest.approx([0.0, 0.0])


def test_a_proximal_bent_straight_down_gives_plus_half_pi_of_pitch():
    chains = [straight_chain(20.0 * f) for f in range(5)]
    chains[1] = [[20, 0, 0], [20, 0, -10], [20, -10, -10], [20, -20, -10], [20, -30, -10]]
    f = F.hand_features(tiny_hand(chains))
    # Proximal: prev - next = (0,10,0) → (0,1,0): pitch asin(-1) = -π/2, yaw atan2(0,0) = 0.
    # Feature: metacarpal (0, 0) minus (-π/2, 0).
    assert f[list(bone(1, 1))] == pytest.approx([PI / 2, 0.0])
    assert f[list(bone(1, 2))] == pytest.approx([0.0, 0.0])  # intermediate continues down
    assert f[list(bone(1, 3))] == pytest.approx([0.0, 0.0])


def test_a_proximal_turned_30_degrees_towards_plus_x_gives_plus_pi_over_6_of_yaw():
    s, c = 0.5, math.sqrt(3) / 2
    knuckle = np.array([20.0, 0.0, -10.0])
    step = 10.0 * np.array([s, 0.0, -c])
    chain = [[20.0, 0.0, 0.0]] + [list(knuckle + k * step) for k in range(4)]
    chains = [straight_chain(20.0 * f) for f in range(5)]
    chains[1] = chain
    f = F.hand_features(tiny_hand(chains))
    # Proximal tip-to-base direction (-1/2, 0, √3/2): yaw atan2(-1/2, √3/2) = -π/6.
    assert f[list(bone(1, 1))] == pytest.approx([0.0, PI / 6])
    assert f[list(bone(1, 2))] == pytest.approx([0.0, 0.0])


def test_lifting_the_hand_direction_by_alpha_gives_minus_alpha_on_every_metacarpal():
    alpha = 0.3
    direction = (0.0, math.sin(alpha), -math.cos(alpha))
    f = F.hand_features(tiny_hand(direction=direction))
    # Direction: pitch asin(-sin α) = -α, yaw π; wrist vector (0,0,-1): pitch 0, yaw π.
    assert f[:2] == pytest.approx([alpha, 0.0])
    for finger in range(1, 5):
        assert f[list(bone(finger, 0))] == pytest.approx([-alpha, PI])


def test_yaw_differences_jump_by_almost_two_pi_when_the_direction_crosses_minus_z():
    eps = 0.1
    right = F.hand_features(tiny_hand(direction=(math.sin(eps), 0.0, -math.cos(eps))))
    left = F.hand_features(tiny_hand(direction=(-math.sin(eps), 0.0, -math.cos(eps))))
    # Direction yaw: atan2(±sin ε, -cos ε) = ±(π - ε); bones' yaw 0; wrist vector's yaw π.
    assert right[bone(2, 0)[1]] == pytest.approx(PI - eps)
    assert left[bone(2, 0)[1]] == pytest.approx(-PI + eps)
    assert right[1] == pytest.approx(eps)
    assert left[1] == pytest.approx(2 * PI - eps)  # not unwrapped
    assert right[bone(2, 0)[1]] - left[bone(2, 0)[1]] == pytest.approx(2 * PI - 2 * eps)


def test_distances_follow_itertools_combinations_order_of_tips_then_palm():
    xs = [1.0, 2.0, 4.0, 8.0, 16.0]  # tips at x = 2^f, palm at the origin: all gaps differ
    chains = [[[x, 0.0, 40.0 - 10.0 * k] for k in range(5)] for x in xs]
    f = F.hand_features(tiny_hand(chains))
    expected = [1, 3, 7, 15, 1,   # thumb to index, middle, ring, pinky, palm
                2, 6, 14, 2,      # index to middle, ring, pinky, palm
                4, 12, 4,         # middle to ring, pinky, palm
                8, 8,             # ring to pinky, palm
                16]               # pinky to palm
    assert f[42:] == pytest.approx(expected)


def test_the_zero_length_thumb_metacarpal_takes_its_direction_from_its_rotation():
    # 60° about x, q = (sin 30°, 0, 0, cos 30°): the basis z axis is (0, -sin 60°, cos 60°):
    # pitch asin(sin 60°) = π/3, yaw atan2(0, 1/2) = 0.
    f = F.hand_features(tiny_hand(thumb_rotation=(0.5, 0.0, 0.0, math.sqrt(3) / 2)))
    assert f[list(bone(0, 0))] == pytest.approx([-PI / 3, PI])
    # The thumb proximal (along -z: pitch 0, yaw 0) is compared with that metacarpal.
    assert f[list(bone(0, 1))] == pytest.approx([PI / 3, 0.0])


def test_without_a_rotation_the_thumb_metacarpal_borrows_the_proximal_direction():
    f = F.hand_features(tiny_hand(thumb_rotation=None))
    assert f[list(bone(0, 0))] == pytest.approx([0.0, PI])
    assert f[list(bone(0, 1))] == pytest.approx([0.0, 0.0])


def test_many_hands_at_once_equal_one_at_a_time():
    hands = [tiny_hand(), tiny_hand(direction=(0.1, 0.2, -0.97)), tiny_hand(side="right")]
    batch = F.hands_features(hands)
    assert batch.shape == (3, 57) and batch.dtype == np.float64
    for hand, row in zip(hands, batch, strict=True):
        assert F.hand_features(hand) == pytest.approx(row)
    assert F.hands_features([]).shape == (0, 57)


def test_to_recorded_side_negates_only_the_yaw_differences_of_right_hands():
    direction = (0.2, 0.1, -0.97)
    left = F.hand_features(tiny_hand(direction=direction), to_recorded_side=True)
    right = F.hand_features(tiny_hand(direction=direction, side="right"))
    mirrored = F.hand_features(tiny_hand(direction=direction, side="right"),
                               to_recorded_side=True)
    assert left == pytest.approx(right)  # the side alone changes nothing
    assert mirrored[F.YAW_FEATURES] == pytest.approx(-right[F.YAW_FEATURES])
    pitches_and_distances = np.setdiff1d(np.arange(57), F.YAW_FEATURES)
    assert mirrored[pitches_and_distances] == pytest.approx(right[pitches_and_distances])


def test_the_real_recordings_show_the_tip_to_base_bone_convention():
    # Straight fingers give (0, π) on the metacarpals with tip-to-base directions, (0, 0)
    # with base-to-tip ones. The recorded open hands are at π (circular mean), not 0.
    x, y, names = load_real_features()
    five = x[y == names.index("five")]
    for finger in range(1, 5):
        yaw = five[:, bone(finger, 0)[1]]
        mean = math.atan2(np.sin(yaw).mean(), np.cos(yaw).mean())
        assert abs(abs(mean) - PI) < 0.35


def test_direction_of_inverts_pitch_yaw():
    d = F.unit(np, np.random.default_rng(0).normal(size=(50, 3)))
    assert np.allclose(F.direction_of(np, *F.pitch_yaw(np, d)), d, atol=1e-12)
