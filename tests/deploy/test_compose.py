"""The deployment files: compose.yaml, the Dockerfile and the Zenoh configs in deploy/.

There is no Docker engine in CI, so `docker compose config` is not run: the compose file is
parsed with PyYAML (which resolves the anchors and merge keys) and checked against the
contract — the service set of `cbgo.registry`, client mode through the router, healthchecks
through liveliness tokens — and every command it runs must be a real entry point of the package.
Override files (``deploy/compose.*.yaml``) are merged onto it with Compose's merge rules
(mappings merged, lists appended, ``command`` replaced, ``!reset``/``!override`` honoured) and
the result is checked the same way: which services start by default, and never two robots.
"""

from __future__ import annotations

import importlib.metadata
import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from cbgo import registry
from cbgo.registry import ROUTER, SERVICES

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
COMPOSE_FILE = DEPLOY / "compose.yaml"
OVERRIDES = sorted(DEPLOY.glob("compose.*.yaml"))
SERVICE_NAMES = [s.name for s in SERVICES]
DEFAULT_NAMES = [s.name for s in registry.defaults()]
ROUTER_ENDPOINT = "tcp/router:7447"
REPLACED_LISTS = {"command", "entrypoint", "test"}  # Compose replaces these instead of appending


class _Reset:
    """``!reset``: the key is removed from the merged file."""


class _Override:
    """``!override VALUE``: VALUE replaces the base file's instead of merging with it."""

    def __init__(self, value):
        self.value = value


class ComposeLoader(yaml.SafeLoader):
    """PyYAML's safe loader plus Compose's merge tags."""


def _tag(constructor):
    def construct(loader, node):
        if isinstance(node, yaml.MappingNode):
            return constructor(loader.construct_mapping(node, deep=True))
        if isinstance(node, yaml.SequenceNode):
            return constructor(loader.construct_sequence(node, deep=True))
        return constructor(loader.construct_scalar(node))
    return construct


ComposeLoader.add_constructor("!reset", _tag(lambda _value: _Reset()))
ComposeLoader.add_constructor("!override", _tag(_Override))


def merge(base, override, key: str = ""):
    """Returns `override` merged onto `base` by Compose's rules (the subset these files use)."""
    if isinstance(override, _Override):
        return override.value
    if isinstance(base, dict) and isinstance(override, dict):
        out = dict(base)
        for k, v in override.items():
            if isinstance(v, _Reset):
                out.pop(k, None)
            else:
                out[k] = merge(base[k], v, k) if k in base else _plain(v)
        return out
    if isinstance(base, list) and isinstance(override, list) and key not in REPLACED_LISTS:
        return base + [v for v in override if v not in base]
    return _plain(override)


def _plain(value):
    """Returns a value with its merge tags applied (a new key has nothing to merge with)."""
    if isinstance(value, _Override):
        return value.value
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if not isinstance(v, _Reset)}
    return value


def started_by_default(services: dict) -> set[str]:
    """Returns the services `docker compose up` starts with no --profile: those without one."""
    return {name for name, service in services.items() if not service.get("profiles")}


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load(COMPOSE_FILE.read_text())


@pytest.fixture(scope="module")
def services(compose) -> dict:
    return compose["services"]


@pytest.fixture(scope="module")
def project_scripts() -> dict[str, str]:
    data = tomllib.loads((REPO / "pyproject.toml").read_text())
    return data["project"].get("scripts", {})


@pytest.fixture(scope="module")
def installed_scripts() -> dict[str, importlib.metadata.EntryPoint]:
    eps = importlib.metadata.entry_points(group="console_scripts")
    return {ep.name: ep for ep in eps if ep.dist is not None and ep.dist.name == "cbgo"}


def environment(service: dict) -> dict[str, str]:
    """Returns a service's environment as a mapping (compose allows a list of KEY=VALUE)."""
    env = service.get("environment") or {}
    if isinstance(env, list):
        env = dict(item.split("=", 1) if "=" in item else (item, None) for item in env)
    return {str(k): None if v is None else str(v) for k, v in env.items()}


