"""Unit tests of cbgo.wire: msgpack encoding and the schema of every message of the contract."""

from __future__ import annotations

import copy
import math
from collections.abc import Callable

import msgpack
import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.errors import CbgoError, RejectedMessage
from cbgo.examples import EXAMPLE_KEYS, example

NAN, INF = math.nan, math.inf
FRAME_KEY = "cbgo/hands/frame"

# --------------------------------------------------------------------------- helpers


def rejection(suffix: str, message: dict, role: str = "message", key: str = "") -> RejectedMessage:
    """Encodes, decodes and validates `message`; returns the rejection it must raise."""
    payload = wire.encode(message)
    with pytest.raises(RejectedMessage) as info:
        wire.decode_checked(payload, wire.schema_for(suffix, role), key)
    return info.value


def accepted(suffix: str, message: dict, role: str = "message") -> dict:
    """Encodes, decodes and validates `message`; returns the decoded message."""
    return wire.decode_checked(wire.encode(message), wire.schema_for(suffix, role))


def _walk(message: dict, path: tuple):
    node = message
    for step in path[:-1]:
        node = node[step]
    return node, path[-1]


def setting(*path_and_value) -> Callable[[dict], None]:
    """A mutation that sets the field at a path (keys and indices) to a value."""
    *path, value = path_and_value

    def mutate(message: dict) -> None:
        node, last = _walk(message, tuple(path))
        node[last] = value
    return mutate


def deleting(*path) -> Callable[[dict], None]:
    """A mutation that removes the field at a path."""
    def mutate(message: dict) -> None:
        node, last = _walk(message, tuple(path))
        del node[last]
    return mutate


def truncating(*path_and_length) -> Callable[[dict], None]:
    """A mutation that keeps the first n items of the list at a path."""
    *path, n = path_and_length

    def mutate(message: dict) -> None:
        node, last = _walk(message, tuple(path))
        node[last] = node[last][:n]
    return mutate


def swapping(*path_and_indices) -> Callable[[dict], None]:
    """A mutation that swaps two items of the list at a path."""
    *path, i, j = path_and_indices

    def mutate(message: dict) -> None:
        node, last = _walk(message, tuple(path))
        items = node[last]
        items[i], items[j] = items[j], items[i]
    return mutate


def mutated(suffix: str, role: str, mutate: Callable[[dict], None]) -> dict:
    message = example(suffix, role, ts=1_700_000_000.0)
    mutate(message)
    return message


BONE_2_OF_INDEX = ("hands", 0, "fingers", 1, "bones", 2)
THUMB_METACARPAL = ("hands", 0, "fingers", 0, "bones", 0)
HAND = ("hands", 0)

# --------------------------------------------------------------------------- examples


@pytest.mark.parametrize(("suffix", "role"), EXAMPLE_KEYS)
def test_every_example_round_trips_through_msgpack_and_validates(suffix, role):
    message = example(suffix, role, ts=1_700_000_000.0)
    payload = wire.encode(message)
    assert isinstance(payload, bytes)
    decoded = wire.decode_checked(payload, wire.schema_for(suffix, role), keys.Keys().of(
        keys.TOPICS[suffix]))
    assert decoded == message


@pytest.mark.parametrize(("suffix", "role"), EXAMPLE_KEYS)
def test_every_example_is_readable_by_a_plain_msgpack_decoder(suffix, role):
    message = example(suffix, role, ts=1_700_000_000.0)
    assert msgpack.unpackb(wire.encode(message), raw=False) == message


def test_every_topic_of_the_contract_has_a_schema_and_an_example_for_each_role():
    for suffix, topic in keys.TOPICS.items():
        roles = ("query", "reply") if topic.query else ("message",)
        for role in roles:
            if suffix != "robot/stop":
                assert isinstance(wire.schema_for(suffix, role), wire.Spec), (suffix, role)
            assert (suffix, role) in EXAMPLE_KEYS, (suffix, role)
    assert {suffix for suffix, _ in EXAMPLE_KEYS} == set(keys.TOPICS)


def test_robot_stop_has_no_schema_so_any_map_is_accepted():
    assert wire.schema_for("robot/stop") is None
    assert wire.validate({"anything": [1, "x"]}, None) == {"anything": [1, "x"]}
    assert wire.decode_checked(wire.encode({}), wire.schema_for("robot/stop")) == {}


def test_asking_for_a_schema_that_does_not_exist_raises_key_error():
    with pytest.raises(KeyError):
        wire.schema_for("no/such/topic")
    with pytest.raises(KeyError):
        wire.schema_for("hands/frame", "query")
    with pytest.raises(KeyError):
        wire.schema_for("hands/frame", "answer")


def test_the_example_factory_applies_overrides_and_returns_independent_copies():
    a = example("hands/frame", hands=[])
    b = example("hands/frame")
    assert a["hands"] == [] and len(b["hands"]) == 1
    b["hands"][0]["id"] = 99
    assert example("hands/frame")["hands"][0]["id"] == 1
    assert example("gaze", ts=12.5)["ts"] == 12.5


def test_an_empty_hands_list_is_a_valid_frame_without_a_hand():
    assert accepted("hands/frame", example("hands/frame", hands=[]))["hands"] == []


def test_the_rejection_is_a_cbgo_error_whose_text_is_key_path_problem():
    error = rejection("hands/frame", mutated("hands/frame", "message", setting("ts", "now")),
                      key=FRAME_KEY)
    assert isinstance(error, CbgoError)
    assert error.key == FRAME_KEY
    assert error.path == "ts"
    assert error.problem == "expected a finite number >= 0.0, got str 'now'"
    assert str(error) == f"{FRAME_KEY}: ts: expected a finite number >= 0.0, got str 'now'"


def test_the_rejection_text_has_no_key_part_when_none_is_given():
    error = rejection("hands/frame", mutated("hands/frame", "message", setting("ts", "now")))
    assert error.key == ""
    assert str(error).startswith("ts: expected")


