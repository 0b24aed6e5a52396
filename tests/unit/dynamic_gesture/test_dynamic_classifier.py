"""Templates, calibrated probabilities with a none class, and the template files."""

import json

import numpy as np
import pytest

from cbgo.errors import ConfigError
from cbgo.services.dynamic_gesture.classifier import (
    NONE,
    Calibration,
    Classifier,
    NeuralCalibration,
    Template,
    calibration_from_dict,
    features,
    fit_calibration,
    fit_neural_calibration,
    mirror_rows,
    mirrored,
    softmax_rows,
)
from cbgo.services.dynamic_gesture.library import (
    DEFAULT_PATH,
    Library,
    check_name,
    read_default,
    save_user_template,
)


def line(direction, length=150.0, n=12, rng=None, noise=2.0):
    s = np.linspace(0, 1, n)
    s = s**3 * (10 - 15 * s + 6 * s**2)
    out = np.outer(s, np.asarray(direction, float)) * length
    if rng is not None:
        out += rng.normal(0, noise, out.shape)
    return out - out[0]


@pytest.fixture(scope="module")
def shipped():
    return Library(DEFAULT_PATH, None).load().classifier()


def test_the_shipped_library_has_the_five_gestures_and_a_none_class(shipped):
    assert shipped.names == ["swipe_up", "swipe_down", "swipe_left", "swipe_right", "rotate",
                             NONE]


def test_probabilities_sum_to_one_and_the_right_gesture_wins(shipped):
    cases = {"swipe_up": (0, 1, 0, 0), "swipe_down": (0, -1, 0, 0),
             "swipe_left": (-1, 0, 0, 0), "swipe_right": (1, 0, 0, 0), "rotate": (0, 0, 0, -1)}
    rng = np.random.default_rng(0)
    for name, direction in cases.items():
        p = shipped.probabilities(line(direction, rng=rng))
        assert p.sum() == pytest.approx(1.0) and np.all(p >= 0)
        assert shipped.names[int(p.argmax())] == name, (name, p)


def test_a_tiny_or_foreign_motion_is_no_gesture(shipped):
    rng = np.random.default_rng(1)
    for obs in (line((0, 1, 0, 0), length=12, rng=rng), line((0, 0, 1, 0), length=200, rng=rng),
                line((0, 0, 0, 1), length=150, rng=rng)):  # twitch, towards the user, roll back
        p = shipped.probabilities(obs)
        assert shipped.names[int(p.argmax())] == NONE, p


def test_a_change_of_hand_shape_makes_a_roll_less_likely_a_rotate(shipped):
    # Real hands change shape while they swipe, so the shape is only a weak cue.
    roll = line((0, 0, 0, -1), length=70)
    steady = shipped.probabilities(roll)
    assert shipped.names[int(steady.argmax())] == "rotate"
    changing = shipped.probabilities(roll, pose_change=1.0)  # a pinch being released
    assert changing[-1] > 2 * steady[-1]


def test_a_template_learned_from_a_few_takes_is_recognised_and_serialisable():
    rng = np.random.default_rng(2)
    takes = [line((0.7, 0.7, 0, 0), rng=rng) for _ in range(3)]
    template = Template.learn("swipe_diag", takes, source="user", user="alice")
    again = Template.from_dict(json.loads(json.dumps(template.to_dict())))
    assert again.name == "swipe_diag" and again.scale == pytest.approx(template.scale)
    _, calibration, _ = read_default()
    other = Template.learn("swipe_up", [line((0, 1, 0, 0), rng=rng) for _ in range(3)])
    classifier = Classifier([again, other], calibration)
    p = classifier.probabilities(line((0.7, 0.7, 0, 0), rng=rng))
    assert classifier.names[int(p.argmax())] == "swipe_diag"



def bowed(direction, bow, roll, rng):
    """A stroke along `direction` that bows towards `bow` and rolls: not mirror-symmetric."""
    s = np.linspace(0, 1, 14)[:, None]
    out = line(direction, n=14, rng=rng) + np.sin(np.pi * s) * np.asarray(bow, float) * 40
    out[:, 3] += s[:, 0] * roll
    return out - out[0]


def test_a_left_hands_stroke_is_scored_as_its_mirror_image_by_a_right_hand(shipped):
    swap = [shipped.names.index(n) for n in ("swipe_up", "swipe_down", "swipe_right",
                                             "swipe_left", "rotate", NONE)]
    rng = np.random.default_rng(5)
    for direction, bow, roll in [((1, 0, 0, 0), (0, 1, 1, 0), 30.0),
                                 ((-1, 0.2, 0, 0), (0, -1, 0.5, 0), -40.0),
                                 ((0.1, 1, 0, 0), (1, 0, 1, 0), 20.0)]:
        right = bowed(direction, bow, roll, rng)
        p_right = shipped.probabilities(right, side="right")
        p_left = shipped.probabilities(mirrored(right), side="left")
        assert p_left == pytest.approx(p_right[swap], abs=1e-9)
        # unmirrored, the left hand would be scored by the right hand's templates as they are
        assert not np.allclose(shipped.probabilities(mirrored(right), side="right"),
                               p_right[swap], atol=1e-3)


