"""Calibrated gesture poses: the data file, sampling, reproducible calibration, realism."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cbgo.hands.data import load_real_features, real_features_sha256
from cbgo.hands.model import PARAM_NAMES
from cbgo.hands.poses import (
    STATIC_GESTURES,
    gesture_mean,
    gesture_pose,
    gesture_spread,
    load_poses,
    parameter_correlation,
)
from cbgo_tools.bench.hands import KEPT, simulate, train_knn, train_mlp
from cbgo_tools.hands.calibrate import calibrate


def test_poses_json_covers_every_gesture_and_says_how_it_was_made():
    data = load_poses()
    assert set(data["gestures"]) == set(STATIC_GESTURES)
    header = data["header"]
    assert header["command"].startswith("cbgo train hands")
    assert header["source_sha256"] == real_features_sha256()
    for entry in data["gestures"].values():
        assert list(entry["mean_deg"]) == list(PARAM_NAMES)
        assert all(v >= 0 for v in entry["spread_deg"].values())
    assert set(data["shape"]) == {"scale", "wrist_mm", "phalanx_factors", "thumb_cmc_mm"}


def test_gesture_pose_is_reproducible_and_zero_variation_gives_the_mean():
    a = gesture_pose("two", np.random.default_rng(5))
    b = gesture_pose("two", np.random.default_rng(5))
    assert a == b
    assert gesture_pose("two", np.random.default_rng(6), variation=0.0) == gesture_mean("two")
    assert gesture_spread("two").shape == (len(PARAM_NAMES),)
    with pytest.raises(ValueError, match="unknown static gesture"):
        gesture_pose("wave", np.random.default_rng(0))


def test_the_parameter_correlation_is_a_valid_correlation_matrix():
    corr = parameter_correlation()
    assert corr == pytest.approx(corr.T)
    assert np.diag(corr) == pytest.approx(1.0)
    assert np.linalg.eigvalsh(corr).min() > 0
    i, j = PARAM_NAMES.index("index_pip"), PARAM_NAMES.index("pinky_pip")
    assert corr[i, j] > 0.5 and corr[i, PARAM_NAMES.index("thumb_ip")] == 0.0


def test_the_calibration_is_reproducible_for_a_seed():
    first = calibrate(restarts=1, steps=25, seed=3, progress=False)
    second = calibrate(restarts=1, steps=25, seed=3, progress=False)
    assert json.dumps(first["gestures"]) == json.dumps(second["gestures"])
    assert first["shape"] == second["shape"]
    assert set(first["gestures"]) == set(STATIC_GESTURES)


def test_real_trained_classifiers_recognise_simulated_gestures():
    x, y, names = load_real_features()
    x_sim, y_sim, _ = simulate(names, per_gesture=60, seed=1)
    for predict in (train_knn(x[:, KEPT], y), train_mlp(x[:, KEPT], y, seed=0, epochs=200)):
        pred = predict(x_sim[:, KEPT])
        for g, name in enumerate(names):
            accuracy = (pred[y_sim == g] == g).mean()
            assert accuracy >= 0.9, f"{name}: {accuracy:.0%}"
