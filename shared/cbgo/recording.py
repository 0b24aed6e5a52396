"""Recordings of cbgo traffic as MCAP files, and the gesture toolbox's JSON hand recordings.

A cbgo recording is an ordinary MCAP file (https://mcap.dev/spec), readable by any MCAP tool:

- one channel per Zenoh key; the channel topic is the full key (``cbgo/hands/frame``) and its
  ``message_encoding`` is ``msgpack``. Channels have no schema (schema id 0): msgpack is
  self-describing, and the MCAP registry lets self-describing encodings omit the schema;
- a message's ``log_time`` is when the recorder received it, its ``publish_time`` the message's
  own ``ts`` when that is a finite number >= 0, else the receive time (both in ns since the Unix
  epoch); ``sequence`` counts the messages of each channel from 0;
- the header's profile is ``cbgo`` and its library names cbgo and mcap-python; a metadata record
  ``cbgo`` (version, prefix, keys subscribed, start time, host) is written at the start and one
  named ``cbgo.end`` (stop time, message count) at the end;
- the data is chunked and zstd-compressed, with message indexes, statistics and a summary
  section, so ``mcap info`` and seeking readers work. The file is complete only after
  `Recorder.close`; a recorder killed with SIGKILL leaves a file that `read_recording` rejects.

`load_toolbox_json` converts a recording of the paper's gesture toolbox
(imitrob/teleop_gesture_toolbox) into contract ``hands/frame`` messages; its docstring says what
that format is and how fields the JSON lacks are filled in.
"""

from __future__ import annotations

import datetime
import functools
import json
import math
import socket
import struct
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack
import numpy as np
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

import cbgo
from cbgo import wire
from cbgo.errors import RecordingError, RejectedMessage
from cbgo.keys import DEFAULT_PREFIX

