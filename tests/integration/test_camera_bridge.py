"""camera-bridge through real processes: real photos and a real video in through `--camera`,
`hands/frame` and then `gestures/static` and `episode/summary` out."""

import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from cbgo import wire

pytest.importorskip("mediapipe")

CLI = [sys.executable, "-m", "cbgo.cli.main"]
FIXTURES = Path(__file__).parents[1] / "fixtures" / "camera"
PHOTOS = FIXTURES / "thumbs_up_photos"
CLIP = FIXTURES / "thumbs_up_clip.mp4"
PER_PHOTO = 8  # gestures/static messages per photo before judging it


def winner(message):
    return message["names"][int(np.argmax(message["probs"]))]


def test_the_thumbs_up_photos_read_as_thumbsup_through_the_running_services(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    frames, gestures = stack.collect("hands/frame"), stack.collect("gestures/static")
    stack.start_service("static-gesture")
    stack.wait_alive(["static-gesture"], timeout=90)
    stack.start_service("camera-bridge", "--camera", str(PHOTOS), "--hold-s", "2",
                        "--gap-s", "0.5", "--rate-hz", "15", "--wait-for", "static-gesture")
    with_hands = frames.wait_count(1, lambda m: m["hands"], timeout=60)
    first_id = with_hands[0]["hands"][0]["id"]
    for hand_id in (first_id, first_id + 1):  # each photo is a new scene: a new hand
        gestures.wait_count(PER_PHOTO, lambda m, h=hand_id: m["hand_id"] == h, timeout=60)
    for message in frames.items():
        wire.validate(message, wire.HANDS_FRAME)
        assert message["source"] == "leap" and message["device"] == "camera"
    for hand_id in (first_id, first_id + 1):
        read = Counter(winner(m) for m in gestures.items() if m["hand_id"] == hand_id)
        assert read.most_common(1)[0][0] == "thumbsup", (hand_id, read)
    status = stack.status("camera-bridge")
    assert status["problems"]["failed"] == 0 and status["counters"]["errors"] == 0


def test_cbgo_up_hands_camera_on_a_thumbs_up_video_gives_an_episode_naming_thumbsup(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    summaries = stack.collect("episode/summary")
    frames = stack.collect("hands/frame")
    up = stack.spawn("up", [*CLI, "up", "--no-router", "--connect", stack.endpoint,
                            "--hands", "camera", "--camera", str(CLIP),
                            "leap-bridge", "static-gesture", "dynamic-gesture", "episode"])
    stack.wait_alive(["camera-bridge", "static-gesture", "dynamic-gesture", "episode"],
                     timeout=120)
    assert "leap-bridge" not in stack.alive()
    summary = summaries.first(timeout=90)
    names = summary["gestures"]["names"]
    probs = summary["gestures"]["probs"]
    assert names and names[int(np.argmax(probs))] == "thumbsup", summary
    assert "thumbsup" in {t["gesture"] for t in summary["triggers"]}, summary
    assert all(m["device"] == "camera" for m in frames.items())
    code, _ = stack.stop("up")
    assert code == 0, up.log()
