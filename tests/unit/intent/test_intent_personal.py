"""Personalisation: a handful of corrections teach the model a user's own gestures."""

import numpy as np

from cbgo.services.intent import datasets
from cbgo.services.intent.decide import DecisionConfig
from cbgo.services.intent.engine import IntentEngine
from cbgo.services.intent.personal import Correction, PersonalStore, personalise, safe_dirname
from cbgo.wire import ACTIONS
from cbgo.world import OBJECT_AGNOSTIC

# what the user's model decides, without asking back below --ask-below
UNASKED = DecisionConfig(ask_below=0.0)


def ask(engine, sample, user):
    gestures = {"names": list(engine.gestures), "probs": sample.g.tolist()}
    return engine.infer(gestures, sample.scene.to_dict(), sample.focus.tolist(), user)


def right(intent, sample):
    return intent["action"] == sample.action and (sample.action in OBJECT_AGNOSTIC
                                                  or intent["object"] == sample.target)


def accuracy(engine, samples, user):
    return float(np.mean([right(ask(engine, s, user), s) for s in samples]))


def test_a_user_who_gestures_like_d3s_user2_is_learnt_from_a_handful_of_corrections(
        tmp_path, shipped):
    # carol is new to the model (read as user1) but swaps left/right and uses five/point for
    # place and put_into, as D3's user2 does.
    store = PersonalStore(tmp_path, shipped)
    engine = IntentEngine(shipped, UNASKED, personal=store)
    test = list(datasets.samples("D3", 100, seed=41, users=["user2"]))
    before = accuracy(engine, test, "carol")
    corrections = 0
    for sample in datasets.samples("D3", 200, seed=42, users=["user2"]):
        intent = ask(engine, sample, "carol")
        if not right(intent, sample):
            obj = None if sample.action in OBJECT_AGNOSTIC else sample.target
            engine.correct({"user": "carol", "episode": None, "action": sample.action,
                            "object": obj})
            corrections += 1
        if corrections == 10:
            break
    after = accuracy(engine, test, "carol")
    assert before < 0.85 and after >= 0.95, (before, after, corrections)
    assert 1 <= corrections <= 10
    assert accuracy(engine, test[:40], "user2") >= 0.95  # the known user2 is untouched
    personal = store.get("carol")
    assert personal.user_vector[1] > 0.5  # read as user2 now
    lines = (tmp_path / "carol" / "feedback.jsonl").read_text().splitlines()
    assert len(lines) == corrections
    reloaded = PersonalStore(tmp_path, shipped).get("carol")  # from disk, not refitted
    assert np.allclose(reloaded.user_vector, personal.user_vector)


def test_a_new_convention_is_learnt_by_fine_tuning_the_users_copy(shipped):
    # dave picks things up with "point" (nobody's table does); otherwise he is user1.
    gestures = list(shipped.meta["gestures"])
    point = np.eye(len(gestures))[gestures.index("point")]
    rng = np.random.default_rng(0)
    picks = [s for s in datasets.samples("D4", 300, seed=43, users=["user1"])
             if s.action == "pick_up"]
    for s in picks:  # dave's gesture vectors: noisy "point"
        s.g = np.abs(point + rng.normal(0, 0.2, len(gestures)))
        s.g /= s.g.sum()
    corrections = [Correction(user="dave", action="pick_up", object=s.target,
                              gestures={"names": gestures, "probs": s.g.tolist()},
                              scene=s.scene.to_dict(), focus=s.focus.tolist())
                   for s in picks[:6]]
    store = PersonalStore(None, shipped, steps=200, replay=400)
    personal = personalise(shipped, corrections, store.start_vector("dave"), store._replay_for,
                           steps=200)
    assert personal.stage == "finetuned"
    engine = IntentEngine(personal.model, UNASKED)
    engine.user_model = lambda user: (personal.model, personal.user_vector, personal)
    assert accuracy(engine, picks[6:], "dave") >= 0.9
    usual = list(datasets.samples("D4", 80, seed=44, users=["user1"]))
    assert accuracy(engine, usual, "dave") >= 0.95
    assert accuracy(IntentEngine(shipped, UNASKED), picks[6:], "dave") < 0.5


def test_user_names_become_safe_folder_names():
    assert safe_dirname("alice") == "alice"
    odd = safe_dirname("../etc/passwd")
    assert "/" not in odd and odd.startswith(".._etc_passwd-")
    assert safe_dirname("a b") != safe_dirname("a_b")


def test_a_correction_round_trips_through_its_json_line():
    c = Correction(user="u", action=ACTIONS[0], object=None,
                   gestures={"names": ["grab"], "probs": [1.0]}, scene={"objects": []},
                   focus=None, params={"distance": 0.1}, episode="ep-1")
    assert Correction.from_json(c.to_json()) == c and "\n" not in c.to_json()
