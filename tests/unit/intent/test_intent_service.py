"""The intent service through FakeBus: summary -> intent, infer queries, errors, feedback."""

import json

import pytest

from cbgo import keys, wire
from cbgo.examples import example
from cbgo.services.intent.main import Intent, IntentSettings
from cbgo.testing import FakeBus


@pytest.fixture
def bus(tmp_path):
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "personal"))))
    yield bus
    bus.stop()


def query(**overrides):
    return example("intent/infer", "query", **overrides)


def pour_scene():
    """The robot holds cup1 (full) above the table; cup2 stands empty on the table."""
    return {"objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.26], "size": 0.06,
         "full": True, "on": None, "inside": None},
        {"name": "cup2", "type": "cup", "position": [0.32, -0.18, 0.03], "size": 0.06,
         "full": False, "on": None, "inside": None},
        {"name": "box1", "type": "box", "position": [0.56, 0.18, 0.025], "size": 0.05}],
        "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": False, "holding": "cup1"}}


def test_an_infer_query_is_answered_with_a_valid_intent(bus):
    ok, reply = bus.query(keys.INTENT_INFER, query())
    assert ok, reply
    wire.validate(reply, wire.INTENT, "cbgo/intent/infer")
    assert (reply["status"], reply["action"], reply["object"]) == ("accepted", "pick_up", "cup1")
    assert set(reply["p_object"]) == {"cup1", "drawer1", "box1"}
    assert set(reply["p_action"]) == set(wire.ACTIONS) and reply["episode"] is None
    assert reply["model"] == "intent-ours-1" and reply["confidence"] > 0.8


@pytest.mark.parametrize("payload, problem", [
    ({"v": 1, "scene": {"objects": [], "robot": {"tcp": [0, 0, 0], "gripper_open": True,
                                                  "holding": None}},
      "focus": None, "user": "u"}, "gestures: missing required field"),
    ("mismatch", "as many probs as names"),
    ("nan-focus", "focus"),
    ("newer", "upgrade cbgo"),
])
def test_a_malformed_query_gets_an_error_reply(bus, payload, problem):
    if payload == "mismatch":
        payload = query(gestures={"names": ["grab", "point"], "probs": [0.9]})
    elif payload == "nan-focus":
        payload = query(focus=[0.5, float("nan"), 0.1])
    elif payload == "newer":
        payload = query(v=2)
    ok, reason = bus.query(keys.INTENT_INFER, payload)
    assert not ok and problem in reason, reason
    assert bus.counters.rejected == 1


@pytest.mark.parametrize("change, problem", [
    (dict(gestures={"names": ["wave", "nod"], "probs": [0.9, 0.1]}), "none of the model's"),
    (dict(gestures={"names": ["grab"], "probs": [0.0]}), "probability 0"),
    (dict(model="gpt"), "unknown model 'gpt'"),
    (dict(params={"angle_deg": "steep"}), "params.angle_deg must be a number"),
    ("holding-ghost", "the robot holds 'ghost'"),
    ("cup-on-cup", "only boxes and drawers carry"),
])
def test_a_semantically_bad_query_gets_an_error_reply_naming_the_problem(bus, change, problem):
    if change == "holding-ghost":
        payload = query()
        payload["scene"]["robot"].update(holding="ghost", gripper_open=False)
    elif change == "cup-on-cup":
        payload = query()
        payload["scene"]["objects"][2]["on"] = "cup1"
    else:
        payload = query(**change)
    ok, reason = bus.query(keys.INTENT_INFER, payload)
    assert not ok and problem in reason, reason
    assert bus.counters.errors == 0  # refused, not crashed


def test_an_empty_scene_is_answered_as_infeasible(bus):
    payload = query()
    payload["scene"]["objects"] = []
    ok, reply = bus.query(keys.INTENT_INFER, payload)
    assert ok and reply["status"] == "infeasible" and reply["action"] is None


