"""Start the router and the services locally, as child processes, until Ctrl-C.

Logs of all children are merged, each line prefixed with its name. `up` starts its own router
first, on loopback (``tcp/127.0.0.1:7447``: only this host can join) unless ``--listen`` says
otherwise, and starts the services once that router answers as the one it started. A port that
is already in use ends `up` at once with exit code 2, naming the port and ``--listen``, and
nothing is started. Services join a router that `up` did not start only when told to:
``--connect ENDPOINT`` joins that router and starts none here.

"ready" means that every process `up` started is alive on this system: its liveliness token is
there and its status reply gives the pid of our child. A process of the same name that `up` did
not start (another host's, another `up`'s) is reported and never counted. `up` also says when
one of its processes disappears and when it is back. A child that crashes is restarted with
back-off; one that exits with a configuration error (code 2) is not; if that is the router, `up`
stops everything and exits with code 2. Ctrl-C or SIGTERM stops the services, then the router.

Only services that exist in this installation can be started (`cbgo up --list` shows them);
nothing is faked for the others. Alternatives (another implementation of a service's keys,
such as dry-robot for mujoco-sim, camera-bridge for leap-bridge) are started only when asked
for, by name, with ``--robot`` or ``--hands``, and never together with the service they replace.

Examples::

    cbgo up                                 # router on 127.0.0.1:7447 + every built service
    cbgo up --robot dry                     # the same, with dry-robot instead of mujoco-sim
    cbgo up --robot dry --foxglove          # and the Foxglove bridge, ws://127.0.0.1:8765
    cbgo up --hands camera --camera 0       # hands from the webcam (camera-bridge), not a Leap
    cbgo up --hands camera --camera clip.mp4   # ... or from a video, played as a camera
    cbgo up dry-robot planner               # router + the symbolic robot + the planner
    cbgo up episode intent                  # router + two services
    cbgo up --listen tcp/127.0.0.1:7448     # router on another port; services follow it
    cbgo up --listen tcp/10.0.0.5:7447 intent planner   # other hosts may join this router
    cbgo up --connect tcp/10.0.0.5:7447 episode         # join that router; start none here

A router that other hosts can reach without TLS logs a warning naming the secured deployment
(`cbgo certs make`, deploy/compose.tls.yaml, deploy/tls/).
"""

from __future__ import annotations

import argparse
import os
import queue
import signal
import socket
import sys
import threading
import time
from dataclasses import dataclass
from typing import NoReturn

from cbgo import client, keys, registry
from cbgo.cli.common import fail
from cbgo.config import DEFAULT_ROUTER_LISTEN, ConfigError, add_zenoh_arguments, resolve_zenoh
from cbgo.endpoints import check_can_listen, local_endpoint
from cbgo.keys import Keys
from cbgo.supervisor import EXIT_CONFIG, AliveWatcher, Child, Supervisor

FOXGLOVE = "foxglove-bridge"  # the optional service `--foxglove` adds
HANDS = {"leap": "leap-bridge", "camera": "camera-bridge"}
"""`cbgo up --hands NAME`: which service publishes cbgo/hands/frame."""
CAMERA_BRIDGE = HANDS["camera"]
SESSION_CLOSE_S = 5.0
"""How long `up`, its children stopped, waits for its liveliness session to close."""
STATUS_TIMEOUT_S = 3.0
"""How long `up` waits for a status reply that says whose a liveliness token is."""
STATUS_TRIES = 3
"""Status queries before a token nobody answers for is reported as unknown."""
RECHECK_S = 1.0
"""How often a token that is there but not known to be ours is checked again."""


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
    parser.add_argument("--hands", choices=list(HANDS), default=None,
                        help="where hands come from: " + ", ".join(
                            f"{k} ({v})" for k, v in HANDS.items())
                        + "; it takes leap-bridge's place in the default set or in the named "
                          "services [leap]")
    parser.add_argument("--camera", default=None, metavar="SRC",
                        help="camera-bridge's source: a camera index or /dev/videoN, a video "
                             "file or a folder of images (with --hands camera) [0]")
    parser.add_argument("--foxglove", action="store_true",
                        help="also start foxglove-bridge, the live Foxglove WebSocket server "
                             "(ws://127.0.0.1:8765; its flags come from the environment, e.g. "
                             "CBGO_WS_PORT)")
    parser.add_argument("--listen", "--router-listen", dest="router_listen", default=None,
                        metavar="ENDPOINT",
                        help=f"where the router that up starts listens [{DEFAULT_ROUTER_LISTEN}:"
                             " this host only]; e.g. tcp/0.0.0.0:7447 or the cell's address "
                             "lets other hosts join. The services follow it. --router-listen "
                             "is the same option")
    parser.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                        help="join the router at ENDPOINT instead of starting one here: the "
                             "services connect to it (repeatable). With --listen, it may only "
                             "name that router")
    parser.add_argument("--no-router", dest="router", action="store_false",
                        help="start no router; join the one at --connect (--connect alone "
                             "does the same)")
    parser.add_argument("--ready-timeout", type=float, default=60.0, metavar="S",
                        help="warn if not every service is alive after S seconds [60]")
    parser.add_argument("--log-level", default=None, help="log level passed to every child")
    parser.add_argument("--color", action=argparse.BooleanOptionalAction, default=None,
                        help="colour the log prefixes [default: when stdout is a terminal]")
    add_zenoh_arguments(parser, skip=("listen", "connect"))


