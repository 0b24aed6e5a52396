"""Asking back: an uncertain intent opens a clarification that a click or a gesture answers."""

import pytest

from cbgo import keys, wire
from cbgo.services.intent.clarify import Clarifications
from cbgo.services.intent.main import Intent, IntentSettings
from cbgo.testing import FakeBus
from cbgo_tools.intent.evaluate import two_cups_scene

HALFWAY = [0.44, 0.0, 0.05]  # between the two cups, 0.2 m apart


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


@pytest.fixture
def bus(tmp_path):
    bus = FakeBus(Intent(IntentSettings(personal_dir=str(tmp_path / "personal"),
                                        update_steps=50, clarify_timeout_s=20.0)))
    bus.clock = Clock()
    bus.service.engine.clarifications.clock = bus.clock
    bus.feed(keys.SCENE_STATE, {"v": 1, "ts": 1.0, "seq": 1, **two_cups_scene().to_dict()})
    yield bus
    bus.stop()


def summary(episode, gesture, user="ann", focus=HALFWAY):
    return {"v": 1, "ts": 2.0, "episode": episode, "user": user, "started": 1.0, "ended": 2.0,
            "gestures": {"names": [gesture], "probs": [0.9]}, "triggers": [], "params": {},
            "focus": focus, "focus_source": "gaze"}


def answer(ident, what, user="ann", **extra):
    return {"v": 1, "ts": 3.0, "id": ident, "user": user, "answer": what, **extra}


def of(published, suffix):
    return [m for s, m in published if s == suffix]


def ask(bus, episode="ep-1"):
    out = bus.feed(keys.EPISODE_SUMMARY, summary(episode, "grab"))
    (intent,), (asked,) = of(out, "intent"), of(out, "intent/clarify")
    return intent, asked


def test_an_uncertain_grab_asks_back_instead_of_refusing(bus):
    intent, asked = ask(bus)
    assert intent["status"] == "low_confidence" and intent["action"] is None
    assert intent["clarification"] == asked["id"]
    wire.validate(asked, wire.INTENT_CLARIFY, "cbgo/intent/clarify")
    assert asked["state"] == "open" and asked["user"] == "ann" and asked["episode"] == "ep-1"
    assert {(c["action"], c["object"]) for c in asked["candidates"][:2]} == {
        ("pick_up", "cup1"), ("pick_up", "cup2")}
    assert asked["highlighted"] == 0 and asked["expires"] == bus.clock.now + 20.0


def test_a_click_confirms_a_candidate_which_goes_out_accepted_and_is_learnt(bus):
    _, asked = ask(bus)
    chosen = asked["candidates"][1]
    out = bus.feed(keys.INTENT_ANSWER, answer(asked["id"], "confirm", choice=1))
    (intent,), (closed,) = of(out, "intent"), of(out, "intent/clarify")
    assert (intent["status"], intent["action"], intent["object"]) == (
        "accepted", chosen["action"], chosen["object"])
    assert intent["episode"] == "ep-1" and intent["clarification"] == asked["id"]
    assert closed["state"] == "confirmed"
    assert bus.service.feedback["stored"] == 1  # the answer is a correction too
    assert bus.service.engine.personal.corrections("ann")[0].object == chosen["object"]
    # answered once: a second answer is refused
    assert bus.feed(keys.INTENT_ANSWER, answer(asked["id"], "confirm")) == []
    assert bus.counters.rejected == 1


def test_a_swipe_steps_the_highlight_and_a_thumbs_up_confirms_it(bus):
    _, asked = ask(bus)
    out = bus.feed(keys.EPISODE_SUMMARY, summary("ep-2", "swipe_right", focus=None))
    (step,), (moved,) = of(out, "intent"), of(out, "intent/clarify")
    assert step["status"] == "low_confidence" and step["episode"] == "ep-2"
    assert moved["state"] == "open" and moved["highlighted"] == 1
    out = bus.feed(keys.EPISODE_SUMMARY, summary("ep-3", "thumbsup", focus=None))
    (intent,), (closed,) = of(out, "intent"), of(out, "intent/clarify")
    second = asked["candidates"][1]
    assert (intent["status"], intent["action"], intent["object"]) == (
        "accepted", second["action"], second["object"])
    assert intent["episode"] == "ep-3" and closed["state"] == "confirmed"


