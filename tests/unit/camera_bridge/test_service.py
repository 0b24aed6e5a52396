"""camera-bridge in memory (FakeBus): its sources, and every problem said and counted."""

import time
from pathlib import Path

import numpy as np
import pytest

from cbgo import wire
from cbgo.cli import up
from cbgo.errors import ConfigError
from cbgo.services.camera_bridge.main import CameraBridge, CameraBridgeSettings
from cbgo.testing import FakeBus

cv2 = pytest.importorskip("cv2")
FIXTURES = Path(__file__).parents[2] / "fixtures" / "camera"
PHOTOS = FIXTURES / "thumbs_up_photos"
WAIT_S = 60.0


@pytest.fixture
def running():
    buses = []

    def start(**settings):
        bus = FakeBus(CameraBridge(CameraBridgeSettings(**settings)))
        buses.append(bus)
        return bus

    yield start
    for bus in buses:
        bus.ctx.stopping.set()
        bus.service.shutdown()


def wait_until(bus, condition):
    """Polls the status until `condition(status)` holds; returns that status."""
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        ok, status = bus.query("status", None)
        if condition(status):
            return status
        time.sleep(0.05)
    raise AssertionError(f"not reached in {WAIT_S} s: {status}")


def frames(bus):
    return [m for k, m in bus.published if k == "hands/frame"]


def test_a_folder_of_photos_becomes_valid_hand_frames_of_the_users_hands(running, tmp_path):
    bus = running(camera=str(PHOTOS), hold_s=0.3, rate_hz=20)
    status = wait_until(bus, lambda s: s["reading"]["state"] == "finished")
    published = frames(bus)
    for message in published:
        wire.validate(message, wire.HANDS_FRAME)
    with_hands = [m for m in published if m["hands"]]
    assert len(with_hands) >= 10
    first = with_hands[0]
    assert first["source"] == "leap" and first["device"] == "camera"
    # the first photo shows a left hand (MediaPipe: "Right", on an unmirrored image)
    assert first["hands"][0]["side"] == "left"
    assert 0.5 < first["hands"][0]["confidence"] <= 1.0
    assert status["frame_time"]["frames"] == 2  # each still image is read once
    assert [m["seq"] for m in published] == list(range(len(published)))
    assert any(k == "user" for k, _ in bus.published)


def test_a_dark_image_is_said_to_be_too_dark(running, tmp_path):
    cv2.imwrite(str(tmp_path / "dark.png"), np.full((480, 640, 3), 5, np.uint8))
    bus = running(camera=str(tmp_path), hold_s=0.2, rate_hz=10)
    status = wait_until(bus, lambda s: s["problems"]["too_dark"] >= 1)
    assert status["problems"]["no_hand"] == 0
    assert all(not m["hands"] for m in frames(bus))


def test_a_bright_image_without_a_hand_is_no_hand_in_view(running, tmp_path):
    cv2.imwrite(str(tmp_path / "wall.png"), np.full((480, 640, 3), 128, np.uint8))
    bus = running(camera=str(tmp_path), hold_s=0.2, rate_hz=10)
    status = wait_until(bus, lambda s: s["problems"]["no_hand"] >= 1)
    assert status["problems"]["too_dark"] == 0


def test_two_hands_publish_the_most_confident_and_count_the_other(running, tmp_path):
    image = cv2.imread(str(PHOTOS / "1_hand_thumb_up.jpg"))
    cv2.imwrite(str(tmp_path / "both.png"), np.hstack([image, cv2.flip(image, 1)]))
    bus = running(camera=str(tmp_path), hold_s=0.2, rate_hz=10)
    status = wait_until(bus, lambda s: s["problems"]["extra_hands"] >= 1)
    assert max(len(m["hands"]) for m in frames(bus)) == 1
    two = running(camera=str(tmp_path), hold_s=0.2, rate_hz=10, max_hands=2)
    wait_until(two, lambda s: s["reading"]["state"] == "finished")
    sides = {h["side"] for m in frames(two) for h in m["hands"]}
    assert sides == {"left", "right"}
    assert status["side_check"]["disagreed"] == 0


def test_a_missing_camera_is_said_and_tried_again_without_stopping(running):
    bus = running(camera="/dev/video99")
    status = wait_until(bus, lambda s: s["problems"]["camera"] >= 1)
    assert status["reading"]["state"] == "no camera"
    assert not bus.ctx.stopping.is_set()


def test_a_video_plays_on_its_own_clock_then_sees_nobody(running):
    bus = running(camera=str(FIXTURES / "thumbs_up_clip.mp4"))
    status = wait_until(bus, lambda s: s["reading"]["state"] == "finished")
    assert status["reading"]["read"] + status["reading"]["dropped"] == 100
    published = frames(bus)
    stamps = np.diff([m["ts"] for m in published if m["hands"]])
    assert np.all(stamps > 0) and np.min(stamps) >= 0.04 - 1e-6  # 25 fps or fewer
    wait_until(bus, lambda s: s["frames"] > len(published))
    assert not frames(bus)[-1]["hands"]


