"""Any hand pose as finger curls: the pose itself, scenario steps that hold it, and their errors."""

import numpy as np
import pytest

from cbgo import wire
from cbgo.errors import ConfigError
from cbgo.hands.model import PARAM_NAMES, HandShape, build_hand
from cbgo.hands.poses import check_curls, curl_pose, gesture_mean
from cbgo.simuser.scenario import hold_scenario, parse_scenario
from cbgo.simuser.user import SimulatedUser

HORNS = [1, 0, 1, 1, 0]


def joint(pose, name):
    return np.degrees(pose.to_vector()[PARAM_NAMES.index(name)])


def test_a_curl_of_0_is_the_open_hand_and_1_the_fist_finger_by_finger():
    assert np.allclose(curl_pose([0] * 5).to_vector(), gesture_mean("five").to_vector())
    fist = curl_pose([1] * 5).to_vector()
    grab = gesture_mean("grab").to_vector()
    assert np.allclose(fist[:21], grab[:21])  # the joints; the palm is held as in five
    horns = curl_pose(HORNS)
    assert joint(horns, "index_pip") < 10 and joint(horns, "pinky_pip") < 10
    assert joint(horns, "middle_pip") > 60 and joint(horns, "ring_pip") > 60


def test_renditions_vary_around_the_mean_and_spread_scales_the_fingers_apart():
    rng = np.random.default_rng(0)
    renditions = np.array([curl_pose(HORNS, rng).to_vector() for _ in range(50)])
    assert 0.5 < np.degrees(renditions[:, :21].std(0)).mean() < 15
    together = curl_pose(HORNS, spread=0.0)
    assert joint(together, "pinky_spread") == 0 and joint(curl_pose(HORNS), "pinky_spread") > 5


@pytest.mark.parametrize("curls, spread", [([1, 0, 1, 1], 1.0), ([1, 0, 1, 1, 2], 1.0),
                                           ("10110", 1.0), (HORNS, -1.0), (HORNS, "wide")])
def test_bad_curls_are_refused_saying_what_they_must_be(curls, spread):
    with pytest.raises(ValueError, match="straight|spread"):
        check_curls(curls, spread)


def test_a_scenario_step_may_hold_any_named_pose_given_as_curls():
    scenario = parse_scenario({"episodes": [{"gestures": [
        {"gesture": "horns", "curls": HORNS, "hold_s": 1.0}, "grab"]}]})
    step = scenario.episodes[0].gestures[0]
    assert step.curls == [1.0, 0.0, 1.0, 1.0, 0.0] and not step.dynamic and not step.idle
    frames = list(SimulatedUser(scenario, 60.0).frames())
    held = [f for f in frames if f.label == "horns"]
    assert len(held) >= 60
    for frame in held[::20]:
        wire.validate({"v": 1, "ts": 1.0, "seq": 0, "source": "simulated", "device": "sim",
                       "hands": frame.hands}, wire.HANDS_FRAME)
    # the index and little finger stand out from the curled middle and ring fingers
    tips = np.array([f["bones"][3]["next_joint"] for f in held[-1].hands[0]["fingers"]])
    palm = np.array(held[-1].hands[0]["palm_position"])
    reach = np.linalg.norm(tips - palm, axis=1)
    assert min(reach[1], reach[4]) > max(reach[2], reach[3]) + 20


@pytest.mark.parametrize("step, message", [
    ({"gesture": "horns"}, "unknown gesture 'horns'; known: .* any name with its finger curls"),
    ({"gesture": "horns", "curls": [1, 0]}, r"gestures\[0\]: curls .* give 5 numbers"),
    ({"gesture": "swipe_up", "curls": HORNS}, "not a stroke or idle motion"),
    ({"gesture": "Horns!", "curls": HORNS}, "lower-case letters"),
    ({"gesture": "grab", "spread": 0.5}, "give curls too"),
])
def test_a_bad_curl_step_is_refused_naming_the_place_at_fault(step, message):
    with pytest.raises(ConfigError, match=message):
        parse_scenario({"episodes": [{"gestures": [step]}]})


def test_a_hold_scenario_shows_the_pose_once_per_take_the_hand_leaving_in_between():
    data = hold_scenario("horns", HORNS, takes=3, hold_s=2.0)
    frames = list(SimulatedUser(parse_scenario(data), 60.0).frames())
    appearances = sum(1 for a, b in zip(frames, frames[1:], strict=False)
                      if not a.hands and b.hands)
    assert appearances == 3
    assert sum(f.label == "horns" for f in frames) >= 3 * 2.0 * 60
    assert hold_scenario("two")["episodes"][0]["gestures"][0] == {"gesture": "two", "hold_s": 3.0}
    with pytest.raises(ConfigError, match="unknown gesture 'peace'"):
        hold_scenario("peace")


def test_a_curl_pose_builds_a_valid_hand_on_either_side():
    for side in ("left", "right"):
        hand = build_hand(HandShape.default(side=side), curl_pose(HORNS), [0.0, 220.0, 0.0])
        assert hand["side"] == side and 0.3 < hand["grab_strength"] < 0.7  # two of four