def test_validate_labels_its_rejection_with_the_key():
    message = mutated("hands/frame", "message", setting(*HAND, "side", "middle"))
    with pytest.raises(RejectedMessage) as info:
        wire.validate(message, wire.schema_for("hands/frame"), FRAME_KEY)
    assert str(info.value).startswith(f"{FRAME_KEY}: hands[0].side: ")


def test_decode_checked_labels_a_decoding_failure_with_the_key():
    with pytest.raises(RejectedMessage) as info:
        wire.decode_checked(b"\xc1", wire.schema_for("gaze"), "cbgo/gaze")
    assert info.value.key == "cbgo/gaze"
    assert str(info.value).startswith("cbgo/gaze: not a msgpack payload")


def test_a_long_bad_value_is_shortened_in_the_message():
    error = rejection("user", example("user", user=["x" * 500]))
    assert error.path == "user"
    assert "..." in error.problem
    assert len(error.problem) < 150


# --------------------------------------------------------------------------- bad fields

# (id, suffix, role, mutation, expected path, substrings the problem must contain)
BAD_FIELDS = [
    # missing required fields, at every depth
    ("missing-bone-width", "hands/frame", "message", deleting(*BONE_2_OF_INDEX, "width"),
     "hands[0].fingers[1].bones[2].width",
     ["missing required field", "a finite number >= 0.0"]),
    ("missing-ts", "hands/frame", "message", deleting("ts"), "ts",
     ["missing required field"]),
    ("missing-palm-position", "hands/frame", "message", deleting(*HAND, "palm_position"),
     "hands[0].palm_position", ["missing required field", "a list of 3 finite numbers"]),
    ("missing-finger-type", "hands/frame", "message", deleting(*HAND, "fingers", 3, "type"),
     "hands[0].fingers[3].type", ["missing required field", "'ring'"]),
    ("missing-gaze-point", "gaze", "message", deleting("point"), "point",
     ["missing required field"]),
    ("missing-robot-holding", "scene/state", "message", deleting("robot", "holding"),
     "robot.holding", ["missing required field", "null or a non-empty string"]),
    ("missing-summary-focus", "episode/summary", "message", deleting("focus"), "focus",
     ["missing required field", "null or a list of 3 finite numbers"]),
    ("missing-intent-status", "intent", "message", deleting("status"), "status",
     ["missing required field", "'accepted'"]),
    ("missing-act-duration", "robot/act", "reply", deleting("duration_s"), "duration_s",
     ["missing required field"]),
    ("missing-reset-v", "sim/reset", "query", deleting("v"), "v",
     ["missing required field", "an integer >= 1"]),
    ("missing-plan-step-state", "plan/status", "message", deleting("sequence", 0, "state"),
     "sequence[0].state", ["missing required field", "'pending'"]),
    ("missing-dynamic-window", "gestures/dynamic", "message", deleting("window"), "window",
     ["missing required field", "a list of 2 finite numbers"]),
    ("missing-infer-scene-object-name", "intent/infer", "query",
     deleting("scene", "objects", 0, "name"), "scene.objects[0].name",
     ["missing required field"]),
    ("missing-act-reply-scene-tcp", "robot/act", "reply", deleting("scene", "robot", "tcp"),
     "scene.robot.tcp", ["missing required field"]),
    # wrong types: string / bool / float where something else is required
    ("string-ts", "hands/frame", "message", setting("ts", "now"), "ts",
     ["expected a finite number >= 0.0", "got str 'now'"]),
    ("string-position", "hands/frame", "message", setting(*HAND, "palm_position", 1, "200"),
     "hands[0].palm_position[1]", ["expected a finite number", "got str '200'"]),
    ("bool-ts", "gaze", "message", setting("ts", True), "ts",
     ["expected a finite number", "got bool True"]),
    ("bool-confidence", "hands/frame", "message", setting(*HAND, "confidence", True),
     "hands[0].confidence", ["expected a finite number in [0.0, 1.0]", "got bool True"]),
    ("bool-position-entry", "hands/frame", "message",
     setting(*HAND, "palm_position", 0, False), "hands[0].palm_position[0]",
     ["expected a finite number", "got bool False"]),
    ("bool-bone-width", "hands/frame", "message", setting(*BONE_2_OF_INDEX, "width", True),
     "hands[0].fingers[1].bones[2].width", ["got bool True"]),
    ("bool-probability", "gestures/static", "message", setting("probs", 0, True), "probs[0]",
     ["expected a finite number in [0.0, 1.0]", "got bool True"]),
    ("bool-seq", "hands/frame", "message", setting("seq", True), "seq",
     ["expected an integer >= 0", "got bool True"]),
    ("float-seq", "hands/frame", "message", setting("seq", 12.0), "seq",
     ["expected an integer >= 0", "got float 12.0"]),
    ("float-hand-id", "hands/frame", "message", setting(*HAND, "id", 1.0), "hands[0].id",
     ["expected an integer", "got float 1.0"]),
    ("string-version", "user", "message", setting("v", "1"), "v",
     ["expected an integer >= 1", "got str '1'"]),
    ("list-robot", "scene/state", "message", setting("robot", [0.3, 0.0, 0.4]), "robot",
     ["expected a map", "got list"]),
    ("list-hand", "hands/frame", "message", setting("hands", 0, []), "hands[0]",
     ["expected a map", "got list"]),
    ("list-p-action", "intent", "message", setting("p_action", ["pick_up"]), "p_action",
     ["expected a map with string keys", "got list"]),
    ("list-params", "episode/summary", "message", setting("params", [1.0]), "params",
     ["expected a map of parameter names", "got list"]),
    ("map-hands", "hands/frame", "message", setting("hands", {}), "hands",
     ["expected a list", "got dict"]),
    ("string-names", "gestures/static", "message", setting("names", "grab"), "names",
     ["expected a list of at least 1 items", "got str 'grab'"]),
    ("int-full", "scene/state", "message", setting("objects", 0, "full", 1), "objects[0].full",
     ["expected a boolean", "got int 1"]),
    ("string-moving", "robot/state", "message", setting("moving", "no"), "moving",
     ["expected a boolean", "got str 'no'"]),
    ("string-png", "sim/render", "reply", setting("png", "iVBORw0KGgo="), "png",
     ["expected bytes (msgpack bin)", "got str"]),
    ("empty-user", "user", "message", setting("user", ""), "user",
     ["expected a non-empty string", "got str ''"]),
    ("int-device", "hands/frame", "message", setting("device", 3), "device",
     ["expected a string", "got int 3"]),
    ("int-p-action-key", "intent", "message", setting("p_action", {"pick_up": 0.5, 3: 0.5}),
     "p_action", ["expected non-empty string keys", "got int 3"]),
    ("int-params-key", "robot/act", "query", setting("params", {1: 0.5}), "params",
     ["expected non-empty string keys", "got int 1"]),
    ("list-infer-scene", "intent/infer", "query", setting("scene", []), "scene",
     ["expected a map", "got list"]),
    # NaN, +inf, -inf where a finite number is required
    ("nan-ts", "hands/frame", "message", setting("ts", NAN), "ts",
     ["expected a finite number >= 0.0", "got float nan"]),
    ("inf-ts", "hands/frame", "message", setting("ts", INF), "ts",
     ["expected a finite number", "got float inf"]),
    ("minus-inf-ts", "user", "message", setting("ts", -INF), "ts",
     ["expected a finite number", "got float -inf"]),
    ("nan-in-a-hand-position", "hands/frame", "message",
     setting(*HAND, "palm_position", 2, NAN), "hands[0].palm_position[2]",
     ["expected a finite number", "got float nan"]),
    ("inf-in-a-bone-joint", "hands/frame", "message",
     setting("hands", 0, "fingers", 4, "bones", 3, "next_joint", 0, INF),
     "hands[0].fingers[4].bones[3].next_joint[0]", ["expected a finite number", "got float inf"]),
    ("minus-inf-in-gaze", "gaze", "message", setting("point", 0, -INF), "point[0]",
     ["expected a finite number", "got float -inf"]),
    ("nan-joint", "robot/state", "message", setting("joints", 3, NAN), "joints[3]",
     ["expected a finite number", "got float nan"]),
    ("nan-param", "episode/summary", "message", setting("params", "distance", NAN),
     "params.distance", ["expected a finite number", "got float nan"]),
    ("inf-in-a-nested-param", "robot/act", "query",
     setting("params", {"offset": [0.0, INF, 0.0]}), "params.offset[1]",
     ["expected a finite number", "got float inf"]),
    ("minus-inf-in-a-param-map", "intent", "message",
     setting("params", {"target": {"angle_deg": -INF}}), "params.target.angle_deg",
     ["expected a finite number", "got float -inf"]),
    ("nan-in-to-base", "hands/frame", "message",
     setting("to_base", [1.0, 0, 0, 0, 0, NAN, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]), "to_base[5]",
     ["expected a finite number", "got float nan"]),
    ("inf-in-to-base", "hands/frame", "message",
     setting("to_base", [1.0, 0, 0, INF, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]), "to_base[3]",
     ["expected a finite number", "got float inf"]),
    ("nan-p-action", "intent", "message", setting("p_action", "pick_up", NAN),
     "p_action.pick_up", ["got float nan"]),
    ("nan-window", "gestures/dynamic", "message", setting("window", 0, NAN), "window[0]",
     ["expected a finite number", "got float nan"]),
    ("nan-scene-size", "scene/state", "message", setting("objects", 2, "size", NAN),
     "objects[2].size", ["got float nan"]),
    # out of range
    ("confidence-above-one", "hands/frame", "message", setting(*HAND, "confidence", 1.5),
     "hands[0].confidence", ["expected a finite number in [0.0, 1.0]", "got float 1.5"]),
    ("negative-ts", "hands/frame", "message", setting("ts", -1.0), "ts",
     ["expected a finite number >= 0.0", "got float -1.0"]),
    ("negative-palm-width", "hands/frame", "message", setting(*HAND, "palm_width", -85.0),
     "hands[0].palm_width", ["expected a finite number >= 0.0", "got float -85.0"]),
    ("negative-grab-strength", "hands/frame", "message",
     setting(*HAND, "grab_strength", -0.1), "hands[0].grab_strength",
     ["in [0.0, 1.0]", "got float -0.1"]),
    ("drawer-opening-two", "scene/state", "message", setting("objects", 1, "opening", 2),
     "objects[1].opening", ["expected a finite number in [0.0, 1.0]", "got int 2"]),
    ("negative-seq", "scene/state", "message", setting("seq", -1), "seq",
     ["expected an integer >= 0", "got int -1"]),
    ("version-zero", "gaze", "message", setting("v", 0), "v",
     ["expected an integer >= 1", "got int 0"]),
    ("event-prob-above-one", "episode/event", "message", setting("prob", 1.01), "prob",
     ["in [0.0, 1.0]"]),
    ("negative-gripper-width", "robot/state", "message", setting("gripper_width", -0.01),
     "gripper_width", [">= 0.0", "got float -0.01"]),
    ("render-width-too-small", "sim/render", "query", setting("width", 8), "width",
     ["in [16, 4096]", "got int 8"]),
    ("negative-reset-seed", "sim/reset", "query", setting("seed", -1), "seed",
     ["expected an integer >= 0", "got int -1"]),
    ("intent-confidence-two", "intent/infer", "reply", setting("confidence", 2), "confidence",
     ["in [0.0, 1.0]"]),
    ("negative-duration", "robot/act", "reply", setting("duration_s", -1.0), "duration_s",
     [">= 0.0"]),
    ("negative-trigger-ts", "episode/summary", "message", setting("triggers", 0, "ts", -5.0),
     "triggers[0].ts", [">= 0.0", "got float -5.0"]),
    # bad enumerations
    ("side-middle", "hands/frame", "message", setting(*HAND, "side", "middle"),
     "hands[0].side", ["expected one of 'left', 'right'", "got str 'middle'"]),
    ("source-kinect", "hands/frame", "message", setting("source", "kinect"), "source",
     ["expected one of 'leap', 'replay', 'simulated'", "got str 'kinect'"]),
    ("object-type-plate", "scene/state", "message", setting("objects", 0, "type", "plate"),
     "objects[0].type", ["expected one of 'cup', 'drawer', 'box'", "got str 'plate'"]),
    ("status-maybe", "intent", "message", setting("status", "maybe"), "status",
     ["expected one of 'accepted', 'low_confidence', 'infeasible'", "got str 'maybe'"]),
    ("gaze-source-kinect", "gaze", "message", setting("source", "kinect"), "source",
     ["'eyetracker'", "got str 'kinect'"]),
    ("event-kind-pause", "episode/event", "message", setting("kind", "pause"), "kind",
     ["expected one of 'start', 'end', 'trigger'", "got str 'pause'"]),
    ("plan-state-paused", "plan/status", "message", setting("state", "paused"), "state",
     ["'running', 'success', 'failure'"]),
    ("plan-step-skipped", "plan/status", "message", setting("sequence", 0, "state", "skipped"),
     "sequence[0].state", ["'pending', 'running', 'done', 'failed'", "got str 'skipped'"]),
    ("finger-type-toe", "hands/frame", "message", setting(*HAND, "fingers", 2, "type", "toe"),
     "hands[0].fingers[2].type", ["'thumb', 'index', 'middle', 'ring', 'pinky'"]),
    ("bone-type-tip", "hands/frame", "message", setting(*BONE_2_OF_INDEX, "type", "tip"),
     "hands[0].fingers[1].bones[2].type", ["'metacarpal', 'proximal', 'intermediate'"]),
    ("gesture-side-both", "gestures/dynamic", "message", setting("side", "both"), "side",
     ["expected one of 'left', 'right'"]),
    # wrong list lengths
    ("three-fingers", "hands/frame", "message", truncating(*HAND, "fingers", 3),
     "hands[0].fingers", ["expected a list of exactly 5 items", "3 items"]),
    ("three-bones", "hands/frame", "message", truncating(*HAND, "fingers", 2, "bones", 3),
     "hands[0].fingers[2].bones", ["expected a list of exactly 4 items", "3 items"]),
    ("position-of-two", "hands/frame", "message", setting(*HAND, "palm_position", [0.0, 1.0]),
     "hands[0].palm_position", ["expected a list of 3 finite numbers", "got list [0.0, 1.0]"]),
    ("gaze-point-of-four", "gaze", "message", setting("point", [0.0, 0.0, 0.0, 0.0]), "point",
     ["expected a list of 3 finite numbers"]),
    ("six-joints", "robot/state", "message", truncating("joints", 6), "joints",
     ["expected a list of 7 finite numbers"]),
    ("window-of-three", "gestures/dynamic", "message", setting("window", [0.0, 0.5, 1.0]),
     "window", ["expected a list of 2 finite numbers"]),
    ("seventeen-hands", "hands/frame", "message",
     lambda m: m.__setitem__("hands", m["hands"] * 17), "hands", ["17 items"]),
    ("no-gesture-names", "gestures/static", "message", setting("names", []), "names",
     ["expected a list of at least 1 items"]),
    # fingers and bones in the wrong order
    ("fingers-out-of-order", "hands/frame", "message", swapping(*HAND, "fingers", 1, 2),
     "hands[0].fingers",
     ["expected types in the order ['thumb', 'index', 'middle', 'ring', 'pinky']",
      "got ['thumb', 'middle', 'index', 'ring', 'pinky']"]),
    ("bones-out-of-order", "hands/frame", "message",
     swapping(*HAND, "fingers", 2, "bones", 0, 3), "hands[0].fingers[2].bones",
     ["expected types in the order ['metacarpal', 'proximal', 'intermediate', 'distal']",
      "got ['distal', 'proximal', 'intermediate', 'metacarpal']"]),
    ("finger-repeated", "hands/frame", "message",
     lambda m: m["hands"][0]["fingers"].__setitem__(4, copy.deepcopy(
         m["hands"][0]["fingers"][3])),
     "hands[0].fingers", ["got ['thumb', 'index', 'middle', 'ring', 'ring']"]),
    # cross-field rules
    ("static-probs-not-summing-to-one", "gestures/static", "message",
     setting("probs", [0.5] + [0.01] * 7), "probs",
     ["expected probs summing to 1", "got sum 0.570000"]),
    ("dynamic-probs-not-summing-to-one", "gestures/dynamic", "message",
     setting("probs", [0.5, 0.5, 0.5, 0.0, 0.0, 0.0]), "probs",
     ["expected probs summing to 1", "got sum 1.500000"]),
    ("static-names-probs-mismatch", "gestures/static", "message", truncating("probs", 7),
     "probs", ["expected as many probs as names", "got 7 probs for 8 names"]),
    ("dynamic-names-probs-mismatch", "gestures/dynamic", "message",
     setting("names", ["swipe_up"]), "probs",
     ["expected as many probs as names", "got 6 probs for 1 names"]),
    ("summary-names-probs-mismatch", "episode/summary", "message",
     setting("gestures", "probs", [0.9]), "gestures.probs",
     ["got 1 probs for 3 names"]),
    ("infer-names-probs-mismatch", "intent/infer", "query",
     setting("gestures", "names", ["grab"]), "gestures.probs", ["got 8 probs for 1 names"]),
    ("static-duplicate-names", "gestures/static", "message", setting("names", 1, "grab"),
     "names", ["expected unique names", "duplicates"]),
    ("summary-duplicate-names", "episode/summary", "message",
     setting("gestures", "names", ["grab", "grab", "point"]), "gestures.names",
     ["expected unique names"]),
    ("window-ends-before-it-starts", "gestures/dynamic", "message",
     setting("window", [10.0, 9.5]), "window",
     ["expected t_start <= t_end", "got [10.0, 9.5]"]),
    ("trigger-without-gesture", "episode/event", "message", deleting("gesture"), "gesture",
     ["missing required field for kind 'trigger'", "a non-empty string"]),
    ("summary-ends-before-it-starts", "episode/summary", "message",
     lambda m: m.update(started=100.0, ended=99.0), "ended",
     ["expected ended >= started", "got 99.0 < 100.0"]),
    ("duplicate-object-names", "scene/state", "message", setting("objects", 2, "name", "cup1"),
     "objects", ["expected unique object names", "duplicates ['cup1']"]),
    ("duplicate-object-names-in-act-reply", "robot/act", "reply",
     setting("scene", "objects", 1, "name", "cup1"), "scene.objects",
     ["duplicates ['cup1']"]),
    ("duplicate-object-names-in-infer-query", "intent/infer", "query",
     setting("scene", "objects", 0, "name", "box1"), "scene.objects", ["duplicates ['box1']"]),
    ("duplicate-object-names-in-reset-query", "sim/reset", "query",
     setting("scene", {"objects": [{"name": "a", "type": "box", "position": [0, 0, 0],
                                    "size": 0.1}] * 2}),
     "scene.objects", ["duplicates ['a']"]),
    ("act-refused-without-error", "robot/act", "reply",
     lambda m: m.update(ok=False, error=None), "error",
     ["expected a non-empty error reason when ok is false"]),
    ("act-refused-with-an-empty-error", "robot/act", "reply",
     lambda m: m.update(ok=False, error="  "), "error", ["non-empty error reason"]),
    ("act-refused-without-error-field", "robot/act", "reply",
     lambda m: (m.update(ok=False), m.pop("error")), "error", ["missing required field"]),
    ("reset-refused-without-error", "sim/reset", "reply",
     lambda m: m.update(ok=False, error=None), "error", ["non-empty error reason"]),
    ("render-refused-without-error", "sim/render", "reply",
     lambda m: m.update(ok=False, error=None), "error", ["non-empty error reason"]),
    ("zero-quaternion", "hands/frame", "message",
     setting(*THUMB_METACARPAL, "rotation", [0.0, 0.0, 0.0, 0.0]),
     "hands[0].fingers[0].bones[0].rotation", ["expected a non-zero quaternion"]),
    # optional fields: present but invalid
    ("to-base-of-fifteen", "hands/frame", "message", setting("to_base", [0.0] * 15),
     "to_base", ["expected a list of 16 finite numbers"]),
    ("rotation-of-three", "hands/frame", "message",
     setting(*THUMB_METACARPAL, "rotation", [0.0, 0.0, 1.0]),
     "hands[0].fingers[0].bones[0].rotation", ["expected a list of 4 finite numbers"]),
    ("event-gesture-empty", "episode/event", "message", setting("gesture", ""), "gesture",
     ["expected a non-empty string"]),
    ("contains-a-number", "scene/state", "message", setting("objects", 1, "contains", ["cup1", 3]),
     "objects[1].contains[1]", ["expected a non-empty string", "got int 3"]),
    ("object-on-a-number", "scene/state", "message", setting("objects", 0, "on", 7),
     "objects[0].on", ["expected null or a non-empty string", "got int 7"]),
    ("infer-params-nan", "intent/infer", "query", setting("params", {"distance": NAN}),
     "params.distance", ["got float nan"]),
    ("infer-model-empty", "intent/infer", "query", setting("model", ""), "model",
     ["a non-empty string"]),
    ("render-camera-number", "sim/render", "query", setting("camera", 1), "camera",
     ["a non-empty string", "got int 1"]),
    ("reset-robot-holding-number", "sim/reset", "query",
     setting("scene", {"objects": [], "robot": {"holding": 3}}), "scene.robot.holding",
     ["expected null or a non-empty string", "got int 3"]),
    # nullable fields with the wrong type
    ("focus-string", "episode/summary", "message", setting("focus", "here"), "focus",
     ["expected null or a list of 3 finite numbers", "got str 'here'"]),
    ("focus-nan", "episode/summary", "message", setting("focus", [0.0, NAN, 0.0]), "focus[1]",
     ["got float nan"]),
    ("focus-source-number", "episode/summary", "message", setting("focus_source", 3),
     "focus_source", ["expected null or one of 'gaze', 'pointing'", "got int 3"]),
    ("focus-source-nose", "episode/summary", "message", setting("focus_source", "nose"),
     "focus_source", ["null or one of 'gaze', 'pointing'", "got str 'nose'"]),
    ("holding-number", "scene/state", "message", setting("robot", "holding", 5),
     "robot.holding", ["expected null or a non-empty string", "got int 5"]),
    ("holding-empty", "scene/state", "message", setting("robot", "holding", ""),
     "robot.holding", ["expected null or a non-empty string", "got str ''"]),
    ("robot-action-number", "robot/state", "message", setting("action", 0), "action",
     ["expected null or a non-empty string", "got int 0"]),
    ("intent-episode-bool", "intent", "message", setting("episode", False), "episode",
     ["expected null or a non-empty string", "got bool False"]),
    ("act-error-number", "robot/act", "reply", setting("error", 500), "error",
     ["expected null or a string", "got int 500"]),
    # asking back: the question and its answer
    ("missing-clarify-candidates", "intent/clarify", "message", deleting("candidates"),
     "candidates", ["missing required field", "a list of 1 to 8 items"]),
    ("clarify-without-candidates", "intent/clarify", "message", setting("candidates", []),
     "candidates", ["expected a list of 1 to 8 items", "got 0 items"]),
    ("clarify-candidate-action-fly", "intent/clarify", "message",
     setting("candidates", 0, "action", "fly"), "candidates[0].action",
     ["expected one of 'move_up'", "got str 'fly'"]),
    ("clarify-candidate-p-above-one", "intent/clarify", "message",
     setting("candidates", 1, "p", 1.5), "candidates[1].p", ["in [0.0, 1.0]", "got float 1.5"]),
    ("clarify-highlight-not-a-candidate", "intent/clarify", "message", setting("highlighted", 2),
     "highlighted", ["expected the index of a candidate (0-1)", "got 2"]),
    ("clarify-state-maybe", "intent/clarify", "message", setting("state", "maybe"), "state",
     ["expected one of 'open', 'confirmed', 'expired', 'cancelled'", "got str 'maybe'"]),
    ("clarify-expires-nan", "intent/clarify", "message", setting("expires", NAN), "expires",
     ["expected a finite number", "got float nan"]),
    ("answer-maybe", "intent/answer", "message", setting("answer", "maybe"), "answer",
     ["expected one of 'confirm', 'next', 'previous', 'cancel'", "got str 'maybe'"]),
    ("answer-choice-negative", "intent/answer", "message", setting("choice", -1), "choice",
     ["expected an integer >= 0", "got int -1"]),
    ("answer-choice-bool", "intent/answer", "message", setting("choice", True), "choice",
     ["expected an integer >= 0", "got bool True"]),
    ("answer-missing-id", "intent/answer", "message", deleting("id"), "id",
     ["missing required field", "a non-empty string"]),
    ("answer-user-empty", "intent/answer", "message", setting("user", ""), "user",
     ["expected a non-empty string", "got str ''"]),
]


