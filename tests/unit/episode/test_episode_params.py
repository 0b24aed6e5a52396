"""Metric parameters from hand geometry: thumb-index distance, palm roll, stroke length."""

import functools

import numpy as np
import pytest

from cbgo.examples import open_hand
from cbgo.services.episode.params import (
    aperture,
    hand_sample,
    roll_deg,
    rotate_angle,
    scale_of,
    stroke_length,
)
from cbgo.simuser.scenario import parse_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.transform import default_to_base


def pinching(gap_mm, side="right"):
    """An open hand whose thumb tip is gap_mm from the index tip."""
    hand = open_hand(side=side)
    index_tip = np.array(hand["fingers"][1]["bones"][3]["next_joint"])
    hand["fingers"][0]["bones"][3]["next_joint"] = (index_tip + [0.0, -gap_mm, 0.0]).tolist()
    return hand


def test_the_thumb_index_distance_is_in_metres_through_to_base():
    sample = hand_sample(1.0, 7, pinching(30.0), default_to_base())
    assert sample.aperture_m == pytest.approx(0.030)
    assert hand_sample(1.0, 7, pinching(30.0), None).aperture_m == pytest.approx(0.030)
    assert scale_of(default_to_base([0.5, 0.2, 0.1], 35.0)) == pytest.approx(1e-3)


def test_the_distance_is_the_median_over_samples():
    samples = [hand_sample(i, i, pinching(g), None) for i, g in enumerate([20, 21, 22, 90])]
    assert aperture(samples) == pytest.approx(0.0215)
    assert aperture([]) is None


@functools.cache
def rotate_samples(angle_deg, side):
    scenario = parse_scenario({"users": {"u": {"side": side}}, "episodes": [
        {"gestures": [{"gesture": "rotate", "angle_deg": angle_deg}], "pause_s": 0.1}]})
    frames = SimulatedUser(scenario, 60.0).frames()
    return [hand_sample(f.t, i, f.hands[0], default_to_base())
            for i, f in enumerate(frames) if f.label == "rotate"]


@pytest.mark.parametrize(("angle", "side"), [(90, "right"), (90, "left"), (-45, "right"),
                                             (60, "left")])
def test_the_palm_roll_of_a_rotate_has_its_size_and_anatomical_sign(angle, side):
    samples = rotate_samples(angle, side)
    assert rotate_angle(samples) == pytest.approx(angle, abs=6.0)


def test_roll_is_relative_to_the_first_sample():
    samples = rotate_samples(90, "right")
    rolls = roll_deg(samples)
    assert rolls[0] == 0.0 and abs(rolls[-1]) > 80
    assert rotate_angle(samples[:1]) is None


def test_stroke_length_is_the_farthest_the_palm_got():
    samples = []
    for i, x in enumerate([0.0, 50.0, 120.0, 100.0]):
        hand = open_hand(palm=(x, 200.0, 0.0))
        samples.append(hand_sample(i, i, hand, default_to_base()))
    assert stroke_length(samples) == pytest.approx(0.120)
    assert stroke_length(samples[:1]) is None
