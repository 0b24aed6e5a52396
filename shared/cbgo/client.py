"""The client side of cbgo: everything outside a service that talks to cbgo over Zenoh.

The CLI, the demo, `cbgo.testing.Stack`, the benches and the demonstrate tools open their
sessions and send their queries here, so that a reply is checked the same way everywhere:

- `connect` / `session`: a client session from the usual Zenoh flags and environment
  (`cbgo.config.resolve_zenoh`, `zenoh_config`), giving up after a connect timeout with a
  `ConnectError` that says what to do;
- `query`: the first successful reply, decoded within the key's size limit
  (`keys.Topic.max_bytes`) and validated against the key's reply schema (`keys.Topic.reply_schema`;
  status replies against `wire.SERVICE_STATUS`), or a `QueryError` with the error reply's text,
  the malformed reply's fault, or "no reply ... within X s"; `query_all` for wildcard queries;
- `status`, `alive`: which services answer and are alive;
- `wait_matched`, `put_when_matched`: publish only once a subscriber is there (a put before
  that is lost);
- `Collector` (`collect`): every message published on a key, with its arrival time.

`cbgo.runtime.Context.query` shares `pick_reply`, so a service and a client read replies alike.
Zenoh is imported only where a session is opened.
"""

from __future__ import annotations

import argparse
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from cbgo import wire
from cbgo.config import ZenohOptions, add_zenoh_arguments, resolve_zenoh, zenoh_config
from cbgo.errors import CbgoError, ConfigError, QueryError, RejectedMessage, zenoh_reason
from cbgo.keys import TOPICS, Keys

DEFAULT_CONNECT_TIMEOUT_S = 5.0
NO_REPLY_HINT = "is its service up?"


class ConnectError(CbgoError):
    """A client session could not be opened; the text says why and what to do.

    Attributes:
        code: the exit code a command should end with (2: bad configuration, 1: unreachable).
    """

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


# --------------------------------------------------------------------------- sessions


def add_network_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the Zenoh flags and --connect-timeout to a command's parser."""
    add_zenoh_arguments(parser)
    parser.add_argument("--connect-timeout", type=float, default=DEFAULT_CONNECT_TIMEOUT_S,
                        metavar="S",
                        help="give up if the router cannot be reached within S seconds "
                             "[default: 5]")


def open_session(options: ZenohOptions, name: str = "cbgo-client",
                 connect_timeout_s: float | None = None):
    """Opens a Zenoh session of a client process named `name`.

    Args:
        options: the resolved Zenoh options.
        name: the session's name in the router's admin space.
        connect_timeout_s: give up after this long (None: wait for the router forever).

    Raises:
        ConnectError: the configuration is invalid or the network cannot be reached.
    """
    import zenoh

    try:
        conf = zenoh_config(options, name)
    except ConfigError as e:
        raise ConnectError(f"configuration error: {e}", 2) from None
    except zenoh.ZError as e:  # an endpoint or --cfg value Zenoh cannot parse
        raise ConnectError(f"configuration error: {zenoh_reason(e)}; endpoints look like "
                           "tcp/127.0.0.1:7447 or tls/router:7447", 2) from None
    if connect_timeout_s is not None:
        conf.insert_json5("connect/timeout_ms", str(int(connect_timeout_s * 1000)))
    try:
        return zenoh.open(conf)
    except zenoh.ZError as e:
        raise ConnectError(unreachable(options.connect, connect_timeout_s,
                                       zenoh_reason(e))) from None


def unreachable(endpoints: list[str], timeout_s: float | None, reason: str = "") -> str:
    """Returns the message for a router that does not answer: where, and how to start one.

    Zenoh's own reason is left out when it only says that the connection timed out.
    """
    within = f" within {timeout_s:g} s" if timeout_s is not None else ""
    why = "" if not reason or "Timeout" in reason else f" ({reason})"
    return (f"no Zenoh router answered at {', '.join(endpoints) or '(no endpoint)'}{within}"
            f"{why}. Start one with `cbgo up` (the router and the services) or `cbgo router`, "
            "or point --connect (or ZENOH_CONNECT) at a running one.")


def connect(flags: argparse.Namespace | Mapping[str, Any],
            name: str = "cbgo-client") -> tuple[Any, Keys]:
    """Opens a client session from parsed flags and the environment; returns (session, keys).

    Args:
        flags: the flags of `add_network_arguments` (a Namespace or ``vars()`` of one).
        name: the session's name.

    Raises:
        ConnectError: see `open_session`.
    """
    values = dict(vars(flags) if isinstance(flags, argparse.Namespace) else flags)
    try:
        options = resolve_zenoh(values)
    except ConfigError as e:
        raise ConnectError(f"configuration error: {e}", 2) from None
    timeout = values.get("connect_timeout", DEFAULT_CONNECT_TIMEOUT_S)
    return open_session(options, name, timeout), Keys(options.prefix)


@contextmanager
def session(flags: argparse.Namespace | Mapping[str, Any],
            name: str = "cbgo-client") -> Iterator[tuple[Any, Keys]]:
    """Yields (session, keys) of `connect` and closes the session afterwards.

    Raises:
        ConnectError: see `open_session` (raised before the body runs).
    """
    sess, keys = connect(flags, name)
    with sess:
        yield sess, keys


