"""A user's stated mapping: validated, written into the user's table, a prior of their model."""

import numpy as np
import pytest

from cbgo.services.intent import datasets
from cbgo.services.intent import mapping as mp
from cbgo.services.intent.decide import DecisionConfig
from cbgo.services.intent.engine import IntentEngine
from cbgo.services.intent.mapping import GestureMapping, MappingError, Rule
from cbgo.services.intent.personal import PersonalStore
from cbgo.wire import PAPER_GESTURES
from cbgo.world import OBJECT_AGNOSTIC

# what the user's model decides, without asking back below --ask-below
UNASKED = DecisionConfig(ask_below=0.0)

GESTURES = list(PAPER_GESTURES)
UP_DOWN_SWAPPED = GestureMapping((Rule("swipe_up", "move_down"), Rule("swipe_down", "move_up")))


def parse(data):
    return mp.parse(data, GESTURES)


@pytest.mark.parametrize("rule, expected", [
    ({"gesture": "wave", "action": "pick_up"}, ["unknown gesture 'wave'", "swipe_up", "point"]),
    ({"gesture": "grab", "action": "fly"}, ["unknown action 'fly'", "pick_up", "close"]),
    ({"gesture": "grab", "action": "pick_up", "on": "mug"},
     ["unknown object type 'mug'", "cup, drawer, box"]),
    ({"gesture": "grab", "action": "open", "on": "drawer", "state": "ajar"},
     ["unknown state of a drawer 'ajar'", "closed, open"]),
    ({"gesture": "grab", "action": "pick_up", "state": "full"}, ["a state needs an object type"]),
    ({"gesture": "grab", "action": "open", "on": "cup"},
     ["open never applies to a cup", "it applies to drawer"]),
    ({"gesture": "grab", "action": "pick_up", "when": "now"}, ["unknown field 'when'"]),
    ("grab means pick_up", ["expected a map with gesture and action"]),
])
def test_a_bad_rule_is_refused_naming_what_is_known(rule, expected):
    with pytest.raises(MappingError) as e:
        parse({"rules": [rule]})
    for text in expected:
        assert text in str(e.value)
    assert str(e.value).startswith("rules[0]: ")


def test_rules_that_contradict_each_other_are_refused():
    with pytest.raises(MappingError, match="contradict.*cbgo mapping unset"):
        parse({"rules": [{"gesture": "grab", "action": "pick_up", "on": "cup"},
                         {"gesture": "grab", "action": "pour", "on": "cup"}]})


def test_a_more_precise_rule_overrides_a_general_one_without_contradiction():
    mapping = parse({"rules": [{"gesture": "thumbsup", "action": "place"},
                               {"gesture": "thumbsup", "action": "pour", "on": "cup"}]})
    table = mp.apply(datasets.load_tables(), "user1", mapping).tables["D4"]
    assert table["0"]["user1"]["cup"]["pour"] == "thumbsup"
    assert table["0"]["user1"]["box"]["place"] == "thumbsup"
    assert table["0"]["user1"]["cup"]["place"] is None  # thumbsup no longer places a cup
    assert table["0"]["user2"]["cup"]["pour"] == "rotate"  # other profiles untouched


def test_a_file_that_is_not_yaml_or_not_a_rule_list_is_refused_with_its_path(tmp_path):
    path = tmp_path / "mapping.yaml"
    path.write_text("rules: [gesture: grab\n")
    with pytest.raises(MappingError, match=f"{path}: not YAML"):
        mp.load(path, GESTURES)
    path.write_text("rules: grab\n")
    with pytest.raises(MappingError, match="rules: expected a list"):
        mp.load(path, GESTURES)
    assert mp.load(tmp_path / "absent.yaml", GESTURES) == GestureMapping()


def test_set_replaces_the_rule_of_the_same_gesture_and_context_and_unset_removes_it(tmp_path):
    mapping = GestureMapping().with_rule(Rule("grab", "pick_up", "cup"))
    mapping = mapping.with_rule(Rule("grab", "pour", "cup")).with_rule(Rule("five", "place"))
    assert mapping.rules == (Rule("grab", "pour", "cup"), Rule("five", "place"))
    path = tmp_path / "u" / "mapping.yaml"
    mp.save(path, mapping)
    assert mp.load(path, GESTURES) == mapping
    fewer, removed = mapping.without("grab", "cup")
    assert removed == 1 and fewer.rules == (Rule("five", "place"),)


def ask(engine, sample, user):
    gestures = {"names": GESTURES, "probs": sample.g.tolist()}
    return engine.infer(gestures, sample.scene.to_dict(), sample.focus.tolist(), user)


def followed(intents_and_samples):
    return np.mean([i["status"] == "accepted" and i["action"] == s.action and (
        s.action in OBJECT_AGNOSTIC or i["object"] == s.target) for i, s in intents_and_samples])


def swapped_moves(n, seed):
    tables = mp.apply(datasets.load_tables(), "user1", UP_DOWN_SWAPPED)
    return [s for s in datasets.samples("D4", n, seed, users=["user1"], tables=tables)
            if s.action in ("move_up", "move_down")]


