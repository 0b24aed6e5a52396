"""The static-gesture trainer: data set, user gestures, atomic saving, grouped validation split."""

import json

import numpy as np
import pytest

from cbgo.hands.data import load_real_features
from cbgo.services.static_gesture import invariant, train
from cbgo.services.static_gesture.classifier import (
    Posterior,
    StaticClassifier,
    default_model_path,
)
from cbgo.wire import STATIC_GESTURES


def small_real(n=240):
    x, y, names = load_real_features()
    return x[:n], y[:n], names


def take(user="alice", count=5):
    return {"user": user, "ts": 1.0, "time": "2025-01-01T00:00:00Z", "count": count,
            "device": "sim"}


def test_the_data_set_holds_real_simulated_no_gesture_and_user_rows_in_name_order(tmp_path):
    rng = np.random.default_rng(0)
    horns = train.UserGesture("horns", rng.normal(0, 1, (5, 57)), [take()])
    grab = train.UserGesture("grab", rng.normal(0, 1, (400, 57)), [take(count=400)])
    options = train.TrainOptions(per_gesture=3, none=10, off_vocabulary=6)
    data = train.build_dataset(options, small_real(), user=[horns, grab])
    assert data.names == [*STATIC_GESTURES, "horns", "none"]
    summary = data.summary()
    # the real rows come twice: as recorded and with device-style variation
    assert summary["per_source"] == {"real": 2 * 240, "simulated": 24, "none": 10 + 6,
                                     "user": train.USER_MIN_ROWS + 400}
    assert summary["per_class"]["horns"] == train.USER_MIN_ROWS  # augmented
    assert (data.y[data.source == "none"] == data.names.index("none")).all()
    assert {g["name"] for g in data.user_gestures} == {"horns", "grab"}


def test_off_vocabulary_poses_use_no_finger_pattern_of_the_vocabulary():
    assert len(train.OFF_VOCABULARY) == 16 - len(train.VOCABULARY_PATTERNS)
    assert not set(train.OFF_VOCABULARY) & set(train.VOCABULARY_PATTERNS)
    x = train.simulate_off_vocabulary(9, np.random.default_rng(0))
    assert x.shape == (9, 57) and np.isfinite(x).all()


def test_the_raw_feature_set_still_trains_models_on_the_57():
    options = train.TrainOptions(per_gesture=1, none=2, off_vocabulary=0, hidden=[4], epochs=1,
                                 features="raw")
    trained = train.fit(train.build_dataset(options, small_real(), user=[]), options)
    assert trained.metadata["transform"] is None
    assert trained.metadata["inputs"] == list(train.INPUTS)
    clf = train.classifier_of(trained)
    assert clf.predict_features(small_real()[0][:3]).shape == (3, 9)


def test_without_the_no_gesture_class_there_is_no_none_name():
    data = train.build_dataset(train.TrainOptions(per_gesture=2, none=0), small_real(), user=[])
    assert data.names == list(STATIC_GESTURES) and "none" not in data.source


def test_simulation_is_reproducible_and_never_shares_people_between_streams():
    a = train.simulate_gestures(["grab"], 4, train._rng(train.SIM_STREAM_TRAIN, 0))[0]
    b = train.simulate_gestures(["grab"], 4, train._rng(train.SIM_STREAM_TRAIN, 0))[0]
    c = train.simulate_gestures(["grab"], 4, train._rng(train.SIM_STREAM_BENCH, 0))[0]
    assert np.array_equal(a, b) and not np.allclose(a, c)
    assert train.simulate_none(6, ["five"], np.random.default_rng(1)).shape == (6, 57)


def test_a_recorded_gesture_accumulates_takes_with_their_attribution(tmp_path):
    train.store_gesture("horns", np.zeros((3, 57)), take("alice", 3), tmp_path)
    path = train.store_gesture("horns", np.ones((2, 57)), take("bob", 2), tmp_path)
    g = train.read_gesture(path)
    assert g.name == "horns" and g.x.shape == (5, 57)
    assert [t["user"] for t in g.takes] == ["alice", "bob"]
    train.store_gesture("horns", np.ones((4, 57)), take("carol", 4), tmp_path, replace=True)
    (g,) = train.load_user_gestures(tmp_path)
    assert g.x.shape == (4, 57) and [t["user"] for t in g.takes] == ["carol"]
    assert not list(tmp_path.glob("tmp-*"))


