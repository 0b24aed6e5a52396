"""camera-bridge's geometry: distance, axes, and the Leap hand derived from 21 landmarks."""

from pathlib import Path

import numpy as np
import pytest

from cbgo import wire
from cbgo.hands.features import UNTRUSTED_FEATURES, hand_features
from cbgo.hands.model import HandShape, build_hand
from cbgo.hands.poses import gesture_pose
from cbgo.services.camera_bridge import geometry as G
from cbgo.services.camera_bridge.main import shape_side, user_side

PHOTOS = Path(__file__).parents[2] / "fixtures" / "camera" / "thumbs_up_photos"


def model_hand(side="right", gesture="thumbsup", palm=(10.0, 200.0, 20.0)):
    pose = gesture_pose(gesture, np.random.default_rng(0), 0.0)
    return build_hand(HandShape.default(side=side), pose, palm)


def test_the_translation_is_recovered_exactly_from_a_projection():
    rng = np.random.default_rng(1)
    world = rng.normal(0.0, 0.04, (21, 3))
    t = np.array([0.05, -0.03, 0.45])
    K = G.camera_matrix(640, 480, 60.0)
    p = (world + t) @ K.T
    image = p[:, :2] / p[:, 2:]
    assert np.allclose(G.solve_translation(world, image, K), t, atol=1e-9)
    assert G.reprojection_px(world, t, image, K) < 1e-6


def test_the_default_field_of_view_sets_the_focal_length():
    K = G.camera_matrix(640, 480)
    # 60° across 640 px: f = 320 / tan(30°)
    assert K[0, 0] == pytest.approx(320.0 / np.tan(np.radians(30.0)))
    assert (K[0, 2], K[1, 2]) == (320.0, 240.0)
    assert np.allclose(G.scale_matrix(K, (640, 480), (1280, 960)), np.diag([2, 2, 1]) @ K)


@pytest.mark.parametrize("placement", G.PLACEMENTS)
@pytest.mark.parametrize("pitch", [0.0, 30.0])
def test_every_camera_pose_is_a_proper_rotation(placement, pitch):
    R = G.CameraPose(placement, (0.0, 0.0, 0.0), pitch).rotation()
    assert np.allclose(R @ R.T, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)


def test_a_front_camera_sees_the_users_right_on_the_left_of_its_image():
    pose = G.CameraPose("front", (0.0, 200.0, -450.0), 0.0)
    assert np.allclose(pose.to_leap(np.array([0.0, 0.0, 450.0])), [0.0, 200.0, 0.0])
    right_in_image = pose.to_leap(np.array([100.0, 0.0, 450.0]))
    below_in_image = pose.to_leap(np.array([0.0, 100.0, 450.0]))
    farther = pose.to_leap(np.array([0.0, 0.0, 550.0]))
    assert right_in_image[0] == pytest.approx(-100.0)  # the user's left
    assert below_in_image[1] == pytest.approx(100.0)  # lower
    assert farther[2] == pytest.approx(100.0)  # nearer the user


def test_a_side_camera_sees_the_users_right_on_the_right_of_its_image():
    pose = G.CameraPose("side", (0.0, 450.0, 350.0), 0.0)
    assert pose.to_leap(np.array([100.0, 0.0, 400.0]))[0] == pytest.approx(100.0)
    assert pose.to_leap(np.array([0.0, 0.0, 400.0]))[2] == pytest.approx(-50.0)  # away
    tilted = G.CameraPose("side", (0.0, 450.0, 350.0), 30.0)
    ahead = tilted.to_leap(np.array([0.0, 0.0, 400.0]))
    assert ahead[1] == pytest.approx(450.0 - 200.0)  # 30° down: 400 · sin 30°
    assert ahead[2] == pytest.approx(350.0 - 400.0 * np.cos(np.radians(30.0)))


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("gesture", ["thumbsup", "point", "five", "grab", "pinch"])
def test_a_model_hand_through_its_21_landmarks_comes_back_as_it_was(side, gesture):
    hand = model_hand(side, gesture)
    again = G.leap_hand(G.landmarks_from_hand(hand), side, 7, 0.9)
    wire.validate(again, wire.HAND)
    for field in ("palm_position", "wrist_position", "palm_normal", "direction"):
        assert np.allclose(again[field], hand[field], atol=1e-6), field
    assert again["palm_width"] == pytest.approx(hand["palm_width"])
    assert again["pinch_strength"] == pytest.approx(hand["pinch_strength"], abs=1e-6)
    assert again["grab_strength"] == pytest.approx(hand["grab_strength"], abs=0.1)
    for f, finger in enumerate(hand["fingers"]):
        for b, bone in enumerate(finger["bones"]):
            got = again["fingers"][f]["bones"][b]
            assert np.allclose(got["prev_joint"], bone["prev_joint"], atol=1e-6), (f, b)
            assert np.allclose(got["next_joint"], bone["next_joint"], atol=1e-6), (f, b)
            assert got["width"] == pytest.approx(bone["width"])
    # The 57 features agree but for the thumb metacarpal's direction, which the camera hand
    # cannot give (no rotation: features fall back to the proximal) and the model hand gives.
    trusted = np.setdiff1d(np.arange(57), UNTRUSTED_FEATURES)
    assert np.allclose(hand_features(again)[trusted], hand_features(hand)[trusted], atol=1e-6)


def test_the_derived_parts_scale_with_the_knuckle_span():
    hand = model_hand("right", "five")
    points = G.landmarks_from_hand(hand)
    bigger = G.leap_hand(points * 1.2, "right", 1, 1.0)
    assert bigger["palm_width"] == pytest.approx(hand["palm_width"] * 1.2)
    assert np.allclose(bigger["palm_position"], np.asarray(hand["palm_position"]) * 1.2)


@pytest.mark.parametrize("side", ["left", "right"])
def test_a_curled_hands_shape_says_its_side(side):
    hand = model_hand(side, "grab")
    # as MediaPipe's world landmarks: metres, camera axes (a proper rotation of the Leap's)
    R = G.CameraPose("front").rotation()
    world = (G.landmarks_from_hand(hand) - hand["palm_position"]) @ R / 1000.0
    assert shape_side(world) == side
    assert shape_side(world * np.array([-1.0, 1.0, 1.0])) != side  # its mirror image


def test_mediapipes_label_assumes_a_mirrored_image():
    assert user_side("Right", mirrored=False) == "left"
    assert user_side("Left", mirrored=False) == "right"
    assert user_side("Right", mirrored=True) == "right"


def test_the_photos_distance_agrees_with_opencvs_solve_pnp():
    cv2 = pytest.importorskip("cv2")
    from cbgo.services.camera_bridge.tracker import HandTracker

    tracker = HandTracker(still_images=True)
    image = cv2.imread(str(PHOTOS / "1_hand_thumb_up.jpg"))
    height, width = image.shape[:2]
    K = G.camera_matrix(width, height)
    (found,) = tracker.detect(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    ok, rvec, tvec = cv2.solvePnP(found.world_m, found.image_px, K, None,
                                  flags=cv2.SOLVEPNP_SQPNP)
    assert ok
    t = G.solve_translation(found.world_m, found.image_px, K)
    assert np.linalg.norm(t - tvec.ravel()) < 0.02  # m
    assert np.degrees(np.linalg.norm(rvec)) < 15.0  # world axes are the camera's
    # and the label names the mirror of the hand whose shape the image shows
    assert shape_side(found.world_m) == ("left" if found.label == "Right" else "right")
