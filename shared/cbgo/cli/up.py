"""Start the router and the services locally, as child processes, until Ctrl-C.

Logs of all children are merged, each line prefixed with its name. A child that crashes is
restarted with back-off. `up` says when every liveliness token is alive, when one disappears
and when it is back. Ctrl-C or SIGTERM stops the services, then the router, cleanly.

Only services that exist in this installation can be started (`cbgo up --list` shows them);
nothing is faked for the others. Alternatives (another implementation of a service's keys,
such as dry-robot for mujoco-sim) are started only when asked for, by name or with
``--robot``, and never together with the service they replace.

Examples::

    cbgo up                                 # router + every built service
    cbgo up --robot dry                     # the same, with dry-robot instead of mujoco-sim
    cbgo up --robot dry --foxglove          # and the Foxglove bridge, ws://127.0.0.1:8765
    cbgo up dry-robot planner               # router + the symbolic robot + the planner
    cbgo up episode intent                  # router + two services
    cbgo up --no-router --connect tcp/10.0.0.5:7447 planner   # join a remote router
    cbgo up --listen tcp/127.0.0.1:7448     # router on another port; services follow it
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from typing import NoReturn

from cbgo import registry
from cbgo.cli.common import fail
from cbgo.client import open_session
from cbgo.config import DEFAULT_ROUTER_LISTEN, ConfigError, add_zenoh_arguments, resolve_zenoh
from cbgo.keys import Keys
from cbgo.supervisor import AliveWatcher, Child, Supervisor

FOXGLOVE = "foxglove-bridge"  # the optional service `--foxglove` adds
SESSION_CLOSE_S = 5.0
"""How long `up`, its children stopped, waits for its liveliness session to close."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds up's flags."""
    parser.add_argument("services", nargs="*",
                        help="services to start (default: every built service)")
    parser.add_argument("--list", action="store_true",
                        help="list the services, whether each is built, and exit")
    parser.add_argument("--robot", choices=list(registry.ROBOTS), default=None,
                        help="which robot answers cbgo/robot/act: " + ", ".join(
                            f"{k} ({v})" for k, v in registry.ROBOTS.items())
                        + "; it takes mujoco-sim's place in the default set or in the "
                          "named services [mujoco]")
    parser.add_argument("--foxglove", action="store_true",
                        help="also start foxglove-bridge, the live Foxglove WebSocket server "
                             "(ws://127.0.0.1:8765; its flags come from the environment, e.g. "
                             "CBGO_WS_PORT)")
    parser.add_argument("--no-router", dest="router", action="store_false",
                        help="do not start a router; join the one at --connect")
    parser.add_argument("--router-listen", default=DEFAULT_ROUTER_LISTEN, metavar="ENDPOINT",
                        help=f"endpoint the router listens on [{DEFAULT_ROUTER_LISTEN}]")
    parser.add_argument("--ready-timeout", type=float, default=60.0, metavar="S",
                        help="warn if not every service is alive after S seconds [60]")
    parser.add_argument("--log-level", default=None, help="log level passed to every child")
    parser.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                        help="colour the log prefixes [default: when stdout is a terminal]")
    add_zenoh_arguments(parser)


def list_services() -> int:
    """Prints every service from its manifest: built?, alternatives, its keys and tools."""
    for info in registry.SERVICES:
        state = "built" if info.exists() else f"not built yet (issue {info.issue})"
        if info.replaces:
            state += f", replaces {info.replaces}"
        if info.optional:
            state += ", optional"
        print(f"{info.name:<16} {state:<34} {info.summary}")
        _print_interface(info)
    robots = {v: k for k, v in registry.ROBOTS.items()}
    for info in registry.SERVICES:
        if info.replaces:
            how = f"`cbgo up --robot {robots[info.name]}`" if info.name in robots else "by name"
            print(f"\n{info.name} takes the place of {info.replaces} only when asked: {how}, or "
                  f"by name (`cbgo up {info.name} ...`)")
        if info.optional:
            how = " `cbgo up --foxglove`, or" if info.name == FOXGLOVE else ""
            print(f"\n{info.name} is optional, started only when asked:{how} by name "
                  f"(`cbgo up {info.name} ...`)")
    return 0