def published_ports(service: dict) -> list[tuple[str, str]]:
    """Returns (host port, container port) pairs, from the short or the long syntax."""
    pairs = []
    for port in service.get("ports", []):
        if isinstance(port, dict):
            pairs.append((str(port.get("published")), str(port.get("target"))))
        else:
            parts = str(port).split("/")[0].split(":")
            pairs.append((parts[-2] if len(parts) > 1 else "", parts[-1]))
    return pairs


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=60,
                          cwd=REPO)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# --- the shape of the compose file -------------------------------------------------------------


def test_the_compose_file_has_the_shape_of_the_compose_spec(compose):
    allowed = {"services", "volumes", "networks", "configs", "secrets", "name", "include"}
    unknown = {k for k in compose if k not in allowed and not k.startswith("x-")}
    assert not unknown, f"top-level keys outside the compose spec: {unknown}"
    assert isinstance(compose.get("services"), dict) and compose["services"]
    assert isinstance(compose.get("volumes"), dict)
    for name, service in compose["services"].items():
        assert "build" in service or "image" in service, f"{name} has neither build nor image"
        assert isinstance(service.get("command"), list), f"{name}: command must be a list"
        for dep in service.get("depends_on", {}):
            assert dep in compose["services"], f"{name} depends on unknown service {dep}"
        for mount in service.get("volumes", []):
            source = mount["source"] if isinstance(mount, dict) else mount.split(":")[0]
            if not source.startswith((".", "/", "~")):
                assert source in compose["volumes"], f"{name} mounts undeclared volume {source}"


def test_the_services_are_the_router_and_every_service_of_the_registry(services):
    assert set(services) == {ROUTER, *SERVICE_NAMES}


def test_only_the_router_and_the_default_services_start_by_default(services):
    # An alternative (dry-robot) answers the same keys as the service it replaces: starting
    # both would put two answers on cbgo/robot/act. It sits under a profile until swapped in.
    assert started_by_default(services) == {ROUTER, *DEFAULT_NAMES}
    for info in SERVICES:
        if info.replaces or info.optional:
            assert services[info.name].get("profiles"), f"{info.name} needs a profile"


def test_every_container_runs_the_one_image_built_from_the_dockerfile(services):
    images = {service.get("image") for service in services.values()}
    assert len(images) == 1, f"one image for all services, got {images}"
    for name, service in services.items():
        build = service["build"]
        context = (COMPOSE_FILE.parent / build["context"]).resolve()
        assert context == REPO, f"{name}: build context must be the repository root"
        assert (context / build["dockerfile"]).resolve() == DEPLOY / "Dockerfile"
    assert (DEPLOY / "Dockerfile").is_file()
    assert (REPO / ".dockerignore").is_file()


def test_every_service_is_a_zenoh_client_of_the_router(services):
    for name in SERVICE_NAMES:
        env = environment(services[name])
        assert env.get("ZENOH_CONNECT") == ROUTER_ENDPOINT, name
        assert env.get("ZENOH_MODE") == "client", name
        assert env.get("CBGO_PREFIX") == "${CBGO_PREFIX:-cbgo}", name
        assert env.get("CBGO_LOG_FORMAT") == "json", name


def test_the_router_keeps_its_router_mode_and_shares_the_prefix(services):
    # The environment wins over the router's defaults: ZENOH_MODE=client or a ZENOH_CONNECT
    # to itself would break it.
    env = environment(services[ROUTER])
    # Listening on every interface is explicit: the router's own default is loopback, which
    # the other containers and the published port could not reach.
    assert services[ROUTER]["command"] == ["cbgo", "router", "--listen", "tcp/0.0.0.0:7447"]
    assert "ZENOH_MODE" not in env and "ZENOH_CONNECT" not in env
    assert env.get("CBGO_PREFIX") == "${CBGO_PREFIX:-cbgo}"
    assert env.get("CBGO_LOG_FORMAT") == "json"


