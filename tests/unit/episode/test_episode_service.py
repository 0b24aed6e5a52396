"""The episode service through FakeBus: events, summaries, evidence, focus, params, user, errors."""

import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.errors import ConfigError
from cbgo.evidence import EvidenceSettings
from cbgo.examples import open_hand
from cbgo.services.episode.main import EpisodeSettings
from cbgo.simuser.scenario import parse_scenario
from cbgo.simuser.user import SimulatedUser
from cbgo.transform import default_to_base

T0 = 1000.0  # the driver's frames clock at its time 0 (conftest.T0)


def test_an_episode_has_a_start_and_an_end_event_and_one_summary(drive):
    d = drive()
    d.empty(0.2)
    first = d.hold(0.5, "grab")
    assert [m["kind"] for k, m in first if k == "episode/event"][0] == "start"
    d.empty(0.4)
    events = d.of("episode/event")
    assert [e["kind"] for e in events] == ["start", "trigger", "end"]
    (summary,) = d.summaries
    wire.validate(summary, wire.EPISODE_SUMMARY, "cbgo/episode/summary")
    assert summary["episode"] == events[0]["episode"] == events[-1]["episode"]
    assert summary["started"] == pytest.approx(T0 + 0.2 + d.period)
    assert summary["ended"] == pytest.approx(T0 + 0.7)
    published = [k for k, _ in d.bus.published]
    assert published[-2:] == ["episode/event", "episode/summary"]  # end, then the summary


def test_an_episode_with_replayed_frames_has_a_summary_marked_replayed(drive):
    d = drive()
    d.hold(0.5, "grab")
    d.empty(0.4)
    d.bus.feed(keys.HANDS_FRAME, {"v": 1, "ts": T0 + d.now + 0.01, "seq": d.seq, "hands": [
        open_hand()], "source": "replay", "device": "test", "replayed": True})
    d.seq += 1
    d.hold(0.5, "grab")
    d.empty(0.4)
    live, replayed = d.summaries
    assert "replayed" not in live and replayed["replayed"] is True
    wire.validate(replayed, wire.EPISODE_SUMMARY, "cbgo/episode/summary")


def test_the_episode_ends_on_the_first_empty_frame_after_the_debounce(drive):
    d = drive(debounce_s=0.1)
    d.hold(0.3)
    out = []
    for _ in range(10):
        out = d.frame([])
        if out:
            break
    assert [m.get("kind") for _, m in out] == ["end", None]
    assert d.svc.ended_by["frame"] + d.svc.ended_by["clock"] == 1
    assert out[1][1]["ended"] == pytest.approx(T0 + 0.3)
    assert d.now - 0.3 >= 0.1 - 1e-9


def test_a_one_frame_dropout_does_not_split_the_episode(drive):
    d = drive()
    d.hold(0.4, "grab")
    d.frame([])  # one frame without the hand
    d.hold(0.4, "grab")
    d.empty(0.3)
    assert len(d.of("episode/event", "start")) == 1 and len(d.summaries) == 1


def test_the_timer_ends_the_episode_when_frames_stop(drive):
    d = drive()
    d.hold(0.3)
    wait = d.svc.settings.debounce_s + d.svc.settings.clock_slack_s
    assert d.tick(wait - 0.05) == []
    out = d.tick(0.06)
    assert [k for k, _ in out] == ["episode/event", "episode/summary"]
    assert d.svc.ended_by["clock"] == 1
    assert d.svc.status_extra()["end_latency_ms"]["n"] == 1


def test_each_episode_gets_a_unique_id(drive):
    d = drive()
    for _ in range(3):
        d.hold(0.2)
        d.empty(0.3)
    ids = [s["episode"] for s in d.summaries]
    assert len(ids) == len(set(ids)) == 3


def test_a_gesture_triggers_once_when_its_evidence_passes_the_threshold(drive):
    d = drive()
    d.hold(0.2, "grab")
    assert d.of("episode/event", "trigger") == []  # 0.2 s at p = 0.9: evidence 0.44
    d.hold(1.0, "grab")
    (trig,) = d.of("episode/event", "trigger")
    assert trig["gesture"] == "grab" and trig["prob"] == pytest.approx(0.9)
    assert 0.3 <= trig["ts"] - T0 <= 0.4
    d.empty(0.3)
    (summary,) = d.summaries
    assert [t["gesture"] for t in summary["triggers"]] == ["grab"]


