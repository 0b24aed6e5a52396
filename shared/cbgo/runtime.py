"""The service runtime: one way for every cbgo service to live on the Zenoh network.

A service subclasses `Service` and follows py_trees' lifecycle:

- ``__init__(settings)``: no I/O;
- ``setup(ctx)``: load models, declare inputs (``ctx.subscribe``), outputs (``ctx.publishes``),
  queryables, control verbs and timers; called once, before the liveliness token exists;
- handlers ``on_<input>(msg)``: return messages to publish (``[(topic, msg), ...]``) instead of
  publishing; they run one at a time on the service's event loop, so service state needs no
  locks (``immediate=True`` inputs, e.g. robot/stop, run at once on Zenoh's thread instead);
- ``shutdown()``: called once when the process stops.

`run()` owns everything Zenoh: it opens the session (``with zenoh.open``), decodes and validates
each input with `cbgo.wire` (a bad one is counted, logged at a limited rate and dropped; the
service keeps running), validates each output, declares ``<prefix>/@alive/<service>`` only after
``setup()``, answers ``<prefix>/@ctl/<service>/status``, and closes the session and exits within
2 s of SIGTERM/SIGINT. `Context` is transport-agnostic: `cbgo.testing.FakeBus` drives the very
same dispatch code without a network.
"""

from __future__ import annotations

import gc
import heapq
import logging
import os
import queue
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import cbgo
from cbgo import wire
from cbgo.client import pick_reply
from cbgo.config import NoSettings, Resolved, resolve, zenoh_config
from cbgo.endpoints import check_can_listen, exposure_warning, listen_endpoints
from cbgo.errors import ConfigError, DeviceError, QueryError, RejectedMessage, zenoh_reason
from cbgo.keys import Keys, Topic, check_service_name
from cbgo.logs import RateLimited, kv, setup_logging
from cbgo.zenoh_transport import ZenohTransport

Output = tuple[Topic, dict]
Handler = Callable[[dict], "Iterable[Output] | None"]
QueryHandler = Callable[[dict], dict]

EXIT_OK, EXIT_CONFIG, EXIT_DEVICE, EXIT_CRASH = 0, 2, 3, 1
SHUTDOWN_DEADLINE_S = 1.8  # the contract: exit within 2 s of SIGTERM/SIGINT
MAX_BACKLOG = 256  # queued droppable samples before new ones are dropped (newest wins)


class Service:
    """Base class of every cbgo service; see the module docstring for the lifecycle.

    Attributes:
        name: the service name (kebab-case), used for the liveliness token, status key,
            logs, console script and compose service.
        description: one line for --help.
        settings_class: the dataclass of the service's own settings.
        zenoh_defaults: Zenoh option defaults that differ from a plain client's.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    settings_class: ClassVar[type] = NoSettings
    zenoh_defaults: ClassVar[dict] = {}

    def __init__(self, settings: Any):
        self.settings = settings

    def setup(self, ctx: Context) -> None:
        """Called once before the service is announced alive: declare inputs and outputs."""

    def shutdown(self) -> None:
        """Called once when the process stops, before the Zenoh session closes."""

    def status_extra(self) -> dict:
        """Returns service-specific fields for the status reply.

        Called on Zenoh's thread, and only once `setup` returned.
        """
        return {}


@dataclass
class Counters:
    """What a service has seen and done; served in its status."""

    received: int = 0
    published: int = 0
    rejected: int = 0
    errors: int = 0
    dropped: int = 0
    last_error: dict | None = None
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, name: str, n: int = 1) -> None:
        """Increments one counter (thread-safe)."""
        with self.lock:
            setattr(self, name, getattr(self, name) + n)

    def error(self, where: str, message: str) -> None:
        """Records an error and remembers it as the last one."""
        with self.lock:
            self.errors += 1
            self.last_error = {"ts": time.time(), "where": where, "message": message}

    def as_dict(self) -> dict:
        """Returns the counters as plain data."""
        with self.lock:
            return {"received": self.received, "published": self.published,
                    "rejected": self.rejected, "errors": self.errors, "dropped": self.dropped}


class IncomingQuery(Protocol):
    """What a transport hands the context for one query."""

    payload: bytes | None

    def reply(self, payload: bytes) -> None:
        """Sends the one successful reply."""

    def reply_err(self, reason: str) -> None:
        """Sends an error reply."""


class Transport(Protocol):
    """The network side of a `Context`: Zenoh in `run()`, memory in `cbgo.testing.FakeBus`."""

    def subscribe(self, key: str, callback: Callable[[str, bytes], None]) -> None:
        """Calls callback(key, payload) for each sample on key."""

    def serve(self, key: str, callback: Callable[[IncomingQuery], None]) -> None:
        """Calls callback(query) for each query on key."""

    def publisher(self, key: str, topic: Topic | None) -> Callable[[bytes], None]:
        """Returns a put function for key with the topic's delivery policy."""

    def get(self, key: str, payload: bytes, timeout_s: float) -> list[tuple[bool, bytes]]:
        """Queries key; returns (ok, payload) per reply."""

    def matching(self, key: str) -> bool:
        """Returns whether a subscriber matches a declared publisher's key."""

    def alive(self, key: str, timeout_s: float) -> list[str]:
        """Returns the liveliness tokens currently matching key."""


