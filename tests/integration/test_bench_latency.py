"""`cbgo bench latency --quick` through real processes: it runs, and its figures are consistent.

No speed is asserted (the bench prints figures; the machine may be busy): the test checks that
every episode of the smoke run ends in an accepted intent whose plan reaches the robot, that all
four measures have values, and that the values agree with each other and with causality.
"""

import json

import pytest

from cbgo_tools.bench.latency import QUICK_EPISODES
from cbgo_tools.bench.latency_figures import MEASURES


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """Runs the smoke bench once (about 30 s) and returns (printed text, results)."""
    from cbgo.cli.main import main

    out = tmp_path_factory.mktemp("bench-latency") / "results.json"
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "latency", "--quick", "--out", str(out)])
    assert exit_info.value.code == 0
    return json.loads(out.read_text())


def test_every_episode_ends_in_an_intent_and_a_robot_action(quick_run):
    tally = quick_run["tally"]
    assert tally["episodes"] == QUICK_EPISODES
    assert tally["lost"] == 0, tally["lost_reasons"]
    assert tally["as_expected"] == QUICK_EPISODES, tally["unexpected"]
    assert tally["plans"] == {"success": QUICK_EPISODES}
    assert quick_run["robot"]  # says which robot answered robot/act


def test_all_four_measures_have_positive_values(quick_run):
    measures = quick_run["measures"]
    assert set(measures) == set(MEASURES)
    for name in MEASURES:
        fig = measures[name]
        assert fig["n"] > 0, name
        assert 0 < fig["min"] <= fig["p50"] <= fig["p90"] <= fig["p99"] <= fig["max"], name
    for name in ("end_condition_to_intent", "last_hand_frame_to_intent",
                 "intent_to_first_robot_action"):
        assert measures[name]["n"] == QUICK_EPISODES, name
    # Several frames with a hand per episode, each with its static message.
    assert measures["frame_to_static"]["n"] > 10 * QUICK_EPISODES
    assert quick_run["static_missing"] == 0


def test_the_measures_agree_with_each_other(quick_run):
    debounce_ms = quick_run["settings"]["debounce_s"] * 1e3
    end = quick_run["measures"]["end_condition_to_intent"]
    last = quick_run["measures"]["last_hand_frame_to_intent"]
    # Unix time stamps as float64 are exact to about 0.2 µs: compare to 1 µs.
    assert last["p50"] == pytest.approx(end["p50"] + debounce_ms, abs=1e-3)
    assert last["min"] >= end["min"]
    for r in quick_run["records"]:
        # Causal order on the host's one clock: the episode is decided after its end
        # condition, the summary is received after it was stamped, and so on.
        assert r["last_hand_ts"] < r["end_condition"] < r["summary_ts"] <= r["summary_received"]
        # The bench and the intent service each receive the summary: the intent may be
        # stamped before the bench's own copy arrives (seen: by 0.3 ms), so only the
        # episode's stamp orders it.
        assert r["summary_ts"] <= r["intent_ts"] <= r["intent_received"]
        assert r["first_robot_action"] > r["intent_ts"]
        # The bench's own frames agree with the episode service on the last hand frame.
        assert r["bench_last_hand_ts"] == pytest.approx(r["last_hand_ts"], abs=1e-9)
    stages = quick_run["breakdown_from_end_condition"]
    assert stages["intent_received"]["p50"] == pytest.approx(end["p50"], abs=1e-3)
    assert stages["summary_stamped"]["p50"] <= stages["intent_received"]["p50"]