def test_g_is_the_elementwise_max_of_the_triggered_snapshots_without_none(drive):
    d = drive()
    d.hold(0.6, "point", p=0.8)
    d.hold(0.6, "grab", p=0.95)
    d.empty(0.3)
    (summary,) = d.summaries
    g = dict(zip(summary["gestures"]["names"], summary["gestures"]["probs"], strict=True))
    assert "none" not in g
    assert g["point"] == pytest.approx(0.8) and g["grab"] == pytest.approx(0.95)
    others = [p for n, p in g.items() if n not in ("point", "grab")]
    assert max(others) == pytest.approx(0.2 / 8)  # the first snapshot: (1 - 0.8) / 8 each
    assert summary["gestures"]["names"][:8] == list(wire.STATIC_GESTURES)
    assert set(wire.DYNAMIC_GESTURES) <= set(g)


def test_a_gesture_seen_but_never_triggered_keeps_only_its_snapshot_values(drive):
    d = drive()
    d.hold(0.6, "grab", p=0.9)
    d.hold(0.15, "point", p=0.95)  # too short to trigger, after grab's snapshot
    d.empty(0.3)
    g = dict(zip(*d.summaries[0]["gestures"].values(), strict=True))
    assert g["point"] == pytest.approx(0.1 / 8)


def test_static_and_dynamic_vectors_merge_by_name(drive):
    d = drive()
    d.hold(0.6, "point")
    start = d.now
    d.hold(0.45, None)
    d.dynamic("swipe_down", start, d.now, p=0.9)
    d.empty(0.3)
    (summary,) = d.summaries
    assert [t["gesture"] for t in summary["triggers"]] == ["point", "swipe_down"]
    g = dict(zip(*summary["gestures"].values(), strict=True))
    leaders = sorted(g, key=g.get, reverse=True)[:2]
    assert set(leaders) == {"point", "swipe_down"}


def test_a_stroke_window_published_as_the_hand_leaves_still_counts(drive):
    d = drive()
    start = d.now
    d.hold(0.5, None)
    end = d.now
    d.frame([])
    d.frame([])
    d.dynamic("swipe_left", start, end)  # 33 ms after the hand left, before the end decision
    d.empty(0.3)
    assert [t["gesture"] for t in d.summaries[0]["triggers"]] == ["swipe_left"]


def test_gesture_messages_after_the_end_are_counted_as_late_and_dropped(drive):
    d = drive()
    start = d.now
    d.hold(0.3, "grab")
    d.empty(0.3)
    first = d.seq - 1
    assert d.dynamic("swipe_left", start, start + 0.3) == []
    assert d.static("grab", seq=first - 20) == []
    d.static("grab", seq=0)  # a frame of the finished episode
    assert d.svc.stray["late"] == 3
    d.svc.closed = None
    d.static("grab")
    assert d.svc.stray["outside"] == 1
    assert len(d.summaries) == 1 and len(d.of("episode/event", "trigger")) == 0


def test_the_focus_comes_from_gaze_robust_to_outliers(drive):
    d = drive()
    rng = np.random.default_rng(3)
    d.gaze([0.45, 0.1, 0.05])  # before the episode: within the look-back
    for i in range(30):
        d.hold(1 / 60, "grab")
        point = [0.45, 0.1, 0.05] + rng.normal(0, 0.01, 3)
        d.gaze([1.5, -1.0, 0.0] if i % 10 == 0 else point)  # a glance elsewhere now and then
    d.empty(0.3)
    (summary,) = d.summaries
    assert summary["focus_source"] == "gaze"
    assert np.linalg.norm(np.subtract(summary["focus"], [0.45, 0.1, 0.05])) < 0.01


def test_old_gaze_before_the_episode_is_not_its_focus(drive):
    d = drive()
    for _ in range(5):
        d.gaze([0.45, 0.1, 0.05])
    d.empty(1.0)
    d.hold(0.5, "grab")
    d.empty(0.3)
    assert d.summaries[0]["focus"] is None and d.summaries[0]["focus_source"] is None


def pointing_hand(to_base, target):
    hand = open_hand()
    knuckle = np.array([1.0, 0.05, 0.25])
    direction = np.subtract(target, knuckle)
    from cbgo.transform import base_to_leap

    bones = hand["fingers"][1]["bones"]
    bones[1]["prev_joint"] = base_to_leap(to_base, knuckle).tolist()
    bones[3]["next_joint"] = base_to_leap(to_base, knuckle + 0.08 * direction
                                          / np.linalg.norm(direction)).tolist()
    return hand


