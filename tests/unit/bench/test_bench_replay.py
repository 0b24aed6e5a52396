"""`cbgo bench replay` produces its figures (printed, not asserted as speed goals)."""

import argparse

import numpy as np
import pytest

from cbgo.recording import read_recording
from cbgo_tools.bench import replay


def test_the_recording_holds_every_message_at_its_random_gap(tmp_path):
    written = replay.write_recording(tmp_path / "r.mcap", "cbgo", 50, (2.0, 18.0), seed=1)
    recorded = list(read_recording(tmp_path / "r.mcap"))
    assert [(m.key, m.payload, m.log_time_ns) for m in recorded] == written
    gaps_ms = np.diff([n for _k, _p, n in written]) / 1e6
    assert gaps_ms.min() >= 2.0 and gaps_ms.max() <= 18.0
    assert {k for k, _p, _n in written} == {f"cbgo/{k}" for k in replay.KEYS}


def test_timing_errors_are_zero_on_schedule_and_measure_a_late_message():
    logged = np.array([0, 10, 30, 35], dtype=np.float64) * 1e6  # ns
    on_time = 5.0 + np.array([0.0, 0.010, 0.030, 0.035])  # any origin
    exact = replay.timing_errors(on_time, logged, speed=1.0)
    assert exact["interval"]["max"] == pytest.approx(0.0, abs=1e-9)
    assert exact["offset"]["max"] == pytest.approx(0.0, abs=1e-9)
    late = on_time + [0.0, 0.0, 0.004, 0.0]  # the third message 4 ms late
    errors = replay.timing_errors(late, logged, speed=1.0)
    assert errors["interval"]["max"] == pytest.approx(4.0)
    assert errors["offset"]["max"] == pytest.approx(4.0)
    doubled = replay.timing_errors(5.0 + np.array([0.0, 0.005, 0.015, 0.0175]), logged, 2.0)
    assert doubled["interval"]["max"] == pytest.approx(0.0, abs=1e-9)


def test_the_bench_replays_through_a_real_router_and_prints_its_figures(capsys):
    args = argparse.Namespace(count=40, min_ms=1.0, max_ms=3.0, speed=1.0, seed=3)
    assert replay.run(args) == 0
    out = capsys.readouterr().out
    assert "replayed 40 messages" in out and "40 arrived, all in order, as recorded" in out
    assert "|interval error|" in out and "|offset from schedule|" in out


def test_bad_flags_are_refused():
    args = argparse.Namespace(count=1, min_ms=2.0, max_ms=18.0, speed=1.0, seed=3)
    assert replay.run(args) == 2
