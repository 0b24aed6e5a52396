"""The latency bench's bookkeeping, on hand-made observations (no processes, no clock)."""

import pytest

from cbgo_tools.bench.latency import GESTURE_FOR
from cbgo_tools.bench.latency_figures import (
    Frame,
    Observed,
    Run,
    episode_record,
    figures,
    goals,
    measure,
    static_latencies,
    tally,
)

DEBOUNCE = 0.15
T0 = 1_700_000_000.0  # Unix seconds, as in real time stamps


def observed(ended=T0 + 1.0, summary_delay=0.005, intent_delay=0.03, status="accepted",
             action="pick_up"):
    """One episode seen by the bench: hand frames from T0+0.5 to `ended`, its summary, intent."""
    seen = Observed()
    for seq in range(31):
        ts = T0 + 0.5 + seq / 60
        seen.frames[seq] = Frame(ts, ts <= ended + 1e-9, ts + 0.001)
        seen.static[seq] = ts + 0.004
    end = ended + DEBOUNCE
    summary = {"episode": "ep-1", "started": T0 + 0.5, "ended": ended, "ts": end + 0.002}
    seen.summaries["ep-1"] = (end + summary_delay, summary)
    intent = {"episode": "ep-1", "ts": end + intent_delay - 0.001, "status": status,
              "action": action, "object": "cup1", "reason": "", "confidence": 0.9}
    seen.intents["ep-1"] = (end + intent_delay, intent)
    seen.plans["ep-1"] = (end + 0.2, {"state": "success", "error": None})
    return seen


def run(index=0):
    return Run(index, *GESTURE_FOR[False], played=T0, duration_s=1.4, finished=T0 + 1.4)


def test_figures_are_milliseconds_with_ordered_percentiles():
    fig = figures([0.010, 0.020, 0.030, 0.040, 1.0])
    assert fig["n"] == 5 and fig["p50"] == pytest.approx(30.0) and fig["max"] == 1000.0
    assert fig["min"] <= fig["p50"] <= fig["p90"] <= fig["p99"] <= fig["max"]
    assert figures([]) == {"n": 0}


def test_the_end_condition_is_the_last_hand_frame_plus_the_debounce():
    seen = observed()
    record = episode_record(run(), float("inf"), seen, DEBOUNCE, lambda since, until: None)
    assert record["lost"] is None
    assert record["last_hand_ts"] == T0 + 1.0
    assert record["end_condition"] == pytest.approx(T0 + 1.0 + DEBOUNCE)
    assert record["intent_received"] - record["end_condition"] == pytest.approx(0.03, abs=1e-6)
    # The bench's own frames agree on the last hand frame.
    assert record["bench_last_hand_ts"] == pytest.approx(T0 + 1.0, abs=1e-9)


def test_the_first_robot_action_is_searched_from_the_intent_stamp_within_the_episode():
    seen = observed()
    intent_ts = seen.intents["ep-1"][1]["ts"]
    asked = []

    def first_act(since, until):
        asked.append((since, until))
        return since + 0.04

    record = episode_record(run(), T0 + 5.0, seen, DEBOUNCE, first_act)
    assert asked == [(intent_ts, T0 + 5.0)]
    assert record["first_robot_action"] == pytest.approx(intent_ts + 0.04)


def test_an_intent_that_is_not_accepted_has_no_robot_action():
    seen = observed(status="low_confidence", action=None)
    record = episode_record(run(), float("inf"), seen, DEBOUNCE,
                            lambda since, until: pytest.fail("no action is looked for"))
    assert record["first_robot_action"] is None and record["status"] == "low_confidence"


def test_lost_episodes_say_why():
    seen = observed()
    del seen.intents["ep-1"]
    assert episode_record(run(), float("inf"), seen, DEBOUNCE, None)["lost"] == (
        "no intent for the summary")
    empty = Observed()
    assert episode_record(run(), float("inf"), empty, DEBOUNCE, None)["lost"].startswith(
        "no episode summary")
    # A summary of a later run does not belong to this one.
    late = observed()
    assert episode_record(run(), T0 + 0.4, late, DEBOUNCE, None)["lost"].startswith(
        "no episode summary")


def test_measures_and_tally_of_two_episodes():
    records = [episode_record(run(0), float("inf"), observed(intent_delay=d), DEBOUNCE,
                              lambda since, until: since + 0.05) for d in (0.010, 0.030)]
    static, missing = static_latencies(observed(), [run()])
    result = measure(records, static, DEBOUNCE)
    end = result["measures"]["end_condition_to_intent"]
    last = result["measures"]["last_hand_frame_to_intent"]
    assert end["n"] == 2 and end["p50"] == pytest.approx(20.0, abs=1e-3)
    assert last["p50"] == pytest.approx(end["p50"] + DEBOUNCE * 1e3, abs=1e-3)
    assert result["measures"]["frame_to_static"]["p50"] == pytest.approx(4.0, abs=1e-3)
    assert missing == 0
    counts = tally(records)
    assert counts["lost"] == 0 and counts["as_expected"] == 2
    assert counts["plans"] == {"success": 2}


def test_goals_are_met_or_missed_at_their_limits():
    def fig(p50, p99):
        return {"n": 10, "p50": p50, "p99": p99}

    met = goals({"end_condition_to_intent": fig(20.0, 50.0),
                 "last_hand_frame_to_intent": fig(170.0, 200.0)}, DEBOUNCE)
    assert met["end_condition_to_intent"]["met"] and met["last_hand_frame_to_intent"]["met"]
    missed = goals({"end_condition_to_intent": fig(19.0, 50.1),
                    "last_hand_frame_to_intent": fig(170.1, 171.0)}, DEBOUNCE)
    assert not missed["end_condition_to_intent"]["met"]
    assert not missed["last_hand_frame_to_intent"]["met"]
    assert missed["frame_to_static"]["met"] is None  # no goal given for it


class FakeStack:
    """Answers the driver's queries like a robot would; records them."""

    def __init__(self):
        from cbgo.keys import Keys

        self.keys, self.queries = Keys("cbgo"), []

    def query(self, key, message, timeout=5.0):
        self.queries.append((key, message))
        return [(True, {"v": 1, "ok": True, "error": None, "scene": message.get("scene")})]


class FakeTap:
    def __init__(self, seen):
        self.seen = seen


@pytest.mark.parametrize(("action", "plan", "reset"), [
    ("pick_up", "success", False),   # as asked: the robot now holds the cup, no reset
    ("pour", "success", True),       # another intent than asked: the world is reset
    ("pick_up", "failure", True),    # the plan failed: the world is reset
])
def test_the_driver_resets_the_world_after_an_episode_that_went_astray(action, plan, reset,
                                                                       monkeypatch):
    import argparse

    from cbgo_tools.bench.latency import SCENE, Driver

    monkeypatch.setattr("time.sleep", lambda s: None)
    seen = observed(action=action)
    seen.plans["ep-1"] = (T0 + 2, {"state": plan, "error": None})
    stack = FakeStack()
    driver = Driver(stack, FakeTap(seen), argparse.Namespace())
    episode = run()
    assert driver._settled(episode)
    assert episode.reset_after is reset
    assert driver.holding is (not reset)
    driver.reset_world_if_needed(episode)
    assert stack.queries == ([("cbgo/sim/reset", {"v": 1, "scene": SCENE})] if reset else [])
    assert driver.holding is (not reset)  # after a reset the gripper is empty again
