"""The TLS deployment files: deploy/compose.tls.yaml and deploy/tls/{router,client}.json5.

No Docker engine here: the override is merged onto compose.yaml in Python, by the rules of
the compose specification ("merge": mappings merge, `command` and `healthcheck.test` are
replaced, `volumes` are unique by target, other sequences append), and the result is checked.
The JSON5 files are read by Zenoh itself. Every path they name must be a file that `cbgo certs
make` writes, in the directory the override mounts; the ACL must give every name it makes
rights, and query rights on robot/act to the planner (and routers) only. Whether the ACL works
is tested on real processes in tests/integration/test_tls.py.
"""

from __future__ import annotations

import json
import re
from pathlib import Path, PurePosixPath

import pytest
import yaml

from cbgo import keys
from cbgo.cli.certs import DEFAULT_HOSTS, default_names, make
from cbgo.registry import ROUTER

REPO = Path(__file__).resolve().parents[2]
DEPLOY = REPO / "deploy"
SECRETS = PurePosixPath("/run/secrets/cbgo-tls")
CLIENT_IN_CONTAINER = "/etc/cbgo/tls/client.json5"
ROUTER_IN_CONTAINER = "/etc/cbgo/tls/router.json5"
CERTS_VARIABLE = re.compile(r"^\$\{CBGO_CERTS:\?[^}]+\}/")
TLS_PATH_KEYS = ("root_ca_certificate", "listen_certificate", "listen_private_key",
                 "connect_certificate", "connect_private_key")
COMMANDERS = {"planner", ROUTER}
ROBOTS = {"mujoco-sim", "dry-robot", "franka"}


# ------------------------------------------------------------------------ compose merge rules


def volume_target(volume: str | dict) -> str:
    if isinstance(volume, dict):
        return volume["target"]
    return CERTS_VARIABLE.sub("certs/", volume).split(":")[1]


def merge(base, override, path: tuple[str, ...] = ()):
    """Returns `override` merged onto `base` as `docker compose -f base -f override` does."""
    if path[-1:] in (("command",), ("entrypoint",)) or path[-2:] == ("healthcheck", "test"):
        return override
    if isinstance(base, dict) and isinstance(override, dict):
        merged = dict(base)
        for key, value in override.items():
            merged[key] = merge(base[key], value, (*path, key)) if key in base else value
        return merged
    if path[-1:] == ("volumes",) and isinstance(base, list):
        by_target = {volume_target(v): v for v in base}
        by_target.update({volume_target(v): v for v in override})
        return list(by_target.values())
    if isinstance(base, list) and isinstance(override, list):
        return base + override
    return override


@pytest.fixture(scope="module")
def base() -> dict:
    return yaml.safe_load((DEPLOY / "compose.yaml").read_text())


@pytest.fixture(scope="module")
def override() -> dict:
    return yaml.safe_load((DEPLOY / "compose.tls.yaml").read_text())


@pytest.fixture(scope="module")
def services(base, override) -> dict:
    return merge(base, override)["services"]


def mounts(service: dict) -> dict[str, str]:
    """Returns {container path: source} of a service's short-syntax bind mounts and volumes."""
    out = {}
    for volume in service.get("volumes", []):
        source, target = CERTS_VARIABLE.sub("$CBGO_CERTS/", volume).split(":")[:2]
        out[target] = source
    return out


def test_the_merge_follows_the_compose_rules():
    # The checker checks itself on the spec's own examples.
    assert merge({"command": ["a"]}, {"command": ["b"]}) == {"command": ["b"]}
    assert merge({"dns": ["1.1.1.1"]}, {"dns": ["8.8.8.8"]}) == {"dns": ["1.1.1.1", "8.8.8.8"]}
    assert merge({"healthcheck": {"test": ["CMD", "a"], "interval": "5s"}},
                 {"healthcheck": {"test": ["CMD", "b"]}}) == {
        "healthcheck": {"test": ["CMD", "b"], "interval": "5s"}}
    assert merge({"volumes": ["a:/x", "b:/y"]}, {"volumes": ["c:/x"]}) == {
        "volumes": ["c:/x", "b:/y"]}


# ------------------------------------------------------------------------ the override


def test_the_override_covers_every_service_of_compose_yaml_and_adds_none(base, override):
    assert set(override) == {"services"} | {k for k in override if k.startswith("x-")}
    assert set(override["services"]) == set(base["services"])