def test_each_summary_publishes_an_intent_with_the_latest_scene(bus):
    summary = example("episode/summary")
    (topic, first), = bus.feed(keys.EPISODE_SUMMARY, summary)
    assert topic == "intent" and first["status"] == "infeasible"
    assert "no scene" in first["reason"] and first["episode"] == "ep-0001"
    bus.feed(keys.SCENE_STATE, example("scene/state"))
    (topic, intent), = bus.feed(keys.EPISODE_SUMMARY, summary)
    assert (intent["action"], intent["object"], intent["status"]) == ("pick_up", "cup1",
                                                                       "accepted")
    assert intent["params"] == {}  # pick_up takes no parameter; distance is dropped
    bus.feed(keys.SCENE_STATE, {**example("scene/state"), **pour_scene()})
    pour = {**summary, "episode": "ep-0002",
            "gestures": {"names": ["rotate", "grab"], "probs": [0.9, 0.1]},
            "focus": [0.32, -0.18, 0.03], "params": {"angle_deg": 45.0}}
    (_, intent), = bus.feed(keys.EPISODE_SUMMARY, pour)
    assert (intent["action"], intent["object"], intent["params"]) == ("pour", "cup2",
                                                                       {"angle_deg": 45.0})
    (_, intent), = bus.feed(keys.EPISODE_SUMMARY, {**pour, "params": {}})
    assert intent["params"] == {"angle_deg": 90.0}


def test_the_intent_of_a_replayed_episode_is_marked_replayed(bus):
    bus.feed(keys.SCENE_STATE, example("scene/state"))
    (_, live), = bus.feed(keys.EPISODE_SUMMARY, example("episode/summary"))
    (_, replayed), = bus.feed(keys.EPISODE_SUMMARY,
                              {**example("episode/summary"), "replayed": True})
    assert "replayed" not in live and replayed["replayed"] is True
    assert (replayed["action"], replayed["status"]) == (live["action"], live["status"])


def test_a_summary_without_known_gestures_still_gets_an_intent(bus):
    bus.feed(keys.SCENE_STATE, example("scene/state"))
    summary = example("episode/summary", gestures={"names": ["wave"], "probs": [1.0]})
    (_, intent), = bus.feed(keys.EPISODE_SUMMARY, summary)
    assert intent["status"] == "low_confidence" and intent["action"] is None
    assert "none of the model's gestures" in intent["reason"]


def test_last_returns_the_last_intent_and_its_user(bus):
    ok, empty = bus.query("last", {})
    assert ok and empty["intent"] is None
    bus.query(keys.INTENT_INFER, query(user="alice"))
    bus.feed(keys.SCENE_STATE, example("scene/state"))
    bus.feed(keys.EPISODE_SUMMARY, example("episode/summary", user="bob"))
    ok, last = bus.query("last", {})
    assert ok and (last["user"], last["episode"]) == ("bob", "ep-0001")
    ok, alice = bus.query("last", {"user": "alice"})
    assert alice["intent"]["action"] == "pick_up" and alice["episode"] is None


@pytest.fixture
def unasked_bus(tmp_path):
    """The service acting on any intent above --min-confidence (what its model decides)."""
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "personal"),
                                        ask_below=0.0)))
    yield bus
    bus.stop()


def test_a_correction_is_stored_and_the_users_model_follows_it(unasked_bus, tmp_path):
    bus = unasked_bus
    swipe = query(user="carol", gestures={"names": ["swipe_left"], "probs": [1.0]})
    ok, before = bus.query(keys.INTENT_INFER, swipe)
    assert before["action"] == "move_left"
    feedback = example("intent/feedback", user="carol", episode=None, action="move_right",
                       object=None)
    assert bus.feed(keys.INTENT_FEEDBACK, feedback) == []
    folder = tmp_path / "personal" / "carol"
    (line,) = (folder / "feedback.jsonl").read_text().splitlines()
    stored = json.loads(line)
    assert (stored["action"], stored["predicted"]["action"]) == ("move_right", "move_left")
    assert (folder / "model.pt").exists() and (folder / "model.json").exists()
    ok, after = bus.query(keys.INTENT_INFER, swipe)
    assert (after["action"], after["model"]) == ("move_right", "intent-ours-1+carol")
    ok, others = bus.query(keys.INTENT_INFER, {**swipe, "user": "user1"})
    assert others["action"] == "move_left"
    status = bus.query("status", {})[1]
    assert status["feedback"] == {"stored": 1, "refused": 0}


def test_a_correction_that_cannot_apply_is_refused_and_counted(bus):
    bus.feed(keys.INTENT_FEEDBACK, example("intent/feedback", user="nobody"))
    bus.query(keys.INTENT_INFER, query(user="dora"))
    bus.feed(keys.INTENT_FEEDBACK, example("intent/feedback", user="dora", action="fly"))
    bus.feed(keys.INTENT_FEEDBACK, example("intent/feedback", user="dora", object="cup9"))
    status = bus.query("status", {})[1]
    assert status["feedback"] == {"stored": 0, "refused": 3} and bus.counters.errors == 0


