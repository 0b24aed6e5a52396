"""Test helpers for cbgo services: `FakeBus` (no network) and `Stack` (real processes).

`FakeBus` drives a service's handlers through the very same `cbgo.runtime.Context` dispatch
the real runtime uses (decode, validate, handler, validate outputs, counters), with an
in-memory transport, so service tests are fast and still exercise the contract::

    bus = FakeBus(Episode(EpisodeSettings()))
    out = bus.feed(keys.HANDS_FRAME, example("hands/frame"))   # -> [(topic suffix, msg)]
    bus.feed_raw(keys.HANDS_FRAME, b"junk"); assert bus.counters.rejected == 1

`Stack` starts a Zenoh router on a free loopback port and services as real processes, waits
for their liveliness tokens, and tears everything down (also when a test fails)::

    with Stack(tmp_path) as stack:
        stack.start_router()
        stack.start_service("episode")
        stack.wait_alive(["router", "episode"])

The test talks to the processes from its own Zenoh session, through `cbgo.client`:
`Stack.collect` gathers what is published on a key (a `cbgo.client.Collector`), `Stack.put`
publishes once a subscriber is there, `Stack.query` checks replies against the contract, and
`Process.wait_for_line` waits for a line in a process's log::

        summaries = stack.collect("episode/summary")
        stack.put("hands/frame", example("hands/frame"))
        (summary,) = summaries.wait_count(1, timeout=10)
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from cbgo import client, registry, wire
from cbgo.client import Collector
from cbgo.errors import QueryError
from cbgo.keys import Keys, Topic
from cbgo.runtime import Context, IncomingQuery, Service

# ============================================================================ FakeBus


class _FakeQuery:
    def __init__(self, payload: bytes | None):
        self.payload = payload
        self.replies: list[tuple[bool, bytes]] = []

    def reply(self, payload: bytes) -> None:
        self.replies.append((True, payload))

    def reply_err(self, reason: str) -> None:
        self.replies.append((False, reason.encode()))


class _MemoryTransport:
    """A `Transport` in memory: exact-key delivery, scripted answers for outgoing queries."""

    def __init__(self):
        self.subscribers: dict[str, list[Callable[[str, bytes], None]]] = {}
        self.queryables: dict[str, Callable[[IncomingQuery], None]] = {}
        self.sent: list[tuple[str, bytes]] = []
        self.responders: dict[str, Callable[[dict], dict]] = {}
        self.alive_keys: set[str] = set()

    def subscribe(self, key: str, callback: Callable[[str, bytes], None]) -> None:
        self.subscribers.setdefault(key, []).append(callback)

    def serve(self, key: str, callback: Callable[[IncomingQuery], None]) -> None:
        self.queryables[key] = callback

    def publisher(self, key: str, topic: Topic | None) -> Callable[[bytes], None]:
        return lambda payload: self.sent.append((key, payload))

    def get(self, key: str, payload: bytes, timeout_s: float) -> list[tuple[bool, bytes]]:
        if key not in self.responders:
            return []
        try:
            return [(True, wire.encode(self.responders[key](wire.decode(payload))))]
        except QueryError as e:
            return [(False, str(e).encode())]

    def matching(self, key: str) -> bool:
        return True

    def alive(self, key: str, timeout_s: float) -> list[str]:
        return [key] if key in self.alive_keys else []


class FakeBus:
    """Runs one service in memory through the real runtime dispatch.

    Args:
        service: the service instance (not yet set up).
        prefix: the key prefix.
        max_payload_bytes: the input size limit, as ``--max-payload-bytes``.
    """

    def __init__(self, service: Service, prefix: str = "cbgo",
                 max_payload_bytes: int = wire.DEFAULT_MAX_BYTES):
        self.keys = Keys(prefix)
        self.transport = _MemoryTransport()
        self.ctx = Context(service, self.keys, self.transport, {"test": True},
                           max_payload_bytes)
        self.service = service
        self._clock_offset = 0.0
        self.ctx.control("status", lambda _q: self.ctx.status(), immediate=True)
        service.setup(self.ctx)
        self.ctx.set_up = True

    @property
    def counters(self):
        """The service's counters (received, published, rejected, errors, dropped)."""
        return self.ctx.counters

    def feed(self, topic: Topic, message: Any) -> list[tuple[str, dict]]:
        """Delivers one message (encoded to msgpack first); returns what was published."""
        return self.feed_raw(topic, wire.encode(message))

    def feed_raw(self, topic: Topic, payload: bytes) -> list[tuple[str, dict]]:
        """Delivers raw bytes on a topic; returns the messages published in response."""
        key = self.keys.of(topic)
        start = len(self.transport.sent)
        for callback in self.transport.subscribers.get(key, []):
            callback(key, payload)
        return self._decoded(self.transport.sent[start:])

    def query(self, topic: Topic | str, message: dict | None) -> tuple[bool, Any]:
        """Sends a query to the service (a topic, or a control verb name).

        Returns:
            (True, reply message) or (False, error reason).
        """
        key = self.keys.of(topic) if isinstance(topic, Topic) else self.keys.ctl(
            self.service.name, topic)
        if key not in self.transport.queryables:
            raise KeyError(f"the service does not answer {key}")
        query = _FakeQuery(None if message is None else wire.encode(message))
        self.transport.queryables[key](query)
        (ok, payload), = query.replies
        return (True, wire.decode(payload, wire.MAX_BYTES_RENDER)) if ok else (
            False, payload.decode())

    def answer(self, topic: Topic, responder: Callable[[dict], dict]) -> None:
        """Scripts the reply to queries the service sends on topic.

        The responder may raise QueryError to answer with an error.
        """
        self.transport.responders[self.keys.of(topic)] = responder

    def set_alive(self, *services: str) -> None:
        """Makes services appear alive to `ctx.wait_for_service`."""
        self.transport.alive_keys |= {self.keys.alive(s) for s in services}

    def tick(self, seconds: float) -> list[tuple[str, dict]]:
        """Advances the timers' clock by `seconds`; returns what they published."""
        start = len(self.transport.sent)
        self._clock_offset += seconds
        self.ctx.run_due_timers(time.monotonic() + self._clock_offset)
        return self._decoded(self.transport.sent[start:])

    @property
    def published(self) -> list[tuple[str, dict]]:
        """Everything published so far, as (topic suffix, message)."""
        return self._decoded(self.transport.sent)

    def _decoded(self, sent: list[tuple[str, bytes]]) -> list[tuple[str, dict]]:
        head = self.keys.prefix + "/"
        return [(k[len(head):], wire.decode(p, wire.MAX_BYTES_RENDER)) for k, p in sent]

    def stop(self) -> None:
        """Calls the service's shutdown, as the runtime does at exit."""
        self.ctx.stopping.set()
        self.service.shutdown()


