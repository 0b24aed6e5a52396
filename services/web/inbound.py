"""What the page may ask for over its WebSocket, checked before anything reaches the network.

The browser is an input like any other: every message is parsed and checked here, and one
that breaks a rule raises `RejectedMessage` with the reason (the service counts it, logs it at a
limited rate and answers the page with the reason). Requests are JSON objects of at most
`MAX_REQUEST_BYTES`:

- ``{"type": "stop", "id": N}``: publish ``cbgo/robot/stop`` (``v``, ``ts``, ``reason``);
- ``{"type": "feedback", "id": N, "action": A, "object": O|null, "episode": E|null,
  "user": U|null}``: publish ``cbgo/intent/feedback`` for the user of the episode's summary
  (as the intent service saw it), else for ``user`` (the page's current user);
- ``{"type": "answer", "id": N, "clarification": C, "user": U, "answer": A, "choice": K|null}``:
  publish ``cbgo/intent/answer`` (a click on a clarification's candidate: ``confirm`` with its
  index as ``choice``);
- ``{"type": "mapping", "id": N, "user": U, "op": "show"|"set"|"unset", "gesture": G,
  "action": A, "on": T, "state": S}``: ask the intent service's ``@ctl/intent/mapping`` for
  the user's gesture mapping, or to set or unset one rule (the intent service, which owns
  the user's mapping file, validates the rule and names what it knows).

``id`` (optional, an integer) is echoed in the answer so the page knows which click it was.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass

from cbgo import wire
from cbgo.errors import RejectedMessage

MAX_REQUEST_BYTES = 4096
MAPPING_OPS = ("show", "set", "unset")
MAPPING_FIELDS = ("gesture", "action", "on", "state")
MAX_NAME = 64  # a user, gesture, action, type or state name
STOP_REASON = "stop pressed on the web page"


@dataclass(frozen=True)
class Request:
    """One checked request: its kind, the page's id, and the wire message to publish."""

    kind: str
    id: int | None
    message: dict


def parse(text: str | bytes, users: dict[str, str], now: float | None = None) -> Request:
    """Checks one WebSocket message from the page; returns what to publish.

    Args:
        text: the message as received.
        users: who made each known episode (from ``episode/summary``).
        now: the timestamp to stamp with (time.time() when None).

    Raises:
        RejectedMessage: not JSON, too long, an unknown type, or a field that breaks the wire
            contract (named, as the wire names it).
    """
    if isinstance(text, bytes):
        raise RejectedMessage("binary WebSocket messages are not accepted; send JSON text")
    if len(text) > MAX_REQUEST_BYTES:
        raise RejectedMessage(f"request of {len(text)} bytes exceeds {MAX_REQUEST_BYTES}")
    try:
        request = json.loads(text)
    except json.JSONDecodeError as e:
        raise RejectedMessage(f"not JSON: {e}") from None
    if not isinstance(request, dict):
        raise RejectedMessage("expected a JSON object with a 'type'")
    ident = request.get("id")
    if ident is not None and type(ident) is not int:
        raise RejectedMessage("expected an integer or nothing", "id")
    now = time.time() if now is None else now
    kind = request.get("type")
    if kind == "stop":
        return Request("stop", ident, {"v": wire.SCHEMA_VERSION, "ts": now,
                                       "reason": STOP_REASON})
    if kind == "feedback":
        return Request("feedback", ident, _feedback(request, users, now))
    if kind == "answer":
        return Request("answer", ident, _answer(request, now))
    if kind == "mapping":
        return Request("mapping", ident, _mapping(request))
    raise RejectedMessage(f"unknown request type {kind!r}; expected 'stop', 'feedback', "
                          "'answer' or 'mapping'", "type")


def request_id(text: str | bytes) -> int | None:
    """Returns a request's ``id`` when it can be read at all (to answer a rejected request)."""
    try:
        ident = json.loads(text).get("id") if len(text) <= MAX_REQUEST_BYTES else None
    except (json.JSONDecodeError, AttributeError, TypeError, UnicodeDecodeError):
        return None
    return ident if type(ident) is int else None


def _answer(request: dict, now: float) -> dict:
    message = {"v": wire.SCHEMA_VERSION, "ts": now, "id": request.get("clarification"),
               "user": request.get("user"), "answer": request.get("answer")}
    if request.get("choice") is not None:
        message["choice"] = request["choice"]
    return wire.validate(message, wire.INTENT_ANSWER, "intent/answer")


def _name(value, field: str) -> str:
    if not isinstance(value, str) or not 0 < len(value) <= MAX_NAME:
        raise RejectedMessage(f"expected a name of 1-{MAX_NAME} characters", field)
    return value


def _mapping(request: dict) -> dict:
    op = request.get("op", "show")
    if op not in MAPPING_OPS:
        raise RejectedMessage(f"expected one of {', '.join(MAPPING_OPS)}, got {op!r}", "op")
    query = {"v": wire.SCHEMA_VERSION, "user": _name(request.get("user"), "user"), "op": op}
    for field in MAPPING_FIELDS:
        if request.get(field) not in (None, ""):
            query[field] = _name(request[field], field)
    needed = {"show": (), "set": ("gesture", "action"), "unset": ("gesture",)}[op]
    for field in needed:
        if field not in query:
            raise RejectedMessage(f"{op} needs the {field}", field)
    return query


def _feedback(request: dict, users: dict[str, str], now: float) -> dict:
    action = request.get("action")
    if action not in wire.ACTIONS:
        raise RejectedMessage(f"expected one of {', '.join(wire.ACTIONS)}, got {action!r}",
                              "action")
    episode = request.get("episode")
    # The episode's summary says who made it; the page's guess (the current user) comes second.
    user = (users.get(episode) if isinstance(episode, str) else None) or request.get("user")
    if not user:
        raise RejectedMessage("no user: name one, or correct an episode whose summary was "
                              "seen", "user")
    message = {"v": wire.SCHEMA_VERSION, "ts": now, "episode": episode, "user": user,
               "action": action, "object": request.get("object")}
    return wire.validate(message, wire.INTENT_FEEDBACK, "intent/feedback")
