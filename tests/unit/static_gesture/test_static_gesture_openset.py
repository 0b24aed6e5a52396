"""The open-set rule the classifier applies: far frames fade into none (`openset`)."""

import json

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.services.static_gesture import classifier, openset, train
from cbgo.services.static_gesture.classifier import StaticClassifier


def test_the_kth_distance_is_the_kth_smallest_euclidean_distance():
    rng = np.random.default_rng(0)
    reference, query = rng.normal(size=(300, 4)), rng.normal(size=(7, 4))
    want = np.sort(np.linalg.norm(query[:, None] - reference[None], axis=-1), 1)[:, 2]
    assert np.allclose(openset.kth_distance(reference, query, 3), want)


def test_references_and_calibration_rows_are_disjoint_and_cover_every_class():
    y = np.repeat([0, 1, 2], [4 * openset.REFERENCE_PER_CLASS, 40, 3])
    ref, cal = openset.split_per_class(y, [0, 1, 2], np.random.default_rng(0))
    assert not set(ref) & set(cal)
    assert np.bincount(y[ref]).tolist() == [openset.REFERENCE_PER_CLASS, 20, 2]
    assert np.bincount(y[cal]).tolist() == [openset.CALIBRATION_PER_CLASS, 20, 1]


def test_p_values_rank_a_distance_among_the_calibration_ones():
    rule = openset.OpenSet(np.zeros((5, 1)), np.arange(1.0, 100.0), neighbours=1)
    p = rule.p_values(np.array([[0.5], [50.0], [1000.0]]))
    assert p.tolist() == pytest.approx([1.0, 51 / 100, 1 / 100])


def test_faded_probabilities_stay_a_distribution_and_near_frames_keep_theirs():
    rule = openset.OpenSet(np.zeros((5, 1)), np.arange(1.0, 1001.0), neighbours=1, alpha=0.01)
    probs = np.array([[0.7, 0.2, 0.1], [0.7, 0.2, 0.1], [0.7, 0.2, 0.1]])
    out = rule.apply(probs, np.array([[10.0], [995.0], [5000.0]]), none_index=2)
    assert out.sum(1) == pytest.approx(np.ones(3))
    assert out[0] == pytest.approx(probs[0])  # nearer than 99 % of the training gestures
    assert out[1, 0] == pytest.approx(0.7 * (1 + 6) / 1001 / 0.01)  # six calibration rows as far
    assert out[2, :2] == pytest.approx(probs[2, :2] / 1001 / 0.01)  # farther than every one
    assert out[2, 2] > 0.9


@pytest.fixture(scope="module")
def small_model():
    options = train.TrainOptions(per_gesture=30, none=30, off_vocabulary=30, hidden=[8],
                                 epochs=2, mmhgr=False, user_gestures=False, members=2)
    data = train.build_datasets(options, user=[])
    return train.fit(data, options), data[0]


def test_frames_far_from_every_training_gesture_are_none_training_ones_keep_their_answer(
        small_model):
    trained, data = small_model
    clf = train.classifier_of(trained, samples=4)
    known = data.x[np.array(data.names)[data.y] != "none"]
    far = known[:20].copy()
    far[:, 42:] *= 4.0  # every fingertip and palm distance four times a hand's
    none = clf.names.index("none")
    near_raw, near = clf.predict_features(known, open_set=False), clf.predict_features(known)
    assert (near.argmax(1) == near_raw.argmax(1)).mean() > 0.97
    # not all: tanh units saturate, and a frame far out can land where training frames do
    assert (clf.predict_features(far).argmax(1) == none).mean() > 0.7
    assert (clf.predict_features(far, open_set=False).argmax(1) == none).mean() < 0.5


def test_the_rule_travels_with_the_model_and_a_broken_one_is_refused(small_model, tmp_path):
    trained, data = small_model
    train.save_model(tmp_path / "m", trained)
    loaded = StaticClassifier.load(tmp_path / "m", samples=4)
    fresh = train.classifier_of(trained, samples=4)
    assert [rule.reference.shape for rule in loaded.open_sets] == [
        (len(rule.reference), 8) for rule in fresh.open_sets]
    assert loaded.predict_features(data.x[:50]) == pytest.approx(
        fresh.predict_features(data.x[:50]), abs=1e-6)
    assert all(t > 0 for t in loaded.describe()["open_set"]["thresholds"])
    meta = json.loads((tmp_path / "m.json").read_text())
    meta["open_set"][1]["reference"]["shape"] = [3, 8]
    (tmp_path / "m.json").write_text(json.dumps(meta))
    with pytest.raises(ConfigError, match="open_set"):
        StaticClassifier.load(tmp_path / "m")


def test_each_member_needs_its_own_rule(small_model, tmp_path):
    trained, _ = small_model
    train.save_model(tmp_path / "m", trained)
    meta = json.loads((tmp_path / "m.json").read_text())
    meta["open_set"] = meta["open_set"][:1]
    (tmp_path / "m.json").write_text(json.dumps(meta))
    with pytest.raises(ConfigError, match="1 rules for 2 networks"):
        StaticClassifier.load(tmp_path / "m")


@pytest.mark.parametrize("alpha", [0.01, 0.2, 0.999])
def test_ranking_only_the_frames_past_the_line_changes_no_answer(alpha):
    rng = np.random.default_rng(1)
    reference = rng.normal(size=(400, 3))
    rule = openset.OpenSet(reference, np.sort(openset.kth_distance(
        reference, rng.normal(size=(300, 3)), 5)), neighbours=5, alpha=alpha)
    hidden = rng.normal(size=(500, 3)) * np.linspace(0.5, 3.0, 500)[:, None]  # near to far
    probs = rng.dirichlet(np.ones(4), size=500)
    every = np.minimum(1.0, rule.p_values(hidden) / alpha)  # the rule, every frame ranked
    want = probs * every[:, None]
    want[:, 3] = probs[:, 3] + (1.0 - every) * (1.0 - probs[:, 3])
    assert 0 < (every < 1).sum() < 500  # both kinds of frame are there
    assert rule.apply(probs, hidden, none_index=3) == pytest.approx(want, abs=1e-12)


def test_a_frame_is_no_gesture_when_answered_none_or_when_its_top_probability_is_below_half():
    names = ["grab", "none", "point"]
    probs = np.array([[0.9, 0.05, 0.05],    # a sure grab
                      [0.2, 0.7, 0.1],      # none
                      [0.45, 0.1, 0.45],    # nothing sure: rejected
                      [0.1, 0.4, 0.5]])     # point at exactly the line: kept
    assert classifier.answers(names, probs).tolist() == ["grab", "none", "none", "point"]
    assert classifier.is_rejected(np.array(["grab", "none", "point"]),
                                  np.array([0.49, 0.99, 0.5])).tolist() == [True, True, False]