def test_the_router_publishes_port_7447_on_the_host(services):
    # The host's port is CBGO_PORT, 7447 by default.
    assert ("${CBGO_PORT:-7447}", "7447") in published_ports(services[ROUTER])
    for name in SERVICE_NAMES:
        if name in ("web", "foxglove-bridge"):
            continue
        assert not services[name].get("ports"), f"{name} is a client and listens on nothing"


def test_web_publishes_its_page_on_the_hosts_loopback_and_no_zenoh_port(services):
    # web is a Zenoh client like the others; its one port is the page's HTTP port, published
    # on 127.0.0.1 by default because the page can stop the robot.
    web = services["web"]
    assert published_ports(web) == [("${CBGO_WEB_PORT:-8080}", "8080")]
    assert web["ports"][0]["host_ip"] == "${CBGO_WEB_BIND:-127.0.0.1}"
    env = environment(web)
    assert env["CBGO_HTTP_PORT"] == "8080" and env["CBGO_HTTP_HOST"] == "0.0.0.0"
    assert env["ZENOH_CONNECT"] == ROUTER_ENDPOINT


def test_the_foxglove_bridge_is_under_its_profile_and_publishes_8765_on_loopback(services):
    bridge = services["foxglove-bridge"]
    assert bridge["profiles"] == ["foxglove"]
    assert published_ports(bridge) == [("${CBGO_FOXGLOVE_PORT:-8765}", "8765")]
    assert bridge["ports"][0]["host_ip"] == "${CBGO_FOXGLOVE_BIND:-127.0.0.1}"
    env = environment(bridge)
    assert env["CBGO_WS_PORT"] == "8765" and env["CBGO_WS_HOST"] == "0.0.0.0"
    assert env["ZENOH_CONNECT"] == ROUTER_ENDPOINT


def test_every_service_restarts_unless_stopped_under_an_init_and_stops_in_time(services):
    for name, service in services.items():
        assert service.get("restart") == "unless-stopped", name
        assert service.get("init") is True, f"{name}: init reaps zombies and forwards SIGTERM"
        assert service.get("stop_grace_period") == "5s", name
        assert "healthcheck" in service, name


def test_the_services_start_once_the_router_is_healthy(services):
    for name in SERVICE_NAMES:
        assert services[name]["depends_on"] == {ROUTER: {"condition": "service_healthy"}}, name
    assert "depends_on" not in services[ROUTER]


@pytest.mark.parametrize("name", [ROUTER, *SERVICE_NAMES])
def test_every_healthcheck_asks_for_the_liveliness_token_of_its_own_service(services, name):
    health = services[name]["healthcheck"]
    test = health["test"]
    assert test[0] == "CMD", f"{name}: exec form, no shell in the way"
    # At the lowest CPU priority: the checks of all services run together, and at normal
    # priority they stalled the services' frames on a 2-core machine (deploy/README.md).
    assert test[1:4] == ["nice", "-n", "19"], test
    assert test[4:7] == ["cbgo", "wait-alive", name], test
    assert "--timeout" in test
    timeout = float(test[test.index("--timeout") + 1])
    assert float(health["timeout"].rstrip("s")) > timeout, "docker must not kill it first"
    if name == ROUTER:
        assert test[test.index("--connect") + 1] == "tcp/127.0.0.1:7447"


def test_the_models_and_recordings_volumes_are_mounted_under_data(compose, services):
    assert {"models", "recordings"} <= set(compose["volumes"])
    for name, service in services.items():
        mounts = set(service.get("volumes", []))
        assert {"models:/data/models", "recordings:/data/recordings"} <= mounts, name


def test_the_services_keep_what_they_learn_in_the_models_volume(services):
    # cbgo.config.data_dir(): user models, personal intent models, taught gestures.
    for name in SERVICE_NAMES:
        assert environment(services[name]).get("CBGO_DATA_DIR") == "/data/models", name