# ============================================================================ Stack


def free_port() -> int:
    """Returns a TCP port that is free on the loopback interface right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Process:
    """One child process of a `Stack`, its log in a file."""

    def __init__(self, name: str, argv: list[str], log_path: Path, env: dict[str, str]):
        self.name, self.argv, self.log_path = name, argv, log_path
        self._log = open(log_path, "wb")  # noqa: SIM115 - closed in wait()
        self.popen = subprocess.Popen(argv, stdout=self._log, stderr=subprocess.STDOUT,
                                      env=env, start_new_session=True)

    def log(self) -> str:
        """Returns everything the process printed so far."""
        return self.log_path.read_text(errors="replace")

    def signal(self, sig: int = signal.SIGTERM) -> None:
        """Sends a signal if the process is still running."""
        if self.popen.poll() is None:
            self.popen.send_signal(sig)

    def wait(self, timeout: float) -> int | None:
        """Waits for the exit; returns the code, or None if it is still running."""
        try:
            code = self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            return None
        self._log.close()
        return code

    def wait_for_line(self, text: str, timeout: float = 20.0) -> str:
        """Waits until the log has a line containing `text`; returns that line (the first).

        Raises:
            RuntimeError: the process exited without printing it (raised at once, with the log).
            TimeoutError: it is still running and has not printed it after `timeout` seconds.
        """
        deadline = time.monotonic() + timeout
        while True:
            # Whether it had exited is read before the log, so a line printed just before the
            # exit is still found rather than reported missing.
            exited = self.popen.poll() is not None
            line = self._first_line_with(text)
            if line is not None:
                return line
            if exited:
                raise RuntimeError(f"{self.name} exited with {self.popen.returncode} before "
                                   f"printing {text!r}:\n{self.log()}")
            if time.monotonic() > deadline:
                raise TimeoutError(f"{text!r} not in the log of {self.name} after {timeout} s:"
                                   f"\n{self.log()}")
            time.sleep(0.05)

    def _first_line_with(self, text: str) -> str | None:
        return next((line for line in self.log().splitlines() if text in line), None)


class Stack:
    """Router and services as real processes on a free loopback port, for tests.

    Args:
        workdir: where process logs are written.
        prefix: the key prefix for every process.
    """

    def __init__(self, workdir: Path, prefix: str = "cbgo"):
        self.workdir = Path(workdir)
        self.prefix = prefix
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.keys = Keys(prefix)
        self.procs: dict[str, Process] = {}
        self._session = None
        self._publishers: dict[str, Any] = {}

    def __enter__(self) -> Stack:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def env(self) -> dict[str, str]:
        """Returns the environment children run with (the endpoint and prefix set).

        web serves its page on any free port (``CBGO_HTTP_PORT=0``; its status says which), so
        stacks of tests that run at the same time never fight over port 8080.
        """
        return {**os.environ, "PYTHONUNBUFFERED": "1", "ZENOH_CONNECT": self.endpoint,
                "CBGO_PREFIX": self.prefix, "CBGO_HTTP_PORT": "0"}

    def spawn(self, name: str, argv: list[str], env: dict[str, str] | None = None) -> Process:
        """Starts any command as a child process named `name`."""
        proc = Process(name, argv, self.workdir / f"{name}.log", {**self.env(), **(env or {})})
        self.procs[name] = proc
        return proc

    def start_router(self) -> Process:
        """Starts `cbgo router` listening on the stack's loopback endpoint."""
        # ZENOH_CONNECT is emptied: the router listens; it must not dial its own endpoint.
        return self.spawn("router", [sys.executable, "-m", "cbgo.router", "--listen",
                                     self.endpoint], env={"ZENOH_CONNECT": ""})

    def start_service(self, name: str, *flags: str, env: dict[str, str] | None = None):
        """Starts a built service by name (`python -m cbgo.services.<pkg>`)."""
        info = registry.by_name(name)
        return self.spawn(name, [sys.executable, "-m", info.package, *flags], env)

    def session(self):
        """Returns the test's own Zenoh client session (opened on first use)."""
        if self._session is None:
            from cbgo.config import ZenohOptions

            self._session = client.open_session(
                ZenohOptions(connect=[self.endpoint], prefix=self.prefix), "cbgo-test")
        return self._session

    def collect(self, suffix: str) -> Collector:
        """Starts collecting the messages published on a key (relative to the prefix).

        The subscription takes a moment to reach the router: start collecting before the
        messages are due.
        """
        return client.collect(self.session(), self.keys.resolve(suffix))

    def publisher(self, suffix: str, timeout: float = 5.0):
        """Returns the test session's publisher on a key, once a subscriber matches it.

        Raises:
            TimeoutError: nothing subscribes to the key within `timeout` seconds, so a message
                put now would be lost.
        """
        key = self.keys.resolve(suffix)
        if key not in self._publishers:
            self._publishers[key] = self.session().declare_publisher(key)
        publisher = self._publishers[key]
        if not client.wait_matched(publisher, timeout_s=timeout):
            raise TimeoutError(f"no subscriber on {key} within {timeout} s")
        return publisher

    def put(self, suffix: str, message: Any, timeout: float = 5.0) -> None:
        """Publishes a message (encoded to msgpack) once a subscriber is there; see `publisher`."""
        self.put_raw(suffix, wire.encode(message), timeout)

    def put_raw(self, suffix: str, payload: bytes, timeout: float = 5.0) -> None:
        """Publishes raw bytes once a subscriber is there; see `publisher`."""
        self.publisher(suffix, timeout).put(payload)

    def alive(self) -> set[str]:
        """Returns the names of the services whose liveliness token is present."""
        return client.alive(self.session(), self.keys, 1.0)

    def wait_alive(self, names: list[str], timeout: float = 30.0) -> float:
        """Waits until every name has a liveliness token; returns the seconds it took.

        Raises:
            TimeoutError: with the missing names and the tail of their logs.
        """
        t0 = time.monotonic()
        while True:
            missing = set(names) - self.alive()
            if not missing:
                return time.monotonic() - t0
            if time.monotonic() - t0 > timeout:
                raise TimeoutError(f"not alive after {timeout} s: {sorted(missing)}\n"
                                   + self.logs(sorted(missing)))
            for name in missing:
                proc = self.procs.get(name)
                if proc is not None and proc.popen.poll() is not None:
                    raise RuntimeError(f"{name} exited with {proc.popen.returncode}\n"
                                       + self.logs([name]))
            time.sleep(0.05)

    def wait_gone(self, name: str, timeout: float = 10.0) -> float:
        """Waits until a service's liveliness token disappears; returns the seconds."""
        t0 = time.monotonic()
        while name in self.alive():
            if time.monotonic() - t0 > timeout:
                raise TimeoutError(f"{name} still alive after {timeout} s")
            time.sleep(0.05)
        return time.monotonic() - t0

    def query(self, key: str, message: dict | None = None, timeout: float = 5.0):
        """Queries a key; returns [(ok, reply checked against the contract, or error text)]."""
        return client.query_all(self.session(), key, message, timeout_s=timeout)

    def status(self, service: str) -> dict:
        """Returns a service's status reply.

        Raises:
            AssertionError: the service did not answer with exactly one ok reply.
        """
        replies = self.query(self.keys.ctl(service, "status"))
        assert len(replies) == 1 and replies[0][0], f"status of {service}: {replies}"
        return replies[0][1]

    def stop(self, name: str, sig: int = signal.SIGTERM, timeout: float = 10.0):
        """Signals a process and waits; returns (exit code, seconds to exit)."""
        proc = self.procs[name]
        t0 = time.monotonic()
        proc.signal(sig)
        code = proc.wait(timeout)
        return code, time.monotonic() - t0

    def logs(self, names: list[str] | None = None, tail: int = 40) -> str:
        """Returns the last lines of the named processes' logs (all by default)."""
        parts = []
        for name in names or list(self.procs):
            if name in self.procs:
                lines = self.procs[name].log().splitlines()[-tail:]
                parts.append(f"----- {name} -----\n" + "\n".join(lines))
        return "\n".join(parts)

    def close(self) -> None:
        """Stops every process (SIGTERM, then SIGKILL) and closes the test session."""
        self._publishers.clear()
        if self._session is not None:
            with contextlib.suppress(Exception):
                self._session.close()
            self._session = None
        for proc in reversed(list(self.procs.values())):
            proc.signal(signal.SIGTERM)
        for proc in self.procs.values():
            if proc.wait(5.0) is None:
                proc.signal(signal.SIGKILL)
                proc.wait(5.0)
