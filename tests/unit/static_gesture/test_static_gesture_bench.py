"""`cbgo bench static` produces every figure (speed is printed, never asserted)."""

import json

import numpy as np

from cbgo.hands.data import load_real_features
from cbgo_tools.static_gesture import bench


def test_the_bench_reports_accuracy_calibration_throughput_and_latency(tmp_path, capsys):
    x, y, names = load_real_features()
    split = tmp_path / "test.npz"  # a stand-in for ../shared/eval: tests never need it
    np.savez(split, X=x[:80].astype(np.float32), y=y[:80], names=np.array(names))
    out = tmp_path / "fig.json"
    parser = __import__("argparse").ArgumentParser()
    bench.add_arguments(parser)
    args = parser.parse_args(["--eval", str(split), "--per-gesture", "5", "--seconds", "1",
                              "--scenario-seeds", "1", "--frames", "200",
                              "--rate-hz", "60", "--no-crossval", "--json", str(out)])
    assert bench.run(args) == 0
    printed = capsys.readouterr().out
    for text in ("real test split: balanced accuracy", "held-out simulated users",
                 "classifier, one call per frame", "latency frame → gestures/static", "goals:"):
        assert text in printed
    fig = json.loads(out.read_text())
    assert fig["real"]["n"] == 80 and fig["real"]["balanced_accuracy"] > 0.9
    shifted = fig["real"]["shifted"]
    assert [r["times_training"] for r in shifted] == list(bench.SHIFTS)
    assert all(r["accepted_right"] <= r["network_accepted_right"] for r in shifted)
    assert "device- and person-style variation" in printed
    assert fig["throughput"]["per_frame_fps"] > 0 and fig["throughput"]["batch_fps"] > 0
    lat = fig["latency"]
    assert lat["messages"] > 10 and 0 < lat["p50_ms"] <= lat["p99_ms"] <= lat["max_ms"]


def test_a_missing_real_test_file_is_named(tmp_path, capsys):
    parser = __import__("argparse").ArgumentParser()
    bench.add_arguments(parser)
    assert bench.run(parser.parse_args(["--eval", str(tmp_path / "nope.npz")])) == 2
    assert "no such file" in capsys.readouterr().out
    assert bench.find_eval(tmp_path / "nope.npz") is None


def test_the_unknown_pose_goals_read_held_out_and_seen_poses_apart():
    throughput = {"per_frame_fps": 2000.0, "batch_fps": 9000.0, "service_handler_fps": 1500.0,
                  "service_handler_fps_cpu": 1500.0, "load_average": 0.5}
    crossval = {"accuracy": 0.92, "balanced_accuracy": 0.92, "folds": 25,
                "rejection_overall": 0.62, "rejection_seen_overall": 0.955}
    goals = {name: (met, text) for name, met, text in bench._goals(
        {"throughput": throughput, "crossval": crossval})}
    held = next(v for k, v in goals.items() if k.startswith("unknown poses held out"))
    seen = next(v for k, v in goals.items() if "trained as none" in k)
    assert held == (False, "62.0%") and seen == (True, "95.5%")
    skipped = bench._goals({"throughput": throughput})
    assert all(met is None for name, met, _ in skipped if name.startswith("unknown poses"))


def test_the_recipe_of_a_model_keeps_its_number_of_networks():
    import json as _json

    from cbgo.services.static_gesture import train
    from cbgo.services.static_gesture.classifier import StaticClassifier, weights_sha256

    x, y, names = load_real_features()
    options = train.TrainOptions(per_gesture=2, none=4, off_vocabulary=4, hidden=[4], epochs=1,
                                 members=2, mmhgr=False, user_gestures=False)
    trained = train.fit(train.build_datasets(options, (x[:200], y[:200], names), user=[]),
                        options)
    assert bench.recipe_of(train.classifier_of(trained)).members == 2
    network = trained.model.members[0]  # as a model written before ensembles holds it
    meta = _json.loads(_json.dumps(trained.metadata, default=train._plain))
    del meta["members"], meta["options"]["members"]
    meta["open_set"] = meta["open_set"][0]
    meta["weights_sha256"] = weights_sha256(network.state_dict())
    assert bench.recipe_of(StaticClassifier.from_model(network, meta, samples=4)).members == 1


def test_the_thumb_levels_of_the_recorded_thumbs_ups_are_summarised_without_the_hgr_cache():
    levels = bench.thumb_levels(None)
    (label, group), = levels.items()
    assert "paper" in label and group["n"] > 100 and 0.0 <= group["below_-30"] <= 1.0
    values = list(group["percentiles"].values())
    assert values == sorted(values) and list(group["percentiles"]) == list(
        bench.THUMB_PERCENTILES)


def test_the_ok_signs_shape_is_set_beside_the_papers_pinches_without_the_hgr_cache():
    shapes = bench.ok_shapes(None)
    pinches, gemini = shapes.values()
    assert pinches["n"] > 100 and gemini["n"] == 1
    # both hold thumb and index together, thumb tip bent: the same shape (README)
    for g in shapes.values():
        assert 0.0 <= g["tips_mm"] < 30.0 and 30.0 < g["thumb_last_joint_deg"] < 70.0