@pytest.mark.parametrize("content", [b"not a video", b""])
def test_an_unreadable_video_is_a_configuration_error_naming_it(tmp_path, content):
    video = tmp_path / "broken.mp4"
    video.write_bytes(content)
    with pytest.raises(ConfigError, match="cannot read the video .*broken.mp4"):
        FakeBus(CameraBridge(CameraBridgeSettings(camera=str(video))))


def test_a_source_that_is_nothing_is_a_configuration_error(tmp_path):
    with pytest.raises(ConfigError, match="neither a camera"):
        FakeBus(CameraBridge(CameraBridgeSettings(camera=str(tmp_path / "nope.mp4"))))
    with pytest.raises(ConfigError, match="no readable image"):
        FakeBus(CameraBridge(CameraBridgeSettings(camera=str(tmp_path))))


@pytest.mark.parametrize("bad", [{"placement": "above"}, {"max_hands": 0}, {"fov_deg": 5.0},
                                 {"model_complexity": 2}, {"camera_position": [1.0, 2.0]},
                                 {"preview_hz": 11.0}, {"preview_width": 40}])
def test_bad_settings_are_refused_with_their_name(bad):
    with pytest.raises(ConfigError, match=next(iter(bad))):
        CameraBridgeSettings(**bad)


def test_a_calibration_file_sets_the_camera_matrix(running, tmp_path):
    calibration = tmp_path / "cam.yaml"
    calibration.write_text("camera_matrix: [[500, 0, 320], [0, 500, 240], [0, 0, 1]]\n"
                           "image_size: [640, 480]\ndist_coeffs: [0.1, -0.05, 0, 0, 0]\n")
    bus = running(camera=str(PHOTOS), hold_s=0.2, rate_hz=10, calibration=str(calibration))
    assert np.allclose(bus.service.lens.matrix(1280, 960)[0], [1000, 0, 640])
    wait_until(bus, lambda s: s["reading"]["state"] == "finished")
    assert any(m["hands"] for m in frames(bus))
    calibration.write_text("camera_matrix: [1, 2]\n")
    with pytest.raises(ConfigError, match="calibration"):
        FakeBus(CameraBridge(CameraBridgeSettings(camera=str(PHOTOS),
                                                  calibration=str(calibration))))


def test_cbgo_up_hands_camera_puts_camera_bridge_in_leap_bridges_place():
    chosen = [s.name for s in up.chosen_services([], hands="camera")]
    assert "camera-bridge" in chosen and "leap-bridge" not in chosen
    assert chosen.index("camera-bridge") == [
        s.name for s in up.chosen_services([])].index("leap-bridge")
    with pytest.raises(SystemExit):
        up.chosen_services(["leap-bridge", "camera-bridge"])


def test_one_image_looped_with_gaps_comes_back_after_each_gap(running, tmp_path):
    (tmp_path / "one.jpg").write_bytes((PHOTOS / "1_hand_thumb_up.jpg").read_bytes())
    bus = running(camera=str(tmp_path), hold_s=0.2, gap_s=0.2, rate_hz=20, loop=True)
    wait_until(bus, lambda s: s["frame_time"].get("frames", 0) >= 3)
    ids = [m["hands"][0]["id"] for m in frames(bus) if m["hands"]]
    assert len(set(ids)) >= 3  # each showing is a hand entering anew
    assert bus.query("status", None)[1]["problems"]["failed"] == 0


def test_the_preview_is_the_image_made_small_with_the_landmarks_of_the_published_hands(
        running):
    bus = running(camera=str(PHOTOS), hold_s=0.6, rate_hz=20, preview_hz=10)
    wait_until(bus, lambda s: s["reading"]["state"] == "finished")
    previews = [m for k, m in bus.published if k == "camera/preview"]
    assert len(previews) >= 4  # about 6 a photo at 10 a second; only what is due
    by_seq = {m["seq"]: m for m in frames(bus)}
    for preview in previews:
        wire.validate(preview, wire.CAMERA_PREVIEW)
        image = cv2.imdecode(np.frombuffer(preview["jpeg"], np.uint8), cv2.IMREAD_COLOR)
        assert image.shape[:2] == (preview["height"], preview["width"]) and preview["width"] == 320
        frame = by_seq[preview["seq"]]  # the hand frame made of the same image
        assert [h["side"] for h in preview["hands"]] == [h["side"] for h in frame["hands"]]
        for hand in preview["hands"]:
            points = np.asarray(hand["points"])
            assert points.shape == (21, 2) and (points >= -0.1).all() and (points <= 1.1).all()
    assert any(p["hands"] for p in previews)
    stamps = [p["ts"] for p in previews]
    assert min(np.diff(stamps)) >= 0.1 - 1e-6  # no more than preview_hz


def test_no_preview_with_preview_hz_0(running):
    bus = running(camera=str(PHOTOS), hold_s=0.3, rate_hz=20, preview_hz=0)
    wait_until(bus, lambda s: s["reading"]["state"] == "finished")
    assert frames(bus) and not [k for k, _ in bus.published if k == "camera/preview"]