def list_services() -> int:
    """Prints every service from its manifest: built?, alternatives, its keys and tools."""
    for info in registry.SERVICES:
        state = "built" if info.exists() else "not built in this installation"
        if info.replaces:
            state += f", replaces {info.replaces}"
        if info.optional:
            state += ", optional"
        print(f"{info.name:<16} {state:<34} {info.summary}")
        _print_interface(info)
    flags = {v: f"--robot {k}" for k, v in registry.ROBOTS.items()}
    flags |= {v: f"--hands {k}" for k, v in HANDS.items()}
    for info in registry.SERVICES:
        if info.replaces:
            how = f"`cbgo up {flags[info.name]}`" if info.name in flags else "by name"
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
                    foxglove: bool = False, hands: str | None = None) -> list[registry.Manifest]:
    """Returns the services to start, refusing unknown, unbuilt or clashing ones clearly.

    Args:
        names: the services named on the command line (none: the default set).
        robot: a key of `registry.ROBOTS`: that robot takes the place of the one in the set.
        foxglove: add foxglove-bridge (first, so that it sees the others' first messages).
        hands: a key of `HANDS`: that service takes the place of the hand source in the set.
    """
    chosen = [_built(name) for name in names] if names else registry.available()
    if foxglove and FOXGLOVE not in [s.name for s in chosen]:
        chosen = [_built(FOXGLOVE), *chosen]
    if robot is not None:
        chosen = registry.swap(chosen, _built(registry.ROBOTS[robot]))
    if hands is not None:
        chosen = registry.swap(chosen, _built(HANDS[hands]))
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
        fail(f"service {name!r} is not built in this installation; "
             "`cbgo up --list` shows which are", 2)
    return info


@dataclass(frozen=True)
class Network:
    """Where `up`'s router listens (None: it starts none) and what its services dial."""

    listen: str | None
    connect: list[str]


def network_of(args: argparse.Namespace) -> Network:
    """Returns the router to start and the endpoints to dial, refusing contradictions."""
    connect = list(args.connect or [])
    if not args.router:
        if not connect:
            fail("--no-router needs --connect ENDPOINT (the router to join)", 2)
        if args.router_listen:
            fail("--no-router starts no router, so it has nothing to --listen on; drop one "
                 "of them", 2)
        return Network(None, connect)
    if connect and args.router_listen is None:
        return Network(None, connect)  # told to join that router
    listen = args.router_listen or DEFAULT_ROUTER_LISTEN
    dial = local_endpoint(listen)
    if connect and [local_endpoint(c) for c in connect] != [dial]:
        fail(f"--listen {listen} starts a router here, and --connect {', '.join(connect)} "
             f"names another: the services follow the router `up` starts ({dial}). Give "
             "--listen to start one, or --connect alone to join one", 2)
    return Network(listen, [dial])


def _check_router_can_listen(net: Network, services: list[registry.Manifest]) -> None:
    """Ends `up` (exit code 2) before anything starts if its router could not listen."""
    names = " ".join(s.name for s in services) or "SERVICES"
    try:
        check_can_listen([net.listen], "--listen",
                         hint=f"To add services to the system there, join it: `cbgo up "
                              f"--connect {net.connect[0]} {names}`.")
    except ConfigError as e:
        fail(str(e), 2)