@pytest.mark.parametrize(("suffix", "role", "mutate", "path", "expected"),
                         [case[1:] for case in BAD_FIELDS], ids=[case[0] for case in BAD_FIELDS])
def test_a_bad_field_is_rejected_naming_its_path_and_what_was_expected(
        suffix, role, mutate, path, expected):
    key = f"cbgo/{suffix}"
    error = rejection(suffix, mutated(suffix, role, mutate), role, key=key)
    assert error.path == path, str(error)
    for text in expected:
        assert text in error.problem, f"{text!r} not in {error.problem!r}"
    assert str(error) == f"{key}: {path}: {error.problem}"


def test_nan_in_a_hand_position_is_rejected_with_its_path():
    message = mutated("hands/frame", "message", setting(*HAND, "palm_position", 2, NAN))
    error = rejection("hands/frame", message, key=FRAME_KEY)
    assert str(error) == (f"{FRAME_KEY}: hands[0].palm_position[2]: "
                          "expected a finite number, got float nan")


def test_the_first_bad_hand_is_the_one_named_when_several_are_bad():
    message = example("hands/frame")
    message["hands"] = [copy.deepcopy(message["hands"][0]) for _ in range(2)]
    message["hands"][1]["side"] = "middle"
    assert rejection("hands/frame", message).path == "hands[1].side"


