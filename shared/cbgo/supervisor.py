"""The process supervisor behind `cbgo up`: router and services as child processes.

Rules:
- children are started with ``subprocess`` (fork immediately followed by exec, so no Python
  code runs in a forked copy of a process that has Zenoh open), each in its own session, so a
  Ctrl-C reaches only the supervisor, which then stops them in order: services first, in
  reverse pipeline order, then the router;
- every child's stdout and stderr are merged into ours, each line prefixed with its name,
  up to its last line: stopping waits for that (at most `DRAIN_S`);
- a child that exits while we are not stopping is restarted after a back-off that doubles from
  0.5 s up to 30 s, and resets once the child has run for 30 s; one that exits with code 2 (a
  configuration error: a port in use, a bad setting) is not, since a restart cannot fix it;
- readiness is the liveliness token ``<prefix>/@alive/<name>``, watched through our own Zenoh
  client session, of a process we started (`AliveWatcher`: `cbgo up` checks the pid in the
  process's status reply); we say when all are alive, when one disappears and when it comes back.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from cbgo.runtime import EXIT_CONFIG  # a configuration error: restarting cannot fix it

BACKOFF_FIRST_S, BACKOFF_MAX_S, BACKOFF_RESET_AFTER_S = 0.5, 30.0, 30.0
STOP_GRACE_S = 5.0
DRAIN_S = 2.0
"""How long a stopped child's output is still copied to ours, at most."""
_COLORS = ("\033[36m", "\033[32m", "\033[35m", "\033[33m", "\033[34m", "\033[91m",
           "\033[96m", "\033[92m")
_RESET = "\033[0m"


@dataclass
class Child:
    """One supervised process.

    Attributes:
        name: service name, used as log prefix and liveliness name.
        argv: the command line.
        env: extra environment variables.
    """

    name: str
    argv: list[str]
    env: dict[str, str] = field(default_factory=dict)
    proc: subprocess.Popen | None = None
    started_at: float = 0.0
    restarts: int = 0
    backoff_s: float = BACKOFF_FIRST_S
    restart_at: float | None = None
    forwarder: threading.Thread | None = None  # copies its output to ours
    gave_up: bool = False  # exited with a configuration error: not restarted


