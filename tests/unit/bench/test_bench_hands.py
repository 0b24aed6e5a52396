"""`cbgo bench hands` produces its figures (printed; the realism goal is reported, not asserted)."""

import argparse
import json

from cbgo_tools.bench import hands as bench
from cbgo_tools.registry import BENCHES


def test_the_hands_bench_is_registered_and_writes_its_figures_as_json(tmp_path, capsys):
    assert "hands" in BENCHES
    parser = argparse.ArgumentParser()
    bench.add_arguments(parser)
    out = tmp_path / "hands.json"
    assert bench.run(parser.parse_args(["--per-gesture", "10", "--epochs", "30",
                                                 "--json", str(out)])) == 0
    printed = capsys.readouterr().out
    assert "simulated hands recognised" in printed and "worst 10" in printed
    fig = json.loads(out.read_text())
    assert set(fig["classifiers"]) == {"mlp", "knn"}
    for result in fig["classifiers"].values():
        assert set(result["per_gesture"]) == set(fig["names"])
        assert sum(map(sum, result["confusion"])) == 10 * len(fig["names"])
    assert len(fig["feature_comparison"]) == len(fig["names"]) * 53
