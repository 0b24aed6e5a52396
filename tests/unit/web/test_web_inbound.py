"""web's page requests: checked before anything is published, rejected with a reason."""

import json

import pytest

from cbgo import wire
from cbgo.errors import RejectedMessage
from cbgo.services.web.inbound import MAX_REQUEST_BYTES, parse, request_id


def test_stop_becomes_a_stamped_robot_stop_with_a_reason():
    request = parse(json.dumps({"type": "stop", "id": 3}), {}, now=5.0)
    assert request.kind == "stop" and request.id == 3
    assert request.message == {"v": wire.SCHEMA_VERSION, "ts": 5.0,
                               "reason": "stop pressed on the web page"}


def test_feedback_takes_the_user_from_the_episodes_summary():
    request = parse(json.dumps({"type": "feedback", "action": "pick_up", "object": "cup2",
                                "episode": "ep-1"}), {"ep-1": "user1"}, now=1.0)
    wire.validate(request.message, wire.INTENT_FEEDBACK)
    assert (request.message["user"], request.message["object"]) == ("user1", "cup2")


def test_a_click_on_a_candidate_becomes_an_answer_that_confirms_it():
    request = parse(json.dumps({"type": "answer", "id": 4, "clarification": "c-1", "user": "ann",
                                "answer": "confirm", "choice": 1}), {}, now=2.0)
    assert request.kind == "answer" and request.id == 4
    assert request.message == {"v": wire.SCHEMA_VERSION, "ts": 2.0, "id": "c-1", "user": "ann",
                               "answer": "confirm", "choice": 1}


@pytest.mark.parametrize("text, problem", [
    ("not json", "not JSON"),
    ("[1, 2]", "expected a JSON object"),
    ('{"type": "launch"}', "unknown request type"),
    ('{"type": "stop", "id": "x"}', "id"),
    ('{"type": "feedback", "action": "fly", "user": "u"}', "action"),
    ('{"type": "feedback", "action": "open", "episode": "unseen"}', "no user"),
    ('{"type": "feedback", "action": "open", "user": "", "object": 5}', "no user"),
    ('{"type": "feedback", "action": "open", "user": "u", "object": 5}', "object"),
    ('{"type": "answer", "clarification": "c-1", "user": "u", "answer": "maybe"}', "answer"),
    ('{"type": "answer", "clarification": "c-1", "user": "u", "answer": "confirm", '
     '"choice": -1}', "choice"),
    ('{"type": "answer", "user": "u", "answer": "confirm"}', "id"),
    ('{"type": "mapping", "op": "show"}', "user: expected a name"),
    ('{"type": "mapping", "user": "u", "op": "drop"}', "op: expected one of show, set, unset"),
    ('{"type": "mapping", "user": "u", "op": "set", "gesture": "grab"}', "set needs the action"),
    ('{"type": "mapping", "user": "u", "op": "unset"}', "unset needs the gesture"),
    ('{"type": "mapping", "user": "u", "op": "set", "gesture": 5, "action": "open"}',
     "gesture: expected a name"),
    ("x" * (MAX_REQUEST_BYTES + 1), "exceeds"),
])
def test_a_bad_request_is_rejected_naming_the_problem(text, problem):
    with pytest.raises(RejectedMessage) as info:
        parse(text, {})
    assert problem in str(info.value)


def test_a_mapping_request_becomes_a_query_for_the_intent_service():
    request = parse(json.dumps({"type": "mapping", "id": 7, "user": "ann", "op": "set",
                                "gesture": "thumbsup", "action": "pour", "on": "cup",
                                "state": None}), {})
    assert request.kind == "mapping" and request.id == 7
    assert request.message == {"v": wire.SCHEMA_VERSION, "user": "ann", "op": "set",
                               "gesture": "thumbsup", "action": "pour", "on": "cup"}


def test_the_summarys_user_wins_over_the_pages_current_user():
    text = json.dumps({"type": "feedback", "action": "open", "episode": "ep-1", "user": "bob"})
    assert parse(text, {"ep-1": "alice"}).message["user"] == "alice"
    assert parse(text, {}).message["user"] == "bob"


def test_binary_messages_are_rejected():
    with pytest.raises(RejectedMessage, match="binary"):
        parse(b'{"type": "stop"}', {})


def test_the_id_of_a_rejected_request_is_read_when_it_can_be():
    assert request_id('{"type": "x", "id": 4}') == 4
    assert request_id("nonsense") is None and request_id('{"id": "4"}') is None
