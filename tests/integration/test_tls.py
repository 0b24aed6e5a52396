"""Mutual TLS and the access control list of deploy/tls, on loopback, with real certificates.

The certificates come from `cbgo certs make` (openssl); the router is the real `cbgo router`
process with deploy/tls/router.json5 (its certificate paths pointed at the test's directory by
--cfg, as the file's header tells operators to do); every session opens with
deploy/tls/client.json5 through `cbgo.config.zenoh_config`, as services and the CLI do. Then:

- the planner's certificate may query robot/act, the robot's may answer it;
- any other certificate may not query robot/act, not even through a wildcard, may not answer
  it, and still publishes, subscribes and asks the cell's queries;
- a name signed by the authority but absent from the ACL may do nothing at all;
- no certificate, a certificate of another authority, plain tcp: the session does not open;
- the real planner and dry-robot processes run a plan over it, under another prefix.

The last tests check how Zenoh decides between allow and deny (the reasons the ACL in
router.json5 is written as it is), on in-process routers.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path

import pytest

from cbgo import client, wire
from cbgo.cli.certs import DEFAULT_HOSTS, default_names, make
from cbgo.config import ZenohOptions, zenoh_config
from cbgo.keys import Keys
from cbgo.testing import Stack, free_port

zenoh = pytest.importorskip("zenoh")

REPO = Path(__file__).resolve().parents[2]
ROUTER_CONFIG = REPO / "deploy" / "tls" / "router.json5"
CLIENT_CONFIG = REPO / "deploy" / "tls" / "client.json5"
STRANGER = "stranger"  # signed by the authority, named in no ACL subject
OPEN_TIMEOUT_MS = 10_000
REFUSED_TIMEOUT_MS = 2_500
ACT = "cbgo/robot/act"


# ---------------------------------------------------------------------------------- helpers


def tls_overrides(certs: Path, name: str) -> list[str]:
    """Returns --cfg items that point the deploy configs at certs/<name>/."""
    own = certs / name
    paths = {"root_ca_certificate": own / "ca.pem", "connect_certificate": own / "cert.pem",
             "connect_private_key": own / "key.pem"}
    if name == "router":
        paths |= {"listen_certificate": own / "cert.pem", "listen_private_key": own / "key.pem"}
    return [f"transport/link/tls/{key}:{json.dumps(str(path))}" for key, path in paths.items()]


def cfg_flags(certs: Path, name: str) -> list[str]:
    return [arg for item in tls_overrides(certs, name) for arg in ("--cfg", item)]


def open_as(name: str, endpoint: str, certs: Path, timeout_ms: int = OPEN_TIMEOUT_MS):
    """Opens a session with deploy/tls/client.json5 and the certificate of `name`."""
    options = ZenohOptions(connect=[endpoint], config=str(CLIENT_CONFIG),
                           cfg=tls_overrides(certs, name))
    conf = zenoh_config(options, f"test-{name}")
    conf.insert_json5("connect/timeout_ms", str(timeout_ms))
    return zenoh.open(conf)


def ask(session, key: str, payload: bytes = b"", timeout: float = 1.5) -> list[tuple[str, bytes]]:
    """Returns every ok reply (key, payload) to a query; replies are not merged by key."""
    replies = client.replies(session, key, payload, timeout,
                             consolidation=zenoh.ConsolidationMode.NONE)
    return [(r.key, r.payload) for r in replies if r.ok]


def ask_until_answered(session, key: str, payload: bytes = b"", deadline_s: float = 10.0):
    """Queries until a reply comes (a new queryable takes a moment to reach the router)."""
    end = time.monotonic() + deadline_s
    while True:
        replies = ask(session, key, payload, timeout=1.0)
        if replies or time.monotonic() > end:
            return replies


def alive_names(session, prefix: str = "cbgo") -> set[str]:
    return client.alive(session, Keys(prefix), 1.5)


class Inbox:
    """Payloads received on one key by one session."""

    def __init__(self, session, key: str):
        self.items: list[bytes] = []
        self.lock = threading.Lock()
        self.sub = session.declare_subscriber(key, self._on)

    def _on(self, sample) -> None:
        with self.lock:
            self.items.append(sample.payload.to_bytes())

    def snapshot(self) -> list[bytes]:
        with self.lock:
            return list(self.items)


def put_until_received(publisher_session, key: str, payload: bytes, inbox: Inbox,
                       deadline_s: float = 10.0) -> bool:
    """Puts every 0.1 s until the inbox has the payload (a new subscriber takes a moment)."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        publisher_session.put(key, payload)
        time.sleep(0.1)
        if payload in inbox.snapshot():
            return True
    return False