# --------------------------------------------------------------------------- accepted variants


def test_the_episode_summary_gesture_vector_need_not_sum_to_one():
    message = example("episode/summary")
    message["gestures"] = {"names": ["grab", "point", "rotate"], "probs": [0.9, 0.8, 0.7]}
    assert accepted("episode/summary", message)["gestures"]["probs"] == [0.9, 0.8, 0.7]


def test_an_empty_episode_summary_gesture_vector_is_accepted():
    message = example("episode/summary", triggers=[], params={})
    message["gestures"] = {"names": [], "probs": []}
    assert accepted("episode/summary", message)["gestures"] == {"names": [], "probs": []}


def test_gesture_probs_within_the_float32_tolerance_of_one_are_accepted():
    probs = [0.125] * 8
    probs[0] += 0.0009
    assert accepted("gestures/static", example("gestures/static", probs=probs))


def test_a_zero_length_dynamic_window_is_accepted():
    assert accepted("gestures/dynamic", example("gestures/dynamic", window=[5.0, 5.0]))


@pytest.mark.parametrize("kind", ["start", "end"])
def test_start_and_end_events_need_no_gesture(kind):
    message = example("episode/event", kind=kind)
    del message["gesture"], message["prob"]
    assert accepted("episode/event", message)["kind"] == kind


