"""The evidence model: time integration, threshold, decay, re-arming, merge, and g."""

import math

import pytest

from cbgo.evidence import Evidence, EvidenceSettings, gesture_vector

NAMES = ["grab", "point", "none"]


def hold(ev, label, p, seconds, rate_hz, start=0.0, side="right"):
    """Static messages at rate_hz; returns the triggers with their times."""
    out = []
    for i in range(round(seconds * rate_hz) + 1):
        vector = [p if n == label else (1 - p) / 2 for n in NAMES]
        out += ev.static(start + i / rate_hz, side, NAMES, vector)
    return out


@pytest.mark.parametrize("rate_hz", [30, 60, 120])
def test_static_evidence_triggers_at_the_same_time_whatever_the_frame_rate(rate_hz):
    s = EvidenceSettings()
    (trig,) = hold(Evidence(s), "grab", 0.9, 1.0, rate_hz)
    expected = -s.static_tau_s * math.log(1 - s.threshold / 0.9)  # 0.33 s
    assert trig.gesture == "grab" and trig.source == "static" and trig.prob == 0.9
    assert expected <= trig.ts < expected + 1 / rate_hz + 1e-9


def test_a_gesture_triggers_once_per_episode():
    ev = Evidence()
    assert [t.gesture for t in hold(ev, "grab", 0.95, 3.0, 60)] == ["grab"]


def test_a_probability_below_the_threshold_never_triggers():
    assert hold(Evidence(), "grab", 0.59, 5.0, 60) == []


def test_a_short_flicker_does_not_trigger():
    ev = Evidence()
    assert hold(ev, "grab", 1.0, 0.1, 60) == []
    assert ev.value("grab", 0.1) < 0.3


def test_evidence_decays_when_the_gesture_is_not_observed():
    ev = Evidence()
    hold(ev, "grab", 0.9, 1.0, 60)
    at_end = ev.value("grab", 1.0)
    assert at_end == pytest.approx(0.9 * (1 - math.exp(-1 / 0.3)), rel=0.02)
    assert ev.value("grab", 1.3) == pytest.approx(at_end * math.exp(-1), rel=1e-6)
    hold(ev, "grab", 0.0, 1.0, 60, start=2.0)  # observed as absent: decays too
    assert ev.value("grab", 3.0) < 0.01


def test_with_rearm_a_gesture_triggers_again_only_after_it_was_released():
    ev = Evidence(EvidenceSettings(rearm=True))
    first = hold(ev, "grab", 0.9, 1.0, 60)
    assert hold(ev, "grab", 0.9, 1.0, 60, start=1.0 + 1 / 60) == []  # still held: no retrigger
    hold(ev, "point", 0.9, 1.0, 60, start=2.0 + 1 / 60)  # grab released: evidence decays
    again = hold(ev, "grab", 0.9, 1.0, 60, start=3.0 + 1 / 60)
    assert [t.gesture for t in first + again] == ["grab", "grab"]


def test_a_no_gesture_class_never_triggers_and_is_not_a_gesture():
    ev = Evidence()
    assert hold(ev, "none", 1.0, 2.0, 60) == []
    assert "none" not in ev.names and set(ev.names) == {"grab", "point"}
    ev2 = Evidence()
    assert ev2.static(0.0, "right", ["no_gesture", "grab"], [1.0, 0.0]) == []
    assert list(ev2.names) == ["grab"]


def test_one_confident_stroke_window_triggers_at_once():
    ev = Evidence()
    (trig,) = ev.dynamic((1.0, 1.45), "right", ["swipe_down", "none"], [0.9, 0.1])
    assert trig.gesture == "swipe_down" and trig.source == "dynamic"
    assert trig.window == (1.0, 1.45) and trig.ts == 1.45


def test_short_or_unsure_windows_do_not_trigger():
    ev = Evidence()
    assert ev.dynamic((1.0, 1.1), "right", ["swipe_down", "none"], [0.9, 0.1]) == []
    assert ev.dynamic((2.0, 2.6), "right", ["swipe_down", "none"], [0.55, 0.45]) == []