def build_children(args: argparse.Namespace, services, net: Network) -> list[Child]:
    """Returns the child processes to run: the router first (if `up` starts one)."""
    common = []
    if getattr(args, "prefix", None):
        common += ["--prefix", args.prefix]
    if args.log_level:
        common += ["--log-level", args.log_level]
    children = []
    if net.listen:
        # The router listens; ZENOH_CONNECT from our environment is meant for services, and a
        # router dialling its own endpoint would only confuse it.
        children.append(Child(registry.ROUTER, [sys.executable, "-m", "cbgo.router", "--listen",
                                                net.listen, *common],
                              env={"ZENOH_CONNECT": ""}))
    for info in services:
        flags = [f for ep in net.connect for f in ("--connect", ep)]
        if info.name == CAMERA_BRIDGE and getattr(args, "camera", None):
            flags += ["--camera", args.camera, *_camera_waits_for(args.camera, services)]
        children.append(Child(info.name, [sys.executable, "-m", info.package, *flags, *common]))
    return children


def _camera_waits_for(camera: str, services) -> list[str]:
    """A video or image folder plays once: it waits for the services here that read hands."""
    if camera.isdigit() or camera.startswith("/dev/video"):
        return []  # a live camera is not replayed; nothing to wait for
    readers = [s.name for s in services if keys.HANDS_FRAME in s.subscribes]
    return ["--wait-for", ",".join(readers)] if readers else []


def run(args: argparse.Namespace) -> int:
    """Runs the supervisor until Ctrl-C/SIGTERM, then exits the process (`--list`: returns)."""
    if args.list:
        return list_services()
    services = chosen_services(args.services, args.robot, args.foxglove, args.hands)
    if args.camera and CAMERA_BRIDGE not in [s.name for s in services]:
        fail("--camera is camera-bridge's source: add --hands camera", 2)
    net = network_of(args)
    if net.listen:
        _check_router_can_listen(net, services)
    try:
        options = resolve_zenoh({**vars(args), "connect": net.connect})
    except ConfigError as e:
        fail(f"configuration error: {e}", 2)
    if not services:
        print("no service is built yet; running the router only (`cbgo up --list`)",
              flush=True)
    up = Up(build_children(args, services, net), router=bool(net.listen),
            color=sys.stdout.isatty() if args.color is None else args.color)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: up.stop.set())
    # The watcher's session waits for the router in its own thread, so that supervision
    # (restarting a router that died before we reached it) never waits on it.
    watching = threading.Thread(target=up.watch_tokens, args=(options,), daemon=True)
    up.start(watching)
    try:
        up.supervise(args.ready_timeout)
    finally:
        up.stop.set()  # the watcher closes its session while the children stop
        up.say("stopping")
        up.sup.stop_all()
        up.say("stopped")
    if up.failure:
        print(f"cbgo: {up.failure}", file=sys.stderr)
    _exit_without_finalizing(watching, up.connected, up.sup, 2 if up.failure else 0)


