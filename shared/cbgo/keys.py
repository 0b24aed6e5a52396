"""Every key expression cbgo uses, built from one configurable prefix.

Nothing else in the project spells a key: services name a `Topic` and ask `Keys` for its key
expression. Each topic also carries its delivery policy, measured to matter (docs/protocol.md,
"Delivery policy"):
hand frames and other high-rate streams are dropped under congestion and sent express, while
events, summaries, intents, plans and actions block and are never dropped.

Control keys live under ``<prefix>/@alive/<service>`` and ``<prefix>/@ctl/<service>/<verb>``;
the ``@`` chunk keeps them out of ``<prefix>/**`` data wildcards (recorders, ``cbgo echo``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from cbgo import wire
from cbgo.errors import ConfigError

DEFAULT_PREFIX = "cbgo"


@dataclass(frozen=True)
class Topic:
    """One data key of the contract, relative to the prefix.

    Attributes:
        suffix: the key below the prefix, e.g. ``hands/frame``.
        reliable: True: congestion control BLOCK (never dropped); False: DROP.
        express: send at once instead of batching (latency-critical streams).
        query: the key is answered by a queryable, not published.
    """

    suffix: str
    reliable: bool = True
    express: bool = False
    query: bool = False

    # The topic's record: its schemas and size limit (defined in `cbgo.wire`, joined here only)
    # and constructors of its messages, so that nothing else joins tables by suffix.

    @property
    def schema(self) -> wire.Spec | None:
        """The schema of a message on this key (None: any payload counts, e.g. robot/stop)."""
        return wire.SCHEMAS.get(self.suffix)

    @property
    def any_payload(self) -> bool:
        """Whether any payload counts as a message (``robot/stop``: anything stops)."""
        return self.suffix in wire.ANY_PAYLOAD

    @property
    def query_schema(self) -> wire.Spec | None:
        """The schema of a query's payload (None: not a query key)."""
        return wire.QUERY_SCHEMAS.get(self.suffix)

    @property
    def reply_schema(self) -> wire.Spec | None:
        """The schema of a query's reply (None: not a query key)."""
        return wire.REPLY_SCHEMAS.get(self.suffix)

    def max_bytes(self, default: int = wire.DEFAULT_MAX_BYTES) -> int:
        """The payload size limit on this key (larger for render replies)."""
        return wire.max_bytes_for(self.suffix, default)

    def message(self, **fields: Any) -> dict:
        """Returns a message (or query payload) of the current schema version."""
        return {"v": wire.SCHEMA_VERSION, **fields}

    def reply(self, ok: bool = True, error: str | None = None, **fields: Any) -> dict:
        """Returns a query's reply: ``ok``, ``error`` (required when not ok), the fields."""
        return {"v": wire.SCHEMA_VERSION, "ok": ok, "error": error, **fields}


HANDS_FRAME = Topic("hands/frame", reliable=False, express=True)
GAZE = Topic("gaze", reliable=False, express=True)
CAMERA_PREVIEW = Topic("camera/preview", reliable=False)
USER = Topic("user")
GESTURES_STATIC = Topic("gestures/static", reliable=False, express=True)
GESTURES_DYNAMIC = Topic("gestures/dynamic")
EPISODE_EVENT = Topic("episode/event")
EPISODE_SUMMARY = Topic("episode/summary")
SCENE_STATE = Topic("scene/state")
INTENT = Topic("intent")
INTENT_INFER = Topic("intent/infer", query=True)
INTENT_FEEDBACK = Topic("intent/feedback")
INTENT_CLARIFY = Topic("intent/clarify")
INTENT_ANSWER = Topic("intent/answer")
ROBOT_ACT = Topic("robot/act", query=True)
ROBOT_STATE = Topic("robot/state", reliable=False)
ROBOT_STOP = Topic("robot/stop", express=True)
PLAN_STATUS = Topic("plan/status")
SIM_RESET = Topic("sim/reset", query=True)
SIM_RENDER = Topic("sim/render", query=True)
SIM_INFO = Topic("sim/info", query=True)

