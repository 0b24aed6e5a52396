"""static-gesture through FakeBus: one message per hand, rejects, reload, file watching."""

import json
import shutil

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.errors import ConfigError
from cbgo.examples import example
from cbgo.hands import features as F
from cbgo.hands.data import real_features_sha256
from cbgo.hands.model import HandShape, build_hand
from cbgo.hands.poses import gesture_pose
from cbgo.services.static_gesture import invariant
from cbgo.services.static_gesture.classifier import (
    StaticClassifier,
    default_model_path,
    personal_model_path,
    shipped_model_path,
    user_model_path,
)
from cbgo.services.static_gesture.main import StaticGesture, StaticGestureSettings
from cbgo.testing import FakeBus
from cbgo.wire import STATIC_GESTURES


def service(**settings):
    return FakeBus(StaticGesture(StaticGestureSettings(**settings)))


def gesture_hand(name, side="right", hand_id=1, variation=0.0, seed=0):
    rng = np.random.default_rng(seed)
    return build_hand(HandShape.default(side=side), gesture_pose(name, rng, variation),
                      [0.0, 220.0, 0.0], hand_id=hand_id)


def frame(hands, seq=7):
    return example("hands/frame", hands=hands, seq=seq)


def winner(message):
    return message["names"][int(np.argmax(message["probs"]))]


# --------------------------------------------------------------------------- messages


def test_each_hand_of_a_frame_gets_one_message_with_the_frames_seq_and_the_hands_identity():
    bus = service()
    msg = frame([gesture_hand("grab", "left", 3), gesture_hand("point", "right", 4)], seq=42)
    out = bus.feed(keys.HANDS_FRAME, msg)
    assert [topic for topic, _ in out] == ["gestures/static", "gestures/static"]
    for (_, m), hand_id, side in zip(out, (3, 4), ("left", "right"), strict=True):
        wire.validate(m, wire.GESTURES_STATIC)
        assert (m["seq"], m["ts"], m["hand_id"], m["side"]) == (42, msg["ts"], hand_id, side)
        assert m["model"].startswith("static-bnn-") and len(m["model"]) == len("static-bnn-") + 8
        assert m["names"][:8] == list(STATIC_GESTURES) and m["names"][-1] == "none"
        assert abs(sum(m["probs"]) - 1.0) < 1e-9
    assert [winner(m) for _, m in out] == ["grab", "point"]
    assert bus.counters.published == 2 and bus.counters.errors == 0


def test_a_frame_without_hands_publishes_nothing():
    bus = service()
    assert bus.feed(keys.HANDS_FRAME, frame([])) == []
    assert bus.counters.received == 1 and bus.counters.published == 0


def test_a_malformed_frame_is_rejected_counted_and_the_service_keeps_running():
    bus = service()
    bad = frame([gesture_hand("five")])
    bad["hands"][0]["confidence"] = 1.5
    assert bus.feed(keys.HANDS_FRAME, bad) == []
    assert bus.feed_raw(keys.HANDS_FRAME, b"\xc1 not msgpack") == []
    assert bus.counters.rejected == 2
    assert len(bus.feed(keys.HANDS_FRAME, frame([gesture_hand("five")]))) == 1


@pytest.mark.parametrize("side", ["left", "right"])
def test_the_shipped_model_recognises_every_gesture_on_either_hand(side):
    bus = service()
    hands = [gesture_hand(name, side, i) for i, name in enumerate(STATIC_GESTURES)]
    out = bus.feed(keys.HANDS_FRAME, frame(hands))
    assert [winner(m) for _, m in out] == list(STATIC_GESTURES)
    assert min(max(m["probs"]) for _, m in out) > 0.9


def test_a_mirror_image_hand_gets_the_same_probabilities():
    clf = StaticClassifier.load(shipped_model_path())
    hands = [gesture_hand("three", "left", variation=1.0, seed=3),
             gesture_hand("three", "right", variation=1.0, seed=3)]
    left, right = clf.classify_hands(hands)
    assert np.allclose(left, right, atol=1e-6)


def test_the_same_hand_gives_the_same_vector_every_time():
    clf = StaticClassifier.load(shipped_model_path())
    hand = gesture_hand("pinch", variation=1.0, seed=1)
    assert np.array_equal(clf.classify_hands([hand]), clf.classify_hands([hand]))


