"""Intents whose preconditions the planner repairs: the shipped model knows them, the engine
accepts them, and what was ambiguous stays ambiguous."""

import argparse

import numpy as np
import pytest

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig
from cbgo.services.intent.engine import IntentEngine
from cbgo.services.intent.personal import PersonalStore, trained_with_repairs
from cbgo_tools.intent import train
from cbgo_tools.intent.evaluate import demo_scene, two_cups_scene

HALFWAY = [0.44, 0.0, 0.03]  # between the two cups of two_cups_scene


@pytest.fixture(scope="module")
def engine(shipped):
    # what the model decides (the service asks back below --ask-below first)
    return IntentEngine(shipped, DecisionConfig(0.5, accept_repairable=True, ask_below=0.0),
                        None, 32)


def infer(engine, scene, user, gesture, looked_at):
    focus = looked_at if isinstance(looked_at, list) else list(scene.get(looked_at).position)
    return engine.infer({"names": [gesture], "probs": [0.9]}, scene.to_dict(), focus, user)


@pytest.mark.parametrize("scene, user, gesture, looked_at, action, obj", [
    (demo_scene(), "user1", "five", "drawer1", "put_into", "drawer1"),
    (demo_scene(), "user2", "point", "drawer1", "put_into", "drawer1"),
    (demo_scene(), "user1", "grab", "drawer1", "open", "drawer1"),
    (demo_scene(holding=None), "user1", "grab", "drawer1", "open", "drawer1"),
    (demo_scene(holding=None), "user1", "grab", "cup2", "pick_up", "cup2"),
    (demo_scene(), "user1", "grab", "cup2", "pick_up", "cup2"),
    (demo_scene(), "user1", "rotate", "cup2", "pour", "cup2"),
], ids=["user1-five-closed-drawer", "user2-point-closed-drawer", "grab-closed-drawer-holding",
        "grab-closed-drawer", "grab-cup", "grab-cup-holding", "rotate-empty-cup"])
def test_the_demos_gestures_are_accepted_as_meant(engine, scene, user, gesture, looked_at,
                                                  action, obj):
    intent = infer(engine, scene, user, gesture, looked_at)
    assert (intent["status"], intent["action"], intent["object"]) == ("accepted", action, obj), \
        intent["reason"]


@pytest.mark.parametrize("holding", [None, "box1"])
def test_a_grab_halfway_between_two_cups_stays_ambiguous(engine, holding):
    intent = infer(engine, two_cups_scene(0.2, holding), "user1", "grab", HALFWAY)
    assert (intent["status"], intent["action"]) == ("low_confidence", None), intent["reason"]
    assert intent["p_object"]["cup1"] > 0.3 and intent["p_object"]["cup2"] > 0.3
    assert abs(intent["p_object"]["cup1"] - intent["p_object"]["cup2"]) < 0.1


def test_without_accept_repairable_put_into_a_closed_drawer_is_not_accepted(shipped):
    strict = IntentEngine(shipped, DecisionConfig(0.5, accept_repairable=False), None, 32)
    intent = infer(strict, demo_scene(), "user1", "five", "drawer1")
    assert intent["status"] == "infeasible" and "drawer1 is closed" in intent["reason"]
    assert intent["p_action"]["put_into"] > 0.9  # the model still reads the request


def test_the_shipped_model_was_trained_with_repairable_intents(shipped):
    assert shipped.meta["trained_on"]["repairable"] is True
    assert shipped.meta["trained_on"]["repaired_samples"] > 0
    assert "--repairable" in shipped.meta["command"]
    assert shipped.meta["test_repairable"]["repaired"] > 0.95
    assert trained_with_repairs(shipped)


def test_held_out_repairable_intents_are_decided_as_meant_only_when_allowed(shipped):
    test = datasets.make("D4", 1500, seed=77, repairable=True)
    allowed = train.evaluate(shipped, test, accept_repairable=True)
    strict = train.evaluate(shipped, test)
    assert test.repaired.sum() > 10 and allowed["repaired"] > 0.9
    assert allowed["joint"] > strict["joint"]  # strict can never choose a repaired intent
    assert "repaired" not in strict


def test_the_personal_replay_keeps_repairable_intents_of_the_default_model(shipped):
    store = PersonalStore(None, shipped, replay=300)
    replay = store._replay_for("user1")
    assert replay.meta["repairable"] is True and replay.repaired.any()
    assert set(np.asarray(replay.meta["users"])[replay.user]) == {"user1"}


@pytest.mark.parametrize("flag", ["--repairable", "--no-repairable"])
def test_cbgo_train_intent_records_whether_it_drew_repairable_intents(tmp_path, flag, capsys):
    parser = argparse.ArgumentParser()
    train.add_arguments(parser)
    args = parser.parse_args(["-n", "200", "--test", "100", "--steps", "20", "--out",
                              str(tmp_path / "m"), flag])
    assert train.run(args) == 0
    from cbgo.services.intent.models import OursModel

    meta = OursModel.load(tmp_path / "m").meta
    repairable = flag == "--repairable"
    assert meta["trained_on"]["repairable"] is repairable and flag in meta["command"]
    assert ("test_repairable" in meta) is repairable and "joint" in meta["test"]
    assert ("test_repairable" in capsys.readouterr().out) is repairable