class Context:
    """What a service sees of the runtime: declarations, publishing, queries, counters.

    Args:
        service: the service it serves.
        keys: key expressions under the configured prefix.
        transport: the network.
        config: the resolved configuration, served in status.
        max_payload_bytes: inputs larger than this are rejected.
        enqueue: how work reaches the event loop (None: run at once, as FakeBus does).
    """

    def __init__(self, service: Service, keys: Keys, transport: Transport, config: dict,
                 max_payload_bytes: int = wire.DEFAULT_MAX_BYTES,
                 enqueue: Callable[[Callable[[], None], bool], None] | None = None):
        self.service, self.keys, self.transport, self.config = service, keys, transport, config
        self.max_payload_bytes = max_payload_bytes
        self.counters = Counters()
        self.log = logging.getLogger(f"cbgo.{service.name}")
        self.zid = ""  # the Zenoh session id, set by run()
        self.set_up = False  # once service.setup returned; status adds its fields from then
        self.rejects = RateLimited(self.log)
        self.stopping = threading.Event()
        self.exit_code = EXIT_OK
        self.started = time.time()
        self.inputs: list[str] = []
        self.outputs: list[str] = []
        self.queryables: list[str] = []
        self._puts: dict[str, Callable[[bytes], None]] = {}
        self._timers: list[tuple[float, int, float, Callable[[], Any]]] = []
        self._enqueue = enqueue or (lambda work, droppable: work())

    # ---------------------------------------------------------------- declarations (setup)

    def subscribe(self, topic: Topic, handler: Handler, *, immediate: bool = False) -> None:
        """Declares an input: each valid message on the topic is passed to handler.

        Args:
            topic: the contract topic.
            handler: called with the decoded, validated message; returns outputs or None.
            immediate: run on Zenoh's thread at once instead of the event loop (for inputs
                that must not wait behind a long handler, such as robot/stop).
        """
        key = self.keys.of(topic)
        spec, lenient = topic.schema, topic.any_payload
        droppable = not topic.reliable

        def on_sample(sample_key: str, payload: bytes) -> None:
            self.counters.add("received")
            work = lambda: self._handle(sample_key, payload, spec, lenient, handler)  # noqa: E731
            self._run(work, droppable and not immediate, immediate)

        self.transport.subscribe(key, on_sample)
        self.inputs.append(key)

    def queryable(self, topic: Topic, handler: QueryHandler) -> None:
        """Declares that this service answers queries on topic.

        The handler gets the validated query payload and returns the reply; raising
        `QueryError` (or sending a malformed query) produces an error reply, never silence.
        """
        key = self.keys.of(topic)
        self._serve(key, topic.query_schema, topic.reply_schema, handler, immediate=False)
        self.queryables.append(key)

    def control(self, verb: str, handler: QueryHandler, *, immediate: bool = False) -> None:
        """Declares a control verb, answered on ``<prefix>/@ctl/<service>/<verb>``.

        The query payload is optional (an empty map when absent).
        """
        key = self.keys.ctl(self.service.name, verb)
        self._serve(key, None, None, handler, immediate=immediate, counted=False)
        self.queryables.append(key)

    def publishes(self, *topics: Topic) -> None:
        """Declares outputs up front, so the router lists them and the first put is not lost."""
        for topic in topics:
            self._put_for(topic)

    def every(self, period_s: float, fn: Callable[[], Iterable[Output] | None]) -> None:
        """Calls fn on the event loop every period_s seconds; its outputs are published."""
        if period_s <= 0:
            raise ConfigError(f"timer period must be positive, got {period_s}")
        heapq.heappush(self._timers, (time.monotonic() + period_s, id(fn), period_s, fn))

    # ---------------------------------------------------------------- use (any time)

    def publish(self, topic: Topic, message: dict) -> bool:
        """Validates, encodes and publishes one message (thread-safe).

        Returns:
            True if sent; False if the message broke the contract (counted as an error: a bug
            in this service must not reach other services).
        """
        key = self.keys.of(topic)
        try:
            wire.validate(message, topic.schema, key)
            payload = wire.encode(message)
        except (RejectedMessage, TypeError) as e:
            self.counters.error("publish", f"refused to publish an invalid message: {e}")
            self.log.error("refused to publish an invalid message: %s", e)
            return False
        self._put_for(topic)(payload)
        self.counters.add("published")
        return True

    def query(self, topic: Topic, message: dict, timeout_s: float = 10.0) -> dict:
        """Sends a query and returns the first successful, valid reply.

        Raises:
            QueryError: the answer was an error, was malformed, or no one answered in time.
        """
        key = self.keys.of(topic)
        wire.validate(message, topic.query_schema, key)
        replies = self.transport.get(key, wire.encode(message), timeout_s)
        return pick_reply(replies, key, topic.reply_schema,
                          topic.max_bytes(self.max_payload_bytes), timeout_s)

    def wait_for_subscribers(self, topic: Topic, timeout_s: float = 5.0) -> bool:
        """Waits until someone subscribes to topic (a put before that would be lost)."""
        self._put_for(topic)
        deadline = time.monotonic() + timeout_s
        while not self.transport.matching(self.keys.of(topic)):
            if time.monotonic() > deadline or self.stopping.is_set():
                return False
            time.sleep(0.01)
        return True

    def wait_for_service(self, service: str, timeout_s: float = 10.0) -> bool:
        """Waits until a service's liveliness token is present."""
        deadline = time.monotonic() + timeout_s
        while not self.transport.alive(self.keys.alive(service), 0.5):
            if time.monotonic() > deadline or self.stopping.is_set():
                return False
            time.sleep(0.05)
        return True

    def request_exit(self, code: int, reason: str) -> None:
        """Stops the service from any thread; the process exits with `code`.

        For faults a restart may cure (a lost device: EXIT_DEVICE), so that the supervisor
        (`cbgo up`, compose) restarts the process.
        """
        self.counters.error("exit", reason)
        self.log.error("exiting with code %d: %s", code, reason)
        self.exit_code = code
        self.stopping.set()
        self._enqueue(lambda: None, False)  # wake the event loop

    def status(self) -> dict:
        """Returns the reply of ``@ctl/<service>/status``.

        Status is answered from the start, while the service still loads its models; its own
        fields (`Service.status_extra`) join once its setup returned: before, what they read
        may not exist yet (a status poll during intent's setup was answered with an error and
        logged a traceback).
        """
        return {
            "v": wire.SCHEMA_VERSION, "ts": time.time(), "name": self.service.name,
            "version": cbgo.__version__, "pid": os.getpid(), "host": socket.gethostname(),
            "zid": self.zid,
            "uptime_s": time.time() - self.started, "started": self.started,
            "config": self.config, "counters": self.counters.as_dict(),
            "last_error": self.counters.last_error, "inputs": self.inputs,
            "outputs": self.outputs, "queryables": self.queryables,
            **(self.service.status_extra() if self.set_up else {}),
        }

    # ---------------------------------------------------------------- internals

    def _put_for(self, topic: Topic) -> Callable[[bytes], None]:
        key = self.keys.of(topic)
        if key not in self._puts:
            self._puts[key] = self.transport.publisher(key, topic)
            self.outputs.append(key)
        return self._puts[key]

    def _run(self, work: Callable[[], None], droppable: bool, immediate: bool) -> None:
        if immediate:
            work()
        else:
            self._enqueue(work, droppable)

    def _handle(self, key: str, payload: bytes, spec: wire.Spec | None, lenient: bool,
                handler: Handler) -> None:
        try:
            message = wire.decode_checked(payload, spec, key, self.max_payload_bytes)
        except RejectedMessage as e:
            if not lenient:
                self._reject(e)
                return
            message = {}  # e.g. robot/stop: any payload at all must stop the robot
        self._call(f"handler for {key}", lambda: self._publish_all(handler(message)))

    def _reject(self, error: RejectedMessage) -> None:
        self.counters.add("rejected")
        with self.counters.lock:
            self.counters.last_error = {"ts": time.time(), "where": "input",
                                        "message": str(error)}
        self.rejects.warning(error.key or "input", f"rejected input: {error}", key=error.key)

    def _call(self, where: str, fn: Callable[[], Any]) -> Any:
        # The one broad catch of the runtime: a failing handler must not kill the service.
        try:
            return fn()
        except Exception as e:  # noqa: BLE001
            self.counters.error(where, f"{type(e).__name__}: {e}")
            self.log.exception("%s failed", where)
            return None

    def _publish_all(self, outputs: Iterable[Output] | None) -> None:
        for topic, message in outputs or ():
            self.publish(topic, message)

    def _serve(self, key: str, query_spec: wire.Spec | None, reply_spec: wire.Spec | None,
               handler: QueryHandler, immediate: bool, counted: bool = True) -> None:
        def on_query(query: IncomingQuery) -> None:
            if counted:  # control queries (status polls) are not pipeline input
                self.counters.add("received")
            self._run(lambda: self._answer(key, query, query_spec, reply_spec, handler),
                      droppable=False, immediate=immediate)

        self.transport.serve(key, on_query)

    def _answer(self, key: str, query: IncomingQuery, query_spec: wire.Spec | None,
                reply_spec: wire.Spec | None, handler: QueryHandler) -> None:
        try:
            message = wire.decode_checked(query.payload, query_spec, key,
                                          self.max_payload_bytes) if query.payload else {}
            if query_spec is not None and not query.payload:
                wire.validate(message, query_spec, key)
        except RejectedMessage as e:
            self._reject(e)
            query.reply_err(f"rejected: {e}")
            return
        try:
            reply = handler(message)
            wire.validate(reply, reply_spec, key)
            query.reply(wire.encode(reply))
        except QueryError as e:
            query.reply_err(str(e))
        except Exception as e:  # noqa: BLE001 - answer, count and keep running
            self.counters.error(f"query {key}", f"{type(e).__name__}: {e}")
            self.log.exception("answering %s failed", key)
            query.reply_err(f"internal error in {self.service.name}: {type(e).__name__}: {e}")

    def run_due_timers(self, now: float | None = None) -> float:
        """Runs the timers that are due; returns seconds until the next one (or 0.2)."""
        now = time.monotonic() if now is None else now
        while self._timers and self._timers[0][0] <= now:
            due, ident, period, fn = heapq.heappop(self._timers)
            # Skip missed periods instead of bursting after a long handler.
            next_due = due + period if due + period > now else now + period
            heapq.heappush(self._timers, (next_due, ident, period, fn))
            self._call("timer", lambda fn=fn: self._publish_all(fn()))
        return min(0.2, max(0.0, self._timers[0][0] - now)) if self._timers else 0.2


