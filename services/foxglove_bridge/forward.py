"""What the foxglove-bridge sends to Foxglove for each wire message, and how often.

`Forwarder` is the bridge's logic without a network: it takes one valid wire message and
returns the messages to log on the live channels, the wire channel and the derived
Foxglove channels (`cbgo.foxglove.derive`, the same derivation as ``cbgo export``). High-rate
streams (the contract's DROP topics: hand frames, gaze, static gestures, robot state) are
thinned to at most ``stream_hz`` per key, by the messages' own ``ts``: a viewer draws at a
screen's rate, and a 120 Hz skeleton stream over a WebSocket would only queue up. Events,
summaries, intents, plans and scenes always pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cbgo.foxglove.derive import Deriver
from cbgo.keys import Topic


@dataclass
class ForwardCounts:
    """What the forwarder has done, per key; served in the bridge's status.

    Attributes:
        forwarded: wire messages sent on, per key.
        thinned: wire messages left out to keep a stream at ``stream_hz``, per key.
        derived: derived messages sent, per Foxglove topic.
    """

    forwarded: dict[str, int] = field(default_factory=dict)
    thinned: dict[str, int] = field(default_factory=dict)
    derived: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Returns the counts as plain data."""
        return {"forwarded": dict(self.forwarded), "thinned": dict(self.thinned),
                "derived": dict(self.derived)}


def _add(table: dict[str, int], key: str) -> None:
    table[key] = table.get(key, 0) + 1


class Forwarder:
    """Turns valid wire messages into live Foxglove messages.

    Args:
        stream_hz: at most this many messages per second on each high-rate key (0: all).
    """

    def __init__(self, stream_hz: float):
        self.period_s = 1.0 / stream_hz if stream_hz > 0 else 0.0
        self.deriver = Deriver()
        self.counts = ForwardCounts()
        self._last_ts: dict[str, float] = {}

    def forward(self, topic: Topic, key: str, message: dict) -> list[tuple[str, dict]]:
        """Returns [(channel topic, message)] to log for one message on `key`.

        Args:
            topic: the contract topic the message came on.
            key: its full key (the wire channel's topic).
            message: the decoded, validated message.
        """
        if not topic.reliable and self._too_soon(key, message):
            _add(self.counts.thinned, key)
            return []
        _add(self.counts.forwarded, key)
        out = [(key, message)]
        for derived in self.deriver.feed(topic.suffix, message):
            _add(self.counts.derived, derived.topic)
            out.append((derived.topic, derived.message))
        return out

    def _too_soon(self, key: str, message: dict) -> bool:
        ts = message.get("ts")
        if not self.period_s or type(ts) not in (int, float):
            return False
        last = self._last_ts.get(key)
        # A clock that jumps back (a replay starting over) restarts the stream at once.
        if last is not None and 0 <= ts - last < self.period_s:
            return True
        self._last_ts[key] = ts
        return False
