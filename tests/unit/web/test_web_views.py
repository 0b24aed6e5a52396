"""web's views: hands in the base frame, downsampling, recomputed evidence, JSON."""

import json

import numpy as np
import pytest

from cbgo.examples import example
from cbgo.services.web.views import BaseFrame, Downsampler, Views, frame_view, to_json
from cbgo.transform import default_to_base, leap_to_base


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_hands_are_sent_in_the_base_frame_through_the_frames_own_to_base():
    frame = example("hands/frame")
    moved = default_to_base((0.8, 0.1, 0.0), yaw_deg=30.0)
    frame["to_base"] = moved.reshape(-1).tolist()
    view = frame_view(frame, BaseFrame())
    hand, source = view["hands"][0], frame["hands"][0]
    assert np.allclose(hand["palm"], leap_to_base(moved, source["palm_position"]), atol=1e-4)
    tip = source["fingers"][1]["bones"][3]["next_joint"]
    assert np.allclose(hand["fingers"][1][4], leap_to_base(moved, tip), atol=1e-4)
    assert len(hand["fingers"]) == 5 and all(len(f) == 5 for f in hand["fingers"])
    assert np.isclose(np.linalg.norm(hand["direction"]), 1.0, atol=1e-3)


def test_a_frame_without_to_base_uses_the_sensors_default_pose():
    frame = example("hands/frame")
    frame.pop("to_base", None)
    palm = frame_view(frame, BaseFrame())["hands"][0]["palm"]
    assert np.allclose(palm, leap_to_base(default_to_base(), frame["hands"][0]["palm_position"]),
                       atol=1e-4)


def test_120_hz_streams_are_cut_to_the_rate_and_events_never_are():
    clock = Clock()
    down = Downsampler(30.0, clock)
    passed = 0
    for i in range(120):  # one second of 120 Hz frames
        clock.t = i / 120
        passed += down.allow("hands/frame")
    assert passed == 30
    assert all(down.allow("episode/event") for _ in range(50))
    assert down.allow("gestures/static", "left") and down.allow("gestures/static", "right")
    assert not down.allow("gestures/static", "left")


def test_evidence_is_recomputed_from_static_gestures_and_reset_at_episode_start():
    clock = Clock()
    views = Views(1000.0, clock)
    static = example("gestures/static")
    names = static["names"]
    probs = [1.0 if n == "grab" else 0.0 for n in names]
    samples = []
    for i in range(40):
        clock.t = i / 100
        message = {**static, "ts": 100.0 + i / 100, "probs": probs}
        samples += [v for topic, v in views.render("gestures/static", message)
                    if topic == "@evidence"]
    assert samples[-1]["values"]["grab"] > samples[-1]["threshold"] == 0.6
    views.render("episode/event", example("episode/event", kind="start"))
    clock.t = 1.0
    again = [v for t, v in views.render("gestures/static", {**static, "ts": 101.0})
             if t == "@evidence"]
    assert again[0]["values"].get("grab", 0.0) < 0.6


def test_views_are_compact_json_without_nan():
    text = to_json("intent", example("intent"), 12.5)
    assert json.loads(text)["topic"] == "intent" and " " not in text.split('"msg"')[0]
    with pytest.raises(ValueError):
        to_json("x", {"v": float("nan")}, 0.0)


def test_a_camera_preview_goes_out_as_a_data_url_with_its_landmarks_at_the_pages_rate():
    import base64

    clock = Clock()
    views = Views(2.0, clock)
    preview = example("camera/preview", jpeg=b"\xff\xd8\xff\xe0 jpeg bytes")
    (topic, view), = views.render("camera/preview", preview)
    assert topic == "camera/preview"
    head, data = view["src"].split(",", 1)
    assert head == "data:image/jpeg;base64" and base64.b64decode(data) == preview["jpeg"]
    assert view["hands"] == preview["hands"] and view["width"] == preview["width"]
    json.loads(to_json(topic, view, 1.0))  # JSON-safe
    assert views.render("camera/preview", preview) == []  # within the period: skipped
    clock.t += 0.5
    assert len(views.render("camera/preview", preview)) == 1