class Answerer:
    """A queryable that answers `reply` and remembers the payload of every query it got."""

    def __init__(self, session, key: str, reply: bytes):
        self.seen: list[bytes] = []
        self.key, self.reply = key, reply
        self.queryable = session.declare_queryable(key, self._on)

    def _on(self, query) -> None:
        self.seen.append(query.payload.to_bytes() if query.payload is not None else b"")
        query.reply(self.key, self.reply)


# ---------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    directory = tmp_path_factory.mktemp("certs")
    make(directory, [*default_names(), STRANGER], list(DEFAULT_HOSTS), report=lambda _: None)
    return directory


@pytest.fixture(scope="module")
def tls_stack(tmp_path_factory, certs):
    """The real `cbgo router` on tls/127.0.0.1:<free port>, with the deploy router config."""
    with Stack(tmp_path_factory.mktemp("tls-logs")) as stack:
        stack.endpoint = f"tls/127.0.0.1:{stack.port}"  # what children get as ZENOH_CONNECT
        stack.spawn("router", [sys.executable, "-m", "cbgo.router", "--listen", stack.endpoint,
                               *cfg_flags(certs, "router")],
                    env={"ZENOH_CONNECT": "", "ZENOH_CONFIG": str(ROUTER_CONFIG)})
        yield stack


@pytest.fixture(scope="module")
def sessions(tls_stack, certs):
    """Sessions of the planner, the robot (mujoco-sim), intent and the operator."""
    opened = {}
    try:
        for name in ("operator", "planner", "mujoco-sim", "intent"):
            try:
                opened[name] = open_as(name, tls_stack.endpoint, certs)
            except zenoh.ZError as e:
                pytest.fail(f"{name} could not open a TLS session: {e}\n"
                            + tls_stack.logs(["router"]))
        end = time.monotonic() + 20
        while "router" not in alive_names(opened["operator"]):
            assert time.monotonic() < end, "router not alive\n" + tls_stack.logs(["router"])
            time.sleep(0.1)
        yield opened
    finally:
        for session in opened.values():
            session.close()


@pytest.fixture(scope="module")
def robot(sessions):
    """The robot's robot/act and sim/reset, answered from the mujoco-sim session."""
    act = Answerer(sessions["mujoco-sim"], ACT, b"done by mujoco-sim")
    reset = Answerer(sessions["mujoco-sim"], "cbgo/sim/reset", b"reset by mujoco-sim")
    assert ask_until_answered(sessions["planner"], ACT, b"warm-up"), "robot/act never answered"
    yield act
    act.queryable.undeclare()
    reset.queryable.undeclare()


# ---------------------------------------------------------------------------------- the ACL


def test_the_planner_certificate_may_query_robot_act(sessions, robot):
    replies = ask(sessions["planner"], ACT, b"from planner")
    assert replies == [(ACT, b"done by mujoco-sim")]
    assert robot.seen[-1] == b"from planner"


@pytest.mark.parametrize("selector", [ACT, "cbgo/robot/*", "cbgo/**", "**"])
def test_another_certificate_cannot_query_robot_act_even_through_a_wildcard(sessions, robot,
                                                                            selector):
    before = len(robot.seen)
    assert ask(sessions["intent"], selector, b"from intent") == []
    assert ask(sessions["operator"], selector, b"from operator") == []
    # The robot is there and answers: the planner still gets through, after the refused ones.
    assert ask(sessions["planner"], ACT, b"from planner") == [(ACT, b"done by mujoco-sim")]
    assert robot.seen[before:] == [b"from planner"]


def test_another_certificate_cannot_answer_robot_act(sessions, robot):
    intent = sessions["intent"]
    impostor = Answerer(intent, ACT, b"done by an impostor")
    # Declared after the impostor on the same session, so it reaches the router after it:
    # once the probe answers, the impostor would be answering too if it had been let in.
    probe = Answerer(intent, "cbgo/@ctl/intent/probe", b"probe")
    try:
        assert ask_until_answered(sessions["planner"], "cbgo/@ctl/intent/probe") == [
            ("cbgo/@ctl/intent/probe", b"probe")]
        assert ask(sessions["planner"], ACT, b"from planner") == [(ACT, b"done by mujoco-sim")]
        assert impostor.seen == []
    finally:
        impostor.queryable.undeclare()
        probe.queryable.undeclare()


def test_other_certificates_still_publish_subscribe_and_ask_the_cell(tls_stack, sessions, robot):
    intent, planner, operator = sessions["intent"], sessions["planner"], sessions["operator"]
    inbox = Inbox(planner, "cbgo/intent")
    assert put_until_received(intent, "cbgo/intent", b"intent from intent", inbox)
    scenes = Inbox(intent, "cbgo/scene/state")
    assert put_until_received(sessions["mujoco-sim"], "cbgo/scene/state", b"scene", scenes)
    assert ask(intent, "cbgo/sim/reset") == [("cbgo/sim/reset", b"reset by mujoco-sim")]
    assert "router" in alive_names(intent)
    (key, payload), = ask(operator, "cbgo/@ctl/router/status", timeout=5)
    assert wire.decode(payload, wire.MAX_BYTES_RENDER)["name"] == "router"
    assert len(ask(operator, "@/*/router", timeout=5)) == 1, "the admin space did not answer"


