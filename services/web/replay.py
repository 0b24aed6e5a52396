"""Replay: a recording turned into the same views the live page gets, for scrubbing.

`load` reads an MCAP recording (`cbgo.recording.read_recording`), checks every message against
the wire contract as a live service would (a message that breaks it is skipped and counted,
never shown), and renders it with `views.Views`, downsampled by the *recorded* time, so a
replayed page looks as the live page did. Keys under the recording's own prefix (its metadata),
else under `default_prefix`; keys outside the contract (another tool's channels) are skipped.
The page scrubs by applying the views up to the chosen time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from cbgo import wire
from cbgo.errors import ConfigError, RejectedMessage
from cbgo.keys import DEFAULT_PREFIX, Keys
from cbgo.recording import read_recording, recording_info
from cbgo.services.web.views import Views

NS = 1e-9


@dataclass
class Replay:
    """A recording as page views.

    Attributes:
        file: the recording's path.
        prefix: the key prefix its keys were read under.
        items: ``[t (s, receive time), topic, view]`` in time order.
        skipped: messages left out, by reason (``not a contract key``, ``breaks the contract``).
    """

    file: str
    prefix: str
    items: list = field(default_factory=list)
    skipped: dict[str, int] = field(default_factory=dict)

    def skip(self, reason: str) -> None:
        """Counts one message left out."""
        self.skipped[reason] = self.skipped.get(reason, 0) + 1


def _keys(path: Path, default_prefix: str) -> Keys:
    prefix = recording_info(path).prefix
    try:
        return Keys(prefix) if prefix else Keys(default_prefix)
    except ConfigError:
        return Keys(default_prefix)


def load(path: str | Path, rate_hz: float = 30.0,
         default_prefix: str = DEFAULT_PREFIX) -> Replay:
    """Reads a recording into page views.

    Raises:
        RecordingError: a missing, non-MCAP, truncated or corrupt file.
    """
    path = Path(path)
    keys = _keys(path, default_prefix)
    now = [0.0]
    views = Views(rate_hz, clock=lambda: now[0])
    replay = Replay(str(path), keys.prefix)
    for record in read_recording(path):
        topic = keys.topic_of(record.key)
        if topic is None or topic.query:
            replay.skip("not a contract key")
            continue
        try:
            message = wire.validate(record.message, topic.schema, record.key)
        except RejectedMessage:
            if not topic.any_payload:
                replay.skip("breaks the contract")
                continue
            message = {}  # a stop is a stop whatever it carries, as live
        now[0] = record.log_time_ns * NS
        replay.items += [[round(now[0], 4), name, view]
                         for name, view in views.render(topic.suffix, message)]
    return replay
