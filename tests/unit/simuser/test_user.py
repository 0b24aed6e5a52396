"""The simulated user: frames are valid, reproducible, and a pointing hand aims at its target."""

import numpy as np
import pytest

from cbgo import wire
from cbgo.simuser.scenario import load_scenario, parse_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.transform import default_to_base, leap_to_base


def test_every_frame_of_the_demo_scenario_is_valid_and_reproducible():
    scenario = load_scenario("demo")
    first = list(SimulatedUser(scenario, 60.0).frames())
    again = list(SimulatedUser(scenario, 60.0).frames())
    assert len(first) == len(again)
    assert [f.hands for f in first[::50]] == [f.hands for f in again[::50]]
    for frame in first[::10]:
        wire.validate({"v": 1, "ts": 1.0, "seq": 0, "source": "simulated", "device": "sim",
                       "hands": frame.hands}, wire.HANDS_FRAME)
    assert {f.label for f in first} >= {"grab", "point", "swipe_down", "rotate", "five"}


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("target", [[0.6, -0.3, 0.0], [0.4, 0.2, 0.0]])
def test_a_pointing_hand_aims_its_index_finger_at_the_gaze_target(side, target):
    to_base = default_to_base()
    scenario = parse_scenario({"users": {"u": {"side": side}},
                               "episodes": [{"gestures": ["point"], "gaze": target}]})
    hits = []
    for frame in SimulatedUser(scenario, 60.0, lambda g: g, to_base).frames():
        if frame.label == "point":
            bones = frame.hands[0]["fingers"][1]["bones"]
            knuckle = leap_to_base(to_base, bones[1]["prev_joint"])
            tip = leap_to_base(to_base, bones[3]["next_joint"])
            ray = tip - knuckle
            hits.append(knuckle + (-knuckle[2] / ray[2]) * ray)
    error = np.linalg.norm(np.array(hits)[:, :2] - np.array(target[:2]), axis=1)
    assert np.median(error) < 0.07
