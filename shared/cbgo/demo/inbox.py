"""What the demo hears: the decoded messages it follows, liveliness changes, and the recording.

One Zenoh subscription on every data key (``cbgo/**``) feeds the session recording (MCAP,
payloads exactly as received) and keeps the decoded messages of the keys the timeline follows,
each with its receive time, so a step can wait for "the intent of episode X" without racing
the message. A second subscription follows the liveliness tokens, for the fault report.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from cbgo import wire
from cbgo.errors import RejectedMessage
from cbgo.keys import TOPICS, Keys
from cbgo.recording import Recorder

FOLLOWED = ("episode/event", "episode/summary", "intent", "intent/clarify", "plan/status",
            "scene/state", "user")


@dataclass
class Heard:
    """One decoded message and when it arrived (``time.time()``)."""

    at: float
    suffix: str
    message: dict


@dataclass
class TokenChange:
    """A liveliness token appearing (present=True) or disappearing."""

    at: float
    name: str
    present: bool


class Inbox:
    """Collects the followed messages and liveliness changes of one Zenoh session.

    Args:
        session: an open Zenoh session.
        keys: the key prefix.
        recorder: where every data message is also written (None: not recorded).
    """

    def __init__(self, session, keys: Keys, recorder: Recorder | None = None):
        self.keys, self.recorder = keys, recorder
        self.heard: list[Heard] = []
        self.tokens: list[TokenChange] = []
        self.alive: set[str] = set()
        self.rejected = 0
        self._changed = threading.Condition()
        self._head = keys.prefix + "/"
        self._subs = [
            session.declare_subscriber(keys.data, self._on_sample),
            session.liveliness().declare_subscriber(keys.alive("*"), self._on_token,
                                                    history=True),
        ]

    # ---------------------------------------------------------------- callbacks

    def _on_sample(self, sample) -> None:
        received = time.time_ns()
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        if self.recorder is not None and not self.recorder.closed:
            self.recorder.write(key, payload, received)
        suffix = key[len(self._head):]
        if suffix not in FOLLOWED:
            return
        try:
            message = wire.decode_checked(payload, TOPICS[suffix].schema, key)
        except RejectedMessage:
            self.rejected += 1
            return
        with self._changed:
            self.heard.append(Heard(received / 1e9, suffix, message))
            self._changed.notify_all()

    def _on_token(self, sample) -> None:
        import zenoh

        name = self.keys.service_of_alive(str(sample.key_expr))
        if not name:
            return
        present = sample.kind == zenoh.SampleKind.PUT
        with self._changed:
            self.tokens.append(TokenChange(time.time(), name, present))
            (self.alive.add if present else self.alive.discard)(name)
            self._changed.notify_all()

    # ---------------------------------------------------------------- reading

    def mark(self) -> int:
        """Returns a position in the stream of heard messages, for `wait` and `since`."""
        with self._changed:
            return len(self.heard)

    def since(self, mark: int, suffix: str) -> list[Heard]:
        """Returns the messages on `suffix` heard after `mark`."""
        with self._changed:
            return [h for h in self.heard[mark:] if h.suffix == suffix]

    def latest(self, suffix: str) -> Heard | None:
        """Returns the last message heard on `suffix`."""
        with self._changed:
            return next((h for h in reversed(self.heard) if h.suffix == suffix), None)

    def wait(self, mark: int, suffix: str, predicate: Callable[[dict], bool],
             timeout: float) -> Heard | None:
        """Returns the first message on `suffix` after `mark` that satisfies `predicate`.

        Returns None when none arrives within `timeout` seconds.
        """
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                found = next((h for h in self.heard[mark:]
                              if h.suffix == suffix and predicate(h.message)), None)
                left = deadline - time.monotonic()
                if found is not None or left <= 0:
                    return found
                self._changed.wait(left)

    def wait_alive(self, names: set[str], timeout: float) -> bool:
        """Waits until every name has a liveliness token; returns whether they all do."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not names <= self.alive:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._changed.wait(left)
            return True

    def wait_any(self, names: set[str], timeout: float) -> set[str]:
        """Waits until one of the names has a liveliness token; returns those that do."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not names & self.alive:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._changed.wait(left)
            return names & self.alive

    def token_change(self, name: str, present: bool, after: float,
                     timeout: float) -> float | None:
        """Waits for `name`'s token to appear/disappear after time `after`; returns when."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while True:
                found = next((t.at for t in self.tokens if t.name == name
                              and t.present == present and t.at >= after), None)
                left = deadline - time.monotonic()
                if found is not None or left <= 0:
                    return found
                self._changed.wait(left)

    def close(self) -> None:
        """Undeclares the subscriptions."""
        for sub in self._subs:
            sub.undeclare()
