"""The paper's session with the router and the services on three hosts (network namespaces).

Each host is a Linux network namespace with its own address and host name; a fifth namespace
holds the bridge (the "switch") that joins them, so nothing touches the root namespace's
interfaces or routes, and the fixed subnet cannot collide with the machine's own. The hosts
are placed as deploy/README.md ("Several machines") recommends:

    brain   10.213.0.1  cbgo up --listen tcp/10.213.0.1:7447 intent planner
    sensor  10.213.0.2  cbgo up --connect ... leap-bridge static/dynamic-gesture episode
    robot   10.213.0.3  cbgo up --connect ... dry-robot
    console 10.213.0.4  cbgo wait-alive / ls / get / demo --no-start, like an operator's laptop

The router listens on the cell's address only because it is told to: by default (`cbgo router`,
`cbgo up`) it listens on loopback, and another host's connection is refused.

Needs root, `ip` (iproute2) and `unshare` (util-linux); skipped with the reason otherwise.
"""

import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

PORT = 7447  # the documented port: inside the brain namespace it collides with nothing
ROUTER = f"tcp/10.213.0.1:{PORT}"
CLI = [sys.executable, "-m", "cbgo.cli.main"]


@dataclass
class Host:
    """One machine of the cell: a network namespace with an address and a host name."""

    name: str
    address: str
    services: list[str]
    netns: str = ""
    up: subprocess.Popen | None = None
    log: Path | None = None

    @property
    def hostname(self) -> str:
        return f"{self.name}-host"


def cell_hosts() -> dict[str, Host]:
    """The placement under test (the router goes with the brain)."""
    return {h.name: h for h in (
        Host("brain", "10.213.0.1", ["intent", "planner"]),
        Host("sensor", "10.213.0.2",
             ["leap-bridge", "static-gesture", "dynamic-gesture", "episode"]),
        Host("robot", "10.213.0.3", ["dry-robot"]),
        Host("console", "10.213.0.4", []),
    )}


def ip(*args: str) -> None:
    """Runs `ip ARGS`, raising CalledProcessError with ip's message."""
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True, timeout=30)


@dataclass
class Cell:
    """The namespaces, the bridge between them and the `cbgo up` running in them."""

    workdir: Path
    hosts: dict[str, Host] = field(default_factory=cell_hosts)
    suffix: str = field(default_factory=lambda: secrets.token_hex(3))
    created: list[str] = field(default_factory=list)

    @property
    def switch(self) -> str:
        return f"cbgo-switch-{self.suffix}"

    def build(self) -> None:
        """Creates the switch namespace with a bridge, and one namespace a host, cabled in."""
        self._add_netns(self.switch)
        ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
        ip("-n", self.switch, "link", "set", "br0", "up")
        for host in self.hosts.values():
            host.netns = f"cbgo-{host.name}-{self.suffix}"
            self._add_netns(host.netns)
            self._cable(host)

    def _add_netns(self, name: str) -> None:
        ip("netns", "add", name)
        self.created.append(name)
        ip("-n", name, "link", "set", "lo", "up")

    def _cable(self, host: Host) -> None:
        # Both ends are created inside namespaces: no interface ever appears in the root one.
        port = f"to-{host.name}"
        ip("-n", self.switch, "link", "add", port, "type", "veth",
           "peer", "name", "eth0", "netns", host.netns)
        ip("-n", self.switch, "link", "set", port, "master", "br0", "up")
        ip("-n", host.netns, "addr", "add", f"{host.address}/24", "dev", "eth0")
        ip("-n", host.netns, "link", "set", "eth0", "up")

    def argv_in(self, host: Host, argv: list[str]) -> list[str]:
        """`argv` run on `host`: in its network namespace, under its own host name."""
        # A private UTS namespace gives each host its name, which services report as "host".
        return ["ip", "netns", "exec", host.netns, "unshare", "--uts", "sh", "-c",
                'hostname "$0" && exec "$@"', host.hostname, *argv]

    def env(self, host: Host) -> dict[str, str]:
        """The environment `cbgo demo` gives the services it starts (cli/demo.py)."""
        return {**os.environ, "PYTHONUNBUFFERED": "1", "CBGO_ACCEPT_REPAIRABLE": "true",
                "CBGO_DATA_DIR": str(self.workdir / host.name / "data")}

    def start_up(self, host: Host, *flags: str) -> None:
        """Starts `cbgo up FLAGS SERVICES` on `host`; its log goes to <workdir>/<host>.log."""
        host.log = self.workdir / f"{host.name}.log"
        with open(host.log, "wb") as log:
            host.up = subprocess.Popen(
                self.argv_in(host, [*CLI, "up", "--no-color", *flags, *host.services]),
                stdout=log, stderr=subprocess.STDOUT, env=self.env(host),
                start_new_session=True)

    def run(self, host: Host, argv: list[str], timeout: float) -> subprocess.CompletedProcess:
        """Runs a cbgo command on `host` to its end; its output is returned as text."""
        return subprocess.run(self.argv_in(host, [*CLI, *argv]), capture_output=True,
                              text=True, timeout=timeout, env=self.env(host))

    def stop(self) -> dict[str, int | None]:
        """SIGTERMs every `cbgo up` (they stop their children); returns their exit codes."""
        running = [h for h in self.hosts.values() if h.up is not None]
        for host in running:
            if host.up.poll() is None:
                host.up.send_signal(signal.SIGTERM)
        return {host.name: self._wait_or_kill(host.up) for host in running}

    @staticmethod
    def _wait_or_kill(proc: subprocess.Popen) -> int | None:
        try:
            return proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return None

    def teardown(self) -> None:
        """Stops what is left and deletes every namespace (their veths and bridge go too)."""
        self.stop()
        for name in reversed(self.created):
            for pid in netns_pids(name):  # a child that outlived its `cbgo up`
                os.kill(pid, signal.SIGKILL)
            subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=30)

    def logs(self) -> str:
        """The tail of every host's `cbgo up` log, for failure messages."""
        return "\n".join(f"--- {h.name}\n{h.log.read_text(errors='replace')[-3000:]}"
                         for h in self.hosts.values() if h.log is not None)


