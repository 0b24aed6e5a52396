"""Unit tests of cbgo.foxglove: the derived scene, transforms and log, and the JSON channels."""

from __future__ import annotations

import json

import jsonschema
import numpy as np
import pytest

from cbgo import json_schema, keys, transform, wire
from cbgo.examples import example
from cbgo.foxglove import scene as fx
from cbgo.foxglove.channels import foxglove_schema, wire_payload, wire_schema
from cbgo.foxglove.derive import DERIVED_TOPICS, SCENE_TOPIC, TRANSFORMS_TOPIC, Deriver
from cbgo.services.foxglove_bridge.forward import Forwarder

SESSION = ["scene/state", "hands/frame", "gaze", "episode/event", "episode/summary", "intent",
           "plan/status", "robot/state", "gestures/static", "user"]


def derived_of(suffixes, ts=100.0):
    deriver = Deriver()
    return [d for i, s in enumerate(suffixes) for d in deriver.feed(s, example(s, ts=ts + i))]


def test_every_derived_message_fits_foxglove_s_own_schema():
    out = derived_of(SESSION)
    assert {d.topic for d in out} == set(DERIVED_TOPICS)
    for d in out:
        jsonschema.validate(d.message, foxglove_schema(DERIVED_TOPICS[d.topic]))


def test_hands_are_drawn_in_the_base_frame_through_the_frames_to_base():
    frame = example("hands/frame", ts=5.0)
    frame["to_base"] = list(transform.default_to_base((0.8, 0.1, 0.0)).ravel())
    hands = fx.hands_entity(frame)
    palm = hands["spheres"][-1]["pose"]["position"]
    expected = transform.leap_to_base(transform.default_to_base((0.8, 0.1, 0.0)),
                                      frame["hands"][0]["palm_position"])
    assert [palm["x"], palm["y"], palm["z"]] == pytest.approx(list(expected))
    # 20 bones as 20 segments, 25 joints + 1 palm per hand
    assert len(hands["lines"][0]["points"]) == 40 and len(hands["spheres"]) == 26
    assert hands["frame_id"] == "base" and hands["timestamp"] == {"sec": 5, "nsec": 0}


def test_objects_are_cubes_and_cylinders_and_the_accepted_target_is_highlighted():
    deriver = Deriver()
    deriver.feed("scene/state", example("scene/state", ts=1.0))
    intent = {**example("intent", ts=2.0), "status": "accepted", "object": "cup1"}
    objects = next(e for d in deriver.feed("intent", intent) if d.topic == SCENE_TOPIC
                   for e in d.message["entities"])
    assert objects["id"] == "objects" and objects["cylinders"] and objects["cubes"]
    assert objects["cylinders"][0]["color"] == fx.colour(fx.TARGET)
    assert any(t["text"] == "cup1 (target)" for t in objects["texts"])


def test_a_refused_intent_is_a_warning_and_moves_no_highlight():
    deriver = Deriver()
    deriver.feed("scene/state", example("scene/state", ts=1.0))
    refused = {**example("intent", ts=2.0), "status": "low_confidence", "object": "cup1"}
    out = deriver.feed("intent", refused)
    assert [d.topic for d in out] == ["foxglove/log"]
    assert out[0].message["level"] == 3 and "low_confidence" in out[0].message["message"]
    assert deriver.target is None


def test_the_leap_transform_is_repeated_each_second_and_when_it_changes():
    deriver = Deriver()
    times = [0.0, 0.5, 1.0, 1.2]
    sent = [t for t in times if any(d.topic == TRANSFORMS_TOPIC for d in
                                    deriver.feed("hands/frame", example("hands/frame", ts=t)))]
    assert sent == [0.0, 1.0]
    moved = {**example("hands/frame", ts=1.3),
             "to_base": list(transform.default_to_base((0.9, 0, 0)).ravel())}
    tf = next(d for d in deriver.feed("hands/frame", moved) if d.topic == TRANSFORMS_TOPIC)
    leap = tf.message["transforms"][0]
    assert leap["parent_frame_id"] == "base" and leap["child_frame_id"] == "leap"
    assert leap["translation"] == {"x": 0.9, "y": 0.0, "z": 0.0}


def test_the_quaternion_is_the_rotation_of_the_leap_axes():
    rotation = transform.default_to_base()[:3, :3] * 1000.0
    q = fx.quaternion(rotation)
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    back = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    assert back == pytest.approx(rotation)


def test_a_pointing_ray_starts_at_the_index_fingertip_and_a_gaze_ray_at_the_nominal_eye():
    frame = example("hands/frame", ts=1.0)
    pointing = {**example("gaze", ts=1.0), "source": "pointing"}
    origin, nominal = fx.ray_origin(pointing, frame)
    tip = frame["hands"][0]["fingers"][1]["bones"][3]["next_joint"]
    assert not nominal and list(origin) == pytest.approx(
        list(transform.leap_to_base(transform.default_to_base(), tip)))
    _origin, nominal = fx.ray_origin(example("gaze", ts=1.0), frame)
    assert nominal


def test_wire_channels_carry_the_keys_json_schema_and_bytes_survive_as_base64():
    k = keys.Keys()
    name, schema = wire_schema(k, "cbgo/hands/frame")
    assert name == "cbgo.hands.frame" and schema == json_schema.for_key("hands/frame")
    name, schema = wire_schema(k, "cbgo/not/contract")
    assert schema["type"] == "object"
    reply = {"v": 1, "ok": True, "error": None, "png": b"\x89PNG\x00\xff"}
    data = json.dumps(json_schema.to_json(reply)).encode()
    schema_data = json.dumps(json_schema.for_key("sim/render", "reply")).encode()
    assert wire.decode(wire_payload(data, schema_data)) == reply
    with pytest.raises(ValueError):
        wire_payload(b'{"png": "***"}', schema_data)


def test_the_forwarder_thins_high_rate_keys_and_passes_every_event():
    forwarder = Forwarder(stream_hz=10)
    frames = [forwarder.forward(keys.HANDS_FRAME, "cbgo/hands/frame",
                                example("hands/frame", ts=i / 60)) for i in range(60)]
    assert sum(1 for out in frames if out) == 10
    assert forwarder.counts.thinned["cbgo/hands/frame"] == 50
    events = [forwarder.forward(keys.EPISODE_EVENT, "cbgo/episode/event",
                                example("episode/event", ts=1.0)) for _ in range(5)]
    assert all(len(out) == 2 for out in events)  # the event and its log line
    assert events[0][1][0] == "foxglove/log"


def test_a_replay_starting_over_restarts_a_thinned_stream_at_once():
    forwarder = Forwarder(stream_hz=10)
    assert forwarder.forward(keys.GAZE, "cbgo/gaze", example("gaze", ts=50.0))
    assert forwarder.forward(keys.GAZE, "cbgo/gaze", example("gaze", ts=1.0))


def test_the_shipped_layout_is_the_one_the_module_builds_and_names_the_models_classes():
    from pathlib import Path

    from cbgo.foxglove import layout

    repo = Path(__file__).resolve().parents[3]
    assert (repo / "deploy/foxglove/layout.json").read_text() == layout.layout_json()
    static = json.loads((repo / "services/static_gesture/models/static-gesture.json")
                        .read_text())["names"]
    dynamic = json.loads((repo / "services/dynamic_gesture/models/default.json").read_text())
    assert list(layout.STATIC_NAMES) == static
    assert list(layout.DYNAMIC_NAMES) == [t["name"] for t in dynamic["templates"]] + ["none"]
