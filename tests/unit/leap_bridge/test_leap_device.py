"""The LeapC (Gemini, Leap Motion Controller 2) path: LEAP_HAND structs → contract hands.

The frames are laid out as the LeapC structs and the Python bindings' wrappers are
(``tests/fakes/leapc.py``): a zero-length, zero-width thumb metacarpal with an identity basis,
the arm bone ending at the wrist, digits in union order.
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from cbgo.hands import features as F
from cbgo.hands.model import HandShape, build_hand
from cbgo.hands.poses import gesture_pose
from cbgo.services.leap_bridge.leap_device import hand_from_leap
from cbgo.services.static_gesture import invariant
from cbgo.services.static_gesture.classifier import StaticClassifier, shipped_model_path
from cbgo.wire import HANDS_FRAME, STATIC_GESTURES, validate


def _load_fake():
    path = Path(__file__).parents[2] / "fakes" / "leapc.py"
    spec = importlib.util.spec_from_file_location("leapc_fake", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["leapc_fake"] = module
    spec.loader.exec_module(module)
    return module


leapc = _load_fake()


def _hand(name, side="left", seed=0):
    rng = np.random.default_rng(seed)
    return build_hand(HandShape.default(side=side), gesture_pose(name, rng, 0.5),
                      np.array([10.0, 200.0, 20.0]))


def _frame(hands):
    return {"v": 1, "ts": 1.0, "seq": 0, "source": "leap", "device": "lmc2", "hands": hands}


@pytest.mark.parametrize("side", ["left", "right"])
def test_leapc_hand_maps_every_contract_field(side):
    original = _hand("five", side)
    struct = leapc.leapc_hand(original, confidence=0.87)
    hand = hand_from_leap(struct, leapc.leap)
    validate(_frame([hand]), HANDS_FRAME)
    assert hand["side"] == side
    assert hand["confidence"] == pytest.approx(0.87)
    assert hand["wrist_position"] == pytest.approx(original["wrist_position"])
    assert hand["palm_position"] == pytest.approx(original["palm_position"])
    assert hand["direction"] == pytest.approx(original["direction"])
    assert hand["palm_normal"] == pytest.approx(original["palm_normal"])
    assert hand["palm_width"] == pytest.approx(original["palm_width"])
    for f, finger in enumerate(hand["fingers"]):
        assert finger["type"] == original["fingers"][f]["type"]
        for b, bone in enumerate(finger["bones"]):
            if (f, b) == (0, 0):
                continue
            want = original["fingers"][f]["bones"][b]
            assert bone["type"] == want["type"]
            assert bone["prev_joint"] == pytest.approx(want["prev_joint"])
            assert bone["next_joint"] == pytest.approx(want["next_joint"])


def test_zero_length_thumb_metacarpal_is_sent_without_its_placeholder_basis():
    hand = hand_from_leap(leapc.leapc_hand(_hand("thumbsup")), leapc.leap)
    metacarpal = hand["fingers"][0]["bones"][0]
    assert metacarpal["prev_joint"] == metacarpal["next_joint"]
    assert "rotation" not in metacarpal
    assert "rotation" in hand["fingers"][1]["bones"][1]
    # the features then give the metacarpal its proximal's direction, not the sensor's +z
    x = F.hand_features(hand)
    assert x[2:4] == pytest.approx(x[2:4] + x[4:6])  # thumb proximal relative to it: zero
    assert x[4:6] == pytest.approx([0.0, 0.0], abs=1e-12)


def test_confidence_and_strengths_outside_0_1_are_clipped():
    struct = leapc.leapc_hand(_hand("grab"), confidence=1.0000001)
    struct._data.grab_strength = -1e-7
    hand = hand_from_leap(struct, leapc.leap)
    validate(_frame([hand]), HANDS_FRAME)
    assert hand["confidence"] == 1.0 and hand["grab_strength"] == 0.0


@pytest.mark.parametrize("name", STATIC_GESTURES)
def test_leapc_frames_read_the_same_as_the_recording_layout(name):
    """Whatever a device does with the thumb metacarpal, the model's features do not change."""
    hands = [_hand(name, side, seed) for side in ("left", "right") for seed in range(3)]
    converted = [hand_from_leap(leapc.leapc_hand(h), leapc.leap) for h in hands]
    before = invariant.derive(F.hands_features(hands, to_recorded_side=True))
    after = invariant.derive(F.hands_features(converted, to_recorded_side=True))
    assert after == pytest.approx(before, abs=1e-9)
    clf = StaticClassifier.load(shipped_model_path(), samples=8)
    assert clf.classify_hands(converted) == pytest.approx(clf.classify_hands(hands), abs=1e-9)