# --------------------------------------------------------------------------- queries


@dataclass(frozen=True)
class Reply:
    """One raw reply: the key that answered, whether it is ok, and its payload bytes."""

    key: str
    ok: bool
    payload: bytes

    @property
    def text(self) -> str:
        """The payload as text (an error reply's reason)."""
        return self.payload.decode("utf-8", "replace")


def replies(session, key: str, payload: bytes | None = None, timeout_s: float = 10.0,
            **options) -> list[Reply]:
    """Sends a query and returns every raw reply that came before the timeout.

    Args:
        session: a Zenoh session.
        key: the key expression or selector.
        payload: the query payload, if any.
        timeout_s: how long to wait for replies.
        **options: passed on to ``session.get`` (e.g. ``consolidation``).
    """
    out = []
    for reply in session.get(key, payload=payload, timeout=timeout_s, **options):
        if reply.ok is not None:
            out.append(Reply(str(reply.ok.key_expr), True, reply.ok.payload.to_bytes()))
        else:
            out.append(Reply(key, False, reply.err.payload.to_bytes()))
    return out


def reply_contract(key: str, default_max_bytes: int = wire.DEFAULT_MAX_BYTES
                   ) -> tuple[wire.Spec | None, int]:
    """Returns (reply schema, size limit) of a query key (None: the key has no reply schema).

    The key may have any prefix: the query topic is the one it ends with.
    """
    if "/@ctl/" in key and key.endswith("/status"):
        return wire.SERVICE_STATUS, default_max_bytes
    topic = next((t for t in TOPICS.values()
                  if t.reply_schema is not None and key.endswith("/" + t.suffix)), None)
    if topic is None:
        return None, default_max_bytes
    return topic.reply_schema, topic.max_bytes(default_max_bytes)


def read_reply(payload: bytes, key: str, spec: wire.Spec | None, max_bytes: int) -> dict:
    """Decodes and validates an ok reply.

    Raises:
        QueryError: "malformed reply: ..." naming what is wrong.
    """
    try:
        return wire.decode_checked(payload, spec, key, max_bytes)
    except RejectedMessage as e:
        raise QueryError(f"malformed reply: {e}") from None


def pick_reply(answers: list[tuple[bool, bytes]], key: str, spec: wire.Spec | None,
               max_bytes: int, timeout_s: float, hint: str = NO_REPLY_HINT) -> dict:
    """Returns the first ok reply that fits the contract.

    Args:
        answers: (ok, payload) per reply, in arrival order.
        key: the queried key, for the messages.
        spec: the reply schema (None: any map).
        max_bytes: the reply size limit.
        timeout_s: how long the query waited, for the no-reply message.
        hint: what to check when nobody answered.

    Raises:
        QueryError: no reply, or only error and malformed replies (their texts joined).
    """
    if not answers:
        raise QueryError(f"no reply on {key} within {timeout_s:g} s ({hint})")
    errors = []
    for ok, payload in answers:
        if not ok:
            errors.append(payload.decode("utf-8", "replace"))
            continue
        try:
            return read_reply(payload, key, spec, max_bytes)
        except QueryError as e:
            errors.append(str(e))
    raise QueryError("; ".join(errors))


def _encode_query(message: dict | None) -> bytes | None:
    return None if message is None else wire.encode(message)


def query(session, key: str, message: dict | None = None, *, timeout_s: float = 10.0,
          hint: str = NO_REPLY_HINT) -> dict:
    """Sends a query and returns the first successful reply, checked against the contract.

    Args:
        session: a Zenoh session.
        key: the full key expression (e.g. ``keys.of(ROBOT_ACT)``, ``keys.ctl(name, verb)``).
        message: the query payload (None: no payload).
        timeout_s: how long to wait for replies.
        hint: what the no-reply message tells the user to check.

    Raises:
        QueryError: an error reply (its text), a malformed reply, or no reply in time.
    """
    spec, max_bytes = reply_contract(key)
    answers = replies(session, key, _encode_query(message), timeout_s)
    return pick_reply([(r.ok, r.payload) for r in answers], key, spec, max_bytes, timeout_s,
                      hint)


def query_all(session, key: str, message: dict | None = None, *,
              timeout_s: float = 10.0) -> list[tuple[bool, dict | str]]:
    """Sends a (wildcard) query; returns every reply as (True, reply) or (False, error text).

    A malformed ok reply comes back as (False, "malformed reply: ..."). Replies are not
    consolidated: Zenoh's default keeps one per key, and every process of one name answers on
    the same key (two dry-robots would look like one, a reload would seem done by one).

    Args:
        session: a Zenoh session.
        key: the key expression or selector.
        message: the query payload (None: no payload).
        timeout_s: how long to wait for replies.
    """
    import zenoh

    out: list[tuple[bool, dict | str]] = []
    for r in replies(session, key, _encode_query(message), timeout_s,
                     consolidation=zenoh.ConsolidationMode.NONE):
        if not r.ok:
            out.append((False, r.text))
            continue
        spec, max_bytes = reply_contract(r.key)
        try:
            out.append((True, read_reply(r.payload, r.key, spec, max_bytes)))
        except QueryError as e:
            out.append((False, str(e)))
    return out