def test_growing_windows_of_one_stroke_are_not_counted_twice():
    ev = Evidence()
    for end in (0.2, 0.3, 0.4, 0.5):  # the same stroke re-evaluated, p = 0.5 each time
        assert ev.dynamic((0.0, end), "right", ["rotate", "none"], [0.5, 0.5]) == []
    assert ev.value("rotate", 0.5) <= 0.5
    (trig,) = ev.dynamic((0.0, 0.45), "right", ["rotate", "none"], [0.85, 0.15])  # the final
    assert trig.gesture == "rotate"


def test_later_windows_of_the_triggering_stroke_are_saved_with_its_trigger():
    # A preparation triggers swipe_left sure; the real swipe_right triggers on an early, unsure
    # window and is then judged sure: g must name swipe_right, not the preparation.
    ev = Evidence()
    names = ["swipe_left", "swipe_right", "none"]
    (prep,) = ev.dynamic((0.0, 0.5), "right", names, [0.85, 0.05, 0.10])
    (swipe,) = ev.dynamic((2.0, 2.4), "right", names, [0.05, 0.70, 0.25])
    ev.dynamic((2.0, 2.6), "right", names, [0.02, 0.97, 0.01])
    ev.dynamic((5.0, 5.4), "left", names, [0.01, 0.99, 0.0])  # another hand's stroke: not its
    assert swipe.snapshot["swipe_right"] == 0.97 and prep.snapshot["swipe_right"] == 0.05
    g = dict(zip(*gesture_vector([t.snapshot for t in ev.triggers], names), strict=True))
    assert max(g, key=g.get) == "swipe_right"
    assert "none" not in swipe.snapshot


def test_the_snapshot_merges_static_and_dynamic_probabilities_by_name():
    ev = Evidence()
    hold(ev, "point", 0.9, 0.2, 60)
    (trig,) = ev.dynamic((0.0, 0.2), "right", ["swipe_down", "point", "none"], [0.9, 0.05, 0.05])
    snap = trig.snapshot
    assert snap["swipe_down"] == 0.9 and snap["point"] == 0.9  # max of static 0.9, dynamic 0.05
    assert snap["grab"] == pytest.approx(0.05) and "none" not in snap


def test_stale_vectors_are_not_part_of_the_snapshot():
    ev = Evidence()
    ev.dynamic((0.0, 0.5), "right", ["rotate", "none"], [0.9, 0.1])
    (trig,) = hold(ev, "grab", 0.9, 1.0, 60, start=2.0)  # 1.5 s after the window
    assert trig.snapshot["rotate"] == 0.0 and trig.snapshot["grab"] == 0.9


def test_both_hands_accumulate_separately():
    ev = Evidence()
    for i in range(61):
        t = i / 60
        ev.static(t, "left", NAMES, [0.9, 0.05, 0.05])
        ev.static(t, "right", NAMES, [0.05, 0.9, 0.05])
    assert sorted(t.gesture for t in ev.triggers) == ["grab", "point"]
    assert {t.side for t in ev.triggers} == {"left", "right"}


def test_g_is_the_elementwise_maximum_of_the_saved_vectors():
    snaps = [{"point": 0.9, "grab": 0.05, "swipe_down": 0.1},
             {"point": 0.2, "grab": 0.1, "swipe_down": 0.85}]
    names, probs = gesture_vector(snaps, ["grab", "point", "swipe_down", "rotate", "zzz"])
    assert names == ["grab", "point", "swipe_down", "rotate", "zzz"]  # vocabulary order
    assert probs == [0.1, 0.9, 0.85, 0.0, 0.0]


def test_without_triggers_g_is_all_zeros():
    assert gesture_vector([], ["grab", "point"]) == (["grab", "point"], [0.0, 0.0])