def test_the_simulator_renders_headless_through_egl(services):
    assert environment(services["mujoco-sim"]).get("MUJOCO_GL") == "egl"


# --- every command is a real entry point --------------------------------------------------------


def test_the_cbgo_command_is_the_cli_entry_point_of_the_package(project_scripts,
                                                                installed_scripts):
    assert project_scripts.get("cbgo") == "cbgo.cli.main:main"
    assert "cbgo" in installed_scripts, "reinstall the package: pip install -e ."
    assert installed_scripts["cbgo"].value == "cbgo.cli.main:main"


def test_the_router_module_runs_on_its_own():
    result = run_cli("-m", "cbgo.router", "--help")
    assert result.returncode == 0, result.stderr
    assert "router" in result.stdout


@pytest.mark.parametrize("verb", ["router", "wait-alive"])
def test_the_cli_verbs_that_compose_runs_exist(verb):
    # `cbgo router` is the router's command, `cbgo wait-alive` every healthcheck's.
    result = run_cli("-m", "cbgo.cli.main", verb, "--help")
    assert result.returncode == 0, f"`cbgo {verb} --help` failed:\n{result.stderr[-2000:]}"


@pytest.mark.parametrize("info", SERVICES, ids=lambda s: s.name)
def test_each_service_runs_the_console_script_of_its_package(services, project_scripts,
                                                             installed_scripts, info):
    assert services[info.name]["command"] == [info.script]
    if not info.exists():
        pytest.skip(f"{info.name} is not implemented in this checkout")
    target = f"{info.package}.main:main"
    assert project_scripts.get(info.script) == target, (
        f"[project.scripts] needs {info.script} = \"{target}\"")
    assert info.script in installed_scripts, "reinstall the package: pip install -e ."
    assert installed_scripts[info.script].value == target
    main = installed_scripts[info.script].load()
    assert callable(main)


# --- override files ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def dry_robot_merged(compose) -> dict:
    override = yaml.load((DEPLOY / "compose.dry-robot.yaml").read_text(), ComposeLoader)
    return merge(compose, override)


def test_the_merge_rules_of_the_test_are_composes():
    base = {"a": {"profiles": ["x"], "command": ["old"], "dns": ["1"], "keep": 1}}
    override = yaml.load("a: {profiles: !reset [], command: [new], dns: ['2'], "
                         "keep: !override two}", ComposeLoader)
    assert merge(base, override) == {"a": {"command": ["new"], "dns": ["1", "2"], "keep": "two"}}


@pytest.mark.parametrize("path", OVERRIDES, ids=lambda p: p.name)
def test_every_override_file_names_known_services_and_runs_real_entry_points(
        compose, installed_scripts, path):
    override = yaml.load(path.read_text(), ComposeLoader)
    assert set(override) <= {"services", "volumes"}, f"{path.name}: only services and volumes"
    assert set(override["services"]) <= set(compose["services"]), (
        f"{path.name} adds services; add them to compose.yaml (under a profile) instead")
    merged = merge(compose, override)
    for name, service in merged["services"].items():
        program = service["command"][0]
        assert program == "cbgo" or program in installed_scripts, f"{name}: {program}"
        test = service["healthcheck"]["test"]
        assert test[4:7] == ["cbgo", "wait-alive", name], f"{name}: {test}"


def test_the_dry_robot_override_starts_dry_robot_instead_of_mujoco_sim(dry_robot_merged):
    services = dry_robot_merged["services"]
    expected = {ROUTER, *(n for n in DEFAULT_NAMES if n != "mujoco-sim"), "dry-robot"}
    assert started_by_default(services) == expected
    assert services["mujoco-sim"]["profiles"], "mujoco-sim must be disabled by a profile"
    robot = services["dry-robot"]
    assert robot["command"] == ["cbgo-dry-robot"]
    assert environment(robot).get("ZENOH_CONNECT") == ROUTER_ENDPOINT
    assert robot["depends_on"] == {ROUTER: {"condition": "service_healthy"}}


