"""deploy/compose.yaml and its overrides on a real Docker engine (`make test-compose`).

`make test-compose` (deploy/ci/compose-test.sh) starts the engine, builds the image (or reuses
it, by a hash of its inputs) and runs this module with ``CBGO_COMPOSE_TAG`` set to its tag;
without that, every test here is skipped. Each class is one compose project of its own (own
name, own volumes, the router published on a free port), brought up with ``up -d --wait``
(every healthcheck healthy) and taken down with ``down -v`` at the end of the class:

- the default project: every container healthy; the demo's scripted session against the
  published port, 7/7; a crashed container restarted by its restart policy and back in the
  cell; a `docker kill`-ed one (a manual stop, which restart policies ignore) back after
  ``docker compose up -d``;
- the dry-robot override: dry-robot instead of mujoco-sim, and the session 7/7 on it;
- the TLS override with certificates from `cbgo certs make`: every container healthy over TLS,
  the CLI in as ``operator`` over TLS, plain TCP refused on the published port;
- two projects as two hosts: the robot in a second project that reaches the first's router only
  through the host's published port (deploy/compose.remote.yaml); the session 7/7 through it.

The figures (seconds to healthy, demo, restart) are printed, never asserted: run with ``-s``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

from cbgo import registry
from cbgo.testing import Stack, free_port

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
TAG = os.environ.get("CBGO_COMPOSE_TAG", "")
CLI = [sys.executable, "-m", "cbgo.cli.main"]
DEFAULTS = ["router", *(s.name for s in registry.defaults())]
UP_TIMEOUT_S = 420
CONTAINER_UID = "10001"  # deploy/Dockerfile's user, who must own the keys it reads

pytestmark = [
    pytest.mark.skipif(not TAG, reason="needs a Docker engine and cbgo's image: run "
                                       "`make test-compose` (deploy/ci/compose-test.sh)"),
    pytest.mark.timeout(1200),
]


def figure(text: str) -> None:
    """Prints a measured figure (shown with -s, and in CI's log)."""
    print(f"\n[compose figure] {text}", flush=True)


class Project:
    """One compose project from deploy/compose.yaml plus overrides, on its own port."""

    def __init__(self, tmp: Path, *overrides: str, env: dict[str, str] | None = None):
        self.name = f"cbgo-test-{uuid.uuid4().hex[:8]}"
        self.port = free_port()
        self.files = [DEPLOY / "compose.yaml", *(DEPLOY / o for o in overrides)]
        self.tmp = tmp
        # web's page on a free host port too, so projects (and a running cbgo) never clash
        self.web_port = free_port()
        self.env = {**os.environ, "CBGO_TAG": TAG, "CBGO_PORT": str(self.port),
                    "CBGO_WEB_PORT": str(self.web_port), **(env or {})}
        self.endpoint = f"tcp/127.0.0.1:{self.port}"

    def compose(self, *args: str, check: bool = True, timeout: float = UP_TIMEOUT_S + 60):
        argv = ["docker", "compose", "-p", self.name]
        for f in self.files:
            argv += ["-f", str(f)]
        done = subprocess.run([*argv, *args], capture_output=True, text=True, env=self.env,
                              timeout=timeout)
        if check and done.returncode != 0:
            raise AssertionError(f"docker compose {' '.join(args)} exited {done.returncode}:\n"
                                 f"{done.stdout}\n{done.stderr}\n{self.logs()}")
        return done

    def up(self, *services: str, flags: tuple[str, ...] = ()) -> float:
        """``up -d --wait``: returns the seconds until every started container is healthy."""
        t0 = time.monotonic()
        self.compose("up", "-d", "--wait", "--wait-timeout", str(UP_TIMEOUT_S), "--no-build",
                     "--pull", "never", *flags, *services)
        return time.monotonic() - t0

    def down(self) -> None:
        self.compose("down", "-v", "--remove-orphans", "-t", "5", check=False)
        left = subprocess.run(["docker", "volume", "ls", "-q", "--filter",
                               f"label=com.docker.compose.project={self.name}"],
                              capture_output=True, text=True).stdout.split()
        assert left == [], f"volumes left after down -v: {left}"

    def logs(self, tail: int = 30) -> str:
        argv = ["docker", "compose", "-p", self.name]
        for f in self.files:
            argv += ["-f", str(f)]
        done = subprocess.run([*argv, "logs", "--no-color", "--tail", str(tail)],
                              capture_output=True, text=True, env=self.env, timeout=60)
        return done.stdout[-20000:]

    def containers(self) -> dict[str, dict]:
        """Service name -> `docker inspect` of its container (the project's containers only)."""
        ids = self.compose("ps", "-a", "-q").stdout.split()
        if not ids:
            return {}
        data = json.loads(subprocess.run(["docker", "inspect", *ids], capture_output=True,
                                         text=True, check=True).stdout)
        return {c["Config"]["Labels"]["com.docker.compose.service"]: c for c in data}

    def health(self) -> dict[str, str]:
        return {name: c["State"].get("Health", {}).get("Status", c["State"]["Status"])
                for name, c in self.containers().items()}

    def cli(self, *args: str, timeout: float = 60, env: dict[str, str] | None = None,
            connect: str | None = None):
        """Runs a `cbgo` verb on the host against the published port."""
        return subprocess.run([*CLI, *args, "--connect", connect or self.endpoint],
                              capture_output=True, text=True, timeout=timeout,
                              env={**os.environ, **(env or {})})

    def watcher(self) -> Stack:
        """A Zenoh session of the test on the published port (liveliness tokens, queries)."""
        stack = Stack(self.tmp)
        stack.endpoint = self.endpoint
        return stack

    def wait_healthy(self, service: str, timeout: float = UP_TIMEOUT_S) -> float:
        """Waits until `service`'s container is running and healthy; returns the seconds."""
        t0 = time.monotonic()
        while True:
            state = self.containers()[service]["State"]
            if state["Running"] and state.get("Health", {}).get("Status") == "healthy":
                return time.monotonic() - t0
            if time.monotonic() - t0 > timeout:
                raise AssertionError(f"{service} not healthy after {timeout} s: {state}\n"
                                     + self.logs())
            time.sleep(0.5)


def run_demo(project: Project, out: Path, *flags: str, env: dict[str, str] | None = None,
             connect: str | None = None):
    """The scripted session against the project's services; returns (seconds, output, result).

    Played once: a session that does not end 7/7 fails the test. (It used to be played twice,
    because a stalled simulated sensor left a gap in the frames' stamps that split a gesture
    into two episodes; leap-bridge now stamps a scheduled frame with its deadline, see
    deploy/README.md.)
    """
    t0 = time.monotonic()
    done = project.cli("demo", "--no-start", "-o", str(out / "run"), *flags,
                       timeout=900, env=env, connect=connect)
    seconds = time.monotonic() - t0
    text = done.stdout + done.stderr
    if done.returncode != 0:
        problems = [line.strip() for line in text.splitlines() if "NOT as scripted" in line]
        raise AssertionError(f"cbgo demo against {project.name} did not end as scripted: "
                             f"{problems}\n{text[-4000:]}\n{project.logs()}")
    return seconds, text, json.loads((out / "run" / "result.json").read_text())


def steps_as_scripted(result: dict) -> tuple[int, int]:
    steps = result["steps"]
    return sum(1 for s in steps if s.get("ok")), len(steps)


def service_pid_on_host(container: dict) -> int:
    """The host pid of the service process: the child of the container's init (tini)."""
    init = container["State"]["Pid"]
    children = Path(f"/proc/{init}/task/{init}/children").read_text().split()
    assert len(children) == 1, f"init {init} has children {children}"
    return int(children[0])


# --- the default project ------------------------------------------------------------------------


@pytest.fixture(scope="class")
def default_project(tmp_path_factory):
    project = Project(tmp_path_factory.mktemp("default"))
    try:
        seconds = project.up()
        figure(f"default project: up -d to all {len(DEFAULTS)} containers healthy in "
               f"{seconds:.1f} s")
        yield project
    finally:
        project.down()


class TestDefaultProject:
    def test_every_container_of_the_default_set_is_healthy(self, default_project):
        assert default_project.health() == dict.fromkeys(DEFAULTS, "healthy")
        alive = default_project.cli("wait-alive", *DEFAULTS, "--timeout", "30")
        assert alive.returncode == 0, alive.stderr

    def test_the_scripted_session_passes_against_the_containers(self, default_project, tmp_path):
        seconds, text, result = run_demo(default_project, tmp_path / "demo")
        ok, total = steps_as_scripted(result)
        assert (ok, total) == (7, 7), text
        figure(f"demo against the containers (mujoco-sim): {ok}/{total} as scripted, "
               f"cbgo demo took {seconds:.1f} s")

    def test_a_crashed_service_is_restarted_by_its_policy_and_rejoins(self, default_project):
        before = default_project.containers()["planner"]
        with default_project.watcher() as watch:
            watch.wait_alive(["planner"])
            os.kill(service_pid_on_host(before), 9)  # the service's process dies, as in a crash
            t0 = time.monotonic()
            watch.wait_gone("planner")
            watch.wait_alive(["planner"], timeout=120)
            token_s = time.monotonic() - t0
            default_project.wait_healthy("planner")
            healthy_s = time.monotonic() - t0
            watch.status("planner")  # answers its status query: back in the cell
        after = default_project.containers()["planner"]
        assert after["State"]["StartedAt"] != before["State"]["StartedAt"]
        assert after["RestartCount"] == before["RestartCount"] + 1
        figure(f"planner's process killed (kill -9): restarted by the restart policy, its "
               f"liveliness token back {token_s:.1f} s after the kill, the container healthy "
               f"again after {healthy_s:.1f} s (healthcheck every 30 s)")

    def test_a_docker_killed_service_stays_down_until_compose_up_brings_it_back(
            self, default_project):
        name = default_project.containers()["intent"]["Name"].lstrip("/")
        with default_project.watcher() as watch:
            watch.wait_alive(["intent"])
            subprocess.run(["docker", "kill", name], check=True, capture_output=True)
            watch.wait_gone("intent")
            # A manual stop (docker kill, docker stop) is not a failure: no restart policy
            # applies, so it stays down.
            state = default_project.containers()["intent"]
            assert not state["State"]["Running"] and state["RestartCount"] == 0
            assert "intent" not in watch.alive()
            t0 = time.monotonic()
            default_project.up("intent")
            seconds = time.monotonic() - t0
            watch.wait_alive(DEFAULTS)
        figure(f"intent after docker kill: healthy {seconds:.1f} s after "
               "`docker compose up -d --wait intent`")


# --- the dry-robot override ---------------------------------------------------------------------


@pytest.fixture(scope="class")
def dry_project(tmp_path_factory):
    project = Project(tmp_path_factory.mktemp("dry"), "compose.dry-robot.yaml")
    try:
        seconds = project.up()
        figure(f"dry-robot override: up -d to all healthy in {seconds:.1f} s")
        yield project
    finally:
        project.down()


class TestDryRobotOverride:
    def test_dry_robot_runs_instead_of_mujoco_sim(self, dry_project):
        expected = [n if n != "mujoco-sim" else "dry-robot" for n in DEFAULTS]
        assert dry_project.health() == dict.fromkeys(expected, "healthy")

    def test_the_scripted_session_passes_on_dry_robot(self, dry_project, tmp_path):
        seconds, text, result = run_demo(dry_project, tmp_path / "demo", "--robot", "dry")
        ok, total = steps_as_scripted(result)
        assert (ok, total) == (7, 7), text
        figure(f"demo against the dry-robot override: {ok}/{total}, {seconds:.1f} s")


# --- the TLS override ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    if shutil.which("openssl") is None:
        pytest.fail("cbgo certs make needs openssl")
    root = tmp_path_factory.mktemp("certs") / "certs"
    done = subprocess.run([*CLI, "certs", "make", str(root)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    # The containers run as uid 10001 and must own their 0600 keys (deploy/README.md).
    for name in [*DEFAULTS, "dry-robot"]:
        for path in [root / name, *(root / name).iterdir()]:
            shutil.chown(path, int(CONTAINER_UID), int(CONTAINER_UID))
    os.chmod(root, 0o755)
    operator = root / "operator"
    config = (DEPLOY / "tls" / "client.json5").read_text().replace("/run/secrets/cbgo-tls",
                                                                   str(operator))
    (operator / "zenoh.json5").write_text(config)
    return root


@pytest.fixture(scope="class")
def tls_project(tmp_path_factory, certs):
    if os.geteuid() != 0:
        pytest.skip("giving the keys to the containers' uid needs root")
    project = Project(tmp_path_factory.mktemp("tls"), "compose.tls.yaml",
                      env={"CBGO_CERTS": str(certs)})
    try:
        seconds = project.up()
        figure(f"TLS override: up -d to all healthy in {seconds:.1f} s")
        yield project
    finally:
        project.down()


class TestTlsOverride:
    def test_every_container_is_healthy_over_tls(self, tls_project):
        assert tls_project.health() == dict.fromkeys(DEFAULTS, "healthy")

    def test_the_operator_certificate_gets_in_over_tls(self, tls_project, certs):
        env = {"ZENOH_CONFIG": str(certs / "operator" / "zenoh.json5")}
        tls = f"tls/127.0.0.1:{tls_project.port}"
        alive = tls_project.cli("wait-alive", *DEFAULTS, "--timeout", "30", env=env, connect=tls)
        assert alive.returncode == 0, alive.stdout + alive.stderr
        listing = tls_project.cli("ls", env=env, connect=tls)
        assert listing.returncode == 0, listing.stderr
        for name in DEFAULTS:
            assert name in listing.stdout

    def test_plain_tcp_is_refused_on_the_published_port(self, tls_project):
        plain = tls_project.cli("wait-alive", "router", "--timeout", "3", "--connect-timeout", "3")
        assert plain.returncode != 0, plain.stdout


# --- two projects as two hosts ------------------------------------------------------------------


@pytest.fixture(scope="class")
def remote_projects(tmp_path_factory):
    brain = Project(tmp_path_factory.mktemp("brain"))
    robot = None
    try:
        brain.up(*[n for n in DEFAULTS if n != "mujoco-sim"])
        robot = Project(tmp_path_factory.mktemp("robot"), "compose.dry-robot.yaml",
                        "compose.remote.yaml",
                        env={"CBGO_ROUTER": f"tcp/host.docker.internal:{brain.port}"})
        seconds = robot.up("dry-robot", flags=("--no-deps",))
        figure(f"second project (dry-robot only, joining the first's router through the "
               f"host's port): healthy in {seconds:.1f} s")
        yield brain, robot
    finally:
        if robot is not None:
            robot.down()
        brain.down()


class TestRemoteRouter:
    """The robot in a second project that knows the first only by the host's published port."""

    def test_the_second_project_runs_only_the_robot(self, remote_projects):
        brain, robot = remote_projects
        assert robot.health() == {"dry-robot": "healthy"}
        assert "dry-robot" not in brain.health() and "router" in brain.health()
        alive = brain.cli("wait-alive", "dry-robot", "--timeout", "30")
        assert alive.returncode == 0, alive.stderr

    def test_the_scripted_session_passes_across_the_two_projects(self, remote_projects, tmp_path):
        brain, _ = remote_projects
        seconds, text, result = run_demo(brain, tmp_path / "demo", "--robot", "dry")
        ok, total = steps_as_scripted(result)
        assert (ok, total) == (7, 7), text
        figure(f"demo across two projects (the robot in the second): {ok}/{total}, {seconds:.1f} s")