def test_a_summary_that_ends_when_it_starts_is_accepted():
    assert accepted("episode/summary", example("episode/summary", started=10.0, ended=10.0))


@pytest.mark.parametrize("suffix", ["robot/act", "sim/reset", "sim/render"])
def test_a_refusal_with_an_error_string_is_accepted(suffix):
    message = example(suffix, "reply", ok=False, error="object 'cup9' does not exist")
    message.pop("png", None)
    if "scene" in message:
        message["scene"] = None
    assert accepted(suffix, message, "reply")["ok"] is False


def test_integers_are_accepted_where_a_number_is_required():
    message = example("gaze", ts=1_700_000_000, point=[1, 0, 0])
    assert accepted("gaze", message)["point"] == [1, 0, 0]


@pytest.mark.parametrize("value", [0.0, 1.0, 0, 1])
def test_probabilities_on_the_bounds_are_accepted(value):
    assert accepted("episode/event", example("episode/event", prob=value))["prob"] == value


def test_a_frame_with_a_to_base_transform_is_accepted():
    to_base = [0.001, 0, 0, 0.5, 0, 0, -0.001, 0.0, 0, 0.001, 0, 0.1, 0, 0, 0, 1]
    assert accepted("hands/frame", example("hands/frame", to_base=to_base))["to_base"] == to_base