# ==================================================================== run() over Zenoh


class _EventLoop:
    """The service's single worker: a queue of work plus the context's timers."""

    def __init__(self, ctx_getter: Callable[[], Context | None]):
        self.queue: queue.Queue = queue.Queue()
        self._ctx = ctx_getter

    def enqueue(self, work: Callable[[], None], droppable: bool) -> None:
        ctx = self._ctx()
        if droppable and self.queue.qsize() >= MAX_BACKLOG:
            if ctx is not None:
                ctx.counters.add("dropped")  # newest-wins stream: a stale backlog is useless
            return
        self.queue.put(work)

    def run(self, ctx: Context) -> None:
        while not ctx.stopping.is_set():
            self._run_queued(ctx)
            wait = ctx.run_due_timers()
            if ctx.stopping.is_set():
                break
            try:
                work = self.queue.get(timeout=wait)
            except queue.Empty:
                continue
            if work is not None:
                work()

    def _run_queued(self, ctx: Context) -> None:
        """Runs the work already queued, before any timer that fell due meanwhile.

        After a stall (a starved process) a timer must see the messages that arrived during it:
        the episode's end-of-hand check would otherwise end an episode whose next hand frames
        wait in the queue. Only what is queued now runs, so a steady stream cannot starve the
        timers.
        """
        for _ in range(self.queue.qsize()):
            if ctx.stopping.is_set():
                return
            try:
                work = self.queue.get_nowait()
            except queue.Empty:
                return
            if work is not None:
                work()