def test_the_relaxed_hand_between_gestures_is_no_gesture():
    from cbgo.hands.model import neutral_pose

    hand = build_hand(HandShape.default(), neutral_pose(), [0.0, 220.0, 0.0])
    out = service().feed(keys.HANDS_FRAME, frame([hand]))
    assert winner(out[0][1]) == "none"


def test_an_ignored_gesture_is_answered_as_none_and_the_others_are_untouched():
    hands = [gesture_hand("pinch"), gesture_hand("five", hand_id=2)]
    plain = [m for _, m in service().feed(keys.HANDS_FRAME, frame(hands))]
    bus = service(ignore=["pinch"])
    ignored = [m for _, m in bus.feed(keys.HANDS_FRAME, frame(hands))]
    names = ignored[0]["names"]
    pinch, none = names.index("pinch"), names.index("none")
    assert names == plain[0]["names"] and winner(plain[0]) == "pinch"
    for before, after in zip(plain, ignored, strict=True):
        wire.validate(after, wire.GESTURES_STATIC)
        assert after["probs"][pinch] == 0.0 and abs(sum(after["probs"]) - 1.0) < 1e-9
        assert after["probs"][none] == pytest.approx(before["probs"][none] + before["probs"][pinch])
        others = [k for k in range(len(names)) if k not in (pinch, none)]
        assert np.allclose(np.array(after["probs"])[others], np.array(before["probs"])[others])
    assert winner(ignored[0]) == "none" and winner(ignored[1]) == "five"
    assert bus.service.status_extra()["ignored"] == ["pinch"]


@pytest.mark.parametrize(("ignore", "reason"), [(["pinh"], "has no pinh among its classes"),
                                                (["none"], "none is what ignored")])
def test_an_ignored_name_the_model_cannot_answer_is_a_configuration_error(ignore, reason):
    with pytest.raises(ConfigError, match=reason):
        service(ignore=ignore)


def test_a_reloaded_model_without_an_ignored_gesture_is_refused_and_the_old_one_serves(
        make_model, tmp_path):
    pt, _, first = make_model("m", seed=1)
    without, _, _ = make_model("no-pinch", names=[g for g in STATIC_GESTURES if g != "pinch"]
                               + ["none"])
    bus = service(model=str(pt), watch_s=0.0, ignore=["pinch"])
    ok, reason = bus.query("reload", {"model": str(without)})
    assert not ok and f"still serving {first}" in reason and "has no pinch" in reason
    assert bus.feed(keys.HANDS_FRAME, frame([gesture_hand("five")]))[0][1]["model"] == first


# --------------------------------------------------------------------------- the model


def test_the_shipped_model_metadata_is_complete():
    base = shipped_model_path()
    meta = json.loads(base.with_suffix(".json").read_text())
    assert meta["kind"] == "static-gesture" and meta["format"] == "cbgo-bnn/1"
    assert meta["names"] == [*STATIC_GESTURES, "none"]
    assert meta["feature_version"] == F.FEATURE_VERSION
    # the device-independent features, derived from the 57 (no wrist, metacarpal or thumb-
    # metacarpal convention): proximal bones, distances and the joints' angles in 3-D
    names = invariant.names_of(invariant.TRANSFORM_BENDS)
    assert meta["transform"] == invariant.TRANSFORM_BENDS
    assert meta["inputs"] == list(range(len(names)))
    assert meta["feature_names"] == list(names)
    assert len(meta["standardizer"]["mean"]) == len(meta["standardizer"]["std"]) == 49
    assert meta["real_data_sha256"] == real_features_sha256()
    assert len(meta["data_hash"]) == 16 and meta["user_gestures"] == []
    per_source = meta["dataset"]["per_source"]
    assert per_source["real"] == 2 * 4477  # as recorded, and with device-style variation
    assert per_source["mmhgr"] > 0 and per_source["mmhgr_none"] > 0  # other people, unknown
    # poses
    clf = StaticClassifier.load(base)
    assert clf.model_id == meta["model_id"] == "static-bnn-" + meta["weights_sha256"][:8]