class Supervisor:
    """Starts, watches, restarts and stops a set of child processes.

    Args:
        children: in start order (router first).
        say: where the supervisor's own messages go.
        color: prefix child output with ANSI colours.
    """

    def __init__(self, children: list[Child], say: Callable[[str], None] | None = None,
                 color: bool = False):
        self.children = children
        self.stopping = threading.Event()
        self._out_lock = threading.Lock()
        self._say = say or self._default_say
        self._color = color

    def _default_say(self, text: str) -> None:
        self.emit("up", text, 0)

    def emit(self, name: str, line: str, index: int) -> None:
        """Writes one line with the child's name as prefix."""
        prefix = f"{name:>16} |"
        if self._color:
            prefix = f"{_COLORS[index % len(_COLORS)]}{prefix}{_RESET}"
        with self._out_lock:
            sys.stdout.write(f"{prefix} {line}\n")
            sys.stdout.flush()

    def start(self, child: Child) -> None:
        """Starts one child and a thread that forwards its output."""
        env = {**os.environ, "PYTHONUNBUFFERED": "1", **child.env}
        child.proc = subprocess.Popen(
            child.argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env,
            start_new_session=True, text=True, bufsize=1, errors="replace")
        child.started_at = time.monotonic()
        index = self.children.index(child)
        child.forwarder = threading.Thread(target=self._forward, args=(child, child.proc, index),
                                           daemon=True)
        child.forwarder.start()

    def _forward(self, child: Child, proc: subprocess.Popen, index: int) -> None:
        for line in proc.stdout:
            self.emit(child.name, line.rstrip("\n"), index + 1)

    def start_all(self) -> None:
        """Starts every child in order."""
        for child in self.children:
            self.start(child)

    def poll(self) -> list[tuple[Child, int]]:
        """Restarts children that exited (after their back-off); call it periodically.

        Returns:
            the children seen to exit in this call, with their exit codes.
        """
        now = time.monotonic()
        exited = []
        for child in self.children:
            if self.stopping.is_set():
                break
            if child.proc is None:  # not started yet
                continue
            if child.restart_at is not None:
                if now >= child.restart_at:
                    child.restart_at = None
                    child.restarts += 1
                    self._say(f"restarting {child.name} (restart #{child.restarts})")
                    self.start(child)
                continue
            code = child.proc.poll()
            if code is None or child.gave_up:
                continue
            exited.append((child, code))
            ran = now - child.started_at
            if code == EXIT_CONFIG:
                child.gave_up = True
                self._say(f"{child.name} exited with code {code} after {ran:.1f} s: a "
                          "configuration error, named in its log above; not restarting it (fix "
                          "the setting and start it again)")
                continue
            if ran >= BACKOFF_RESET_AFTER_S:
                child.backoff_s = BACKOFF_FIRST_S
            self._say(f"{child.name} exited with code {code} after {ran:.1f} s; "
                      f"restarting in {child.backoff_s:.1f} s")
            child.restart_at = now + child.backoff_s
            child.backoff_s = min(BACKOFF_MAX_S, child.backoff_s * 2)
        return exited

    def stop_all(self) -> None:
        """Stops services in reverse order, then the router: SIGTERM, then SIGKILL.

        Returns once every child's last lines are copied to our output (or after
        `DRAIN_S` for one whose output stays open: a grandchild may hold it).
        """
        self.stopping.set()
        for child in reversed(self.children):
            self._stop(child)
        for child in self.children:
            if child.forwarder is not None:
                child.forwarder.join(DRAIN_S)

    def _stop(self, child: Child) -> None:
        proc = child.proc
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            self._say(f"{child.name} did not stop within {STOP_GRACE_S:g} s; killing it")
            proc.kill()
            proc.wait()


class AliveWatcher:
    """Tracks the liveliness tokens of our own processes; reports readiness, losses, strangers.

    The caller tells it only about tokens it has checked are ours (`on_token`), and about the
    ones of the same names that are not (`on_stranger`), so "ready" means that every expected
    process is alive on this system, not that something of that name answers somewhere.

    Args:
        expected: the names that must be alive.
        say: where to report.
        since: monotonic time the processes were started (readiness is timed from it).
    """

    def __init__(self, expected: list[str], say: Callable[[str], None],
                 since: float | None = None):
        self.expected = set(expected)
        self.alive: set[str] = set()
        self.ready = threading.Event()
        self._say = say
        self._t0 = time.monotonic() if since is None else since
        self._lock = threading.Lock()
        self._strangers: set[tuple[str, str]] = set()

    def on_token(self, name: str, present: bool) -> None:
        """Called for each liveliness change of a service."""
        with self._lock:
            if present and name not in self.alive:
                self.alive.add(name)
                if self.ready.is_set():
                    self._say(f"{name} is alive again")
            elif not present and name in self.alive:
                self.alive.discard(name)
                self._say(f"{name} lost its liveliness token")
            if not self.ready.is_set() and self.expected <= self.alive:
                self.ready.set()
                self._say(f"ready: {', '.join(sorted(self.expected))} alive after "
                          f"{time.monotonic() - self._t0:.1f} s")

    def on_stranger(self, name: str, who: str) -> None:
        """Reports, once, a process of an expected name that we did not start (not counted).

        Args:
            name: the service name of its token.
            who: how to find it, e.g. "pid 4242 on host robot-pc".
        """
        with self._lock:
            if (name, who) in self._strangers:
                return
            self._strangers.add((name, who))
        self._say(f"a {name} that this `cbgo up` did not start is on the router ({who}); it is "
                  f"not counted as ours, and two {name} processes would answer the same keys: "
                  "stop one of them")

    def missing(self) -> list[str]:
        """Returns the expected names without a token."""
        with self._lock:
            return sorted(self.expected - self.alive)