def test_only_whole_mirror_pairs_are_matched_mirrored_taught_gestures_as_performed():
    rng = np.random.default_rng(6)
    _, calibration, _ = read_default()

    def learn(name, direction, mirror=None):
        return Template.learn(name, [bowed(direction, (0, 1, 0, 0), 10.0, rng)
                                     for _ in range(3)], mirror=mirror)
    left = learn("swipe_left", (-1, 0, 0, 0), "swipe_right")
    right = learn("swipe_right", (1, 0, 0, 0), "swipe_left")
    up = learn("swipe_up", (0, 1, 0, 0), "swipe_up")
    wave = learn("wave", (1, 1, 0, 0))
    assert mirror_rows([left, right, up, wave]).tolist() == [1, 0, 2, -1]
    taught_left = learn("swipe_left", (-1, 0, 0, 0))  # a user's, replacing the default one
    assert mirror_rows([taught_left, right, up]).tolist() == [-1, -1, 2]
    classifier = Classifier([taught_left, right, wave], calibration)
    stroke = bowed((1, 0.3, 0, 0), (0, 1, 1, 0), 25.0, rng)
    assert classifier.probabilities(stroke, side="left") == pytest.approx(
        classifier.probabilities(stroke, side="right"))
    again = Template.from_dict(json.loads(json.dumps(right.to_dict())))
    assert again.mirror == "swipe_left"
    assert Template.from_dict(json.loads(json.dumps(wave.to_dict()))).mirror is None


def separable_windows(seed: int, n: int = 300):
    """Feature rows of windows near one of two templates (0, 1) or near neither (2: none)."""
    rng = np.random.default_rng(seed)
    samples, labels = [], []
    for _ in range(n):
        truth = int(rng.integers(3))
        d = rng.uniform(2.0, 4.0, 2)
        if truth < 2:
            d[truth] = rng.uniform(0.5, 1.5)
        samples.append(features(np.array([[0, 0, 0, 0], [100, 0, 0, 0]]), d * 0.03,
                                np.array([0.03, 0.03]), np.array([-3.0, -3.0]), np.zeros(2)))
        labels.append(truth)
    return samples, labels


def test_calibration_recovers_weights_that_separate_gestures_from_none():
    samples, labels = separable_windows(3)
    calibration = fit_calibration(samples, labels)
    assert calibration.theta[0] < 0  # farther from a template: less likely that template
    hits = [int(np.argmax(softmax_rows(f, calibration.theta))) == y
            for f, y in zip(samples, labels, strict=True)]
    assert np.mean(hits) > 0.9


def test_the_neural_calibration_separates_gestures_from_none_and_survives_a_round_trip():
    samples, labels = separable_windows(5)
    calibration = fit_neural_calibration(samples, labels, epochs=150)
    probs = np.array([calibration.probabilities(f) for f in samples])
    assert np.allclose(probs.sum(1), 1.0)
    assert np.mean(probs.argmax(1) == np.asarray(labels)) > 0.9
    data = json.loads(json.dumps(calibration.to_dict()))
    again = calibration_from_dict(data)
    assert isinstance(again, NeuralCalibration)
    assert np.allclose([again.probabilities(f) for f in samples], probs, atol=1e-4)
    assert isinstance(calibration_from_dict({"theta": [0.0] * 9}), Calibration)  # old files


def test_the_neural_calibration_serves_any_number_of_templates():
    samples, labels = separable_windows(6)
    calibration = fit_neural_calibration(samples, labels, epochs=50)
    three = np.vstack([samples[0][:2], samples[0][:1], samples[0][2:]])  # a third template
    assert calibration.probabilities(three).shape == (4,)


def test_neural_calibration_data_is_checked():
    good = fit_neural_calibration(*separable_windows(7, 60), epochs=5).to_dict()
    for broken in ({**good, "w1": [[1.0]]}, {**good, "std": [0.0] * 8},
                   {k: v for k, v in good.items() if k != "none_w"}, {**good, "bias": None}):
        with pytest.raises(ValueError):
            calibration_from_dict(broken)


def test_user_templates_join_the_library_and_replace_a_default_of_the_same_name(tmp_path):
    rng = np.random.default_rng(4)
    library = Library(DEFAULT_PATH, tmp_path).load()
    assert not library.changed()
    save_user_template(tmp_path, Template.learn("lift", [line((0, 1, 0, 0), rng=rng)] * 2,
                                                source="user"))
    save_user_template(tmp_path, Template.learn("rotate", [line((0, 0, 0, 1), rng=rng)] * 2,
                                                source="user"))
    (tmp_path / "broken.json").write_text("{not json")
    assert library.changed()
    library.load()
    assert library.names == ["swipe_up", "swipe_down", "swipe_left", "swipe_right", "rotate",
                             "lift"]
    assert next(t for t in library.templates if t.name == "rotate").source == "user"
    assert "broken.json" in library.skipped
    assert not library.changed()


def test_gesture_names_must_be_usable_on_the_wire_and_as_files():
    assert check_name("swipe_diag") == "swipe_diag"
    for bad in ("", "none", "../x", "a b", "x" * 80):
        with pytest.raises(ConfigError):
            check_name(bad)


def test_a_missing_default_library_says_how_to_make_one(tmp_path):
    with pytest.raises(ConfigError, match="cbgo train dynamic"):
        read_default(tmp_path / "nope.json")


def test_calibration_data_is_checked():
    with pytest.raises(ValueError):
        Calibration.from_dict({"theta": [1.0, 2.0]})