class Up:
    """The processes of one `cbgo up`, the watch on their tokens, and why it must end.

    Args:
        children: the router first (when `router`), then the services.
        router: whether the first child is our router; the services start once it answers
            as ours.
        color: colour the log prefixes.
    """

    def __init__(self, children: list[Child], router: bool, color: bool):
        self.sup = Supervisor(children, color=color)
        self.router = children[0] if router else None
        self.services = children[1:] if router else children
        self.children = {c.name: c for c in children}
        self.stop = threading.Event()
        self.connected = threading.Event()
        self.router_ours = threading.Event()
        self.failure: str | None = None
        self.watcher = AliveWatcher(list(self.children), self.say, since=time.monotonic())
        self._tokens: queue.Queue = queue.Queue()
        self._host = socket.gethostname()
        # Names whose token is there but not (yet) known to be ours: another process holds the
        # same token, and ours, once it declares it too, brings no new token event.
        self._unconfirmed: set[str] = set()

    def say(self, text: str) -> None:
        """Writes one of `up`'s own lines."""
        self.sup.emit("up", text, 0)

    def start(self, watching: threading.Thread) -> None:
        """Starts the router (or, joining a router, the services) and the token watch."""
        for child in [self.router] if self.router else self.services:
            self.sup.start(child)
        watching.start()

    def supervise(self, ready_timeout: float) -> None:
        """Supervises until stopped, or until the router cannot listen (`failure`).

        Restarts crashed children, and starts the services once our router answers as ours.
        """
        warn_at = time.monotonic() + ready_timeout
        waiting_for_router = self.router is not None
        while not self.stop.wait(0.1):
            for child, code in self.sup.poll():
                if child is self.router and code == EXIT_CONFIG:
                    self.failure = (f"the router could not start (exit code {code}; its log "
                                    "above says why); nothing else was started" if
                                    waiting_for_router else
                                    f"the router stopped with exit code {code} (its log above "
                                    "says why); stopping, so that the services cannot join "
                                    "another router on its port")
                    return
            if waiting_for_router and self.router_ours.is_set():
                waiting_for_router = False
                for child in self.services:
                    self.sup.start(child)
            if warn_at and not self.watcher.ready.is_set() and time.monotonic() > warn_at:
                self.say(f"still waiting for: {', '.join(self.watcher.missing())}")
                warn_at = 0.0

    # ---------------------------------------------------------------- liveliness (own thread)

    def watch_tokens(self, options) -> None:
        """Follows the liveliness tokens of our names and checks whose each one is."""
        keys = Keys(options.prefix)
        with client.open_session(options, "cbgo-up") as sess:
            self.connected.set()
            sess.liveliness().declare_subscriber(
                keys.alive("*"), lambda s: self._on_token(keys, s), history=True)
            next_recheck = time.monotonic() + RECHECK_S
            while not self.stop.is_set():
                try:
                    name, present = self._tokens.get(timeout=0.1)
                except queue.Empty:
                    if time.monotonic() > next_recheck:
                        for name in sorted(self._unconfirmed):
                            self._check_token(sess, keys, name, True, tries=1)
                        next_recheck = time.monotonic() + RECHECK_S
                    continue
                self._check_token(sess, keys, name, present)

    def _on_token(self, keys: Keys, sample) -> None:
        """Queues a token change of one of our names; the status query runs elsewhere.

        This runs on Zenoh's thread, which must not block on a query.
        """
        import zenoh

        name = keys.service_of_alive(str(sample.key_expr))
        if name in self.children:
            self._tokens.put((name, sample.kind == zenoh.SampleKind.PUT))

    def _check_token(self, sess, keys: Keys, name: str, present: bool,
                     tries: int = STATUS_TRIES) -> None:
        """Counts a token change of `name` if the process behind it is our child."""
        ours, strangers = self._owners(sess, keys, name, tries=tries if present else 1)
        for who in strangers:
            self.watcher.on_stranger(name, who)
        if present and not ours:
            if not strangers and name not in self._unconfirmed:
                self.say(f"{name}'s liveliness token is there, but no status reply says whose "
                         "it is; not counted as ours until one does")
            self._unconfirmed.add(name)
            return
        self._unconfirmed.discard(name)
        if not present and ours:
            return  # another process's token of that name went; ours still answers
        self.watcher.on_token(name, present)
        if present and self.children[name] is self.router:
            self.router_ours.set()

    def _owners(self, sess, keys: Keys, name: str, tries: int) -> tuple[bool, list[str]]:
        """Asks every process named `name` for its status.

        Returns:
            whether one of them is our child, and how to find each of the others.
        """
        for attempt in range(tries):
            # every process's reply, not one per key (`client.query_all`)
            replies = [reply for ok, reply in client.query_all(
                sess, keys.ctl(name, "status"), timeout_s=STATUS_TIMEOUT_S) if ok]
            if replies or attempt == tries - 1:
                break
            time.sleep(0.5)
        proc = self.children[name].proc
        ours, strangers = False, []
        for reply in replies:
            if proc is not None and reply["pid"] == proc.pid and reply.get("host") == self._host:
                ours = True
            else:
                strangers.append(f"pid {reply['pid']} on host {reply.get('host')}")
        return ours, strangers


def _exit_without_finalizing(watching: threading.Thread, connected: threading.Event,
                             sup: Supervisor, code: int) -> NoReturn:
    """Exits with `code` once the watcher's Zenoh session is closed, without finalizing.

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
    os._exit(code)