def netns_pids(netns: str) -> list[int]:
    """The processes running in a network namespace."""
    done = subprocess.run(["ip", "netns", "pids", netns], capture_output=True, text=True,
                          timeout=10)
    return [int(pid) for pid in done.stdout.split()]


def _why_no_namespaces() -> str | None:
    if os.geteuid() != 0:
        return "network namespaces need root"
    for tool in ("ip", "unshare"):
        if shutil.which(tool) is None:
            return f"`{tool}` is not installed"
    return None


@pytest.fixture
def cell(tmp_path):
    """Three hosts and a console on one bridge; always stopped and deleted at the end."""
    reason = _why_no_namespaces()
    if reason:
        pytest.skip(reason)
    cell = Cell(tmp_path)
    try:
        try:
            cell.build()
        except subprocess.CalledProcessError as e:
            pytest.skip(f"cannot create the namespaces: `{' '.join(e.cmd)}`: {e.stderr.strip()}")
        yield cell
    finally:
        cell.teardown()


def start_services(cell: Cell) -> None:
    """Starts the router and the brain's services first, then the hosts that join it."""
    hosts = cell.hosts
    cell.start_up(hosts["brain"], "--listen", ROUTER)
    for name in ("sensor", "robot"):
        cell.start_up(hosts[name], "--connect", ROUTER)


def service_hosts(cell: Cell) -> dict[str, Host]:
    """{service: the host it was placed on}, the router included."""
    placed = {"router": cell.hosts["brain"]}
    for host in cell.hosts.values():
        placed.update({name: host for name in host.services})
    return placed


def wait_alive(cell: Cell, names: list[str]) -> None:
    """Waits, from the console, until every service's liveliness token is at the router."""
    # The router may still be starting on a loaded machine: the console waits for it too.
    done = cell.run(cell.hosts["console"], ["wait-alive", *names, "--timeout", "90",
                                            "--connect", ROUTER, "--connect-timeout", "60"],
                    timeout=180)
    assert done.returncode == 0, f"{done.stdout}{done.stderr}\n{cell.logs()}"


def json_lines(cell: Cell, argv: list[str]) -> list[dict]:
    """Runs a cbgo command with --json on the console; returns its JSON lines."""
    done = cell.run(cell.hosts["console"], [*argv, "--json", "--connect", ROUTER], timeout=60)
    assert done.returncode == 0, f"{done.stdout}{done.stderr}"
    return [json.loads(line) for line in done.stdout.splitlines() if line.strip()]