@pytest.fixture(scope="module")
def erin_store(tmp_path_factory, shipped):
    """erin (read as user1) states that swipe_up moves down and swipe_down moves up."""
    root = tmp_path_factory.mktemp("personal")
    mp.save(root / "erin" / "mapping.yaml", UP_DOWN_SWAPPED)
    return root, PersonalStore(root, shipped)


def test_a_stated_mapping_is_followed_from_the_first_episode(erin_store, shipped):
    root, store = erin_store
    engine = IntentEngine(shipped, UNASKED, personal=store)
    moves = swapped_moves(300, 61)
    assert len(moves) >= 20
    assert followed([(ask(engine, s, "erin"), s) for s in moves]) >= 0.95
    assert followed([(ask(IntentEngine(shipped, UNASKED), s, "erin"), s) for s in moves]) == 0.0
    assert store.get("erin").stage == "mapped"
    assert (root / "erin" / "model.json").exists()
    # the rest of user1's convention still holds
    usual = [s for s in datasets.samples("D4", 60, 62, users=["user1"])
             if s.action not in ("move_up", "move_down")]
    assert followed([(ask(engine, s, "erin"), s) for s in usual]) >= 0.95


def test_a_malformed_file_is_refused_and_the_mapping_in_use_keeps_serving(erin_store, shipped):
    root, store = erin_store
    store.get("erin")
    path = root / "erin" / "mapping.yaml"
    good = path.read_text()
    path.write_text("rules:\n  - gesture: swipe_up\n    action: fly\n")
    changes = store.poll_mappings()
    assert changes == [("erin", store.mapping_errors["erin"])]
    assert "unknown action 'fly'" in changes[0][1]
    assert store.mapping("erin") == UP_DOWN_SWAPPED
    assert store.get("erin").stage == "mapped"
    # after a restart the file is still bad: the mapping stored with the model serves
    again = PersonalStore(root, shipped)
    assert again.mapping("erin") == UP_DOWN_SWAPPED and "erin" in again.mapping_errors
    assert again.get("erin").stage == "mapped"
    path.write_text(good)
    assert store.poll_mappings() == [] and "erin" not in store.mapping_errors


def test_a_new_mapping_file_is_picked_up_and_removing_it_returns_to_the_default(
        tmp_path, shipped):
    store = PersonalStore(tmp_path, shipped, steps=50)
    assert store.get("fay") is None and store.poll_mappings() == []
    mp.save(tmp_path / "fay" / "mapping.yaml", GestureMapping((Rule("five", "place"),)))
    assert store.poll_mappings() == [("fay", None)]
    assert store.get("fay").stage == "mapped"
    (tmp_path / "fay" / "mapping.yaml").unlink()
    assert store.poll_mappings() == [("fay", None)]
    assert store.get("fay") is None


@pytest.fixture
def service(tmp_path):
    from cbgo.services.intent.main import Intent, IntentSettings
    from cbgo.testing import FakeBus

    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path), watch_s=1.0)))
    yield bus
    bus.stop()


def test_the_mapping_verb_edits_the_file_and_refits_while_intents_are_served(service, tmp_path):
    from cbgo import keys
    from cbgo.examples import example

    ok, shown = service.query("mapping", {"user": "gus"})
    assert ok and shown["rules"] == [] and shown["refitting"] is False
    ok, reply = service.query("mapping", {"user": "gus", "op": "set", "gesture": "swipe_up",
                                          "action": "move_down"})
    assert ok and reply["rules"] == [{"gesture": "swipe_up", "action": "move_down"}]
    assert reply["refitting"] is True and reply["in_use"] == []
    assert mp.load(tmp_path / "gus" / "mapping.yaml", GESTURES).rules == (
        Rule("swipe_up", "move_down"),)
    # the refit runs on the worker thread: a query is answered meanwhile, by the default model
    ok, intent = service.query(keys.INTENT_INFER, example("intent/infer", "query", user="gus"))
    assert ok and "+gus" not in intent["model"]
    service.service.pending["gus"][2].result(timeout=300)
    service.tick(0.25)
    ok, done = service.query("mapping", {"user": "gus"})
    assert done["refitting"] is False and done["in_use"] == done["rules"]
    assert service.service.engine.personal.get("gus").stage == "mapped"
    assert service.tick(1.0) == [] and "gus" not in service.service.pending  # not polled again


@pytest.mark.parametrize("query, problem", [
    ({}, "user: expected a user name"),
    ({"user": "gus", "op": "drop"}, "op: expected show, set or unset"),
    ({"user": "gus", "op": "set", "gesture": "wave", "action": "place"},
     "unknown gesture 'wave'"),
    ({"user": "gus", "op": "set", "gesture": "grab", "action": "open", "on": "cup"},
     "open never applies to a cup"),
    ({"user": "gus", "op": "unset", "gesture": "grab"}, "gus has no rule for 'grab'"),
])
def test_a_bad_mapping_query_gets_an_error_reply_naming_the_problem(service, query, problem):
    ok, reply = service.query("mapping", query)
    assert not ok and problem in reply
    assert service.service.pending == {}