def test_a_weights_file_from_another_training_is_refused(make_model):
    pt_a, _, _ = make_model("a", seed=1)
    _, js_b, _ = make_model("b", seed=2)
    shutil.copy(pt_a, js_b.with_suffix(".pt"))
    with pytest.raises(ConfigError, match="SHA-256 mismatch"):
        StaticClassifier.load(js_b)


def test_a_model_that_does_not_load_at_start_is_a_configuration_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot load model"):
        service(model=str(tmp_path / "missing"))
    with pytest.raises(ConfigError, match="samples"):
        StaticGestureSettings(samples=0)


def test_without_a_model_setting_the_users_model_wins_over_the_shipped_one(tmp_path,
                                                                          monkeypatch,
                                                                          make_model):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    assert default_model_path() == shipped_model_path()
    bus = service(watch_s=1.0)
    shipped_id = bus.feed(keys.HANDS_FRAME, frame([gesture_hand("two")]))[0][1]["model"]
    _, _, user_id = make_model(user_model_path())  # an absolute path stays as it is
    assert default_model_path() == user_model_path()
    bus.tick(1.0)  # the poll re-resolves the default path and finds the user's model
    assert bus.feed(keys.HANDS_FRAME, frame([gesture_hand("two")]))[0][1]["model"] == user_id
    assert user_id != shipped_id


def test_the_person_cbgo_user_names_is_served_their_own_model_and_the_others_the_common_one(
        tmp_path, monkeypatch, make_model):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    _, _, common = make_model(user_model_path(), seed=1)
    _, _, alices = make_model(personal_model_path("alice"), seed=2)
    bus = service(watch_s=0.0)

    def served():
        return bus.feed(keys.HANDS_FRAME, frame([gesture_hand("two")]))[0][1]["model"]

    assert served() == common
    bus.feed(keys.USER, {"v": 1, "ts": 1.0, "user": "alice"})
    assert served() == alices
    assert bus.service.status_extra()["user"] == "alice" and bus.service.status_extra()["personal"]
    bus.feed(keys.USER, {"v": 1, "ts": 2.0, "user": "bob"})  # no model of his own
    assert served() == common and not bus.service.status_extra()["personal"]
    loaded = bus.service._loaded
    bus.feed(keys.USER, {"v": 1, "ts": 3.0, "user": "alice"})  # back: no reload
    assert served() == alices and bus.service._loaded is loaded and len(loaded) == 2
    bus.feed(keys.USER, {"v": 1, "ts": 4.0, "user": "../alice"})  # a name no file may carry
    assert personal_model_path("../alice") is None and served() == common


def test_a_broken_personal_model_is_counted_and_the_model_in_service_stays(
        tmp_path, monkeypatch, make_model):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path))
    pt, _, _ = make_model(personal_model_path("alice"), seed=2)
    pt.write_bytes(b"garbage")
    bus = service(watch_s=0.0)
    before = bus.service.classifier.model_id
    bus.feed(keys.USER, {"v": 1, "ts": 1.0, "user": "alice"})
    assert bus.service.classifier.model_id == before and bus.counters.errors == 1


# --------------------------------------------------------------------------- reload


def test_reload_answers_with_the_new_model_and_messages_carry_it(make_model):
    pt, _, first = make_model("m", seed=1)
    bus = service(model=str(pt.with_suffix("")), watch_s=0.0)
    assert bus.feed(keys.HANDS_FRAME, frame([gesture_hand("five")]))[0][1]["model"] == first
    _, _, second = make_model("m", seed=2)
    ok, reply = bus.query("reload", None)
    assert ok and reply["model"] == second and reply["previous"] == first
    assert bus.feed(keys.HANDS_FRAME, frame([gesture_hand("five")]))[0][1]["model"] == second


def test_reload_can_switch_to_another_model_file(make_model):
    pt_a, _, first = make_model("a", seed=1)
    pt_b, _, second = make_model("b", seed=2)
    bus = service(model=str(pt_a), watch_s=0.0)
    ok, reply = bus.query("reload", {"model": str(pt_b)})
    assert ok and reply["model"] == second
    assert bus.service.status_extra()["model"]["model"] == second


