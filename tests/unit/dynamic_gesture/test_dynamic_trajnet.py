"""The trajectory network (`trajnet`): a second opinion on a window, blended with the templates."""

import json
from dataclasses import replace

import numpy as np
import pytest

from cbgo.services.dynamic_gesture.classifier import NONE, blend, mirrored, net_rows
from cbgo.services.dynamic_gesture.library import (
    Library,
    read_default,
    save_default,
    save_user_template,
)
from cbgo.wire import DYNAMIC_GESTURES
from cbgo_tools.dynamic_gesture import simdata, train

NAMES = [*DYNAMIC_GESTURES, NONE]


@pytest.fixture(scope="module")
def tiny():
    """A classifier learned, templates, calibration and network, from one simulated user."""
    user = simdata.run_user(7, simdata.TRAIN, reps=1)
    return user, train.fit([user], [user], [])


def test_a_library_keeps_its_network_and_answers_as_the_classifier_it_was_saved_from(
        tiny, tmp_path):
    user, classifier = tiny
    assert classifier.net is not None and classifier.net.names == NAMES
    path = tmp_path / "lib.json"
    save_default(path, classifier.templates, classifier.calibration,
                 {"roll_scale_mm_per_rad": 100.0}, {"users": 1}, classifier.net)
    assert json.loads(path.read_text())["trajectory_net"]["kind"] == "mlp"
    again = Library(path, None).load().classifier()
    windows = [lw.window for lw in user.windows]
    ours = np.array([classifier.classify(w) for w in windows])
    theirs = np.array([again.classify(w) for w in windows])
    assert np.allclose(ours, theirs, atol=1e-4)
    assert np.allclose(ours.sum(1), 1.0)
    alone = Library(path, None).load()
    alone.net = None  # the templates alone answer otherwise: the network is in use
    assert not np.allclose(theirs, [alone.classifier().classify(w) for w in windows], atol=1e-3)


def test_a_library_without_a_network_loads_and_uses_the_templates_alone(tiny, tmp_path):
    _, classifier = tiny
    path = tmp_path / "old.json"
    save_default(path, classifier.templates, classifier.calibration, {}, {})
    library = Library(path, None).load()
    assert library.net is None and library.classifier().net is None


def test_a_malformed_network_is_refused_when_the_library_is_read(tiny, tmp_path):
    _, classifier = tiny
    data = classifier.net.to_dict()
    data["layers"][1]["w"] = data["layers"][1]["w"][:-1]  # no longer chains
    path = tmp_path / "bad.json"
    save_default(path, classifier.templates, classifier.calibration, {}, {})
    raw = json.loads(path.read_text())
    raw["trajectory_net"] = data
    path.write_text(json.dumps(raw))
    with pytest.raises(Exception, match="trajectory network"):
        read_default(path)


def test_a_left_hands_window_is_read_as_the_mirror_of_the_right_hands(tiny):
    user, classifier = tiny
    net = classifier.net
    swap = [NAMES.index({"swipe_left": "swipe_right", "swipe_right": "swipe_left"}.get(n, n))
            for n in NAMES]
    for lw in user.windows[:20]:
        w = lw.window
        right = net.probabilities(w.obs, w.final, w.pose_change, w.peak_speed, "right")
        left = net.probabilities(mirrored(w.obs), w.final, w.pose_change, w.peak_speed, "left")
        assert np.allclose(left, right[swap])


def test_the_blend_leaves_a_taught_gesture_and_a_replaced_one_their_templates_probability():
    names = ["swipe_up", "swipe_down", "wave", NONE]
    probs = np.array([0.3, 0.1, 0.2, 0.4])
    net_probs = np.array([0.05, 0.05, 0.05, 0.05, 0.1, 0.7])  # over NAMES: mostly none
    mixed = blend(probs, net_probs, net_rows(names, NAMES, known={"swipe_up", "swipe_down"}))
    assert mixed.sum() == pytest.approx(1.0)
    assert mixed[2] == pytest.approx(0.2)  # "wave": no network opinion
    assert mixed[3] > probs[3] and mixed[0] < probs[0]  # the network leans to none
    users_swipe_up = net_rows(names, NAMES, known={"swipe_down"})
    kept = blend(probs, net_probs, users_swipe_up)
    assert kept[0] == pytest.approx(0.3) and kept[2] == pytest.approx(0.2)
    # the two opinions are multiplied: geometric mean of the shares, renormalised
    agree = blend(probs, net_probs, net_rows(names, NAMES, known={"swipe_up", "swipe_down"}),
                  dtw_weight=1.0)
    assert np.allclose(agree, probs)


def test_a_user_version_of_a_shipped_gesture_gets_no_network_opinion(tiny, tmp_path):
    user, classifier = tiny
    path = tmp_path / "lib.json"
    save_default(path, classifier.templates, classifier.calibration, {}, {}, classifier.net)
    folder = tmp_path / "gestures"
    save_user_template(folder, replace(classifier.templates[0]))
    library = Library(path, folder).load()
    assert library.replaced == {classifier.templates[0].name}
    assert classifier.templates[0].name not in library.classifier().net_known
