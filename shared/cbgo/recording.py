"""Recordings of cbgo traffic as MCAP files: writing, reading, filtering by key.

A cbgo recording is an ordinary MCAP file (https://mcap.dev/spec), readable by any MCAP tool:

- one channel per Zenoh key; the channel topic is the full key (``cbgo/hands/frame``). With
  the default encoding ``msgpack`` its ``message_encoding`` is ``msgpack`` and it has no schema
  (schema id 0): msgpack is self-describing, and the MCAP registry lets self-describing
  encodings omit the schema. With encoding ``json`` (for Foxglove; `cbgo.foxglove.channels`)
  each message is checked against its key's contract and written as JSON with the key's JSON
  Schema (schema encoding ``jsonschema``), and the derived channels ``foxglove/scene``,
  ``foxglove/transforms`` and ``foxglove/log`` are written beside them; a message that breaks
  the contract is not written but counted per key (`Recorder.rejected`);
- a message's ``log_time`` is when the recorder received it, its ``publish_time`` the message's
  own ``ts`` when that is a finite number >= 0, else the receive time (both in ns since the Unix
  epoch); ``sequence`` counts the messages of each channel from 0;
- the header's profile is ``cbgo`` and its library names cbgo and mcap-python; a metadata record
  ``cbgo`` (version, prefix, keys subscribed, start time, host) is written at the start and one
  named ``cbgo.end`` (stop time, message count) at the end;
- the data is chunked and zstd-compressed, with message indexes, statistics and a summary
  section, so ``mcap info`` and seeking readers work. The file is complete only after
  `Recorder.close`; a recorder killed with SIGKILL leaves a file that `read_recording` rejects.

`read_recording` reads both encodings and gives every message as its msgpack payload (a JSON
one re-encoded; bytes fields come back from their base64); derived ``foxglove.*`` channels are
not wire messages and are left out (`RecordingInfo.derived` counts them).

The gesture toolbox's JSON hand recordings are read by `cbgo.toolbox` (`load_toolbox_json`,
re-exported here).
"""

from __future__ import annotations

import datetime
import functools
import json
import logging
import math
import socket
import struct
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import msgpack
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

import cbgo
from cbgo import wire
from cbgo.errors import RecordingError, RejectedMessage
from cbgo.foxglove.channels import MESSAGE_ENCODING as JSON_ENCODING
from cbgo.foxglove.channels import JsonChannels, is_derived, wire_payload
from cbgo.foxglove.derive import DERIVED_TOPICS
from cbgo.keys import DEFAULT_PREFIX

# The toolbox JSON reader moved to cbgo.toolbox; its names stay importable from here.
from cbgo.toolbox import TOOLBOX_DEVICE, load_toolbox_json  # noqa: F401

PROFILE = "cbgo"
MESSAGE_ENCODING = "msgpack"
ENCODINGS = (MESSAGE_ENCODING, JSON_ENCODING)
METADATA_START = "cbgo"
METADATA_END = "cbgo.end"
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}
DEFAULT_CHUNK_BYTES = 1 << 20  # 1 MiB: ~2 s of hand frames at 120 Hz per compressed chunk
_log = logging.getLogger("cbgo.recording")
_U32 = 1 << 32  # MCAP sequence numbers are uint32
_MAX_NS = (1 << 63) - 1


def _iso(ns: int) -> str:
    return datetime.datetime.fromtimestamp(ns / 1e9, datetime.timezone.utc).isoformat()


def publish_time_ns(payload: bytes, receive_time_ns: int) -> int:
    """Returns the message's own ``ts`` in ns, or the receive time if it has no usable one.

    Args:
        payload: the msgpack bytes as received.
        receive_time_ns: the fallback, ns since the Unix epoch.
    """
    try:
        message = msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except (msgpack.ExtraData, msgpack.UnpackException, ValueError, TypeError):
        return receive_time_ns
    ts = message.get("ts") if isinstance(message, dict) else None
    if type(ts) in (int, float) and math.isfinite(ts) and 0 <= ts * 1e9 <= _MAX_NS:
        return int(round(ts * 1e9))
    return receive_time_ns