def test_a_recording_of_another_feature_version_is_skipped_with_a_note(tmp_path, capsys):
    np.savez(tmp_path / "old.npz", X=np.zeros((2, 57)),
             meta=np.array(json.dumps({"name": "old", "feature_version": 0})))
    assert train.load_user_gestures(tmp_path) == []
    assert "record it again" in capsys.readouterr().out


def test_augmentation_jitters_few_rows_up_to_the_minimum():
    x = np.tile(np.linspace(0, 1, 57), (4, 1))
    out = train.augment(x, 50, np.random.default_rng(0))
    assert out.shape == (50, 57) and np.array_equal(out[:4], x)
    assert 0 < np.abs(out[4:] - x[0]).mean() < 3.0
    assert train.augment(x, 2, np.random.default_rng(0)) is x


def test_a_saved_model_is_written_atomically_and_pinned_by_its_weights(tmp_path):
    options = train.TrainOptions(per_gesture=2, none=8, hidden=[4], epochs=2)
    trained = train.fit(train.build_dataset(options, small_real(), user=[]), options)
    pt, js, model_id = train.save_model(tmp_path / "models" / "m.pt", trained)
    assert sorted(p.name for p in (tmp_path / "models").iterdir()) == ["m.json", "m.pt"]
    meta = json.loads(js.read_text())
    assert meta["model_id"] == model_id and model_id == "static-bnn-" + meta["weights_sha256"][:8]
    assert meta["train"]["epochs"] == 2 and meta["options"]["none"] == 8
    clf = StaticClassifier.load(pt)
    assert clf.model_id == model_id
    fresh = train.classifier_of(trained)
    x = small_real(5)[0]
    assert np.allclose(clf.predict_features(x), fresh.predict_features(x))


def test_the_grouped_split_holds_out_whole_clusters_of_every_gesture():
    x, y, _ = load_real_features()
    held, kept = train.grouped_split(x, y, 0.2, seed=0)
    assert not set(held) & set(kept) and len(held) + len(kept) == len(y)
    assert set(np.unique(y[held])) == set(range(8))
    assert 0.1 < len(held) / len(y) < 0.3


def test_evaluation_counts_a_name_the_model_lacks_as_wrong(tmp_path):
    options = train.TrainOptions(per_gesture=0, none=0, hidden=[4], epochs=1)
    clf = train.classifier_of(train.fit(train.build_dataset(options, small_real(), user=[]),
                                        options))
    fig = train.evaluate(clf, np.zeros((2, 57)), ["unknown", "unknown"])
    assert fig["balanced_accuracy"] == 0.0 and fig["classes"] == ["unknown"]


def test_the_trainer_cli_writes_the_model_where_asked(tmp_path, capsys):
    import argparse

    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    args = parser.parse_args(["--out", str(tmp_path / "m"), "--per-gesture", "2", "--none", "5",
                              "--epochs", "1", "--hidden", "4", "--no-user-gestures"])
    assert train.run(args) == 0
    printed = capsys.readouterr().out
    assert "trained static-bnn-" in printed and (tmp_path / "m.pt").is_file()


@pytest.mark.parametrize("flags,expected", [(["--no-none"], 0), ([], train.TrainOptions().none)])
def test_no_none_turns_the_no_gesture_class_off(flags, expected):
    import argparse

    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    assert train.options_from(parser.parse_args(flags)).none == expected


def test_the_same_training_gives_the_same_model_id_wherever_it_is_saved(tmp_path):
    options = train.TrainOptions(per_gesture=2, none=4, hidden=[4], epochs=1)
    ids = [train.save_model(tmp_path / name, train.fit(
        train.build_dataset(options, small_real(), user=[]), options))[2] for name in "ab"]
    assert ids[0] == ids[1]


def test_ensemble_members_see_the_same_recordings_but_their_own_simulated_hands():
    options = train.TrainOptions(per_gesture=3, none=6, off_vocabulary=6, members=3)
    datasets = train.build_datasets(options, small_real(), user=[])
    one = train.build_dataset(options, small_real(), user=[])
    assert len(datasets) == 3 and np.array_equal(datasets[0].x, one.x)
    recorded = [d.x[d.source == "real"][:240] for d in datasets]  # then their varied copies
    simulated = [d.x[d.source == "simulated"] for d in datasets]
    assert all(np.array_equal(small_real()[0], r) for r in recorded)
    assert not np.allclose(simulated[0], simulated[1])
    assert not np.allclose(simulated[1], simulated[2])