def test_a_name_signed_by_the_authority_but_not_in_the_acl_may_do_nothing(tls_stack, certs,
                                                                          sessions):
    stranger = open_as(STRANGER, tls_stack.endpoint, certs)  # the TLS handshake itself succeeds
    try:
        inbox = Inbox(sessions["planner"], "cbgo/intent")
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            stranger.put("cbgo/intent", b"from the stranger")
            time.sleep(0.1)
        assert put_until_received(sessions["intent"], "cbgo/intent", b"from intent", inbox)
        assert b"from the stranger" not in inbox.snapshot()
        assert ask(stranger, "cbgo/@ctl/router/status") == []
        assert alive_names(stranger) == set()
        assert ask(stranger, ACT) == []
    finally:
        stranger.close()


# ---------------------------------------------------------------------------------- mTLS


def no_client_certificate(certs: Path, endpoint: str):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("transport/link/tls/root_ca_certificate",
                      json.dumps(str(certs / "operator" / "ca.pem")))
    return conf


def foreign_authority_certificate(certs: Path, endpoint: str):
    # A certificate named "planner", made by another authority; the router's own CA is
    # trusted, so the handshake fails only because the router refuses this certificate.
    forged = certs.parent / (certs.name + "-forged")
    if not (forged / "planner").exists():
        make(forged, ["planner"], list(DEFAULT_HOSTS), report=lambda _: None)
    conf = no_client_certificate(certs, endpoint)
    conf.insert_json5("transport/link/tls/connect_certificate",
                      json.dumps(str(forged / "planner" / "cert.pem")))
    conf.insert_json5("transport/link/tls/connect_private_key",
                      json.dumps(str(forged / "planner" / "key.pem")))
    conf.insert_json5("transport/link/tls/enable_mtls", "true")
    return conf


def plain_tcp(certs: Path, endpoint: str):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint.replace("tls/", "tcp/")]))
    return conf


@pytest.mark.parametrize("make_config", [no_client_certificate, foreign_authority_certificate,
                                         plain_tcp])
def test_a_client_without_a_certificate_of_the_authority_cannot_open_a_session(
        tls_stack, certs, sessions, make_config):
    conf = make_config(certs, tls_stack.endpoint)
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/timeout_ms", str(REFUSED_TIMEOUT_MS))
    with pytest.raises(zenoh.ZError, match="Unable to connect"):
        zenoh.open(conf).close()
    assert "router" in alive_names(sessions["operator"]), "the router must stay up"


# ---------------------------------------------------------------------------------- services


PAPER_SCENE = {
    "objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.2], "size": 0.06,
         "full": False, "on": None, "inside": None},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11,
         "open": False},
    ],
    "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": False, "holding": "cup1"},
}


def test_the_real_planner_commands_dry_robot_and_the_cli_works_over_tls(tls_stack, certs, sessions):
    # Another prefix: the robot session of the other tests answers cbgo/robot/act, not this.
    prefix = "tls-cell"
    for name in ("dry-robot", "planner"):
        tls_stack.spawn(f"{prefix}-{name}", [sys.executable, "-m",
                                         f"cbgo.services.{name.replace('-', '_')}",
                                         *cfg_flags(certs, name)],
                    env={"ZENOH_CONFIG": str(CLIENT_CONFIG), "CBGO_PREFIX": prefix,
                         "CBGO_STATE_RATE_HZ": "5", "CBGO_ROBOT_RATE_HZ": "5",
                         "CBGO_ACTION_S": "0"})
    operator, intent = sessions["operator"], sessions["intent"]
    end = time.monotonic() + 60
    while not {"dry-robot", "planner"} <= alive_names(operator, prefix):
        assert time.monotonic() < end, tls_stack.logs([f"{prefix}-dry-robot", f"{prefix}-planner"])
        time.sleep(0.2)

    cli = tls_stack.spawn("cli-status", [sys.executable, "-m", "cbgo.cli.main", "status", "planner",
                                     "--prefix", prefix, *cfg_flags(certs, "operator")],
                      env={"ZENOH_CONFIG": str(CLIENT_CONFIG)})
    assert cli.wait(30) == 0, cli.log()
    assert "planner" in cli.log()

    (_, reset), = ask(operator, f"{prefix}/sim/reset",
                      wire.encode({"v": 1, "scene": PAPER_SCENE}), timeout=10)
    assert wire.decode(reset, wire.MAX_BYTES_RENDER)["ok"] is True
    plans = Inbox(operator, f"{prefix}/plan/status")
    message = {"v": 1, "ts": time.time(), "episode": "ep-tls", "action": "put_into",
               "object": "drawer1", "params": {}, "p_action": {"put_into": 0.9},
               "p_object": {"drawer1": 0.9}, "confidence": 0.9, "status": "accepted",
               "reason": "", "model": "test"}
    publisher = intent.declare_publisher(f"{prefix}/intent")
    assert client.wait_matched(publisher, timeout_s=max(0.0, end - time.monotonic())), \
        "the planner never subscribed to the intent"
    publisher.put(wire.encode(message))
    end = time.monotonic() + 30
    while True:
        done = [m for m in map(wire.decode, plans.snapshot()) if m["state"] != "running"]
        if done:
            break
        assert time.monotonic() < end, tls_stack.logs([f"{prefix}-planner", f"{prefix}-dry-robot"])
        time.sleep(0.05)
    assert (done[0]["state"], done[0]["error"]) == ("success", None), done[0]
    assert [(s["action"], s["object"]) for s in done[0]["sequence"]] == [
        ("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"), ("put_into", "drawer1")]
    # The intent service's certificate cannot do what the planner just did.
    assert ask(intent, f"{prefix}/robot/act", wire.encode({"v": 1})) == []


