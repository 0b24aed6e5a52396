"""web: a live page of what cbgo sees and decides, served over HTTP and a WebSocket.

Behaviour (the contract is services/web/README.md):
- every data key is subscribed to; each valid message becomes a view for the page
  (`views.Views`: hands in the robot base frame, high-rate streams downsampled to ``rate_hz``,
  evidence recomputed with the episode service's model) and goes out on the WebSocket;
- the page's requests (STOP, feedback, a clarification's answer) are checked (`inbound.parse`)
  and published on ``cbgo/robot/stop``, ``cbgo/intent/feedback`` and ``cbgo/intent/answer``;
  a bad one is rejected, counted, logged and answered with the reason; the mapping table's
  requests are asked of ``@ctl/intent/mapping`` (the intent service owns the users' mapping
  files) and its answer goes to the pages as ``@mapping``;
- every ``status_period_s`` the services are asked for their status (`cbgo.client.status`) and
  their liveliness tokens; the page's services panel shows the answers, and the robot panel
  where the robot cell's world comes from (`robot_cell_view`);
- the workspace comes from the robot's ``cbgo/sim/info`` answer, until then from
  `cbgo.world.workspace` (the contract's default grid).

Threads: handlers run on the service's event loop (the runtime's); the HTTP server runs on its
own asyncio loop (`server.HttpServer`), and the status poll on a thread of its own, so a slow
status query never delays the stream.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field

import cbgo
from cbgo import client, keys, wire
from cbgo.config import described as _help
from cbgo.errors import ConfigError, QueryError, RejectedMessage
from cbgo.runtime import Context, Service, main_for
from cbgo.services.web import inbound, replay
from cbgo.services.web.server import HttpServer
from cbgo.services.web.views import Views, to_json
from cbgo.world.workspace import workspace_info

MAX_EPISODES = 1000  # episode -> user entries kept for feedback
MAPPING_TIMEOUT_S = 5.0  # how long a mapping query waits for the intent service


@dataclass
class WebSettings:
    """Settings of web (flags ``--http-host`` ... or env ``CBGO_HTTP_HOST`` ...)."""

    http_host: str = field(default="127.0.0.1", metadata=_help(
        "address the page is served on (0.0.0.0: every interface; the page can STOP the robot, "
        "so expose it only on networks you trust)"))
    http_port: int = field(default=8080, metadata=_help(
        "TCP port of the page (0: any free port; `cbgo status web` shows the URL)"))
    rate_hz: float = field(default=30.0, metadata=_help(
        "most messages per second the page gets of each high-rate stream (hand frames, static "
        "gestures, gaze, robot state), per hand (1-120)"))
    status_period_s: float = field(default=2.0, metadata=_help(
        "how often the services are asked for their status, s (0.5-60)"))

    def __post_init__(self):
        if not self.http_host:
            raise ConfigError("http_host must not be empty; e.g. 127.0.0.1 or 0.0.0.0")
        if not 0 <= self.http_port <= 65535:
            raise ConfigError(f"http_port={self.http_port} must be within 0-65535")
        if not 1.0 <= self.rate_hz <= 120.0:
            raise ConfigError(f"rate_hz={self.rate_hz} must be within 1-120")
        if not 0.5 <= self.status_period_s <= 60.0:
            raise ConfigError(f"status_period_s={self.status_period_s} must be within 0.5-60")


class Web(Service):
    """Serves the live page; see the module docstring."""

    name = "web"
    description = ("Serves a live web page of cbgo: hands, scene, gestures, episodes, intents, "
                   "plans, services; STOP and feedback from the page.")
    settings_class = WebSettings

    def __init__(self, settings: WebSettings):
        super().__init__(settings)
        self.ctx: Context | None = None
        self.server: HttpServer | None = None
        self.views = Views(settings.rate_hz, time.monotonic)
        self.users: OrderedDict[str, str] = OrderedDict()
        self._users_lock = threading.Lock()  # written on the event loop, read on the server's
        self.requests = {"stop": 0, "feedback": 0, "answer": 0, "mapping": 0, "rejected": 0}
        self.workspace = {"source": "cbgo.world.workspace (default grid)",
                          "workspace": workspace_info()}
        self._stop = threading.Event()

    def setup(self, ctx: Context) -> None:
        """Called once before going alive: subscribes to every data key, starts the server.

        Raises:
            ConfigError: the HTTP address cannot be bound (the process exits with code 2).
        """
        self.ctx = ctx
        for topic in keys.DATA_TOPICS:
            ctx.subscribe(topic, lambda msg, suffix=topic.suffix: self.forward(suffix, msg))
        ctx.publishes(keys.ROBOT_STOP, keys.INTENT_FEEDBACK, keys.INTENT_ANSWER)
        self.server = HttpServer(self.settings.http_host, self.settings.http_port, self.info,
                                 self.on_request, load_upload=self.load_upload)
        url = self.server.start()
        ctx.log.info("serving the page at %s", url)
        self._send("@workspace", self.workspace)
        session = getattr(ctx.transport, "session", None)
        if session is not None:  # FakeBus has none: no status poll in unit tests
            threading.Thread(target=self._poll, args=(session,), name="web-status",
                             daemon=True).start()

    def shutdown(self) -> None:
        """Called once at exit: stops the status poll and the HTTP server."""
        self._stop.set()
        if self.server is not None:
            self.server.stop()

    def status_extra(self) -> dict:
        """Adds the URL, the pages connected and what was sent, skipped, dropped and reset."""
        hub = self.server.hub if self.server else None
        return {"url": self.server.url if self.server else None,
                "pages": len(hub.pages) if hub else 0,
                "views": {"sent": hub.sent if hub else 0, "dropped": hub.dropped if hub else 0,
                          "pages_reset": hub.resets if hub else 0,
                          "passed": self.views.down.passed,
                          "downsampled": self.views.down.skipped},
                "requests": dict(self.requests)}

    # ------------------------------------------------------------------ data to the page

    def forward(self, suffix: str, message: dict) -> None:
        """Handler of every data key: views of the message go to the pages."""
        if suffix == "episode/summary":
            self._remember_user(message["episode"], message["user"])
        for topic, view in self.views.render(suffix, message):
            self._send(topic, view)

    def _send(self, topic: str, view: dict) -> None:
        if self.server is not None:
            self.server.send(topic, to_json(topic, view, time.time()))

    def _remember_user(self, episode: str, user: str) -> None:
        with self._users_lock:
            self.users[episode] = user
            while len(self.users) > MAX_EPISODES:
                self.users.popitem(last=False)

    def info(self) -> dict:
        """Returns the ``/api/info`` answer."""
        assert self.ctx is not None
        return {"mode": "live", "version": cbgo.__version__, "prefix": self.ctx.keys.prefix,
                "rate_hz": self.settings.rate_hz, "actions": list(wire.ACTIONS),
                **self.workspace}

    def load_upload(self, path: str) -> tuple[list, dict]:
        """Reads a recording opened from the page into replay views (any thread).

        Raises:
            RecordingError: not a complete MCAP recording.
        """
        shown = replay.load(path, self.settings.rate_hz, self.ctx.keys.prefix if self.ctx
                            else "cbgo")
        return shown.items, shown.skipped

    # ------------------------------------------------------------------ requests from the page

    def on_request(self, data: str | bytes) -> str:
        """Checks and publishes one request from a page; returns the answer (JSON text)."""
        assert self.ctx is not None
        try:
            with self._users_lock:
                users = dict(self.users)
            request = inbound.parse(data, users)
        except RejectedMessage as e:
            return self._reject(e, inbound.request_id(data))
        if request.kind == "mapping":
            return self._mapping_request(request)
        topic = {"stop": keys.ROBOT_STOP, "feedback": keys.INTENT_FEEDBACK,
                 "answer": keys.INTENT_ANSWER}[request.kind]
        ok = self.ctx.publish(topic, request.message)
        self.requests[request.kind] += 1
        if request.kind == "stop":
            self.ctx.log.warning("STOP pressed on the page: published %s",
                                 self.ctx.keys.of(topic))
        answer = {"ok": ok, "id": request.id, "kind": request.kind,
                  "key": self.ctx.keys.of(topic), "message": request.message,
                  "error": None if ok else "the message broke the contract; see the log"}
        return to_json("@reply", answer, time.time())

    def _mapping_request(self, request: inbound.Request) -> str:
        """Asks the intent service about a user's mapping on a thread of its own.

        The intent service may be busy for seconds (a correction's refit); the page is answered
        at once, and the mapping (or the error) follows on ``@mapping`` to every page.
        """
        assert self.ctx is not None
        self.requests["mapping"] += 1
        key = self.ctx.keys.ctl("intent", "mapping")
        threading.Thread(target=self._ask_mapping, args=(request, key), name="web-mapping",
                         daemon=True).start()
        return to_json("@reply", {"ok": True, "id": request.id, "kind": "mapping", "key": key,
                                  "message": request.message, "error": None}, time.time())

    def _ask_mapping(self, request: inbound.Request, key: str) -> None:
        assert self.ctx is not None
        try:
            replies = self.ctx.transport.get(key, wire.encode(request.message), MAPPING_TIMEOUT_S)
            reply = client.pick_reply(replies, key, None, wire.DEFAULT_MAX_BYTES,
                                      MAPPING_TIMEOUT_S, hint="is the intent service running?")
            view = {**reply, "ok": True, "id": request.id, "op": request.message["op"]}
        except QueryError as e:
            view = {"ok": False, "id": request.id, "op": request.message["op"],
                    "user": request.message["user"], "error": str(e)}
        self._send("@mapping", view)

    def _reject(self, error: RejectedMessage, ident: int | None) -> str:
        assert self.ctx is not None
        self.requests["rejected"] += 1
        counters = self.ctx.counters
        counters.add("rejected")
        with counters.lock:
            counters.last_error = {"ts": time.time(), "where": "page request",
                                   "message": str(error)}
        self.ctx.rejects.warning("page", f"rejected a request from the page: {error}")
        return to_json("@reply", {"ok": False, "id": ident, "error": str(error)}, time.time())

    # ------------------------------------------------------------------ services and workspace

    def _poll(self, session) -> None:
        period = self.settings.status_period_s
        while not self._stop.is_set():
            started = time.monotonic()
            self._send("@services", self._services(session, min(period, 1.5)))
            if self.workspace["source"].startswith("cbgo.world"):
                self._ask_workspace()
            self._stop.wait(max(0.0, period - (time.monotonic() - started)))

    def _services(self, session, timeout_s: float) -> dict:
        assert self.ctx is not None
        replies = client.status(session, self.ctx.keys, timeout_s=timeout_s)
        tokens = client.alive(session, self.ctx.keys, timeout_s=0.5)
        rows = []
        for name in sorted(tokens | set(replies)):
            reply = replies.get(name, {})
            rows.append({"name": name, "alive": name in tokens, "pid": reply.get("pid"),
                         "host": reply.get("host"), "uptime_s": reply.get("uptime_s"),
                         "counters": reply.get("counters"),
                         "last_error": reply.get("last_error"), **robot_cell_view(reply)})
        return {"ts": time.time(), "services": rows}

    def _ask_workspace(self) -> None:
        assert self.ctx is not None
        try:
            reply = self.ctx.query(keys.SIM_INFO, {"v": wire.SCHEMA_VERSION}, timeout_s=1.0)
        except QueryError:
            return  # no robot yet: keep the default grid, ask again next period
        if reply.get("ok") and reply.get("workspace"):
            self.workspace = {"source": f"cbgo/sim/info of {reply['robot']}",
                              "workspace": reply["workspace"]}
            self._send("@workspace", self.workspace)


def robot_cell_view(status: dict) -> dict:
    """Returns where a robot cell's world comes from and how many actions it has done.

    A robot cell's status (`cbgo.robot_cell`) carries ``scene_source`` (``seed N`` or
    ``scene``) and action counts; the page says so beside the robot's state, so that a start
    scene in which the robot holds something reads as the robot's start, not as an action.
    Other services' statuses give nothing.
    """
    if not isinstance(status.get("scene_source"), str):
        return {}
    counts = status.get("actions")
    done = counts.get("actions") if isinstance(counts, dict) else None
    return {"scene_source": status["scene_source"],
            "actions": done if isinstance(done, int) else None}


main = main_for(Web)