TOPICS: dict[str, Topic] = {
    t.suffix: t
    for t in (
        HANDS_FRAME, GAZE, CAMERA_PREVIEW, USER, GESTURES_STATIC, GESTURES_DYNAMIC, EPISODE_EVENT,
        EPISODE_SUMMARY, SCENE_STATE, INTENT, INTENT_INFER, INTENT_FEEDBACK, INTENT_CLARIFY,
        INTENT_ANSWER, ROBOT_ACT,
        ROBOT_STATE, ROBOT_STOP, PLAN_STATUS, SIM_RESET, SIM_RENDER, SIM_INFO,
    )
}
DATA_TOPICS: tuple[Topic, ...] = tuple(t for t in TOPICS.values() if not t.query)
"""Every key that carries data (no query): what a viewer of the whole system subscribes to."""

_CHUNK = re.compile(r"^[A-Za-z0-9_.\-]+$")
_SERVICE = re.compile(r"^[a-z][a-z0-9\-]*$")


def check_prefix(prefix: str) -> str:
    """Returns the prefix if it is a plain key expression, else raises ConfigError.

    A prefix is one or more ``/``-separated chunks of letters, digits, ``_ . -``; no wildcards,
    no ``@``, no leading or trailing slash (``cbgo``, ``cell-2/cbgo``).
    """
    chunks = prefix.split("/")
    if not prefix or not all(_CHUNK.match(c) for c in chunks):
        raise ConfigError(
            f"invalid key prefix {prefix!r}: use chunks of letters, digits, '_', '.', '-' "
            "separated by '/', e.g. 'cbgo' or 'cell-2/cbgo'"
        )
    return prefix


def check_service_name(name: str) -> str:
    """Returns the service name if it is lower-case kebab-case, else raises ConfigError."""
    if not _SERVICE.match(name):
        raise ConfigError(f"invalid service name {name!r}: use lower-case kebab-case, "
                          "e.g. 'episode'")
    return name


class Keys:
    """Key expressions under one prefix.

    Args:
        prefix: the configurable root, ``cbgo`` by default.
    """

    def __init__(self, prefix: str = DEFAULT_PREFIX):
        self.prefix = check_prefix(prefix)

    def __repr__(self) -> str:
        return f"Keys({self.prefix!r})"

    def of(self, topic: Topic) -> str:
        """Returns the key expression of a topic, e.g. ``cbgo/hands/frame``."""
        return f"{self.prefix}/{topic.suffix}"

    def alive(self, service: str) -> str:
        """Returns the liveliness token key of a service (``*`` for all)."""
        return f"{self.prefix}/@alive/{service}"

    def ctl(self, service: str, verb: str) -> str:
        """Returns a control key of a service, e.g. ``cbgo/@ctl/episode/status``."""
        return f"{self.prefix}/@ctl/{service}/{verb}"

    @property
    def data(self) -> str:
        """The wildcard of all data keys (control keys excluded by their ``@`` chunk)."""
        return f"{self.prefix}/**"

    def topic_of(self, key: str) -> Topic | None:
        """Returns the topic a concrete key belongs to, or None if it is not a contract key."""
        head = self.prefix + "/"
        return TOPICS.get(key[len(head):]) if key.startswith(head) else None

    def service_of_alive(self, key: str) -> str | None:
        """Returns the service name of a liveliness key, or None if it is not one."""
        head = f"{self.prefix}/@alive/"
        name = key[len(head):] if key.startswith(head) else ""
        return name or None

    def resolve(self, key: str) -> str:
        """Returns a user-typed key as a full key expression.

        Keys that already start with the prefix, or with ``@`` (Zenoh's admin space, ``@/...``),
        are taken as they are, except cbgo's own control keys (``@ctl/...``, ``@alive/...``),
        which live under the prefix; anything else is taken as relative to the prefix
        (``hands/frame``, ``@ctl/*/status``).
        """
        own_control = key.startswith(("@ctl/", "@alive/"))
        if (key.startswith(self.prefix + "/") or key == self.prefix
                or (key.startswith("@") and not own_control)):
            return key
        return f"{self.prefix}/{key.lstrip('/')}"