# --- the Zenoh configs --------------------------------------------------------------------------


def test_the_router_config_opens_a_router_whose_admin_space_answers():
    import zenoh

    conf = zenoh.Config.from_file(str(DEPLOY / "router.json5"))
    assert json.loads(conf.get_json("mode")) == "router"
    assert json.loads(conf.get_json("listen/endpoints")) == ["tcp/0.0.0.0:7447"]
    assert json.loads(conf.get_json("adminspace/enabled")) is True
    assert json.loads(conf.get_json("adminspace/permissions/read")) is True
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False
    assert json.loads(conf.get_json("metadata")) == {"name": "router"}

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    client = zenoh.Config.from_file(str(DEPLOY / "client.json5"))
    client.insert_json5("connect/endpoints", json.dumps([endpoint]))
    with zenoh.open(conf) as router, zenoh.open(client) as session:
        deadline = time.monotonic() + 10
        while not list(session.info.routers_zid()) and time.monotonic() < deadline:
            time.sleep(0.05)
        replies = [r.ok for r in session.get(f"@/{router.zid()}/router", timeout=5) if r.ok]
        assert replies, "the router's admin space did not answer"


def test_the_client_config_connects_to_the_compose_router_and_waits_for_it():
    import zenoh

    conf = zenoh.Config.from_file(str(DEPLOY / "client.json5"))
    assert json.loads(conf.get_json("mode")) == "client"
    assert json.loads(conf.get_json("connect/endpoints")) == [ROUTER_ENDPOINT]
    assert json.loads(conf.get_json("connect/timeout_ms")) == -1
    assert json.loads(conf.get_json("scouting/multicast/enabled")) is False


# --- the image ----------------------------------------------------------------------------------


def test_the_dockerfile_installs_cpu_torch_and_the_package_and_runs_as_a_non_root_user():
    lines = [line.strip() for line in (DEPLOY / "Dockerfile").read_text().splitlines()
             if line.strip() and not line.strip().startswith("#")]
    text = "\n".join(lines)
    assert lines[0].startswith("FROM python:3.11-slim")
    # Where torch comes from is a build argument; its default is the PyTorch CPU index.
    assert 'ARG TORCH_PIP_ARGS="--index-url https://download.pytorch.org/whl/cpu"' in lines
    assert "RUN pip install torch==2.13.0 $TORCH_PIP_ARGS" in lines
    assert text.index("pip install torch==2.13.0") < text.index("pip install /tmp/cbgo-src"), (
        "CPU torch must be installed before the package, or pip pulls the CUDA build")
    users = [line.split()[1] for line in lines if line.startswith("USER ")]
    assert users and users[-1] not in ("root", "0")
    assert "PYTHONUNBUFFERED=1" in text
    assert lines[-1] == 'CMD ["cbgo", "--help"]'


def test_the_build_context_lets_in_only_what_the_image_installs():
    patterns = [line.strip() for line in (REPO / ".dockerignore").read_text().splitlines()
                if line.strip() and not line.startswith("#")]
    # Everything out (the venv, .git, out/, certificates made in the checkout), then back in
    # only what `pip install` needs; then caches and recordings out again inside those.
    assert patterns[0] == "*"
    allowed = {p[1:] for p in patterns if p.startswith("!")}
    assert allowed == {"pyproject.toml", "setup.py", "MANIFEST.in", "README.md", "shared",
                       "services"}
    last_allow = max(i for i, p in enumerate(patterns) if p.startswith("!"))
    assert {"**/__pycache__", "**/*.mcap"} <= set(patterns[last_allow:])
    copies = [line.split() for line in (DEPLOY / "Dockerfile").read_text().splitlines()
              if line.startswith("COPY ")]
    assert copies == [["COPY", ".", "/tmp/cbgo-src"]]