def status(session, keys: Keys, name: str = "*", timeout_s: float = 3.0) -> dict[str, dict]:
    """Returns {service name: status reply} of every service answering (``*``: all)."""
    return {reply["name"]: reply
            for ok, reply in query_all(session, keys.ctl(name, "status"), timeout_s=timeout_s)
            if ok}


def alive(session, keys: Keys, timeout_s: float = 1.0) -> set[str]:
    """Returns the names of the services whose liveliness token is present."""
    names = set()
    for reply in session.liveliness().get(keys.alive("*"), timeout=timeout_s):
        if reply.ok is not None:
            name = keys.service_of_alive(str(reply.ok.key_expr))
            if name:
                names.add(name)
    return names


# --------------------------------------------------------------------------- publishing


def wait_matched(*publishers, timeout_s: float | None = 5.0,
                 stop: threading.Event | None = None) -> bool:
    """Waits until every publisher has a matching subscriber; returns whether they all do.

    Args:
        publishers: Zenoh publishers.
        timeout_s: how long to wait (None: until matched or stopped).
        stop: an event that ends the wait early.
    """
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    while not all(p.matching_status.matching for p in publishers):
        if (deadline is not None and time.monotonic() > deadline) or (stop and stop.is_set()):
            return all(p.matching_status.matching for p in publishers)
        time.sleep(0.01)
    return True


def put_when_matched(publisher, payload: bytes, timeout_s: float = 5.0) -> None:
    """Puts payload once a subscriber matches the publisher.

    Raises:
        TimeoutError: nothing subscribed within `timeout_s` (the put would have been lost).
    """
    if not wait_matched(publisher, timeout_s=timeout_s):
        raise TimeoutError(f"no subscriber on {publisher.key_expr} within {timeout_s} s")
    publisher.put(payload)


# --------------------------------------------------------------------------- collecting


class Collector:
    """Every message published on one key, decoded, as this session receives it.

    Zenoh delivers on its own thread, so the waits poll under a lock. Each message is kept with
    its arrival time (`time.perf_counter()`), for rate and pacing checks.

    Args:
        session: the Zenoh session to subscribe with (anything with `declare_subscriber`).
        key: the full key expression.
    """

    POLL_S = 0.02

    def __init__(self, session, key: str):
        self.key = key
        self._lock = threading.Lock()
        self._arrivals: list[tuple[float, Any]] = []
        # Held so that the subscription lasts as long as the collector does.
        self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample) -> None:
        arrived = time.perf_counter()  # before decoding, which would add to the measured pace
        message = wire.decode(sample.payload.to_bytes())
        with self._lock:
            self._arrivals.append((arrived, message))

    def arrivals(self) -> list[tuple[float, Any]]:
        """Returns [(arrival time, message)] so far, oldest first."""
        with self._lock:
            return list(self._arrivals)

    def items(self) -> list[Any]:
        """Returns the messages so far, oldest first."""
        return [message for _, message in self.arrivals()]

    def last(self) -> Any:
        """Returns the newest message.

        Raises:
            AssertionError: nothing has arrived.
        """
        got = self.items()
        assert got, f"nothing arrived on {self.key}"
        return got[-1]

    def wait_count(self, n: int, predicate: Callable[[Any], bool] | None = None,
                   timeout: float = 20.0) -> list[Any]:
        """Waits until at least `n` messages match; returns every match so far, oldest first.

        Args:
            n: how many matching messages to wait for.
            predicate: which messages count (all when None).
            timeout: seconds to wait.

        Raises:
            TimeoutError: with the number that matched and the newest message.
        """
        deadline = time.monotonic() + timeout
        while True:
            got = self.items()
            found = [m for m in got if predicate is None or predicate(m)]
            if len(found) >= n:
                return found
            if time.monotonic() > deadline:
                newest = repr(got[-1])[:500] if got else "nothing"
                raise TimeoutError(f"{len(found)} of {n} matching messages on {self.key} "
                                   f"within {timeout} s; the newest: {newest}")
            time.sleep(self.POLL_S)

    def wait(self, predicate: Callable[[Any], bool] | None = None,
             timeout: float = 20.0) -> list[Any]:
        """Waits until a message matches; returns every match so far, oldest first."""
        return self.wait_count(1, predicate, timeout)

    def first(self, predicate: Callable[[Any], bool] | None = None,
              timeout: float = 20.0) -> Any:
        """Waits until a message matches; returns the earliest match."""
        return self.wait(predicate, timeout)[0]

    def window(self, seconds: float) -> list[tuple[float, Any]]:
        """Sleeps `seconds`; returns [(arrival time, message)] of what arrived meanwhile."""
        start = len(self.arrivals())
        time.sleep(seconds)
        return self.arrivals()[start:]


def collect(session, key: str) -> Collector:
    """Starts collecting the messages published on a full key expression.

    The subscription takes a moment to reach the router: start collecting before the messages
    are due.
    """
    return Collector(session, key)
