"""Asking back: the open clarifications, their answers and their expiry (no Zenoh here).

When the decision is ``clarify`` (`decide`), the engine opens a `Clarification`: the candidate
(action, object) pairs with their probabilities, the first one highlighted, an id, and a time
after which it expires. One clarification per user is open at a time; a new one cancels the
user's previous one. Every change of state is queued in `Clarifications.outbox` as a
``cbgo/intent/clarify`` message, which the service publishes.

Answers (``cbgo/intent/answer``, or the user's next gesture while a clarification is open):

- ``confirm`` (a thumbs-up, or a click on the page with the candidate's index as ``choice``):
  the highlighted (or chosen) candidate becomes an accepted intent and a correction of the
  user's model;
- ``next`` / ``previous`` (a swipe right / left): the highlight steps through the candidates and
  the clarification's time starts again;
- ``cancel``: closed, nothing moves. An unanswered clarification expires after
  ``timeout_s``; nothing moves either.
"""

from __future__ import annotations

import itertools
import os
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

from cbgo.wire import SCHEMA_VERSION

ANSWERS = ("confirm", "next", "previous", "cancel")
# The gestures that answer an open clarification (the user's next episode): a thumbs-up
# confirms the highlighted candidate, a swipe steps to the next or the previous one.
ANSWER_GESTURES = {"thumbsup": "confirm", "swipe_right": "next", "swipe_left": "previous"}
KEPT_CLOSED = 64  # closed clarifications remembered, so a late answer is told why it is refused


class AnswerError(ValueError):
    """An answer that cannot be applied (unknown id, already closed, a bad choice)."""


@dataclass
class Clarification:
    """One question to the user: which of these did you mean?

    Attributes:
        id: unique within the service's run (``<pid>-<n>``).
        record: the inference that asked (an `engine.Record`: its input, user and episode).
        candidates: the offered `decide.Candidate`s, most probable first.
        params: each candidate's intent params.
        expires: when it closes unanswered (time.time()).
        highlighted: the candidate a thumbs-up confirms.
        state: open, confirmed, expired or cancelled.
        chosen: the confirmed candidate's index.
    """

    id: str
    record: Any
    candidates: list
    params: list[dict[str, Any]]
    expires: float
    highlighted: int = 0
    state: str = "open"
    chosen: int | None = None
    reason: str = "uncertain between these; confirm one"

    @property
    def user(self) -> str:
        """Whose question it is."""
        return self.record.user

    def message(self, now: float) -> dict[str, Any]:
        """The ``cbgo/intent/clarify`` message of its current state."""
        return {"v": SCHEMA_VERSION, "ts": now, "id": self.id, "episode": self.record.episode,
                "user": self.user, "state": self.state,
                "candidates": [{"action": c.action, "object": c.object, "p": round(c.p, 4)}
                               for c in self.candidates],
                "highlighted": self.highlighted, "expires": self.expires,
                "reason": self.reason}


@dataclass
class Clarifications:
    """The open clarifications of every user, and what to publish about them.

    Args:
        timeout_s: how long one stays open without an answer (and after each step).
    """

    timeout_s: float = 20.0
    open: OrderedDict[str, Clarification] = field(default_factory=OrderedDict)
    recent: OrderedDict[str, Clarification] = field(default_factory=OrderedDict)  # closed
    outbox: list[dict[str, Any]] = field(default_factory=list)
    clock: Any = time.time  # what "now" is (a test sets its own)
    _ids: Any = field(default_factory=lambda: itertools.count(1))

    def ask(self, record: Any, candidates: list, params: list[dict[str, Any]],
            now: float | None = None) -> Clarification:
        """Opens a clarification for `record`'s user (cancelling their open one)."""
        now = self.clock() if now is None else now
        previous = self.of_user(record.user)
        if previous is not None:
            self._close(previous, "cancelled", now, "a newer gesture was asked about")
        asked = Clarification(f"{os.getpid()}-{next(self._ids)}", record, list(candidates),
                              list(params), now + self.timeout_s)
        self.open[asked.id] = asked
        self.outbox.append(asked.message(now))
        return asked

    def of_user(self, user: str) -> Clarification | None:
        """Returns the user's open clarification, if any."""
        return next((c for c in self.open.values() if c.user == user), None)

    def answer(self, ident: str, answer: str, choice: int | None = None,
               now: float | None = None) -> Clarification:
        """Applies an answer; returns the clarification (``state`` says what happened).

        Raises:
            AnswerError: an unknown or closed id, an unknown answer, or a choice out of range.
        """
        now = self.clock() if now is None else now
        asked = self.open.get(ident)
        if asked is None:
            if ident in self.recent:
                raise AnswerError(f"clarification {ident!r} is already "
                                  f"{self.recent[ident].state}")
            raise AnswerError(f"no clarification {ident!r} (open: "
                              f"{', '.join(self.open) or 'none'})")
        if answer not in ANSWERS:
            raise AnswerError(f"unknown answer {answer!r}; one of {', '.join(ANSWERS)}")
        if choice is not None and not 0 <= choice < len(asked.candidates):
            raise AnswerError(f"choice {choice} is not a candidate's index (0-"
                              f"{len(asked.candidates) - 1})")
        if answer == "confirm":
            asked.chosen = asked.highlighted if choice is None else choice
            label = asked.candidates[asked.chosen].label
            self._close(asked, "confirmed", now, f"confirmed {label}")
        elif answer == "cancel":
            self._close(asked, "cancelled", now, "cancelled by the user")
        else:
            step = 1 if answer == "next" else -1
            asked.highlighted = (asked.highlighted + step) % len(asked.candidates)
            asked.expires = now + self.timeout_s
            asked.reason = f"highlighted {asked.candidates[asked.highlighted].label}"
            self.outbox.append(asked.message(now))
        return asked

    def expire(self, now: float | None = None) -> list[Clarification]:
        """Closes the clarifications whose time is up; returns them."""
        now = self.clock() if now is None else now
        due = [c for c in self.open.values() if c.expires <= now]
        for asked in due:
            self._close(asked, "expired", now, f"no answer within {self.timeout_s:g} s; "
                                               "nothing was done")
        return due

    def cancel_others(self, user: str, now: float | None = None) -> None:
        """Cancels the questions of every other user: the operator has changed."""
        now = self.clock() if now is None else now
        for asked in [c for c in self.open.values() if c.user != user]:
            self._close(asked, "cancelled", now, f"{user} is operating now")

    def drain(self) -> list[dict[str, Any]]:
        """Returns the queued ``cbgo/intent/clarify`` messages and empties the queue."""
        out, self.outbox = self.outbox, []
        return out

    def _close(self, asked: Clarification, state: str, now: float, reason: str) -> None:
        asked.state, asked.reason = state, reason
        self.open.pop(asked.id, None)
        self.recent[asked.id] = asked
        while len(self.recent) > KEPT_CLOSED:
            self.recent.popitem(last=False)
        self.outbox.append(asked.message(now))