def test_absent_optional_fields_are_fine():
    frame = example("hands/frame")
    del frame["hands"][0]["fingers"][0]["bones"][0]["rotation"]
    assert "to_base" not in frame
    accepted("hands/frame", frame)
    event = example("episode/event", kind="start")
    del event["gesture"], event["prob"]
    accepted("episode/event", event)
    scene = example("scene/state")
    scene["objects"] = [{k: o[k] for k in ("name", "type", "position", "size")}
                        for o in scene["objects"]]
    accepted("scene/state", scene)
    accepted("sim/render", {"v": 1}, "query")
    accepted("sim/reset", {"v": 1}, "query")
    accepted("sim/render", {"v": 1, "ok": True, "error": None}, "reply")
    infer = example("intent/infer", "query")
    assert "params" not in infer and "model" not in infer
    accepted("intent/infer", infer, "query")


def test_present_optional_fields_are_accepted_when_valid():
    infer = example("intent/infer", "query", params={"distance": 0.05, "unit": "m", "fine": True,
                                                    "offset": [0.0, 0.1], "none": None},
                    model="intent-ours-1")
    assert accepted("intent/infer", infer, "query")["model"] == "intent-ours-1"
    reset = {"v": 1, "seed": 3, "scene": {
        "objects": [{"name": "cup1", "type": "cup", "position": [0.5, 0.1, 0.05], "size": 0.08}],
        "robot": {"holding": "cup1"}}}
    accepted("sim/reset", reset, "query")