def offline_tools(service: str) -> list[str]:
    """Returns a service's benchmarks and trainers, where this checkout has the offline tools."""
    try:
        from cbgo_tools.registry import tools_of
    except ModuleNotFoundError:  # an installed wheel: the tools live in a checkout's tools/
        return []
    return tools_of(service)


def _print_interface(info: registry.Manifest) -> None:
    """Prints a manifest's keys and tools, indented under its line."""
    for label, topics in (("reads", info.subscribes), ("writes", info.publishes),
                          ("answers", info.answers), ("asks", info.asks)):
        if topics:
            print(f"{'':17}{label + ':':<9}{', '.join(t.suffix for t in topics)}")
    tools = offline_tools(info.name)
    tools += [f"cbgo plot {f.name}" for f in info.figures]
    if info.demonstrate:
        tools.append(f"cbgo gestures record --{info.demonstrate.name}")
    if tools:
        print(f"{'':17}{'tools:':<9}{', '.join(tools)}")


def chosen_services(names: list[str], robot: str | None = None,
                    foxglove: bool = False) -> list[registry.Manifest]:
    """Returns the services to start, refusing unknown, unbuilt or clashing ones clearly.

    Args:
        names: the services named on the command line (none: the default set).
        robot: a key of `registry.ROBOTS`: that robot takes the place of the one in the set.
        foxglove: add foxglove-bridge (first, so that it sees the others' first messages).
    """
    chosen = [_built(name) for name in names] if names else registry.available()
    if foxglove and FOXGLOVE not in [s.name for s in chosen]:
        chosen = [_built(FOXGLOVE), *chosen]
    if robot is not None:
        chosen = registry.swap(chosen, _built(registry.ROBOTS[robot]))
    for first, other in registry.clashes(chosen):
        if first.name == other.name:
            fail(f"{first.name} is named twice", 2)
        fail(f"{first.name} and {other.name} answer the same keys (one replaces the other); "
             "start one of them", 2)
    return chosen


def _built(name: str) -> registry.Manifest:
    try:
        info = registry.by_name(name)
    except KeyError as e:
        fail(str(e.args[0]), 2)
    if not info.exists():
        fail(f"service {name!r} is not built yet (issue {info.issue}); "
             "`cbgo up --list` shows which are", 2)
    return info


def _local_endpoint(listen: str) -> str:
    """Returns the endpoint a local child uses to reach a router listening on `listen`."""
    proto, _, address = listen.partition("/")
    host, _, port = address.rpartition(":")
    if host in ("0.0.0.0", "[::]", ""):
        host = "127.0.0.1"
    return f"{proto}/{host}:{port}"


def build_children(args: argparse.Namespace, services) -> tuple[list[Child], list[str]]:
    """Returns the child processes to run and the endpoint(s) they connect to."""
    common = []
    if getattr(args, "prefix", None):
        common += ["--prefix", args.prefix]
    if args.log_level:
        common += ["--log-level", args.log_level]
    children = []
    if args.router:
        connect = [_local_endpoint(args.router_listen)]
        # The router listens; ZENOH_CONNECT from our environment is meant for services, and a
        # router dialling its own endpoint would only confuse it.
        children.append(Child(registry.ROUTER, [sys.executable, "-m", "cbgo.router", "--listen",
                                                args.router_listen, *common],
                              env={"ZENOH_CONNECT": ""}))
    else:
        connect = getattr(args, "connect", None) or []
        if not connect:
            fail("--no-router needs --connect ENDPOINT (the router to join)", 2)
    for info in services:
        flags = [f for ep in connect for f in ("--connect", ep)]
        children.append(Child(info.name, [sys.executable, "-m", info.package, *flags, *common]))
    return children, connect