# ---------------------------------------------------------------------------------- precedence


def run_acl(certs: Path, acl: dict, querier: str, selector: str) -> list[tuple[str, bytes]]:
    """Runs an in-process router with `acl`; returns what `querier` gets on `selector` while
    mujoco-sim answers robot/act."""
    conf = zenoh.Config.from_file(str(ROUTER_CONFIG))
    endpoint = f"tls/127.0.0.1:{free_port()}"
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    for item in tls_overrides(certs, "router"):
        key, value = item.split(":", 1)
        conf.insert_json5(key, value)
    conf.insert_json5("access_control", json.dumps(acl))
    with zenoh.open(conf), open_as("mujoco-sim", endpoint, certs) as robot_session, \
            open_as("planner", endpoint, certs) as planner, \
            open_as(querier, endpoint, certs) as session:
        act = Answerer(robot_session, ACT, b"done")
        assert ask_until_answered(planner, ACT) == [(ACT, b"done")], "robot/act not up"
        replies = ask(session, selector)
        act.queryable.undeclare()
        return replies


EVERYTHING = {"id": "everything", "permission": "allow", "flows": ["ingress", "egress"],
              "messages": ["put", "delete", "declare_subscriber", "query", "declare_queryable",
                           "reply", "liveliness_token", "declare_liveliness_subscriber",
                           "liveliness_query"],
              "key_exprs": ["**", "**/@alive/**", "**/@ctl/**", "@/**"]}
DENY_ACT = {"id": "deny act", "permission": "deny", "flows": ["ingress"], "messages": ["query"],
            "key_exprs": ["**/robot/act"]}


def acl(subjects: list[dict], policies: list[dict]) -> dict:
    return {"enabled": True, "default_permission": "deny", "rules": [EVERYTHING, DENY_ACT],
            "subjects": [{"id": "trusted", "cert_common_names": ["planner", "mujoco-sim"]},
                         *subjects],
            "policies": [{"subjects": ["trusted"], "rules": ["everything"]}, *policies]}


def test_a_deny_rule_on_robot_act_does_not_stop_a_wildcard_query(certs):
    # Why router.json5 grants queries on a list of keys instead of denying robot/act.
    naive = acl([{"id": "intent", "cert_common_names": ["intent"]}],
                [{"subjects": ["intent"], "rules": ["everything", "deny act"]}])
    assert run_acl(certs, naive, "intent", ACT) == []
    assert run_acl(certs, naive, "intent", "cbgo/robot/*") == [(ACT, b"done")]


def test_one_name_in_two_subjects_gets_both_rule_sets_and_deny_wins(certs):
    split = acl([{"id": "intent a", "cert_common_names": ["intent"]},
                 {"id": "intent b", "cert_common_names": ["intent"]}],
                [{"subjects": ["intent a"], "rules": ["everything"]},
                 {"subjects": ["intent b"], "rules": ["deny act"]}])
    assert run_acl(certs, split, "intent", ACT) == []


def test_subjects_matched_by_different_properties_need_only_one_allow(certs):
    # Why router.json5 has no broad subject (say, every TLS link) next to the names.
    broad = acl([{"id": "intent", "cert_common_names": ["intent"]},
                 {"id": "every tls link", "link_protocols": ["tls"]}],
                [{"subjects": ["intent"], "rules": ["everything", "deny act"]},
                 {"subjects": ["every tls link"], "rules": ["everything"]}])
    assert run_acl(certs, broad, "intent", ACT) == [(ACT, b"done")]
