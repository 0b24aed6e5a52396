"""The runtime's `Transport` over a real zenoh.Session (`cbgo.runtime.run` opens the session).

`cbgo.testing.FakeBus` is the other transport: the same calls in memory, so a service's
logic is tested through the runtime's own dispatch without a router.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from cbgo.client import replies
from cbgo.keys import Topic

if TYPE_CHECKING:
    from cbgo.runtime import IncomingQuery


class _ZenohQuery:
    def __init__(self, query: Any, key: str):
        self._query, self._key = query, key
        self.payload = query.payload.to_bytes() if query.payload is not None else None

    def reply(self, payload: bytes) -> None:
        """Sends the reply and finalises the query."""
        try:
            self._query.reply(self._key, payload)
        finally:
            self._query.drop()  # finalise now, so the querier is not left waiting for more

    def reply_err(self, reason: str) -> None:
        """Sends an error reply and finalises the query."""
        try:
            self._query.reply_err(reason.encode())
        finally:
            self._query.drop()


class ZenohTransport:
    """`Transport` over an open zenoh.Session."""

    def __init__(self, session: Any):
        import zenoh

        self._zenoh, self.session = zenoh, session
        self._entities: list[Any] = []  # keep declarations alive for the session's lifetime
        self._publishers: dict[str, Any] = {}

    def subscribe(self, key: str, callback: Callable[[str, bytes], None]) -> None:
        """Declares a Zenoh subscriber whose samples go to callback."""
        self._entities.append(self.session.declare_subscriber(
            key, lambda s: callback(str(s.key_expr), s.payload.to_bytes())))

    def serve(self, key: str, callback: Callable[[IncomingQuery], None]) -> None:
        """Declares a Zenoh queryable whose queries go to callback."""
        self._entities.append(self.session.declare_queryable(
            key, lambda q: callback(_ZenohQuery(q, key))))

    def publisher(self, key: str, topic: Topic | None) -> Callable[[bytes], None]:
        """Declares a publisher with the topic's congestion control and express flag."""
        z = self._zenoh
        reliable = topic is None or topic.reliable
        pub = self.session.declare_publisher(
            key,
            congestion_control=z.CongestionControl.BLOCK if reliable else z.CongestionControl.DROP,
            express=bool(topic and topic.express),
        )
        self._publishers[key] = pub
        return pub.put

    def get(self, key: str, payload: bytes, timeout_s: float) -> list[tuple[bool, bytes]]:
        """Sends a query and collects every reply until the timeout."""
        return [(r.ok, r.payload) for r in replies(self.session, key, payload, timeout_s)]

    def matching(self, key: str) -> bool:
        """Returns whether a subscriber matches the publisher of key."""
        pub = self._publishers.get(key)
        return bool(pub is not None and pub.matching_status.matching)

    def alive(self, key: str, timeout_s: float) -> list[str]:
        """Returns the liveliness tokens matching key."""
        return [str(r.ok.key_expr) for r in self.session.liveliness().get(key, timeout=timeout_s)
                if r.ok is not None]