def test_without_gaze_the_focus_is_where_the_pointing_ray_meets_the_table(drive):
    to_base = default_to_base([1.1, -0.1, 0.02], yaw_deg=-15.0)
    d = drive()
    d.to_base = to_base.reshape(-1).tolist()
    hand = pointing_hand(to_base, [0.5, -0.25, 0.0])
    d.hold(0.3, "grab")  # not pointing: its rays do not count
    d.hold(0.6, "point", hand=hand)
    d.empty(0.3)
    (summary,) = d.summaries
    assert summary["focus_source"] == "pointing"
    assert summary["focus"] == pytest.approx([0.5, -0.25, 0.0], abs=1e-6)


def test_without_to_base_there_is_no_pointing_focus(drive):
    d = drive()
    hand = pointing_hand(default_to_base(), [0.5, -0.25, 0.0])
    for _ in range(40):
        d.frame([hand], to_base=False)
        d.static("point")
    d.empty(0.3)
    assert d.summaries[0]["focus_source"] is None


def test_the_focus_sources_can_be_restricted_to_pointing(drive):
    d = drive(focus=["pointing"])
    for _ in range(5):
        d.gaze([0.45, 0.1, 0.05])
    d.hold(0.5, "point", hand=pointing_hand(default_to_base(), [0.6, 0.2, 0.0]))
    d.empty(0.3)
    assert d.summaries[0]["focus_source"] == "pointing"


def test_params_carry_the_pinch_distance(drive):
    d = drive()
    hand = open_hand()
    tip = np.array(hand["fingers"][1]["bones"][3]["next_joint"])
    hand["fingers"][0]["bones"][3]["next_joint"] = (tip + [0.0, -25.0, 0.0]).tolist()
    d.hold(0.3, "grab")  # an open hand: its aperture is not the pinch's
    d.hold(0.6, "pinch", hand=hand)
    d.empty(0.3)
    assert d.summaries[0]["params"]["distance"] == pytest.approx(0.025)


def rolled_hand(deg):
    """An open hand whose palm is rolled by `deg` about its direction."""
    hand = open_hand()
    n, axis = np.array(hand["palm_normal"]), np.array(hand["direction"])
    a = np.radians(deg)
    rolled = n * np.cos(a) + np.cross(axis, n) * np.sin(a) + axis * (axis @ n) * (1 - np.cos(a))
    hand["palm_normal"] = rolled.tolist()
    return hand


def roll(d, start_deg, end_deg, seconds):
    """Frames rolling the palm from start_deg to end_deg; returns (t_start, t_end)."""
    t0, steps = d.now, round(seconds / d.period)
    for i in range(1, steps + 1):
        d.frame([rolled_hand(start_deg + (end_deg - start_deg) * i / steps)])
    return t0, d.now


def test_the_rotate_angle_comes_from_the_most_confident_rotate_stroke(drive):
    d = drive()
    d.hold(0.2)
    release = roll(d, 0.0, 60.0, 0.3)  # a pose released rolls the palm, a less sure rotate
    d.dynamic("rotate", *release, p=0.93)
    d.hold(0.2, hand=rolled_hand(60.0))
    rotate = roll(d, 60.0, 150.0, 0.5)
    d.dynamic("rotate", *rotate, p=0.99)
    d.hold(0.2, hand=rolled_hand(150.0))
    d.empty(0.3)
    (summary,) = d.summaries
    assert [t["gesture"] for t in summary["triggers"]] == ["rotate"]
    assert abs(summary["params"]["angle_deg"]) == pytest.approx(90, abs=3)


def test_the_user_is_the_last_one_announced_else_the_default(drive):
    d = drive(user="ops")
    d.hold(0.2)
    d.empty(0.3)
    d.bus.feed(keys.USER, {"v": 1, "ts": T0, "user": "alice"})
    d.bus.feed(keys.USER, {"v": 1, "ts": T0, "user": "bob"})
    d.hold(0.2)
    d.empty(0.3)
    assert [s["user"] for s in d.summaries] == ["ops", "bob"]


def test_bad_messages_are_rejected_and_counted_and_the_service_keeps_running(drive):
    d = drive()
    d.bus.feed_raw(keys.HANDS_FRAME, b"\x00junk")
    d.bus.feed(keys.GESTURES_STATIC, {"v": 1, "ts": T0, "seq": 1, "hand_id": 1,
                                      "side": "right", "names": ["grab", "point"],
                                      "probs": [0.9, 0.9], "model": "x"})  # sum != 1
    d.bus.feed(keys.GESTURES_DYNAMIC, {"v": 1, "ts": T0, "seq": 1, "hand_id": 1,
                                       "side": "right", "names": ["rotate"], "probs": [1.0],
                                       "window": [T0 + 1, T0], "model": "x"})  # reversed
    d.bus.feed(keys.GAZE, {"v": 1, "ts": T0, "point": [float("nan"), 0, 0],
                           "source": "simulated"})
    assert d.bus.counters.rejected == 4 and d.bus.counters.errors == 0
    d.hold(0.5, "grab")
    d.empty(0.3)
    assert len(d.summaries) == 1 and d.bus.counters.errors == 0


