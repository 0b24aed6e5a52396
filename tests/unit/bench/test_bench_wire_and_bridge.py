"""`cbgo bench wire` produces its figures (values are printed, not asserted as speed goals)."""

from cbgo.examples import EXAMPLE_KEYS
from cbgo_tools.bench.wire import codec_table, router_latency


def test_the_codec_table_has_a_row_per_example_with_measured_costs():
    rows = codec_table(repeat=10)
    assert [(r["key"], r["role"]) for r in rows] == list(EXAMPLE_KEYS)
    assert all(r["bytes"] > 0 and r["encode_us"] > 0 and r["decode_us"] > 0 for r in rows)


def test_router_latency_receives_every_frame_sent_through_a_real_router():
    lat = router_latency(count=30, rate=200)
    assert lat["frames_received"] == 30
    assert 0 < lat["p50_ms"] <= lat["p99_ms"] <= lat["max_ms"]


def test_the_bridge_benchmark_measures_a_real_leap_bridge_stream():
    from cbgo_tools.bench.bridge import measure

    s = measure(60.0, 1.5, "demo")
    assert s["frames"] > 60 and s["invalid"] == 0
    assert 50.0 < s["rate_hz"] < 70.0
