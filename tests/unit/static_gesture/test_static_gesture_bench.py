"""`cbgo bench static` produces every figure (speed is printed, never asserted)."""

import json

import numpy as np

from cbgo.hands.data import load_real_features
from cbgo.services.static_gesture import bench


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
    assert fig["throughput"]["per_frame_fps"] > 0 and fig["throughput"]["batch_fps"] > 0
    lat = fig["latency"]
    assert lat["messages"] > 10 and 0 < lat["p50_ms"] <= lat["p99_ms"] <= lat["max_ms"]


def test_a_missing_real_test_file_is_named(tmp_path, capsys):
    parser = __import__("argparse").ArgumentParser()
    bench.add_arguments(parser)
    assert bench.run(parser.parse_args(["--eval", str(tmp_path / "nope.npz")])) == 2
    assert "no such file" in capsys.readouterr().out
    assert bench.find_eval(tmp_path / "nope.npz") is None