def test_a_frame_with_a_broken_to_base_is_used_without_it(drive):
    d = drive()
    d.to_base = [1.0] * 16  # not a rotation: ignored, with a warning
    d.hold(0.5, "point", hand=pointing_hand(default_to_base(), [0.6, 0.2, 0.0]))
    d.empty(0.3)
    assert d.summaries[0]["focus"] is None and d.bus.counters.errors == 0


def test_the_status_tells_the_open_episode_and_the_latency(drive):
    d = drive()
    d.hold(0.2)
    ok, status = d.bus.query("status", None)
    assert ok and status["episode"].startswith("ep-") and status["episodes"] == 1
    d.empty(0.3)
    ok, status = d.bus.query("status", None)
    assert status["episode"] is None and status["end_latency_ms"]["n"] == 1
    assert status["stray"] == {"late": 0, "outside": 0} and status["user"] == "user1"
    wire.validate(status, wire.SERVICE_STATUS)


@pytest.mark.parametrize("bad", [{"debounce_s": 0.0}, {"evidence.threshold": 1.5},
                                 {"focus": ["eyes"]}, {"check_period_s": 0.5},
                                 {"evidence.static_tau_s": 0.0}, {"user": ""}])
def test_invalid_settings_are_configuration_errors(bad):
    (name, value), = bad.items()
    with pytest.raises(ConfigError):
        if name.startswith("evidence."):  # the evidence model's settings, a group of their own
            EpisodeSettings(evidence=EvidenceSettings(**{name.split(".")[1]: value}))
        else:
            EpisodeSettings(**bad)


def test_simulated_episodes_give_one_summary_each_with_their_gestures(drive, scripted):
    """The simulated user and scripted classifiers, in memory (the integration test's twin)."""
    scenario = parse_scenario({"seed": 5, "episodes": [
        {"gestures": ["point", "swipe_down"], "gaze": [0.5, 0.1, 0.0], "pause_s": 0.3},
        {"gestures": ["grab"], "gaze": None, "pause_s": 0.3},
        {"gestures": ["pinch", {"gesture": "rotate", "angle_deg": 90}], "dropout_frames": 1,
         "pause_s": 0.3}]})
    to_base = default_to_base()
    frames = list(SimulatedUser(scenario, 60.0, lambda g: g, to_base).frames())
    classifier = scripted.ScriptedClassifier({tuple(f.hands[0]["palm_position"]): f.label
                                              for f in frames if f.hands})
    d = drive()
    for f in frames + [type(frames[0])(None, [])] * 20:
        d.now += d.period
        msg = {"v": 1, "ts": T0 + d.now, "seq": d.seq, "source": "simulated", "device": "t",
               "hands": f.hands, "to_base": to_base.reshape(-1).tolist()}
        d.seq += 1
        d.bus.feed(keys.HANDS_FRAME, msg)
        if f.gaze is not None:
            d.gaze(f.gaze)
        for topic, message in classifier.on_frame(msg):
            d.bus.feed(topic, message)
        d.bus.tick(d.period)
    assert classifier.unmatched == 0
    s1, s2, s3 = d.summaries
    assert [[t["gesture"] for t in s["triggers"]] for s in (s1, s2, s3)] == [
        ["point", "swipe_down"], ["grab"], ["pinch", "rotate"]]
    for s, leaders in ((s1, {"point", "swipe_down"}), (s2, {"grab"}),
                       (s3, {"pinch", "rotate"})):
        g = dict(zip(*s["gestures"].values(), strict=True))
        assert set(sorted(g, key=g.get, reverse=True)[:len(leaders)]) == leaders
    assert s1["focus_source"] == "gaze" and s1["focus"] == pytest.approx([0.5, 0.1, 0.0])
    assert 0.08 < s1["params"]["move_distance"] < 0.2
    assert s2["focus"] is None and s3["focus"] is None
    assert s3["params"]["angle_deg"] == pytest.approx(90, abs=10)
    assert 0.005 < s3["params"]["distance"] < 0.04
