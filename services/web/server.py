"""The HTTP side of web: an aiohttp application on its own thread and event loop.

- ``GET /`` the page, ``/static/...`` its scripts, styles and the vendored libraries (three.js,
  with its licence), so the page needs nothing from the internet;
- ``GET /api/info``: the mode (``live`` or ``replay``), the prefix, the workspace, the version;
- ``GET /api/replay``: in replay mode, every view of the recording (``[t, topic, view]``);
- ``POST /api/upload``: a recording opened from the page (the file as the body, at most
  `MAX_UPLOAD_BYTES`): its views, for the page to scrub through; the live stream goes on;
- ``GET /ws``: the live stream. A new page first gets what the `Hub` remembers (the newest
  scene, robot state, intent, plan, services, and the recent gesture history), then every view
  as it comes; a socket opened by another site's page (its ``Origin``) is refused. Each page
  has its own bounded queue: a page that cannot keep up is not allowed to slow the service or
  the other pages, nor to lose an intent or a plan unseen. Its socket is closed instead
  (counted), and the page reconnects to a fresh snapshot. Requests from the page (STOP,
  feedback) arrive on the same socket and are answered on it.

Threads: Zenoh's and the service's threads hand views over with `HttpServer.send`
(thread-safe); everything else here runs on the server's loop.
"""

from __future__ import annotations

import asyncio
import logging
import tempfile
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from urllib.parse import urlsplit

from aiohttp import WSCloseCode, WSMsgType, web

from cbgo.errors import ConfigError, RecordingError

STATIC = Path(__file__).parent / "static"
CLIENT_QUEUE = 512  # views queued per page beyond its snapshot before it counts as behind
# How many views of a topic a new page is sent first (the rest keep only the newest).
HISTORY = {"episode/event": 200, "episode/summary": 20, "intent": 20, "plan/status": 20,
           "gestures/static": 600, "gestures/dynamic": 100, "@evidence": 300, "@reply": 0}
START_TIMEOUT_S = 10.0
MAX_UPLOAD_BYTES = 256 << 20  # a recording opened from the page: minutes of a session
log = logging.getLogger("cbgo.web")


class Hub:
    """The pages connected to the live stream, and what a new page is sent first."""

    def __init__(self):
        self.pages: dict[asyncio.Queue, Callable[[], None]] = {}
        self.sent = 0
        self.dropped = 0
        self.resets = 0
        self._recent: dict[str, deque] = {}

    def publish(self, topic: str, text: str) -> None:
        """Sends one view to every page and remembers it (call on the server's loop)."""
        keep = HISTORY.get(topic, 1)
        if keep:
            self._recent.setdefault(topic, deque(maxlen=keep)).append(text)
        for queue in list(self.pages):
            self.offer(queue, text)

    def join(self, on_behind: Callable[[], None]) -> asyncio.Queue:
        """Opens a new page's queue, holding the whole snapshot first.

        Args:
            on_behind: called once if the page falls `CLIENT_QUEUE` views behind; it must
                close the page's socket (the page is no longer sent anything).
        """
        snapshot = self.snapshot()
        # Room for the whole snapshot: a page opened late in a session must get its intents
        # and plans, which come after the long gesture histories.
        queue: asyncio.Queue = asyncio.Queue(len(snapshot) + CLIENT_QUEUE)
        for text in snapshot:
            queue.put_nowait(text)
        self.sent += len(snapshot)
        self.pages[queue] = on_behind
        return queue

    def leave(self, queue: asyncio.Queue) -> None:
        """Forgets a page whose socket closed."""
        self.pages.pop(queue, None)

    def offer(self, queue: asyncio.Queue, text: str) -> None:
        """Queues a view for one page; a page too far behind is dropped from the stream.

        Dropping only the views that do not fit would lose whatever came then, an intent or a
        plan included, and the page would show a stale world as live. So a page that lags is
        reset: it reconnects and starts again from a snapshot of the newest state.
        """
        try:
            queue.put_nowait(text)
            self.sent += 1
        except asyncio.QueueFull:
            self.dropped += 1
            on_behind = self.pages.pop(queue, None)
            if on_behind is not None:
                self.resets += 1
                on_behind()

    def snapshot(self) -> list[str]:
        """Returns what a new page gets first, oldest topic history first."""
        return [text for recent in self._recent.values() for text in recent]