def test_nullable_fields_accept_null():
    summary = example("episode/summary", focus=None, focus_source=None)
    assert accepted("episode/summary", summary)["focus"] is None
    scene = example("scene/state")
    assert scene["robot"]["holding"] is None
    accepted("scene/state", scene)
    scene["robot"]["holding"] = "cup1"
    accepted("scene/state", scene)
    assert accepted("robot/state", example("robot/state", action=None))["action"] is None
    assert accepted("robot/state", example("robot/state", action="pick_up"))["action"] == "pick_up"
    intent = example("intent", episode=None, action=None, object=None)
    accepted("intent", intent)
    accepted("robot/act", example("robot/act", "reply", scene=None), "reply")
    accepted("intent/infer", example("intent/infer", "query", focus=None), "query")


# --------------------------------------------------------------------------- unknown fields


def test_unknown_fields_are_tolerated_at_every_level_and_preserved():
    frame = example("hands/frame")
    frame["x_top"] = {"anything": [1, 2]}
    frame["hands"][0]["x_hand"] = "extra"
    frame["hands"][0]["fingers"][1]["x_finger"] = 3
    frame["hands"][0]["fingers"][1]["bones"][2]["x_bone"] = [0.5, None]
    decoded = accepted("hands/frame", frame)
    assert decoded["x_top"] == {"anything": [1, 2]}
    assert decoded["hands"][0]["x_hand"] == "extra"
    assert decoded["hands"][0]["fingers"][1]["x_finger"] == 3
    assert decoded["hands"][0]["fingers"][1]["bones"][2]["x_bone"] == [0.5, None]


def test_unknown_fields_in_scene_objects_and_the_robot_are_preserved():
    scene = example("scene/state")
    scene["objects"][0]["color"] = "red"
    scene["objects"][0]["mass_kg"] = 0.2
    scene["robot"]["force"] = [0.0, 0.0, 1.5]
    decoded = accepted("scene/state", scene)
    assert decoded["objects"][0]["color"] == "red"
    assert decoded["objects"][0]["mass_kg"] == 0.2
    assert decoded["robot"]["force"] == [0.0, 0.0, 1.5]


def test_unknown_fields_are_not_checked_for_finiteness():
    # Only known fields are validated: an extension may carry anything msgpack can.
    decoded = accepted("gaze", example("gaze", x_quality=NAN))
    assert math.isnan(decoded["x_quality"])


# --------------------------------------------------------------------------- numpy values


def test_numpy_scalars_and_arrays_encode_as_plain_msgpack_and_validate():
    frame = example("hands/frame")
    frame["ts"] = np.float32(1_700_000.5)
    frame["seq"] = np.int64(1234)
    hand = frame["hands"][0]
    hand["palm_position"] = np.array([1.0, 200.0, 30.0], dtype=np.float32)
    hand["confidence"] = np.float64(0.75)
    hand["id"] = np.int32(4)
    hand["fingers"][1]["bones"][2]["width"] = np.float32(16.0)
    payload = wire.encode(frame)
    plain = msgpack.unpackb(payload, raw=False)
    assert type(plain["ts"]) is float and plain["ts"] == 1_700_000.5
    assert type(plain["seq"]) is int and plain["seq"] == 1234
    assert plain["hands"][0]["palm_position"] == [1.0, 200.0, 30.0]
    assert all(type(x) is float for x in plain["hands"][0]["palm_position"])
    assert type(plain["hands"][0]["id"]) is int
    decoded = wire.decode_checked(payload, wire.schema_for("hands/frame"))
    assert decoded["hands"][0]["fingers"][1]["bones"][2]["width"] == 16.0


def test_numpy_probability_arrays_and_bools_encode_and_validate():
    probs = np.full(8, 0.01, dtype=np.float32)
    probs[0] = 1.0 - 0.07
    message = example("gestures/static", probs=probs, hand_id=np.int64(2))
    decoded = accepted("gestures/static", message)
    assert len(decoded["probs"]) == 8 and decoded["hand_id"] == 2
    state = example("robot/state", joints=np.zeros(7), moving=np.bool_(True))
    assert accepted("robot/state", state)["moving"] is True


def test_a_numpy_nan_is_encoded_and_then_rejected():
    message = example("gaze", point=np.array([0.1, np.nan, 0.2]))
    assert rejection("gaze", message).path == "point[1]"


def test_a_tuple_is_encoded_as_a_list():
    assert accepted("gaze", example("gaze", point=(0.5, 0.1, 0.05)))["point"] == [0.5, 0.1, 0.05]


def test_values_without_a_msgpack_form_raise_type_error_on_encode():
    with pytest.raises(TypeError, match="cannot encode"):
        wire.encode({"v": 1, "when": object()})
    with pytest.raises(TypeError):
        wire.encode({"v": 1, "names": {"a", "b"}})


def test_numpy_values_are_not_accepted_by_validate_before_encoding():
    # validate() reads wire data; numpy values only become plain numbers through encode().
    message = example("gaze", ts=np.float32(5.0))
    with pytest.raises(RejectedMessage, match="got float32"):
        wire.validate(message, wire.schema_for("gaze"))


# --------------------------------------------------------------------------- payload level


def test_a_payload_over_the_default_limit_of_one_mebibyte_is_rejected():
    payload = wire.encode(example("hands/frame", device="x" * (1 << 20)))
    assert len(payload) > wire.DEFAULT_MAX_BYTES == 1 << 20
    with pytest.raises(RejectedMessage) as info:
        wire.decode_checked(payload, wire.schema_for("hands/frame"), FRAME_KEY)
    assert info.value.key == FRAME_KEY
    assert f"payload of {len(payload)} bytes exceeds the limit of 1048576 bytes" in str(info.value)


def test_a_payload_over_a_custom_smaller_limit_is_rejected_and_one_at_the_limit_is_not():
    payload = wire.encode(example("hands/frame"))
    with pytest.raises(RejectedMessage, match=f"exceeds the limit of {len(payload) - 1} bytes"):
        wire.decode(payload, max_bytes=len(payload) - 1)
    with pytest.raises(RejectedMessage, match="exceeds the limit of 1000 bytes"):
        wire.decode_checked(payload, wire.schema_for("hands/frame"), max_bytes=1000)
    assert wire.decode(payload, max_bytes=len(payload))["seq"] == 1234