# ============================================================================ writing


@dataclass
class KeyStats:
    """What a recorder has written for one key.

    Attributes:
        count: messages written.
        bytes: payload bytes written.
        first_ns: receive time of the first message (ns since the Unix epoch).
        last_ns: receive time of the last message.
    """

    count: int = 0
    bytes: int = 0
    first_ns: int = 0
    last_ns: int = 0

    @property
    def rate_hz(self) -> float:
        """Mean message rate between the first and the last message (0 with fewer than 2)."""
        span = (self.last_ns - self.first_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


class Recorder:
    """Writes received Zenoh samples into an MCAP file, one channel per key.

    `write` may be called from any thread (Zenoh callbacks); calls after `close` are ignored, so
    a late callback racing a Ctrl-C cannot corrupt the file.

    Args:
        path: the file to create (overwritten if it exists).
        prefix: the key prefix the traffic was recorded under, stored in the metadata.
        keys: the key expressions subscribed to, stored in the metadata.
        profile: the MCAP header profile.
        compression: ``zstd``, ``lz4`` or ``none``.
        chunk_bytes: uncompressed size at which a chunk is closed and compressed.
        encoding: ``msgpack`` (payloads as received) or ``json`` (checked, JSON with schemas,
            and the derived Foxglove channels).
        metadata: extra entries of the start metadata record (`cbgo export` names its source).

    Raises:
        RecordingError: the file cannot be created, or the compression or encoding is unknown.
    """

    def __init__(self, path: str | Path, *, prefix: str = DEFAULT_PREFIX,
                 keys: Iterable[str] = (), profile: str = PROFILE,
                 compression: str = "zstd", chunk_bytes: int = DEFAULT_CHUNK_BYTES,
                 encoding: str = MESSAGE_ENCODING, metadata: dict[str, str] | None = None):
        if compression not in COMPRESSIONS:
            raise RecordingError(f"unknown compression {compression!r}; use one of "
                                 f"{', '.join(COMPRESSIONS)}")
        if encoding not in ENCODINGS:
            raise RecordingError(f"unknown encoding {encoding!r}; use one of "
                                 f"{', '.join(ENCODINGS)}")
        self.path = Path(path)
        try:
            self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as e:
            raise RecordingError(f"cannot create {self.path}: {e.strerror}") from None
        self._lock = threading.Lock()
        self._writer = Writer(self._file, chunk_size=chunk_bytes,
                              compression=COMPRESSIONS[compression])
        self._channels: dict[str, int] = {}
        self._stats: dict[str, KeyStats] = {}
        self._closed = False
        self.encoding = encoding
        self._json = None  # JsonChannels, once the writer has started
        self.rejected: dict[str, tuple[int, str]] = {}  # key -> (count, last reason); json only
        self.started_ns = time.time_ns()
        self._writer.start(profile=profile,
                           library=f"cbgo/{cbgo.__version__}; {LIBRARY_IDENTIFIER}")
        self._writer.add_metadata(METADATA_START, {
            "cbgo_version": cbgo.__version__, "prefix": prefix, "keys": json.dumps(list(keys)),
            "start_time_ns": str(self.started_ns), "start_time": _iso(self.started_ns),
            "host": socket.gethostname(), "encoding": encoding, **(metadata or {}),
        })
        if encoding == JSON_ENCODING:
            self._json = JsonChannels(self._writer, prefix)

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """True once `close` has run."""
        return self._closed

    def write(self, key: str, payload: bytes, receive_time_ns: int | None = None) -> bool:
        """Appends one message on key; thread-safe.

        Args:
            key: the concrete key it arrived on (the channel topic).
            payload: the bytes as received (not re-encoded).
            receive_time_ns: when it arrived, ns since the Unix epoch (now if None).

        Returns:
            False if the recorder is already closed (the message is dropped), else True (also
            for a message the json encoding rejected: see `rejected`).
        """
        received = time.time_ns() if receive_time_ns is None else int(receive_time_ns)
        published = publish_time_ns(payload, received)  # decoded outside the lock
        with self._lock:
            if self._closed:
                return False
            if self._json is not None:
                self._write_json(key, payload, received, published)
                return True
            channel = self._channels.get(key)
            if channel is None:
                channel = self._writer.register_channel(key, MESSAGE_ENCODING, 0)
                self._channels[key] = channel
                self._stats[key] = KeyStats(first_ns=received)
            stats = self._stats[key]
            self._writer.add_message(channel, log_time=received, data=payload,
                                     publish_time=published, sequence=stats.count % _U32)
            stats.count += 1
            stats.bytes += len(payload)
            stats.last_ns = received
        return True

    def _write_json(self, key: str, payload: bytes, received: int, published: int) -> None:
        try:
            written = self._json.write(key, payload, received, published)
        except RejectedMessage as e:
            count, _ = self.rejected.get(key, (0, ""))
            self.rejected[key] = (count + 1, str(e))
            return
        for topic, size in written:
            stats = self._stats.setdefault(topic, KeyStats(first_ns=received))
            stats.count += 1
            stats.bytes += size
            stats.last_ns = received

    def stats(self) -> dict[str, KeyStats]:
        """Returns a snapshot of what was written, per key, in first-seen order."""
        with self._lock:
            return {k: KeyStats(s.count, s.bytes, s.first_ns, s.last_ns)
                    for k, s in self._stats.items()}

    @property
    def message_count(self) -> int:
        """Wire messages written so far, all keys together (derived Foxglove ones not)."""
        with self._lock:
            return sum(s.count for k, s in self._stats.items() if k not in DERIVED_TOPICS)

    def close(self) -> None:
        """Writes the end metadata, the indexes and the summary, and closes the file.

        Idempotent. After it returns the file is a complete MCAP file.
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            stopped = time.time_ns()
            try:
                self._writer.add_metadata(METADATA_END, {
                    "stop_time_ns": str(stopped), "stop_time": _iso(stopped),
                    "message_count": str(sum(s.count for k, s in self._stats.items()
                                             if k not in DERIVED_TOPICS)),
                })
                self._writer.finish()
            finally:
                self._file.close()


# ============================================================================ reading


@dataclass
class RecordedMessage:
    """One message of a recording.

    Attributes:
        key: the key it was received on.
        log_time_ns: when the recorder received it (ns since the Unix epoch).
        publish_time_ns: the message's own ``ts`` in ns, or the receive time.
        payload: the bytes exactly as received.
        sequence: its index among the messages of its key.
    """

    key: str
    log_time_ns: int
    publish_time_ns: int
    payload: bytes
    sequence: int = 0

    @functools.cached_property
    def message(self) -> dict:
        """The decoded msgpack map, decoded on first access.

        Raises:
            RejectedMessage: the payload is not one msgpack map with string keys.
        """
        return wire.decode(self.payload, max_bytes=max(len(self.payload), 1))


@dataclass
class RecordingInfo:
    """What a recording's header, summary and metadata say.

    Attributes:
        path: the file.
        profile: the header's profile (``cbgo`` for files written by `Recorder`).
        library: the header's library string.
        counts: message count per key (channel topic), in channel order; wire channels only.
        start_ns: log time of the first message (0 if there is none).
        end_ns: log time of the last message.
        metadata: every metadata record, by name.
        derived: message count per derived Foxglove channel (``foxglove/scene``...).
        encodings: the message encoding of each channel, derived ones included.
    """

    path: Path
    profile: str
    library: str
    counts: dict[str, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    derived: dict[str, int] = field(default_factory=dict)
    encodings: dict[str, str] = field(default_factory=dict)

    def count(self, channel, schema, n: int = 1) -> None:
        """Adds n messages of an MCAP channel (with its schema, or None) to the counts."""
        name = schema.name if schema is not None else None
        table = self.derived if is_derived(name) else self.counts
        table[channel.topic] = table.get(channel.topic, 0) + n
        self.encodings[channel.topic] = channel.message_encoding

    @property
    def message_count(self) -> int:
        """Messages in the file, all keys together."""
        return sum(self.counts.values())

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last message."""
        return max(0, self.end_ns - self.start_ns) / 1e9

    @property
    def prefix(self) -> str | None:
        """The key prefix the recorder ran with, if the file says."""
        return self.metadata.get(METADATA_START, {}).get("prefix")


# Exceptions the mcap reader, its decompressors and struct raise on corrupt or truncated data
# (found by flipping bytes of a recording): lz4.frame reports corrupt frames with RuntimeError,
# a corrupt offset makes seek fail with OSError, and a corrupt chunk length makes the reader ask
# for an impossible buffer (MemoryError).
_CORRUPT: tuple[type[BaseException], ...] = (McapError, struct.error, ValueError, EOFError,
                                             KeyError, IndexError, OverflowError, OSError,
                                             RuntimeError, MemoryError)
try:
    import zstandard

    _CORRUPT += (zstandard.ZstdError,)
except ImportError:  # pragma: no cover - mcap depends on zstandard
    pass


def _open_reader(path: str | Path):
    path = Path(path)
    try:
        stream = open(path, "rb")  # noqa: SIM115 - the caller closes it
    except OSError as e:
        raise RecordingError(f"cannot open recording {path}: {e.strerror}") from None
    try:
        # No record is longer than the file: a corrupt length then fails fast, not in malloc.
        reader = SeekingReader(stream, validate_crcs=True,
                               record_size_limit=max(path.stat().st_size, 1))
        header = reader.get_header()
        summary = reader.get_summary()
    except _CORRUPT as e:
        stream.close()
        raise RecordingError(f"{path} is not a complete MCAP file ({type(e).__name__}: {e}); "
                             "was the recorder killed before it could close the file?") from None
    return path, stream, reader, header, summary


def recording_info(path: str | Path) -> RecordingInfo:
    """Returns the header, per-key counts, time range and metadata of a recording.

    Raises:
        RecordingError: the file is missing, not MCAP, truncated or corrupt.
    """
    path, stream, reader, header, summary = _open_reader(path)
    with stream:
        info = RecordingInfo(path, header.profile, header.library)
        try:
            info.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                for cid, channel in summary.channels.items():
                    info.count(channel, summary.schemas.get(channel.schema_id),
                               stats.channel_message_counts.get(cid, 0))
                info.start_ns, info.end_ns = stats.message_start_time, stats.message_end_time
                return info
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                info.count(channel, schema)
                info.start_ns = min(info.start_ns or message.log_time, message.log_time)
                info.end_ns = max(info.end_ns, message.log_time)
        except _CORRUPT as e:
            raise RecordingError(f"{path} is corrupt ({type(e).__name__}: {e})") from None
    return info


class KeyFilter:
    """Matches concrete keys against key expressions with Zenoh's ``*`` and ``**`` wildcards.

    Args:
        expressions: key expressions (``cbgo/hands/*``, ``cbgo/**``); None matches every key.

    Raises:
        RecordingError: an expression is not a valid Zenoh key expression.
    """

    def __init__(self, expressions: Iterable[str] | str | None):
        if isinstance(expressions, str):
            expressions = [expressions]
        self._exprs = None
        self._seen: dict[str, bool] = {}
        if expressions is not None:
            import zenoh  # only here: reading a recording without a filter needs no zenoh

            expressions = list(expressions)
            try:
                self._exprs = [zenoh.KeyExpr.autocanonize(e) for e in expressions]
            except zenoh.ZError as e:
                reason = str(e).split(" at /", 1)[0]  # drop the Rust source location
                raise RecordingError(f"invalid key expression in {expressions}: "
                                     f"{reason}") from None

    def __call__(self, key: str) -> bool:
        """Returns whether key matches one of the expressions."""
        if self._exprs is None:
            return True
        hit = self._seen.get(key)
        if hit is None:
            import zenoh

            try:
                concrete = zenoh.KeyExpr(key)
            except zenoh.ZError:
                hit = False  # a topic that is no key expression matches no filter
            else:
                hit = any(e.intersects(concrete) for e in self._exprs)
            self._seen[key] = hit
        return hit


def read_recording(path: str | Path, keys: Iterable[str] | str | None = None
                   ) -> Iterator[RecordedMessage]:
    """Returns the messages of a recording in log-time order.

    The file is opened and checked at once; messages are read lazily, chunk by chunk.

    Args:
        path: an MCAP file (written by `Recorder` or any MCAP writer).
        keys: only messages whose key matches one of these key expressions (exact keys or
            Zenoh ``*``/``**`` wildcards); None for all.

    Raises:
        RecordingError: at the call for a missing, non-MCAP or truncated file or a bad key
            expression; during iteration for a corrupt chunk.
    """
    matches = KeyFilter(keys)
    path, stream, reader, _header, summary = _open_reader(path)
    topics = None
    if keys is not None and summary is not None:
        topics = [c.topic for c in summary.channels.values() if matches(c.topic)
                  and not is_derived(_schema_name(summary, c))]
    return _iterate(path, stream, reader, topics, matches)


def _iterate(path: Path, stream, reader, topics, matches: KeyFilter
             ) -> Iterator[RecordedMessage]:
    bad: dict[str, int] = {}
    try:
        yield from _messages(path, stream, reader, topics, matches, bad)
    finally:
        for key, n in bad.items():
            _log.warning("%s: skipped %d unreadable JSON message%s on %s", path, n,
                         "s" if n != 1 else "", key)


def _messages(path: Path, stream, reader, topics, matches: KeyFilter, bad: dict[str, int]
              ) -> Iterator[RecordedMessage]:
    with stream:
        if topics == []:
            return
        messages = reader.iter_messages(topics=topics, log_time_order=True)
        while True:
            try:
                schema, channel, record = next(messages)
            except StopIteration:
                return
            except _CORRUPT as e:
                raise RecordingError(f"{path} is corrupt ({type(e).__name__}: {e})") from None
            if not matches(channel.topic) or is_derived(schema.name if schema else None):
                continue
            payload = _payload(channel, schema, record, bad)
            if payload is not None:
                yield RecordedMessage(channel.topic, record.log_time, record.publish_time,
                                      payload, record.sequence)


def _schema_name(summary, channel) -> str | None:
    schema = summary.schemas.get(channel.schema_id)
    return schema.name if schema is not None else None


def _payload(channel, schema, record, bad: dict[str, int]) -> bytes | None:
    """Returns a record's msgpack payload: as stored, or re-encoded from a JSON channel.

    A JSON message that cannot be read back (corrupt JSON, bad base64) is skipped, counted per
    key in `bad` and logged once per key: replaying it byte for byte would put JSON, not
    msgpack, on the wire.
    """
    if channel.message_encoding != JSON_ENCODING:
        return bytes(record.data)
    try:
        return wire_payload(bytes(record.data), schema.data if schema else None)
    except (ValueError, TypeError) as e:  # json.JSONDecodeError is a ValueError
        bad[channel.topic] = bad.get(channel.topic, 0) + 1
        if bad[channel.topic] == 1:
            _log.warning("skipping an unreadable JSON message on %s (%s); the count follows "
                         "at the end", channel.topic, e)
        return None