def run(args: argparse.Namespace) -> int:
    """Runs the supervisor until Ctrl-C/SIGTERM, then exits the process (`--list`: returns)."""
    if args.list:
        return list_services()
    services = chosen_services(args.services, args.robot, args.foxglove)
    if not services:
        print("no service is built yet; running the router only (`cbgo up --list`)",
              flush=True)
    children, connect = build_children(args, services)
    sup = Supervisor(children, color=sys.stdout.isatty() if args.color is None else args.color)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    started = time.monotonic()
    sup.start_all()
    watcher = AliveWatcher([c.name for c in children], lambda t: sup.emit("up", t, 0),
                           since=started)
    try:
        resolved = resolve_zenoh({**vars(args), "connect": connect})
    except ConfigError as e:
        fail(f"configuration error: {e}", 2)
    # The watcher's session waits for the router in its own thread, so that supervision
    # (restarting a router that died before we reached it) never waits on it.
    connected = threading.Event()
    watching = threading.Thread(target=_watch_tokens,
                                args=(resolved, watcher, stop, connected), daemon=True)
    watching.start()
    try:
        _supervise(sup, watcher, stop, args.ready_timeout)
    finally:
        stop.set()  # the watcher closes its session while the children stop
        sup.emit("up", "stopping", 0)
        sup.stop_all()
        sup.emit("up", "stopped", 0)
    _exit_without_finalizing(watching, connected, sup)


def _exit_without_finalizing(watching: threading.Thread, connected: threading.Event,
                             sup: Supervisor) -> NoReturn:
    """Exits 0 once the watcher's Zenoh session is closed, without finalizing the interpreter.

    Why: Zenoh works, and calls back into Python, on threads of its own, some of them still
    busy just after its session closed (the services going away send their liveliness changes
    at that very moment). A Zenoh thread that enters Python while the interpreter finalizes is
    made to exit under Rust frames, and the whole process aborts ("FATAL: exception not
    rethrown", exit code 134) after a clean stop: 7 of 30 stops on a loaded machine did
    (`tests/stress/up_stop.sh 30 3`; 0 of 30 since), and closing the session first was not
    enough in a scratch run (1 of 20). The children are stopped and nothing is left to finalize,
    so the process flushes its output and exits at once. A session that connected is given
    `SESSION_CLOSE_S` to close (the router hears it go); one still waiting for an unreachable
    router is not waited for.
    """
    if connected.is_set():
        watching.join(SESSION_CLOSE_S)
        if watching.is_alive():
            sup.emit("up", f"the liveliness session did not close within {SESSION_CLOSE_S:g} "
                     "s; exiting without it", 0)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _watch_tokens(options, watcher: AliveWatcher, stop: threading.Event,
                  connected: threading.Event) -> None:
    keys = Keys(options.prefix)
    with open_session(options, "cbgo-up") as sess:
        connected.set()
        sess.liveliness().declare_subscriber(
            keys.alive("*"), lambda s: _on_token(watcher, keys, s), history=True)
        stop.wait()


def _on_token(watcher: AliveWatcher, keys, sample) -> None:
    import zenoh

    name = keys.service_of_alive(str(sample.key_expr))
    if name:
        watcher.on_token(name, sample.kind == zenoh.SampleKind.PUT)


def _supervise(sup: Supervisor, watcher: AliveWatcher, stop: threading.Event,
               ready_timeout: float) -> None:
    warn_at = time.monotonic() + ready_timeout
    while not stop.wait(0.1):
        sup.poll()
        if warn_at and not watcher.ready.is_set() and time.monotonic() > warn_at:
            sup.emit("up", f"still waiting for: {', '.join(watcher.missing())}", 0)
            warn_at = 0.0
