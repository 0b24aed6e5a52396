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
    """Adds web's flags."""
    from cbgo.client import add_network_arguments
    from cbgo.services.web.main import WebSettings

    defaults = WebSettings()
    parser.add_argument("--replay", metavar="FILE.mcap", default=None,
                        help="show a recording instead of the live network")
    parser.add_argument("--http-host", default=defaults.http_host, metavar="HOST",
                        help=f"address to serve the page on [{defaults.http_host}]")
    parser.add_argument("--http-port", type=int, default=defaults.http_port, metavar="PORT",
                        help=f"port of the page (0: any free port) [{defaults.http_port}]")
    parser.add_argument("--rate-hz", type=float, default=defaults.rate_hz, metavar="HZ",
                        help="most views per second of each high-rate stream "
                             f"[{defaults.rate_hz:g}]")
    add_network_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Serves the page until Ctrl-C/SIGTERM; returns the exit code."""
    if args.replay:
        return serve_replay(args)
    from cbgo.runtime import run as run_service
    from cbgo.services.web.main import Web

    argv = ["--http-host", args.http_host, "--http-port", str(args.http_port),
            "--rate-hz", str(args.rate_hz)]
    for name in ("connect", "listen"):
        for endpoint in getattr(args, name, None) or []:
            argv += [f"--{name}", endpoint]
    for name in ("mode", "prefix", "config"):
        if getattr(args, name, None):
            argv += [f"--{name}", str(getattr(args, name))]
    return run_service(Web, argv)


def serve_replay(args: argparse.Namespace) -> int:
    """Loads the recording and serves it until Ctrl-C/SIGTERM."""
    from cbgo import __version__, wire
    from cbgo.errors import ConfigError, RecordingError
    from cbgo.services.web import replay
    from cbgo.services.web.server import HttpServer
    from cbgo.world.workspace import workspace_info

    try:
        shown = replay.load(args.replay, args.rate_hz, getattr(args, "prefix", None) or "cbgo")
    except RecordingError as e:
        fail(str(e), 2)
    skipped = ", ".join(f"{n} {why}" for why, n in shown.skipped.items()) or "none"
    info = {"mode": "replay", "file": shown.file, "prefix": shown.prefix,
            "version": __version__, "rate_hz": args.rate_hz, "actions": list(wire.ACTIONS),
            "source": "cbgo.world.workspace (default grid)", "workspace": workspace_info()}
    def load_upload(path: str) -> tuple[list, dict]:
        opened = replay.load(path, args.rate_hz, shown.prefix)
        return opened.items, opened.skipped

    server = HttpServer(args.http_host, args.http_port, lambda: info, _refuse, shown.items,
                        load_upload)
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