def test_an_unanswered_clarification_expires_and_nothing_moves(bus):
    _, asked = ask(bus)
    bus.clock.now += 19.0
    assert of(bus.tick(0.5), "intent/clarify") == []
    bus.clock.now += 1.5
    out = bus.tick(0.5)
    (closed,) = of(out, "intent/clarify")
    assert closed["state"] == "expired" and of(out, "intent") == []
    assert bus.feed(keys.INTENT_ANSWER, answer(asked["id"], "confirm")) == []


def test_another_gesture_is_a_new_request_that_cancels_the_question(bus):
    _, first = ask(bus)
    out = bus.feed(keys.EPISODE_SUMMARY, summary("ep-2", "grab"))
    states = [m["state"] for m in of(out, "intent/clarify")]
    assert states == ["cancelled", "open"]
    assert of(out, "intent/clarify")[0]["id"] == first["id"]


def test_another_users_gesture_cancels_the_question_and_is_read_as_their_own(bus):
    _, asked = ask(bus)
    out = bus.feed(keys.EPISODE_SUMMARY, summary("ep-2", "swipe_right", user="bob"))
    (closed,) = [m for m in of(out, "intent/clarify") if m["id"] == asked["id"]]
    assert closed["state"] == "cancelled"
    (intent,) = of(out, "intent")
    assert intent["episode"] == "ep-2" and intent.get("clarification") != asked["id"]
    assert all(m["user"] == "bob" for m in of(out, "intent/clarify") if m is not closed)


@pytest.mark.parametrize("bad, problem", [
    (dict(id="nope"), "no clarification 'nope'"),
    (dict(user="bob"), "asks 'ann', not 'bob'"),
    (dict(choice=7), "choice 7 is not a candidate's index"),
])
def test_a_bad_answer_is_rejected_counted_and_the_question_stays_open(bus, bad, problem,
                                                                      caplog):
    _, asked = ask(bus)
    message = {**answer(asked["id"], "confirm"), **bad}
    assert bus.feed(keys.INTENT_ANSWER, message) == []
    assert bus.counters.rejected == 1
    assert problem in caplog.text
    assert bus.service.engine.clarifications.of_user("ann").id == asked["id"]


@pytest.mark.parametrize("bad, path", [
    (dict(answer="maybe"), "answer"), (dict(choice=-1), "choice"), (dict(id=""), "id"),
    (dict(choice=True), "choice"),
])
def test_a_malformed_answer_is_rejected_by_the_contract(bus, bad, path):
    _, asked = ask(bus)
    assert bus.feed(keys.INTENT_ANSWER, {**answer(asked["id"], "confirm"), **bad}) == []
    assert bus.counters.rejected == 1
    assert bus.service.engine.clarifications.of_user("ann") is not None


def test_an_infer_query_asks_no_one():
    bus = FakeBus(Intent(IntentSettings(personalise=False)))
    query = {"v": 1, "gestures": {"names": ["grab"], "probs": [0.9]}, "focus": HALFWAY,
             "user": "ann", "scene": two_cups_scene().to_dict()}
    ok, reply = bus.query(keys.INTENT_INFER, query)
    assert ok and reply["status"] == "low_confidence" and "clarification" not in reply
    assert reply["reason"].startswith("asking back")
    assert bus.published == []
    bus.stop()


def test_the_highlight_wraps_and_a_step_restarts_the_time():
    clock = Clock()
    asked_about = Clarifications(timeout_s=5.0, clock=clock)

    class Record:
        user, episode, intent = "ann", None, {}

    class Candidate:
        def __init__(self, label):
            self.action, self.object, self.p, self.label = "pick_up", label, 0.4, label

    asked = asked_about.ask(Record(), [Candidate("cup1"), Candidate("cup2")], [{}, {}])
    clock.now += 4.0
    asked_about.answer(asked.id, "previous")
    assert asked.highlighted == 1 and asked.expires == clock.now + 5.0
    clock.now += 4.0
    assert asked_about.expire() == []
    asked_about.answer(asked.id, "cancel")
    assert [m["state"] for m in asked_about.drain()] == ["open", "open", "cancelled"]