def _install_signal_handlers(ctx_stop: threading.Event, loop: _EventLoop, log) -> None:
    def on_signal(signum, _frame):
        if ctx_stop.is_set():
            return
        log.info("received %s, stopping", signal.Signals(signum).name)
        ctx_stop.set()
        loop.queue.put(None)
        threading.Thread(target=_watchdog, args=(log,), daemon=True).start()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)


def _watchdog(log) -> None:
    # If a handler or the session close hangs, still honour the 2 s exit promise.
    time.sleep(SHUTDOWN_DEADLINE_S)
    log.error("shutdown did not finish within %.1f s; exiting now", SHUTDOWN_DEADLINE_S)
    os._exit(EXIT_OK)


def run(service_cls: type[Service], argv: list[str] | None = None) -> int:
    """Runs a service until SIGTERM/SIGINT; returns the process exit code.

    Exit codes: 0 stopped by signal, 1 crash, 2 configuration error, 3 device fault.
    """
    check_service_name(service_cls.name)
    try:
        resolved = resolve(service_cls.settings_class, argv, prog=f"cbgo-{service_cls.name}",
                           description=service_cls.description,
                           zenoh_defaults=service_cls.zenoh_defaults)
    except ConfigError as e:
        print(f"cbgo-{service_cls.name}: configuration error: {e}", file=sys.stderr)
        return EXIT_CONFIG
    log = setup_logging(service_cls.name, resolved.runtime.log_level, resolved.runtime.log_format)
    log.info("starting", extra=kv(version=cbgo.__version__, pid=os.getpid(),
                                  config=resolved.as_dict()))
    try:
        return _serve_forever(service_cls, resolved, log)
    except ConfigError as e:
        log.error("configuration error: %s", e)
        return EXIT_CONFIG
    except DeviceError as e:
        log.error("device fault, exiting so that the supervisor restarts us: %s", e)
        return EXIT_DEVICE


