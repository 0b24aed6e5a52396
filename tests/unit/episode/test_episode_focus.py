"""Focus: robust gaze centre, pointing rays on the table, the choice between them."""

import numpy as np
import pytest

from cbgo.examples import open_hand
from cbgo.services.episode.focus import choose_focus, pointing_focus, robust_center, table_hit
from cbgo.services.episode.params import hand_sample
from cbgo.transform import base_to_leap, default_to_base


def test_the_gaze_centre_ignores_outliers():
    rng = np.random.default_rng(1)
    target = np.array([0.5, 0.1, 0.05])
    points = list(target + rng.normal(0, 0.01, (40, 3)))
    points += [[2.0, 2.0, 2.0], [-1.0, 0.0, 0.0], [0.5, 0.9, 0.0], [0.0, 0.0, 1.5]]
    assert np.linalg.norm(robust_center(points) - target) < 0.006
    assert np.linalg.norm(np.mean(points, axis=0) - target) > 0.05  # a mean would be pulled off
    assert robust_center([]) is None
    assert robust_center([[1.0, 2.0, 3.0]]).tolist() == [1.0, 2.0, 3.0]


def test_a_ray_going_down_hits_the_table():
    hit = table_hit(np.array([1.0, 0.0, 0.3]), np.array([-1.0, 0.0, -0.5]))
    assert hit == pytest.approx([0.4, 0.0, 0.0])


@pytest.mark.parametrize("direction", [[-1.0, 0.0, 0.2], [-1.0, 0.0, 0.0], [-1.0, 0.0, -0.01]])
def test_rays_that_do_not_reach_the_table_in_front_are_ignored(direction):
    # up, level, and so shallow that the hit is farther than max_range_m
    assert table_hit(np.array([1.0, 0.0, 0.3]), np.array(direction), max_range_m=3.0) is None


def pointing_hand(to_base, knuckle_base, target_base):
    """A hand whose index finger (knuckle -> tip) points at target (base frame)."""
    hand = open_hand()
    knuckle = np.asarray(knuckle_base, dtype=float)
    direction = np.asarray(target_base, dtype=float) - knuckle
    tip = knuckle + 0.08 * direction / np.linalg.norm(direction)
    bones = hand["fingers"][1]["bones"]
    bones[1]["prev_joint"] = base_to_leap(to_base, knuckle).tolist()
    bones[3]["next_joint"] = base_to_leap(to_base, tip).tolist()
    return hand


def test_the_pointing_ray_is_taken_in_the_base_frame_of_to_base():
    to_base = default_to_base([1.2, 0.1, 0.05], yaw_deg=20.0)
    target = [0.45, -0.2, 0.0]
    sample = hand_sample(0.0, 0, pointing_hand(to_base, [1.0, 0.0, 0.3], target), to_base)
    assert pointing_focus([sample.ray]) == pytest.approx(target, abs=1e-6)


def test_gaze_is_preferred_then_pointing_then_nothing():
    gaze = [[0.5, 0.1, 0.0]] * 3
    ray = (np.array([1.0, 0.0, 0.3]), np.array([-1.0, 0.0, -0.5]))
    assert choose_focus(["gaze", "pointing"], gaze, [ray]) == (pytest.approx([0.5, 0.1, 0.0]),
                                                               "gaze")
    assert choose_focus(["gaze", "pointing"], gaze[:2], [ray]) == (
        pytest.approx([0.4, 0.0, 0.0]), "pointing")  # too few gaze points
    assert choose_focus(["pointing", "gaze"], gaze, [ray])[1] == "pointing"
    assert choose_focus(["gaze"], [], [ray]) == (None, None)
    assert choose_focus(["gaze", "pointing"], [], []) == (None, None)