def test_render_replies_have_a_larger_limit_than_the_default():
    assert wire.max_bytes_for("sim/render") > wire.DEFAULT_MAX_BYTES
    assert wire.max_bytes_for("sim/render") == wire.MAX_BYTES_RENDER
    assert wire.max_bytes_for("hands/frame") == wire.DEFAULT_MAX_BYTES
    assert wire.max_bytes_for("hands/frame", default=4096) == 4096
    payload = wire.encode(example("sim/render", "reply", png=b"\x89PNG" + bytes(2 << 20)))
    with pytest.raises(RejectedMessage, match="exceeds the limit"):
        wire.decode(payload)
    reply = wire.decode_checked(payload, wire.schema_for("sim/render", "reply"),
                                max_bytes=wire.max_bytes_for("sim/render"))
    assert isinstance(reply["png"], bytes) and len(reply["png"]) == (2 << 20) + 4


MAP = wire.encode({"v": 1, "ts": 1.0, "user": "u"})
BAD_PAYLOADS = [
    ("not-msgpack", b"\xc1", ["not a msgpack payload"]),
    ("empty", b"", ["not a msgpack payload"]),
    ("truncated", MAP[:-1], ["not a msgpack payload"]),
    ("text", b"hello, world", ["not a msgpack payload"]),
    ("json", b'{"v": 1}', ["not a msgpack payload"]),
    ("trailing-garbage", MAP + b"\x00", ["not a msgpack payload", "ExtraData"]),
    ("two-maps", MAP + MAP, ["not a msgpack payload", "ExtraData"]),
    ("invalid-utf8-string", b"\x81\xa1v\xa2\xff\xfe", ["not a msgpack payload"]),
    ("top-level-list", msgpack.packb([1, 2, 3]),
     ["expected a msgpack map at the top level", "got list [1, 2, 3]"]),
    ("top-level-int", msgpack.packb(7), ["expected a msgpack map at the top level", "got int 7"]),
    ("top-level-string", msgpack.packb("v"), ["at the top level", "got str 'v'"]),
    ("top-level-nil", msgpack.packb(None), ["at the top level", "got NoneType None"]),
    ("int-top-level-key", msgpack.packb({1: "a", "v": 1}),
     ["expected string keys in the top-level map"]),
    ("bytes-top-level-key", msgpack.packb({b"v": 1}, use_bin_type=True),
     ["expected string keys in the top-level map"]),
]


@pytest.mark.parametrize(("payload", "expected"), [c[1:] for c in BAD_PAYLOADS],
                         ids=[c[0] for c in BAD_PAYLOADS])
def test_a_payload_that_is_not_one_msgpack_map_with_string_keys_is_rejected(payload, expected):
    with pytest.raises(RejectedMessage) as info:
        wire.decode_checked(payload, wire.schema_for("user"), "cbgo/user")
    error = info.value
    assert error.key == "cbgo/user" and error.path == ""
    for text in expected:
        assert text in error.problem, f"{text!r} not in {error.problem!r}"


def test_a_payload_that_is_not_a_map_is_rejected_even_for_robot_stop():
    with pytest.raises(RejectedMessage, match="at the top level"):
        wire.decode_checked(msgpack.packb([1]), wire.schema_for("robot/stop"))


@pytest.mark.parametrize("payload", [b"\x81\x91\x01\x01", b"\x81\x81\xa1a\x01\x01"],
                         ids=["array-key", "map-key"])
def test_a_map_with_an_unhashable_key_is_rejected_not_crashing(payload):
    with pytest.raises(RejectedMessage, match="not a msgpack payload|string keys"):
        wire.decode_checked(payload, wire.schema_for("robot/stop"), "cbgo/robot/stop")


def test_a_deeply_nested_params_value_is_rejected_not_crashing():
    value: object = 0.0
    for _ in range(1020):
        value = [value]
    payload = wire.encode(example("episode/summary", params={"deep": value}))
    assert len(payload) < 4096
    try:
        wire.decode_checked(payload, wire.schema_for("episode/summary"))
    except RejectedMessage:
        pass


# --------------------------------------------------------------------------- schema version


def test_a_newer_schema_version_is_rejected_with_upgrade_advice():
    error = rejection("hands/frame", example("hands/frame", v=2), key=FRAME_KEY)
    assert error.path == "v"
    assert "schema version 2 is newer than this build's 1" in error.problem
    assert "upgrade cbgo" in error.problem
    assert str(error).startswith(f"{FRAME_KEY}: v: ")


def test_version_zero_is_rejected_as_out_of_range():
    error = rejection("user", example("user", v=0))
    assert (error.path, error.problem) == ("v", "expected an integer >= 1, got int 0")


def test_the_current_version_is_one():
    assert wire.SCHEMA_VERSION == 1
    for suffix, role in EXAMPLE_KEYS:
        assert example(suffix, role)["v"] == 1


def test_a_newer_version_with_a_changed_schema_is_rejected_for_its_version_first():
    message = example("gaze", v=2)
    del message["source"]
    error = rejection("gaze", message)
    assert error.path == "v" and "upgrade cbgo" in error.problem


# --------------------------------------------------------------------------- message quality


def test_too_many_hands_is_rejected_naming_the_limit():
    message = example("hands/frame")
    message["hands"] = message["hands"] * 17
    error = rejection("hands/frame", message)
    assert "16" in error.problem


def test_a_wrong_typed_nullable_field_says_that_null_is_allowed():
    error = rejection("scene/state", mutated("scene/state", "message",
                                             setting("robot", "holding", 5)))
    assert error.problem == "expected null or a non-empty string, got int 5"


def test_a_nullable_field_names_the_inner_path_when_its_content_is_bad():
    error = rejection("episode/summary", example("episode/summary", focus=[0.0, NAN, 0.0]))
    assert (error.path, error.problem) == ("focus[1]", "expected a finite number, got float nan")


def test_a_fractional_render_width_is_rejected():
    rejection("sim/render", example("sim/render", "query", width=640.5), "query")