def put_into_closed_drawer(user="user1", gesture="five"):
    """The demo: the robot holds full cup1, the person looks at the closed drawer1."""
    from cbgo_tools.intent.evaluate import demo_scene

    scene = demo_scene()
    return query(gestures={"names": [gesture], "probs": [0.9]}, scene=scene.to_dict(),
                 focus=list(scene.get("drawer1").position), user=user)


def test_by_default_put_into_a_closed_drawer_is_accepted_for_the_planner(bus):
    assert IntentSettings().accept_repairable is True
    ok, reply = bus.query(keys.INTENT_INFER, put_into_closed_drawer("user1", "five"))
    assert ok, reply
    assert (reply["status"], reply["action"], reply["object"]) == ("accepted", "put_into",
                                                                   "drawer1")
    assert "the planner repairs: drawer1 is closed" in reply["reason"]


def test_a_less_certain_put_into_a_closed_drawer_is_asked_back_with_it_first(bus):
    # user2's point reads p = 0.93, below the default --ask-below
    ok, reply = bus.query(keys.INTENT_INFER, put_into_closed_drawer("user2", "point"))
    assert ok and (reply["status"], reply["action"]) == ("low_confidence", None), reply
    assert reply["reason"].startswith("asking back: put_into(drawer1) p=0.9")


def test_no_accept_repairable_refuses_put_into_a_closed_drawer(tmp_path):
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "p"),
                                        accept_repairable=False)))
    try:
        ok, reply = bus.query(keys.INTENT_INFER, put_into_closed_drawer())
        assert ok and (reply["status"], reply["action"]) == ("infeasible", None)
        assert "drawer1 is closed" in reply["reason"]
    finally:
        bus.stop()


# --------------------------------------------------------------------------- the model store


def model_copy(folder, name, model_id):
    """The shipped model copied to folder/name.{pt,json} under another model id."""
    from cbgo.services.intent.main import default_model_path

    shipped = default_model_path()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.pt").write_bytes(shipped.with_suffix(".pt").read_bytes())
    meta = json.loads(shipped.read_text())
    meta["model_id"] = model_id
    (folder / f"{name}.json").write_text(json.dumps(meta))
    return folder / name


def test_reload_serves_another_model_and_the_last_intent_stays_correctable(tmp_path):
    first = model_copy(tmp_path / "m", "a", "intent-ours-a")
    second = model_copy(tmp_path / "m", "b", "intent-ours-b")
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "p"), model=str(first),
                                        watch_s=0.0)))
    ok, reply = bus.query(keys.INTENT_INFER, query())
    assert ok and reply["model"] == "intent-ours-a"
    ok, reply = bus.query("reload", {"model": str(second)})
    assert ok and (reply["model"], reply["previous"]) == ("intent-ours-b", "intent-ours-a")
    ok, reply = bus.query(keys.INTENT_INFER, query())
    assert ok and reply["model"] == "intent-ours-b"
    ok, last = bus.query("last", {})
    assert ok and last["intent"] is not None  # the history moved to the new model
    bus.stop()


def test_a_broken_model_on_reload_is_an_error_reply_and_the_old_one_keeps_serving(tmp_path):
    base = model_copy(tmp_path / "m", "a", "intent-ours-a")
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "p"), model=str(base),
                                        watch_s=0.0)))
    base.with_suffix(".pt").write_bytes(b"half a model")
    ok, reason = bus.query("reload", {})
    assert not ok and "reload failed, still serving intent-ours-a" in reason
    ok, reason = bus.query("reload", {"model": 3})
    assert not ok and "model must be a path" in reason
    ok, reply = bus.query(keys.INTENT_INFER, query())
    assert ok and reply["model"] == "intent-ours-a"
    bus.stop()


def test_the_poll_picks_up_the_users_first_trained_model_and_a_broken_one_once(tmp_path,
                                                                               monkeypatch):
    monkeypatch.setenv("CBGO_DATA_DIR", str(tmp_path / "data"))
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "p"), watch_s=1.0)))
    shipped = bus.service.engine.model.name
    model_copy(tmp_path / "data" / "models", "intent-ours", "intent-ours-mine")
    bus.tick(1.0)
    assert bus.service.engine.model.name == "intent-ours-mine" != shipped
    (tmp_path / "data" / "models" / "intent-ours.pt").write_bytes(b"torn")
    bus.tick(1.0)
    bus.tick(1.0)
    assert bus.service.engine.model.name == "intent-ours-mine"
    assert bus.counters.errors == 1
    bus.stop()