def _serve_forever(service_cls: type[Service], resolved: Resolved, log) -> int:

    service = service_cls(resolved.settings)
    ctx_box: list[Context] = []
    loop = _EventLoop(lambda: ctx_box[0] if ctx_box else None)
    stop = threading.Event()
    _install_signal_handlers(stop, loop, log)
    conf = zenoh_config(resolved.zenoh, service_cls.name)
    _check_listeners(conf, log)
    session = _open_session(conf, stop, log)
    if session is None:
        return EXIT_OK
    with session:
        transport = ZenohTransport(session)
        ctx = Context(service, Keys(resolved.zenoh.prefix), transport, resolved.as_dict(),
                      resolved.runtime.max_payload_bytes, enqueue=loop.enqueue)
        ctx.stopping, ctx.zid = stop, str(session.zid())
        ctx_box.append(ctx)
        ctx.control("status", lambda _q: ctx.status(), immediate=True)
        try:
            service.setup(ctx)
            ctx.set_up = True
            if stop.is_set():
                return EXIT_OK
            # What imports and setup created (torch, numpy, models: ~10^5 objects) lives as long
            # as the process. Freezing it keeps the cyclic GC's full passes off it: measured in
            # static-gesture, such a pass stalled a frame by 80-200 ms (p99 latency 150 ms).
            gc.collect()
            gc.freeze()
            token = session.liveliness().declare_token(ctx.keys.alive(service.name))
            log.info("ready", extra=kv(zid=str(session.zid()), inputs=ctx.inputs,
                                       outputs=ctx.outputs, queryables=ctx.queryables))
            loop.run(ctx)
            token.undeclare()
        finally:
            ctx.stopping.set()
            ctx._call("shutdown", service.shutdown)
    log.info("stopped")
    return ctx.exit_code