def test_a_broken_model_on_reload_is_an_error_reply_and_the_old_model_keeps_serving(make_model):
    pt, js, first = make_model("m")
    bus = service(model=str(pt), watch_s=0.0)
    pt.write_bytes(b"garbage")
    ok, reason = bus.query("reload", {})
    assert not ok and f"reload failed, still serving {first}" in reason
    js.write_text("{not json")
    ok, reason = bus.query("reload", {})
    assert not ok and "cannot load model" in reason
    ok, reason = bus.query("reload", {"model": 3})
    assert not ok and "model must be a path" in reason
    out = bus.feed(keys.HANDS_FRAME, frame([gesture_hand("grab")]))
    assert out[0][1]["model"] == first
    assert bus.counters.errors == 2


def test_a_changed_model_file_is_picked_up_by_the_poll(make_model):
    pt, _, first = make_model("m", seed=1)
    bus = service(model=str(pt), watch_s=1.0)
    bus.tick(1.0)
    assert bus.service.classifier.model_id == first
    _, _, second = make_model("m", seed=2)
    bus.tick(1.0)
    assert bus.service.classifier.model_id == second


def test_a_broken_file_seen_by_the_poll_is_counted_once_and_the_old_model_stays(make_model):
    pt, _, first = make_model("m", seed=1)
    bus = service(model=str(pt), watch_s=1.0)
    pt.write_bytes(b"half a model")
    bus.tick(1.0)
    bus.tick(1.0)
    assert bus.service.classifier.model_id == first
    assert bus.counters.errors == 1
    _, _, second = make_model("m", seed=2)  # the trainer finishes: loaded at the next poll
    bus.tick(1.0)
    assert bus.service.classifier.model_id == second


def test_status_shows_the_model_in_service_and_the_hands_classified():
    bus = service()
    bus.feed(keys.HANDS_FRAME, frame([gesture_hand("four"), gesture_hand("two", hand_id=2)]))
    ok, status = bus.query("status", None)
    assert ok and status["hands_classified"] == 2
    assert status["model"]["names"][-1] == "none" and status["model"]["samples"] == 32


def test_the_posterior_average_is_the_mean_softmax_of_networks_drawn_from_q():
    import torch

    from cbgo import bayes
    from cbgo.services.static_gesture.classifier import Posterior

    torch.manual_seed(0)
    model = bayes.BayesMLP(bayes.Architecture(5, [4, 3], 2))
    with torch.no_grad():
        for layer in model.layers:
            layer.w_rho.fill_(-1.0)  # sigma ≈ 0.31: the draws differ visibly
    x = np.random.default_rng(0).normal(size=(3, 5))
    post = Posterior.draw(model, 6, seed=1)
    reference = []
    for s in range(6):
        h = x
        for i, (w, b) in enumerate(zip(post.weights, post.biases, strict=True)):
            h = h @ w[s] + b[s, 0]
            h = np.tanh(h) if i < 2 else h
        e = np.exp(h - h.max(1, keepdims=True))
        reference.append(e / e.sum(1, keepdims=True))
    assert np.allclose(post.predict(x), np.mean(reference, 0))
    many = Posterior.draw(model, 4000, seed=2).predict(x)
    assert np.allclose(many, bayes.predict_proba(model, x, samples=4000), atol=0.02)


def test_the_fixed_draws_are_the_networks_bayes_draws_from_the_same_seed():
    import torch

    from cbgo import bayes
    from cbgo.services.static_gesture.classifier import Posterior

    torch.manual_seed(0)
    model = bayes.BayesMLP(bayes.Architecture(5, [4, 3], 2))
    with torch.no_grad():
        for layer in model.layers:
            layer.w_rho.fill_(-1.0)
    x = np.random.default_rng(0).normal(size=(3, 5))
    with torch.no_grad():
        logits = model.forward_drawn(torch.as_tensor(x, dtype=torch.float32),
                                     model.draw(6, torch.Generator().manual_seed(1)))
    torch_mean = torch.softmax(logits, -1).mean(0).double().numpy()
    assert np.allclose(Posterior.draw(model, 6, seed=1).predict(x), torch_mean, atol=1e-5)
    assert not np.allclose(Posterior.draw(model, 6, seed=2).predict(x), torch_mean, atol=1e-3)
