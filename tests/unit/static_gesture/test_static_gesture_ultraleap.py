"""Ultraleap's Gemini-tracked poses (vendored from UnityPlugin) → contract hands, and the bench."""

import numpy as np
import pytest

from cbgo.hands import features as F
from cbgo.hands.model import HandShape, build_hand, mirrored_hand
from cbgo.hands.poses import gesture_mean
from cbgo.services.static_gesture import invariant
from cbgo.services.static_gesture.classifier import StaticClassifier, shipped_model_path
from cbgo.wire import HANDS_FRAME, validate
from cbgo_tools.data import ultraleap

POSES = ultraleap.load_poses()


def _frame(hands):
    return {"v": 1, "ts": 1.0, "seq": 0, "source": "leap", "device": "lmc2", "hands": hands}


def _joints(hand):
    return np.array([[b["prev_joint"] + b["next_joint"] for b in f["bones"]]
                     for f in hand["fingers"]]).reshape(5, 4, 2, 3)


def test_every_vendored_pose_is_read_and_named():
    assert set(POSES) == set(ultraleap.POSES)
    assert (ultraleap.POSES_DIR / "LICENSE").is_file()


@pytest.mark.parametrize("name", sorted(ultraleap.POSES))
def test_a_pose_becomes_valid_contract_hands_of_a_real_size(name):
    right, left = POSES[name]
    validate(_frame([right, left]), HANDS_FRAME)
    assert (right["side"], left["side"]) == ("right", "left")
    joints = _joints(right)
    # bones chain: each bone starts where the one before it ends
    assert np.allclose(joints[:, 1:, 0], joints[:, :-1, 1], atol=1e-6)
    # Gemini's thumb metacarpal has zero length; the others are real bones
    lengths = np.linalg.norm(joints[..., 1, :] - joints[..., 0, :], axis=-1)
    assert lengths[0, 0] < 1e-3 and (lengths[1:, 0] > 30).all()
    middle = lengths[2, 1:].sum()
    assert 60.0 < middle < 110.0  # mm: the units are right
    assert right["palm_position"] == list(ultraleap.FIELD_CENTRE_MM)


@pytest.mark.parametrize("name", sorted(ultraleap.POSES))
def test_the_thumb_is_on_a_right_hands_thumb_side_in_the_leap_frame(name):
    # In the right-handed Leap frame a right hand's thumb lies along direction × normal
    # (palm down, fingers forward: −x); without the z flip it would land on the other side.
    for hand in POSES[name]:
        d, n = np.array(hand["direction"]), np.array(hand["palm_normal"])
        thumb_base = _joints(hand)[0, 1, 0] - np.array(hand["palm_position"])
        side = float(thumb_base @ np.cross(d, n))
        assert side > 0 if hand["side"] == "right" else side < 0


@pytest.mark.parametrize("name", sorted(ultraleap.POSES))
def test_the_left_hand_is_the_right_one_mirrored(name):
    right, left = POSES[name]
    assert np.allclose(F.hands_features([mirrored_hand(right)], to_recorded_side=True),
                       F.hands_features([left], to_recorded_side=True), atol=1e-6)


def test_turning_a_hand_gives_it_the_reference_palm_frame_and_keeps_its_shape():
    hand, reference = POSES["point"][0], POSES["thumbs_up"][0]
    turned = ultraleap.turned_like(hand, reference)
    assert np.allclose(F.hand_basis(turned), F.hand_basis(reference), atol=1e-9)
    a, b = _joints(hand).reshape(-1, 3), _joints(turned).reshape(-1, 3)
    assert np.allclose(np.linalg.norm(a[:, None] - a[None], axis=-1),
                       np.linalg.norm(b[:, None] - b[None], axis=-1), atol=1e-6)
    assert turned["palm_position"] == hand["palm_position"]


def test_rolling_a_thumbs_up_over_points_its_thumb_down_and_keeps_its_shape():
    reference = build_hand(HandShape(side="right"), gesture_mean("thumbsup"),
                           ultraleap.FIELD_CENTRE_MM)
    up = ultraleap.turned_like(POSES["thumbs_up"][0], reference)
    down = ultraleap.rolled_over(up)
    assert ultraleap.thumb_elevation_deg(up) > 30 and ultraleap.thumb_elevation_deg(down) < -30
    # the 57 features tell the same within a few degrees (they read the hand's pitch from the
    # metacarpals)
    for hand in (up, down):
        assert invariant.thumb_elevation(F.hands_features([hand], to_recorded_side=True))[0] == \
            pytest.approx(ultraleap.thumb_elevation_deg(hand), abs=5.0)
    assert np.allclose(down["direction"], up["direction"], atol=1e-9)
    assert np.allclose(down["palm_normal"], -np.asarray(up["palm_normal"]), atol=1e-9)
    a, b = _joints(up).reshape(-1, 3), _joints(down).reshape(-1, 3)
    assert np.allclose(np.linalg.norm(a[:, None] - a[None], axis=-1),
                       np.linalg.norm(b[:, None] - b[None], axis=-1), atol=1e-6)


def test_an_unknown_pose_is_right_when_answered_none_or_unsure():
    names = ["grab", "pinch", "none"]
    assert ultraleap._right("none", names, np.array([0.1, 0.2, 0.7]))
    assert ultraleap._right("none", names, np.array([0.3, 0.45, 0.25]))
    assert not ultraleap._right("none", names, np.array([0.05, 0.9, 0.05]))
    assert ultraleap._right("grab", names, np.array([0.6, 0.3, 0.1]))
    assert not ultraleap._right("grab", names, np.array([0.3, 0.6, 0.1]))


def test_the_bench_scores_every_pose_as_held_and_turned_with_the_shipped_model(capsys):
    clf = StaticClassifier.load(shipped_model_path())
    fig = ultraleap.score_poses(clf, POSES)
    assert fig["n"] == len(POSES) and fig["n_turned"] == len(POSES) * 4
    for row in fig["poses"]:
        assert row["truth"] == ultraleap.POSES[row["pose"]]
        assert row["answer"] in clf.names and 0.0 <= row["p"] <= 1.0
        assert list(row["turned"]) == list(ultraleap.TRAINING_ORIENTATIONS)
    # each thumbs-up is also scored rolled over into a thumbs-down, right when rejected
    thumbs = [name for name, truth in ultraleap.POSES.items() if truth == "thumbsup"]
    assert sorted(d["pose"] for d in fig["thumbs_down"]) == sorted(thumbs)
    for row in fig["thumbs_down"]:
        assert row["elevation_deg"] < 0 and row["answer"] in clf.names
        assert row["right"] == (row["answer"] == "none" or row["p"] < 0.5)
    # a pose's left hand is answered as its right one
    for right, left in POSES.values():
        probs = clf.classify_hands([right, left])
        assert np.allclose(probs[0], probs[1], atol=1e-6)
    ultraleap.print_scores(fig)
    assert "Gemini" in capsys.readouterr().out