@pytest.mark.parametrize("name", [n for n in default_names() if n not in (ROUTER, "operator")])
def test_every_service_connects_over_tls_with_the_certificate_of_its_own_name(services, name):
    service = services[name]
    env = service["environment"]
    assert env["ZENOH_CONNECT"] == "tls/router:7447"
    assert env["ZENOH_CONFIG"] == CLIENT_IN_CONTAINER
    assert env["ZENOH_MODE"] == "client"
    assert "ZENOH_LISTEN" not in env
    mounted = mounts(service)
    # The router grants rights by the certificate's CN, so the directory must be the service's.
    assert mounted[str(SECRETS)] == f"$CBGO_CERTS/{name}"
    assert mounted[CLIENT_IN_CONTAINER] == "./tls/client.json5"
    assert {"/data/models", "/data/recordings"} <= set(mounted), "base volumes must stay"
    assert all(v.endswith(":ro") for v in service["volumes"] if "tls" in v)
    # The healthcheck runs in the same environment, so it speaks TLS with the same certificate.
    assert service["healthcheck"]["test"][4:7] == ["cbgo", "wait-alive", name]


def test_the_router_listens_on_tls_only_and_checks_its_own_health_over_tls(services):
    router = services[ROUTER]
    command = router["command"]
    assert command[:2] == ["cbgo", "router"]
    assert command[command.index("--listen") + 1] == "tls/0.0.0.0:7447"
    assert command[command.index("--config") + 1] == ROUTER_IN_CONTAINER
    # Not in the environment: the healthcheck would inherit them and listen on 7447 itself.
    assert not {"ZENOH_LISTEN", "ZENOH_CONFIG", "ZENOH_CONNECT"} & set(router["environment"])
    mounted = mounts(router)
    assert mounted[str(SECRETS)] == "$CBGO_CERTS/router"
    assert mounted[ROUTER_IN_CONTAINER] == "./tls/router.json5"
    test = router["healthcheck"]["test"]
    assert test[:7] == ["CMD", "nice", "-n", "19", "cbgo", "wait-alive", "router"]
    assert test[test.index("--connect") + 1] == "tls/localhost:7447"
    assert test[test.index("--config") + 1] == CLIENT_IN_CONTAINER
    assert {"target": 7447, "published": "${CBGO_PORT:-7447}"} in router["ports"]


def test_the_authority_key_is_mounted_nowhere(services):
    for name, service in services.items():
        for source in mounts(service).values():
            assert source.split("/")[:2] != ["$CBGO_CERTS", "ca"], name  # camera-bridge's is not
            assert source == "$CBGO_CERTS/" + name or not source.startswith("$CBGO_CERTS"), name


def test_every_mounted_config_file_exists_relative_to_compose_yaml(services):
    # Compose resolves relative paths against the first file's directory: deploy/.
    for service in services.values():
        for source in mounts(service).values():
            if source.startswith("./"):
                assert (DEPLOY / source).is_file(), source


# ------------------------------------------------------------------------ the JSON5 configs


def zenoh_config(name: str):
    zenoh = pytest.importorskip("zenoh")
    return zenoh.Config.from_file(str(DEPLOY / "tls" / name))


def get(conf, key: str):
    return json.loads(conf.get_json(key))


@pytest.mark.parametrize("config", ["router.json5", "client.json5"])
def test_every_certificate_path_is_a_file_that_cbgo_certs_make_writes(tmp_path, config):
    make(tmp_path, [ROUTER, "planner"], list(DEFAULT_HOSTS), report=lambda _: None)
    conf = zenoh_config(config)
    tls = get(conf, "transport/link/tls")
    paths = [PurePosixPath(tls[k]) for k in TLS_PATH_KEYS if tls.get(k) is not None]
    assert len(paths) == (5 if config == "router.json5" else 3)
    for path in paths:
        assert path.parent == SECRETS, f"{path} is not where compose.tls.yaml mounts the certs"
        for name in (ROUTER, "planner"):
            assert (tmp_path / name / path.name).is_file(), path


def test_the_router_config_demands_mutual_tls_and_refuses_plain_tcp():
    conf = zenoh_config("router.json5")
    assert get(conf, "mode") == "router"
    assert get(conf, "listen/endpoints") == ["tls/0.0.0.0:7447"]
    assert get(conf, "transport/link/protocols") == ["tls"]
    assert get(conf, "transport/link/tls/enable_mtls") is True
    assert get(conf, "adminspace/enabled") is True
    assert get(conf, "scouting/multicast/enabled") is False


