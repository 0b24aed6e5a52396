"""The `cbgo` command: one verb per module in `cbgo.cli`.

Examples::

    cbgo up                      # router + every built service, logs merged, Ctrl-C stops all
    cbgo ls                      # live services: host, pid, uptime, keys
    cbgo status episode          # one service's status (counters, config, last error)
    cbgo echo hands/frame        # decoded messages on a key (relative to the prefix)
    cbgo hz hands/frame          # message rate and jitter
    cbgo get 'cbgo/@ctl/*/status'
    cbgo pub user '{"user": "alice"}' --stamp
    cbgo web --replay session.mcap   # a recording in the live page's panels, with a slider
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

import cbgo
from cbgo.errors import zenoh_reason

# verb -> module in cbgo.cli; each module has add_arguments(parser) and run(args) -> int.
VERBS = {
    "demo": ("demo", "run the paper's story end to end: services, simulated users, a report"),
    "up": ("up", "start the router and services locally, merge logs, restart crashes"),
    "router": ("router", "run the Zenoh router (Python, admin space on)"),
    "ls": ("ls", "list live services with host, pid, uptime and keys"),
    "status": ("status", "show a service's status: counters, config, last error"),
    "echo": ("echo", "print decoded messages on a key"),
    "hz": ("hz", "measure message rate, jitter and bandwidth on a key"),
    "get": ("get", "send a query and print the replies"),
    "pub": ("pub", "publish a JSON message as msgpack"),
    "wait-alive": ("wait_alive", "wait until services are alive (for scripts, healthchecks)"),
    "bench": ("bench", "run a benchmark and print its figures"),
    "train": ("train", "train a model and write it where its service loads it"),
    "record": ("record", "record traffic to an MCAP file"),
    "replay": ("replay", "replay an MCAP recording onto the network"),
    "export": ("export", "convert a recording to JSON MCAP with schemas, for Foxglove"),
    "foxglove": ("foxglove", "serve the live traffic to Foxglove (WebSocket, 3D scene, log)"),
    "data": ("data", "real data sets (list, fetch, convert) and the paper's intent sets D1-D5"),
    "feedback": ("feedback", "correct the last intent (personalises the user's model)"),
    "mapping": ("mapping", "say what your gestures mean: show, set or unset a user's mapping"),
    "gestures": ("gestures", "record a new gesture by demonstration and retrain"),
    "sim": ("sim", "talk to the simulator: snapshot, reset"),
    "plot": ("plot", "draw figures from recordings (the paper's episode figure)"),
    "plan": ("plan", "show the planner's live behaviour tree"),
    "web": ("web", "serve the live web page, or scrub through a recording in it (--replay)"),
    "certs": ("certs", "make the TLS certificates of a secured network (openssl)"),
}


def build_parser(verb: str | None = None) -> argparse.ArgumentParser:
    """Returns the parser of `cbgo`.

    Only the chosen verb's module is imported (some pull in torch), so `cbgo ls` starts fast;
    without a known verb, every verb is listed with its summary for --help.
    """
    parser = argparse.ArgumentParser(
        prog="cbgo", description="cbgo: command a robot arm with hand gestures read in context.",
        epilog="Run `cbgo VERB --help` for a verb's options and examples.")
    parser.add_argument("--version", action="version", version=f"cbgo {cbgo.__version__}")
    verbs = parser.add_subparsers(dest="verb", metavar="VERB", required=True)
    for name, (module, summary) in VERBS.items():
        if verb is not None and name != verb:
            continue
        if verb is None:
            verbs.add_parser(name, help=summary)
            continue
        mod = importlib.import_module(f"cbgo.cli.{module}")
        sub = verbs.add_parser(name, help=summary, description=mod.__doc__,
                               formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(sub)
        sub.set_defaults(run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> None:
    """Entry point of the `cbgo` console script."""
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["router"]:
        # The router is a service: its flags are the runtime's, parsed by the runtime.
        from cbgo.router import Router
        from cbgo.runtime import run

        sys.exit(run(Router, argv[1:]))
    if argv[:1] == ["foxglove"]:  # the foxglove-bridge service, likewise
        from cbgo.runtime import run
        from cbgo.services.foxglove_bridge.main import FoxgloveBridge

        sys.exit(run(FoxgloveBridge, argv[1:]))
    args = build_parser(argv[0] if argv and argv[0] in VERBS else None).parse_args(argv)
    try:
        sys.exit(args.run(args))
    except KeyboardInterrupt:
        sys.exit(130)
    except BrokenPipeError:  # `cbgo echo ... | head`: the reader left; nothing more to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(141)
    except Exception as e:
        # A Zenoh error the verb did not foresee: its message, without Zenoh's Rust source path.
        if type(e).__module__ != "zenoh":
            raise
        print(f"cbgo: {args.verb}: Zenoh refused: {zenoh_reason(e)}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