def _open_session(conf, stop: threading.Event, log):
    """Opens the Zenoh session; returns None if SIGTERM/SIGINT came first.

    A client waits for its router forever, inside Zenoh's native code, where Python cannot run
    signal handlers; so the session is opened on a helper thread while the main thread stays
    responsive and can exit cleanly (compose and `cbgo up` stop a service still waiting).
    """
    import zenoh

    box: list = []

    def open_it() -> None:
        try:
            box.append(zenoh.open(conf))
        except Exception as e:  # zenoh.ZError and friends: re-raised on the main thread
            box.append(e)

    opener = threading.Thread(target=open_it, name="zenoh-open", daemon=True)
    opener.start()
    announced, since = False, time.monotonic()
    while opener.is_alive() and not stop.is_set():
        opener.join(0.1)
        if opener.is_alive() and not announced and time.monotonic() - since > 2.0:
            log.info("waiting for the Zenoh network (%s)", conf.get_json("connect/endpoints"))
            announced = True
    if stop.is_set() and not box:
        return None
    if isinstance(box[0], Exception):
        # A listener that cannot bind, a TLS file that cannot be read: the configuration's
        # fault, said without the Rust source paths Zenoh appends.
        raise ConfigError(f"cannot open the Zenoh session: {zenoh_reason(box[0])}")
    return box[0]


def _check_listeners(conf, log) -> None:
    """Fails with the fix when a listening endpoint cannot be bound; warns when it is exposed.

    Raises:
        ConfigError: a port is taken or an address is not this host's.
    """
    listening = listen_endpoints(conf)
    check_can_listen(listening)
    warning = exposure_warning(listening)
    if warning:
        log.warning(warning)


def main_for(service_cls: type[Service]) -> Callable[[list[str] | None], None]:
    """Returns the console-script entry point of a service (``cbgo-<name>``)."""

    def main(argv: list[str] | None = None) -> None:
        sys.exit(run(service_cls, argv))

    main.__doc__ = f"Runs the {service_cls.name} service until SIGTERM/SIGINT."
    return main