def test_the_client_config_connects_to_the_compose_router_over_mutual_tls():
    conf = zenoh_config("client.json5")
    assert get(conf, "mode") == "client"
    assert get(conf, "connect/endpoints") == ["tls/router:7447"]
    assert get(conf, "connect/timeout_ms") == -1
    assert get(conf, "transport/link/protocols") == ["tls"]
    assert get(conf, "transport/link/tls/enable_mtls") is True
    assert get(conf, "transport/link/tls/verify_name_on_connect") is True


# ------------------------------------------------------------------------ the ACL


@pytest.fixture(scope="module")
def acl() -> dict:
    return get(zenoh_config("router.json5"), "access_control")


def rights(acl: dict) -> dict[str, list[dict]]:
    """Returns {common name: the rules its subject's policies grant}."""
    rules = {r["id"]: r for r in acl["rules"]}
    names = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
    out: dict[str, list[dict]] = {}
    for policy in acl["policies"]:
        for subject in policy["subjects"]:
            for name in names[subject]:
                out.setdefault(name, []).extend(rules[r] for r in policy["rules"])
    return out


def may_include_robot_act(key_expr: str) -> bool:
    """Whether a rule's key expression could include <prefix>/robot/act (conservative).

    It cannot if it names a verbatim (@) chunk, which only matches itself, or ends in a plain
    chunk other than "act".
    """
    chunks = key_expr.split("/")
    if any(c.startswith("@") for c in chunks):
        return False
    last = chunks[-1]
    return last in ("act", "*", "**", "$*") or "$*" in last or last.endswith("act")


def grants(rule: dict, message: str, flow: str) -> bool:
    return (rule["permission"] == "allow" and message in rule["messages"]
            and flow in rule.get("flows", ["ingress", "egress"]))


def test_access_control_is_on_and_denies_what_it_does_not_grant(acl):
    assert acl["enabled"] is True
    assert acl["default_permission"] == "deny"
    assert all(r["permission"] == "allow" for r in acl["rules"]), (
        "a deny rule does not stop wildcards and loses to an allow of another subject; "
        "grant rights instead (see router.json5)")


def test_every_name_cbgo_certs_makes_is_in_exactly_one_subject(acl):
    listed = [n for s in acl["subjects"] for n in s["cert_common_names"]]
    assert sorted(listed) == sorted(set(listed)), "a name in two subjects merges their rules"
    assert set(listed) == set(default_names())
    set_properties = [{k for k, v in s.items() if v is not None} for s in acl["subjects"]]
    assert all(p == {"id", "cert_common_names"} for p in set_properties), (
        "a subject matched by another property (interface, link protocol) adds its allows to "
        "every name's")


def test_only_the_planner_and_routers_may_query_robot_act(acl):
    for name, granted in rights(acl).items():
        can = any(grants(r, "query", "ingress") and any(map(may_include_robot_act,
                                                            r["key_exprs"])) for r in granted)
        assert can == (name in COMMANDERS), name


def test_only_robots_and_commanders_may_answer_robot_act(acl):
    for name, granted in rights(acl).items():
        can = any(grants(r, "declare_queryable", "ingress")
                  and any(map(may_include_robot_act, r["key_exprs"])) for r in granted)
        assert can == (name in ROBOTS | COMMANDERS), name


def test_everyone_may_ask_and_answer_every_other_query_of_the_protocol(acl):
    queries = [t.suffix for t in keys.TOPICS.values() if t.query and t != keys.ROBOT_ACT]
    assert queries, "the protocol has query keys"
    for name, granted in rights(acl).items():
        asked = {k for r in granted if grants(r, "query", "ingress") for k in r["key_exprs"]}
        answered = {k for r in granted if grants(r, "declare_queryable", "ingress")
                    for k in r["key_exprs"]}
        for suffix in queries:
            assert {f"**/{suffix}", "**"} & asked, f"{name} may not query {suffix}"
            assert {f"**/{suffix}", "**"} & answered, f"{name} may not answer {suffix}"
        assert "**/@ctl/**" in asked and "@/**" in asked, name


def test_everyone_may_publish_subscribe_and_use_liveliness_on_every_key(acl):
    wanted = {"**", "**/@alive/**", "**/@ctl/**", "@/**"}
    for name, granted in rights(acl).items():
        for message in ("put", "declare_subscriber", "reply", "liveliness_token",
                        "declare_liveliness_subscriber", "liveliness_query"):
            for flow in ("ingress", "egress"):
                covered = {k for r in granted if grants(r, message, flow) for k in r["key_exprs"]}
                assert wanted <= covered, (name, message, flow)
