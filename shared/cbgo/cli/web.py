"""Serve the live web page of cbgo, or scrub through a recording in the same page.

Live, it is the web service itself (`cbgo-web`; `cbgo up` starts it by default): it joins the
Zenoh network, and the page shows hands, scene, gestures, episodes, intents, plans and services,
with STOP and feedback. With ``--replay FILE.mcap`` it joins no network: the recording (``cbgo
record``, or the ``session.mcap`` that `cbgo demo` writes) is loaded, checked against the
contract and shown in the same panels with a time slider; STOP and feedback are off.

Examples::

    cbgo web                                   # http://127.0.0.1:8080, live
    cbgo web --http-port 8090 --connect tcp/10.0.0.5:7447
    cbgo web --replay out/demo-20261202-0230/session.mcap
    cbgo web --replay session.mcap --http-host 0.0.0.0 --http-port 0   # any free port
"""

from __future__ import annotations

import argparse
import signal
import threading

from cbgo.cli.common import fail


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds web's flags: --replay, the service's settings and the Zenoh flags."""
    from cbgo.config import add_dataclass_arguments, add_zenoh_arguments
    from cbgo.services.web.main import WebSettings

    parser.add_argument("--replay", metavar="FILE.mcap", default=None,
                        help="show a recording instead of the live network")
    add_dataclass_arguments(parser, WebSettings, "page (also CBGO_HTTP_HOST, CBGO_HTTP_PORT, "
                                                 "...)")
    add_zenoh_arguments(parser)


def _forwarded(args: argparse.Namespace) -> list[str]:
    """Returns the flags given on the command line, as the service's own argv.

    Flags not given are left out, so the environment and the settings file still apply
    (defaults < file < env < flags, resolved once by `cbgo.config.resolve`).
    """
    argv: list[str] = []
    for name, value in vars(args).items():
        if name in ("verb", "run", "replay"):
            continue
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            argv.append(flag if value else "--no-" + flag[2:])
        elif isinstance(value, list):
            argv += [part for item in value for part in (flag, str(item))]
        elif value is not None:
            argv += [flag, str(value)]
    return argv


def run(args: argparse.Namespace) -> int:
    """Serves the page until Ctrl-C/SIGTERM; returns the exit code."""
    from cbgo.services.web.main import Web

    if args.replay:
        return serve_replay(args.replay, _forwarded(args))
    from cbgo.runtime import run as run_service

    return run_service(Web, _forwarded(args))


def serve_replay(path: str, argv: list[str]) -> int:
    """Loads the recording and serves it until Ctrl-C/SIGTERM (no network)."""
    from cbgo import __version__, wire
    from cbgo.config import resolve
    from cbgo.errors import ConfigError, RecordingError
    from cbgo.services.web import replay
    from cbgo.services.web.main import WebSettings
    from cbgo.services.web.server import HttpServer
    from cbgo.world.workspace import workspace_info

    try:
        resolved = resolve(WebSettings, argv, prog="cbgo web --replay")
        settings = resolved.settings
        shown = replay.load(path, settings.rate_hz, resolved.zenoh.prefix)
    except (ConfigError, RecordingError) as e:
        fail(str(e), 2)
    skipped = ", ".join(f"{n} {why}" for why, n in shown.skipped.items()) or "none"
    info = {"mode": "replay", "file": shown.file, "prefix": shown.prefix,
            "version": __version__, "rate_hz": settings.rate_hz, "actions": list(wire.ACTIONS),
            "source": "cbgo.world.workspace (default grid)", "workspace": workspace_info()}

    def load_upload(upload: str) -> tuple[list, dict]:
        opened = replay.load(upload, settings.rate_hz, shown.prefix)
        return opened.items, opened.skipped

    server = HttpServer(settings.http_host, settings.http_port, lambda: info, _refuse,
                        shown.items, load_upload)
    try:
        url = server.start()
    except ConfigError as e:
        fail(str(e), 2)
    print(f"serving {shown.file} ({len(shown.items)} views; skipped: {skipped}) at {url}",
          flush=True)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    stop.wait()
    server.stop()
    return 0


def _refuse(_data) -> str:
    import json

    return json.dumps({"topic": "@reply", "t": 0, "msg": {
        "ok": False, "id": None, "error": "replay: not connected to a robot"}})