def test_an_ensemble_averages_networks_that_disagree(tmp_path):
    options = train.TrainOptions(per_gesture=10, none=10, off_vocabulary=10, hidden=[8],
                                 epochs=3, members=2)
    trained = train.fit(train.build_datasets(options, small_real(), user=[]), options)
    assert len(trained.model.members) == 2 and trained.metadata["members"] == 2
    clf = train.classifier_of(trained, samples=8)
    inputs = clf.network_inputs(small_real()[0])
    seed = int(clf.metadata["weights_sha256"][:8], 16)
    alone = [Posterior.draw(network, 4, seed + i)  # 8 draws in all, 4 from each member
             for i, network in enumerate(trained.model.members)]
    each = [posterior.predict(inputs) for posterior in alone]
    assert np.abs(each[0] - each[1]).max() > 0.05  # their own seeds and data
    assert clf.posterior.predict_members(inputs) == pytest.approx(np.stack(each))
    assert clf.posterior.embed(inputs) == pytest.approx(
        np.stack([posterior.embed(inputs)[0] for posterior in alone]))
    assert clf.predict_features(small_real()[0], open_set=False) == pytest.approx(
        np.mean(each, axis=0))
    _, _, model_id = train.save_model(tmp_path / "m", trained)
    loaded = StaticClassifier.load(tmp_path / "m", samples=8)
    assert loaded.model_id == model_id and loaded.describe()["members"] == 2


def test_a_model_of_one_network_written_before_ensembles_still_loads(tmp_path):
    from cbgo import bayes
    from cbgo.services.static_gesture.classifier import weights_sha256

    options = train.TrainOptions(per_gesture=5, none=5, off_vocabulary=5, hidden=[4],
                                 epochs=1, members=1)
    trained = train.fit(train.build_datasets(options, small_real(), user=[]), options)
    network = trained.model.members[0]
    meta = json.loads(json.dumps(trained.metadata, default=train._plain))
    del meta["members"]
    meta["open_set"] = meta["open_set"][0]  # one rule, not a list, as they were written
    meta["weights_sha256"] = weights_sha256(network.state_dict())
    bayes.save(tmp_path / "old", network, meta)
    old = StaticClassifier.load(tmp_path / "old", samples=4)
    fresh = StaticClassifier.from_model(network, meta, samples=4)  # draws seeded by its hash
    x = small_real(20)[0]
    assert old.posterior.members == 1 and old.open_sets[0] is not None
    assert old.model_id == "static-bnn-" + meta["weights_sha256"][:8]
    assert old.predict_features(x) == pytest.approx(fresh.predict_features(x), abs=1e-9)


@pytest.mark.parametrize("flags", [["--members", "0"], ["--epochs", "0"]])
def test_flags_no_training_can_run_with_are_a_clear_error(flags):
    import argparse

    from cbgo.errors import ConfigError

    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    with pytest.raises(ConfigError, match="must be at least 1"):
        train.options_from(parser.parse_args(flags))


def test_joint_angles_the_caller_computed_already_give_the_same_answer():
    clf = StaticClassifier.load(default_model_path())
    assert clf.transform == invariant.TRANSFORM_BENDS  # the path the service takes
    x = small_real(12)[0]
    assert np.array_equal(clf.predict_features(x, bent=invariant.bends(x)),
                          clf.predict_features(x))
    other = invariant.bends(x[::-1])  # another hand's angles: the model reads what it is given
    assert not np.allclose(clf.predict_features(x, bent=other), clf.predict_features(x))


def test_a_personal_model_reads_only_its_persons_takes_and_the_common_one_none_of_them(tmp_path):
    rows = np.zeros((10, 57))
    rows[6:, 0] = 1.0  # bob's rows
    train.store_gesture("thumbsup", rows[:4], {"user": "alice", "count": 4}, tmp_path)
    train.store_gesture("thumbsup", rows[4:6], {"user": "alice", "count": 2, "personal": True},
                        tmp_path)
    train.store_gesture("thumbsup", rows[6:], {"user": "bob", "count": 4}, tmp_path)
    (alice,) = train.load_user_gestures(tmp_path, user="alice")
    assert len(alice.x) == 6 and not alice.x[:, 0].any()
    (bob,) = train.load_user_gestures(tmp_path, user="bob")
    assert len(bob.x) == 4 and bob.x[:, 0].all()
    (common,) = train.load_user_gestures(tmp_path)  # alice's personal take left out
    assert len(common.x) == 8 and [t["user"] for t in common.takes] == ["alice", "bob"]
    assert train.load_user_gestures(tmp_path, user="carol") == []