def client_addresses(cell: Cell) -> dict[str, str]:
    """{zenoh session id: the IP address its link to the router comes from}."""
    (router,) = json_lines(cell, ["get", "@/*/router"])
    assert router["reply"]["locators"] == [ROUTER]
    return {s["peer"]: s["links"][0]["dst"].split("/")[1].rsplit(":", 1)[0]
            for s in router["reply"]["sessions"]}


def netns_of(pid: int) -> str:
    done = subprocess.run(["ip", "netns", "identify", str(pid)], capture_output=True,
                          text=True, timeout=10, check=True)
    return done.stdout.strip()


@pytest.mark.timeout(300)  # a hang guard for a loaded machine; a normal run takes about a minute
def test_the_session_runs_with_router_and_services_on_three_hosts(cell, tmp_path):
    placed = service_hosts(cell)
    start_services(cell)
    wait_alive(cell, list(placed))
    brain_log = cell.hosts["brain"].log.read_text(errors="replace")
    assert f"listening on {ROUTER} without TLS" in brain_log  # reachable: warned, with the fix
    assert "cbgo certs" in brain_log

    records = {r["name"]: r for r in json_lines(cell, ["ls"])}
    assert set(records) == set(placed), cell.logs()
    addresses = client_addresses(cell)
    for name, host in placed.items():
        record = records[name]
        assert record["host"] == host.hostname, (name, record)
        assert netns_of(record["pid"]) == host.netns, (name, record)
        if name != "router":  # the router is the listener, not one of its own clients
            assert addresses[record["zid"]] == host.address, (name, record)

    out = tmp_path / "demo"
    demo = cell.run(cell.hosts["console"],
                    ["demo", "--no-start", "--connect", ROUTER, "--robot", "dry",
                     "--ready-timeout", "30", "-o", str(out)], timeout=180)
    assert demo.returncode == 0, f"{demo.stdout[-4000:]}{demo.stderr[-2000:]}\n{cell.logs()}"
    steps = json.loads((out / "result.json").read_text())["steps"]
    assert steps and all(s["ok"] for s in steps), steps

    assert cell.stop() == {"brain": 0, "sensor": 0, "robot": 0}, cell.logs()
    left = {h.name: netns_pids(h.netns) for h in cell.hosts.values()}
    assert left == {h: [] for h in left}, "`cbgo up` left processes behind"


def tcp_connect(cell: Cell, host: Host, address: str, port: int) -> str:
    """Opens a TCP connection from `host`; returns "connected" or the error's class name."""
    probe = ("import socket, sys\n"
             "try:\n"
             "    socket.create_connection((sys.argv[1], int(sys.argv[2])), timeout=5).close()\n"
             "    print('connected')\n"
             "except OSError as e:\n"
             "    print(type(e).__name__)\n")
    done = subprocess.run(cell.argv_in(host, [sys.executable, "-c", probe, address, str(port)]),
                          capture_output=True, text=True, timeout=30)
    return done.stdout.strip() or done.stderr.strip()


@pytest.mark.timeout(120)
def test_a_default_router_is_refused_from_another_host(cell):
    brain, console = cell.hosts["brain"], cell.hosts["console"]
    log = cell.workdir / "router.log"
    with open(log, "wb") as out:
        router = subprocess.Popen(cell.argv_in(brain, [*CLI, "router"]), stdout=out,
                                  stderr=subprocess.STDOUT, env=cell.env(brain),
                                  start_new_session=True)
    try:
        here = cell.run(brain, ["wait-alive", "router", "--timeout", "60", "--connect",
                                f"tcp/127.0.0.1:{PORT}"], timeout=90)
        assert here.returncode == 0, f"{here.stdout}{here.stderr}\n{log.read_text()}"
        assert tcp_connect(cell, brain, "127.0.0.1", PORT) == "connected"
        assert tcp_connect(cell, console, brain.address, PORT) == "ConnectionRefusedError"
        there = cell.run(console, ["ls", "--connect", f"tcp/{brain.address}:{PORT}",
                                   "--connect-timeout", "3"], timeout=60)
        assert there.returncode != 0 and "router" not in there.stdout
        assert "without TLS" not in log.read_text()  # loopback: nothing to warn about
    finally:
        if router.poll() is None:
            router.send_signal(signal.SIGTERM)
        Cell._wait_or_kill(router)