class HttpServer:
    """The aiohttp application, served from a thread of its own.

    Args:
        host: the address to listen on.
        port: the port (0: any free one; `url` tells which).
        info: returns the ``/api/info`` answer.
        on_request: answers one WebSocket message from a page (returns the answer, JSON text).
        replay: the ``/api/replay`` views, in replay mode.
        load_upload: reads an uploaded recording's path into (views, skipped); None: no
            uploads.
    """

    def __init__(self, host: str, port: int, info: Callable[[], dict],
                 on_request: Callable[[str | bytes], str], replay: list | None = None,
                 load_upload: Callable[[str], tuple[list, dict]] | None = None):
        self.host, self.port = host, port
        self.info, self.on_request, self.replay = info, on_request, replay
        self.load_upload = load_upload
        self.hub = Hub()
        self.url = ""
        self._loop = asyncio.new_event_loop()
        self._runner: web.AppRunner | None = None
        self._sockets: set[web.WebSocketResponse] = set()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ life cycle

    def start(self) -> str:
        """Binds and starts serving; returns the URL.

        Raises:
            ConfigError: the address cannot be bound (in use, not this host's), with the fix.
        """
        started: list = []
        ready = threading.Event()
        self._thread = threading.Thread(target=self._serve, args=(started, ready),
                                        name="web-http", daemon=True)
        self._thread.start()
        if not ready.wait(START_TIMEOUT_S):
            raise ConfigError(f"the web server did not start within {START_TIMEOUT_S} s")
        if isinstance(started[0], OSError):
            e = started[0]
            raise ConfigError(
                f"cannot serve HTTP on {self.host}:{self.port}: {e.strerror or e}; another "
                "program (another cbgo-web?) may hold the port: stop it, or choose another "
                "with --http-port / CBGO_HTTP_PORT (0: any free port)")
        self.url = started[0]
        return self.url

    def stop(self) -> None:
        """Closes the sockets and stops the loop (within about a second)."""
        if self._thread is None or not self._thread.is_alive():
            return
        future = asyncio.run_coroutine_threadsafe(self._close(), self._loop)
        try:
            future.result(1.0)
        except (TimeoutError, asyncio.TimeoutError):
            log.warning("the web server did not close within 1 s")
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(1.0)

    def send(self, topic: str, text: str) -> None:
        """Hands one view to the pages (thread-safe)."""
        if not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self.hub.publish, topic, text)

    def _serve(self, started: list, ready: threading.Event) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            started.append(self._loop.run_until_complete(self._bind()))
        except OSError as e:
            started.append(e)
        ready.set()
        if isinstance(started[0], OSError):
            return
        self._loop.run_forever()

    async def _bind(self) -> str:
        # A short grace: the service must exit within 2 s of SIGTERM, open pages or not.
        self._runner = web.AppRunner(self._app(), access_log=None, handle_signals=False,
                                     shutdown_timeout=0.5)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port)
        try:
            await site.start()
        except OSError:
            await self._runner.cleanup()
            raise
        host, port = self._runner.addresses[0][:2]
        return f"http://{host}:{port}/" if ":" not in host else f"http://[{host}]:{port}/"

    async def _close(self) -> None:
        # Close the pages' sockets first: the runner's cleanup would wait for their handlers.
        for ws in list(self._sockets):
            await ws.close(code=WSCloseCode.GOING_AWAY, message=b"cbgo-web is stopping")
        if self._runner is not None:
            await self._runner.cleanup()

    # ------------------------------------------------------------------ routes

    def _app(self) -> web.Application:
        app = web.Application(client_max_size=64 * 1024)
        app.router.add_get("/", self._index)
        app.router.add_get("/api/info", self._info)
        app.router.add_get("/api/replay", self._replay)
        app.router.add_post("/api/upload", self._upload)
        app.router.add_get("/ws", self._socket)
        app.router.add_static("/static/", STATIC, follow_symlinks=False)
        return app

    async def _index(self, _request: web.Request) -> web.FileResponse:
        return web.FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    async def _info(self, _request: web.Request) -> web.Response:
        return web.json_response(self.info())

    async def _replay(self, _request: web.Request) -> web.Response:
        if self.replay is None:
            raise web.HTTPNotFound(text="not in replay mode: start `cbgo web --replay FILE`")
        return web.json_response(self.replay)

    async def _upload(self, request: web.Request) -> web.Response:
        """Turns an uploaded recording (the raw file as the body) into replay views."""
        if self.load_upload is None:
            raise web.HTTPNotFound(text="this server does not take uploads")
        with tempfile.NamedTemporaryFile(suffix=".mcap") as file:
            size = 0
            async for chunk in request.content.iter_chunked(1 << 16):
                size += len(chunk)
                if size > MAX_UPLOAD_BYTES:
                    raise web.HTTPRequestEntityTooLarge(MAX_UPLOAD_BYTES, size)
                file.write(chunk)
            file.flush()
            name = request.headers.get("X-File-Name", "upload.mcap")[:200]
            loop = asyncio.get_running_loop()
            try:  # reading a recording is CPU work: off the loop, so the live stream goes on
                items, skipped = await loop.run_in_executor(None, self.load_upload, file.name)
            except RecordingError as e:
                raise web.HTTPBadRequest(text=f"{name}: {e}") from None
        log.info("a page opened the recording %s (%d views)", name, len(items))
        return web.json_response({"file": name, "items": items, "skipped": skipped})

    async def _socket(self, request: web.Request) -> web.WebSocketResponse:
        # Browsers let any web site open a WebSocket to 127.0.0.1; only our own page (or a
        # client that is not a browser, which sends no Origin) may send STOP and feedback.
        origin = request.headers.get("Origin")
        if origin and urlsplit(origin).netloc != request.host:
            log.warning("refused a WebSocket from another site's page (Origin %s)", origin)
            raise web.HTTPForbidden(text=f"cross-origin WebSocket from {origin} refused")
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=64 * 1024)
        await ws.prepare(request)
        queue = self.hub.join(lambda: self._reset(ws))
        self._sockets.add(ws)
        writer = asyncio.ensure_future(self._write(ws, queue))
        try:
            async for message in ws:
                if message.type in (WSMsgType.TEXT, WSMsgType.BINARY):
                    self.hub.offer(queue, self._answer(message.data))
                elif message.type == WSMsgType.ERROR:
                    log.info("a page's socket failed: %s", ws.exception())
        finally:
            self.hub.leave(queue)
            self._sockets.discard(ws)
            writer.cancel()
        return ws

    def _reset(self, ws: web.WebSocketResponse) -> None:
        log.warning("a page fell %d views behind the live stream: closed its socket, so it "
                    "reconnects to the newest state", CLIENT_QUEUE)
        asyncio.ensure_future(ws.close(code=WSCloseCode.TRY_AGAIN_LATER,
                                       message=b"fell behind the live stream: reconnect"))

    def _answer(self, data: str | bytes) -> str:
        return self.on_request(data)

    async def _write(self, ws: web.WebSocketResponse, queue: asyncio.Queue) -> None:
        while not ws.closed:
            text = await queue.get()
            try:
                await ws.send_str(text)
            except (ConnectionError, RuntimeError):
                return  # the page went away; its read loop ends the socket