PROFILE = "cbgo"
MESSAGE_ENCODING = "msgpack"
METADATA_START = "cbgo"
METADATA_END = "cbgo.end"
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}
DEFAULT_CHUNK_BYTES = 1 << 20  # 1 MiB: ~2 s of hand frames at 120 Hz per compressed chunk
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

    Raises:
        RecordingError: the file cannot be created, or the compression is unknown.
    """

    def __init__(self, path: str | Path, *, prefix: str = DEFAULT_PREFIX,
                 keys: Iterable[str] = (), profile: str = PROFILE,
                 compression: str = "zstd", chunk_bytes: int = DEFAULT_CHUNK_BYTES):
        if compression not in COMPRESSIONS:
            raise RecordingError(f"unknown compression {compression!r}; use one of "
                                 f"{', '.join(COMPRESSIONS)}")
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
        self.started_ns = time.time_ns()
        self._writer.start(profile=profile,
                           library=f"cbgo/{cbgo.__version__}; {LIBRARY_IDENTIFIER}")
        self._writer.add_metadata(METADATA_START, {
            "cbgo_version": cbgo.__version__, "prefix": prefix, "keys": json.dumps(list(keys)),
            "start_time_ns": str(self.started_ns), "start_time": _iso(self.started_ns),
            "host": socket.gethostname(),
        })

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
            False if the recorder is already closed (the message is dropped), else True.
        """
        received = time.time_ns() if receive_time_ns is None else int(receive_time_ns)
        published = publish_time_ns(payload, received)  # decoded outside the lock
        with self._lock:
            if self._closed:
                return False
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

    def stats(self) -> dict[str, KeyStats]:
        """Returns a snapshot of what was written, per key, in first-seen order."""
        with self._lock:
            return {k: KeyStats(s.count, s.bytes, s.first_ns, s.last_ns)
                    for k, s in self._stats.items()}

    @property
    def message_count(self) -> int:
        """Messages written so far, all keys together."""
        with self._lock:
            return sum(s.count for s in self._stats.values())

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
                    "message_count": str(sum(s.count for s in self._stats.values())),
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
        counts: message count per key (channel topic), in channel order.
        start_ns: log time of the first message (0 if there is none).
        end_ns: log time of the last message.
        metadata: every metadata record, by name.
    """

    path: Path
    profile: str
    library: str
    counts: dict[str, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)

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
                info.counts = {c.topic: stats.channel_message_counts.get(cid, 0)
                               for cid, c in summary.channels.items()}
                info.start_ns, info.end_ns = stats.message_start_time, stats.message_end_time
                return info
            for _schema, channel, message in reader.iter_messages(log_time_order=False):
                info.counts[channel.topic] = info.counts.get(channel.topic, 0) + 1
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
        topics = [c.topic for c in summary.channels.values() if matches(c.topic)]
    return _iterate(path, stream, reader, topics, matches)


def _iterate(path: Path, stream, reader, topics, matches: KeyFilter
             ) -> Iterator[RecordedMessage]:
    with stream:
        if topics == []:
            return
        messages = reader.iter_messages(topics=topics, log_time_order=True)
        while True:
            try:
                _schema, channel, record = next(messages)
            except StopIteration:
                return
            except _CORRUPT as e:
                raise RecordingError(f"{path} is corrupt ({type(e).__name__}: {e})") from None
            if matches(channel.topic):
                yield RecordedMessage(channel.topic, record.log_time, record.publish_time,
                                      bytes(record.data), record.sequence)


# ============================================================================ toolbox JSON

TOOLBOX_DEVICE = "toolbox-json"
_SIDE_KEYS = (("l", "left"), ("r", "right"), ("left", "left"), ("right", "right"))
PINCH_CLOSED_MM, PINCH_OPEN_MM = 20.0, 70.0  # thumb-index tip distance for pinch 1 and 0


class _FieldError(Exception):
    """A problem at a field of one frame; turned into RecordingError with the frame index."""

    def __init__(self, path: str, problem: str):
        super().__init__(f"{path}: {problem}" if path else problem)


def _number(value: Any, path: str) -> float:
    if type(value) not in (int, float) or not math.isfinite(value):
        raise _FieldError(path, f"expected a finite number, got {value!r}"[:120])
    return float(value)


def _vec3(value: Any, path: str) -> np.ndarray:
    if isinstance(value, dict) and all(k in value for k in "xyz"):
        value = [value["x"], value["y"], value["z"]]
    if not isinstance(value, list) or len(value) != 3:
        raise _FieldError(path, "expected a vector {x, y, z} or [x, y, z], got "
                                f"{value!r}"[:120])
    return np.array([_number(v, f"{path}[{i}]") for i, v in enumerate(value)])


def _optional(hand: dict, name: str, path: str, parse) -> Any:
    """Returns the parsed field, or None when it is absent or null (then it is derived)."""
    value = hand.get(name)
    return None if value is None else parse(value, f"{path}.{name}")


def _unit(v: np.ndarray | None) -> np.ndarray | None:
    if v is None:
        return None
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else None


def _quaternion(basis: Any, path: str) -> list[float] | None:
    """Returns [qx, qy, qz, qw] of a Leap bone basis (x, y, z axes), or None if unusable.

    Leap gives left hands a left-handed basis; flipping its x axis makes it a rotation and keeps
    the z axis, whose negative is the bone's direction (the contract's convention).
    """
    if not isinstance(basis, list) or len(basis) != 3:
        return None
    try:
        m = np.column_stack([_vec3(b, f"{path}[{i}]") for i, b in enumerate(basis)])
    except _FieldError:
        return None
    if np.linalg.det(m) < 0:
        m[:, 0] = -m[:, 0]
    if not np.allclose(m.T @ m, np.eye(3), atol=0.05):
        return None  # the toolbox's all-zero default basis, or a bad one
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i], q[j], q[k] = s / 4, (m[j, i] + m[i, j]) / s, (m[k, i] + m[i, k]) / s
    q = np.array(q) / np.linalg.norm(q)
    return [float(x) for x in q]


def _bones(finger: Any, path: str) -> list[dict]:
    bones = finger.get("bones") if isinstance(finger, dict) else finger
    if not isinstance(bones, list) or len(bones) != 4:
        raise _FieldError(path + ".bones", "expected 4 bones (metacarpal to distal)")
    out = []
    for btype, bone, i in zip(wire.BONE_TYPES, bones, range(4), strict=True):
        where = f"{path}.bones[{i}]"
        if not isinstance(bone, dict):
            raise _FieldError(where, "expected a bone object")
        entry = {"type": btype, "prev_joint": _vec3(bone.get("prev_joint"), where + ".prev_joint"),
                 "next_joint": _vec3(bone.get("next_joint"), where + ".next_joint"),
                 "width": _optional(bone, "width", where, _number)}
        rotation = _quaternion(bone.get("basis"), where + ".basis")
        if rotation is not None:
            entry["rotation"] = rotation
        out.append(entry)
    return out


def _estimates(fingers: list[list[dict]], side: str, direction: np.ndarray | None) -> dict:
    """Hand fields derived from the joints, for files that lack them (see load_toolbox_json)."""
    knuckle = {f: fingers[i][0]["next_joint"] for i, f in enumerate(wire.FINGER_TYPES)}
    wrist = np.mean([fingers[i][0]["prev_joint"] for i in range(1, 5)], axis=0)
    derived_direction = _unit(knuckle["middle"] - wrist)
    direction = direction if direction is not None else derived_direction
    across = knuckle["pinky"] - knuckle["index"]
    normal = None
    if direction is not None:
        normal = _unit(np.cross(direction, across) * (1.0 if side == "right" else -1.0))
    curls = []
    for i in range(1, 5):
        distal = _unit(fingers[i][3]["next_joint"] - fingers[i][3]["prev_joint"])
        if distal is not None and direction is not None:
            curls.append(math.acos(float(np.clip(np.dot(distal, direction), -1, 1))) / math.pi)
    pinch_mm = float(np.linalg.norm(fingers[0][3]["next_joint"] - fingers[1][3]["next_joint"]))
    pinch = (PINCH_OPEN_MM - pinch_mm) / (PINCH_OPEN_MM - PINCH_CLOSED_MM)
    return {
        "wrist_position": wrist, "direction": derived_direction, "palm_normal": normal,
        # four fingers side by side: the knuckles span three of the four finger widths
        "palm_width": float(np.linalg.norm(across)) * 4.0 / 3.0,
        "grab_strength": float(np.clip(np.mean(curls), 0.0, 1.0)) if curls else 0.0,
        "pinch_strength": float(np.clip(pinch, 0.0, 1.0)),
    }


def _side_of(hand: dict, default: str | None, path: str) -> str:
    side = hand.get("side")
    if side in ("left", "right"):
        return side
    if hand.get("is_left") is True:
        return "left"
    if hand.get("is_right") is True:
        return "right"
    if default is None:
        raise _FieldError(path, "cannot tell the side: expected side, is_left or is_right")
    return default


def _hand(hand: dict, side: str, path: str, index: int) -> dict:
    fingers_raw = hand.get("fingers")
    if not isinstance(fingers_raw, list) or len(fingers_raw) != 5:
        raise _FieldError(path + ".fingers", "expected 5 fingers (thumb to pinky)")
    fingers = [_bones(f, f"{path}.fingers[{i}]") for i, f in enumerate(fingers_raw)]
    palm = _vec3(hand.get("palm_position"), path + ".palm_position")
    given = {name: _optional(hand, name, path, _vec3)
             for name in ("palm_velocity", "palm_normal", "direction", "wrist_position")}
    given.update({name: _optional(hand, name, path, _number)
                  for name in ("palm_width", "grab_strength", "pinch_strength", "confidence")})
    given["direction"] = _unit(given["direction"])
    given["palm_normal"] = _unit(given["palm_normal"])
    derived = _estimates(fingers, side, given["direction"])
    out = {name: given[name] if given[name] is not None else derived[name] for name in derived}
    for name in ("direction", "palm_normal"):
        if out[name] is None:
            raise _FieldError(f"{path}.{name}", "missing, and the joints are too degenerate "
                                                "to derive it")
    hand_id = hand.get("id")
    return {
        "id": hand_id if type(hand_id) is int else index, "side": side,
        "confidence": 1.0 if given["confidence"] is None else given["confidence"],
        "palm_position": palm, "palm_velocity": given["palm_velocity"], **out,
        "fingers": [{"type": ftype, "bones": [{**b, "width": b["width"] or 0.0} for b in bones]}
                    for ftype, bones in zip(wire.FINGER_TYPES, fingers, strict=True)],
    }


def _frame_hands(frame: dict) -> list[dict]:
    found = []
    for key, side in _SIDE_KEYS:
        hand = frame.get(key)
        if hand is None:
            continue
        if not isinstance(hand, dict):
            raise _FieldError(key, "expected a hand object")
        if hand.get("visible", True):
            found.append((hand, _side_of(hand, side, key), key))
    listed = frame.get("hands")  # a list of hands; the toolbox itself stores a count here
    if isinstance(listed, list):
        for j, hand in enumerate(listed):
            if not isinstance(hand, dict):
                raise _FieldError(f"hands[{j}]", "expected a hand object")
            if hand.get("visible", True):
                found.append((hand, _side_of(hand, None, f"hands[{j}]"), f"hands[{j}]"))
    return [_hand(hand, side, path, i) for i, (hand, side, path) in enumerate(found)]


def _frame_time(frame: dict) -> float:
    sec = frame.get("sec", frame.get("secs"))
    if sec is not None:
        nanosec = frame.get("nanosec", frame.get("nsecs")) or 0
        t = _number(sec, "sec") + _number(nanosec, "nanosec") * 1e-9
    elif frame.get("ts") is not None:
        t = _number(frame["ts"], "ts")
    else:
        raise _FieldError("sec", "missing timestamp (expected sec and nanosec, or ts)")
    if t < 0:
        raise _FieldError("sec", f"expected a timestamp >= 0, got {t}")
    return t


def _fill_velocities(frames: list[tuple[float, list[dict]]]) -> None:
    """Finite differences of palm positions (mm/s) for hands without a palm velocity."""
    def same_side(i: int, side: str) -> dict | None:
        if 0 <= i < len(frames):
            return next((h for h in frames[i][1] if h["side"] == side), None)
        return None

    for i, (t, hands) in enumerate(frames):
        for hand in hands:
            if hand["palm_velocity"] is not None:
                continue
            velocity = np.zeros(3)
            for j in (i - 1, i + 1):
                other = same_side(j, hand["side"])
                dt = (t - frames[j][0]) if other is not None else 0.0
                if other is not None and dt != 0:
                    velocity = (hand["palm_position"] - other["palm_position"]) / dt
                    break
            hand["palm_velocity"] = velocity


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return [float(x) for x in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def load_toolbox_json(path: str | Path) -> list[tuple[float, dict]]:
    """Returns the frames of a gesture-toolbox JSON recording as contract hand frames.

    The format is the one imitrob/teleop_gesture_toolbox writes with ``json.dumps(frames,
    cls=FrameEncoder)`` (``gesture_detector/utils/saving.py``): a JSON list of ``Frame``
    objects' ``__dict__`` (``hand_processing/frame_lib.py``). A frame has ``seq``, ``sec`` and
    ``nanosec`` (``secs``/``nsecs`` in ROS 1 files), ``fps``, ``hands`` (a count), ``l`` and
    ``r`` (one hand each, ``visible`` false when absent) and ``leapgestures``. A hand has
    ``id``, ``is_left``/``is_right``, ``confidence``, ``grab_strength``, ``pinch_strength``,
    ``palm_position``, ``palm_velocity``, ``palm_normal``, ``direction``, ``wrist_position``,
    ``palm_width`` and ``fingers``: 5 (thumb to pinky) of ``{"bones": [4 bones]}``, each bone
    with ``prev_joint``, ``next_joint``, ``width``, ``basis`` (3 axis vectors) and more.
    Vectors are ``{"x", "y", "z"}`` objects in the Leap frame (mm). Also accepted: ``left``/
    ``right`` instead of ``l``/``r``, a ``hands`` list of hands with ``side`` (or
    ``is_left``/``is_right``), ``[x, y, z]`` lists for vectors, ``ts`` (s) for the time.

    Mapping: ``source`` "replay", ``device`` "toolbox-json", ``seq`` the frame's seq (else its
    index), ``ts`` the frame time ``sec + nanosec * 1e-9`` as the file has it (the Leap
    service's clock, not the Unix epoch). Bones keep their joints, so the thumb's metacarpal is
    zero-length when the sensor made it so; a bone's ``basis`` becomes its ``rotation``
    (quaternion; the x axis of a left-handed basis is flipped). Fields the JSON lacks or has as
    null are filled in, never invented silently:

    - ``palm_velocity``: finite difference of the palm positions of the same side in the
      previous (else next) frame, mm/s; zeros for a hand seen in one frame only;
    - ``confidence``: 1.0; bone ``width``: 0.0 (unknown);
    - ``wrist_position``: the mean of the index-to-pinky metacarpal bases;
    - ``direction``: wrist to middle knuckle; ``palm_normal``: direction x (index to pinky
      knuckle), negated for left hands;
    - ``palm_width``: 4/3 of the index-to-pinky knuckle distance (four finger widths);
    - ``grab_strength``: the mean over the four fingers of the angle between the distal bone and
      the hand direction, divided by 180 degrees (straight 0, folded back 1);
    - ``pinch_strength``: 1 at thumb-index tip distance <= 20 mm, 0 at >= 70 mm, linear between.

    Args:
        path: the JSON file.

    Returns:
        (frame time in seconds, hands/frame message) per frame, in file order.

    Raises:
        RecordingError: unreadable file, not JSON, not a list, or a malformed frame (naming the
            frame index and the field).
    """
    path = Path(path)
    try:
        raw = json.loads(path.read_text())
    except OSError as e:
        raise RecordingError(f"cannot read toolbox recording {path}: {e.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise RecordingError(f"{path} is not JSON: {e}") from None
    if not isinstance(raw, list):
        raise RecordingError(f"{path}: expected a JSON list of frames, got "
                             f"{type(raw).__name__}")
    frames = []
    for i, frame in enumerate(raw):
        try:
            if not isinstance(frame, dict):
                raise _FieldError("", "expected a frame object")
            frames.append((_frame_time(frame), _frame_hands(frame)))
        except _FieldError as e:
            raise RecordingError(f"{path}: frame {i}: {e}") from None
    _fill_velocities(frames)
    out = []
    for i, ((t, hands), frame) in enumerate(zip(frames, raw, strict=True)):
        seq = frame.get("seq")
        message = {"v": wire.SCHEMA_VERSION, "ts": t,
                   "seq": seq if type(seq) is int and seq >= 0 else i,
                   "source": "replay", "device": TOOLBOX_DEVICE, "hands": _plain(hands)}
        try:
            wire.validate(message, wire.HANDS_FRAME, "hands/frame")
        except RejectedMessage as e:
            raise RecordingError(f"{path}: frame {i}: {e}") from None
        out.append((t, message))
    return out
