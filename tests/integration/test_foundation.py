"""The foundation through real processes: router, runtime, `cbgo` CLI, zenoh-cli codec."""

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time

import msgpack
import pytest

from cbgo import client, registry, wire
from cbgo.examples import example

CLI = [sys.executable, "-m", "cbgo.cli.main"]


def cli(stack, *args, timeout=30):
    """Runs a `cbgo` verb against the stack's router; returns the CompletedProcess."""
    return subprocess.run([*CLI, *args, "--connect", stack.endpoint], capture_output=True,
                          text=True, timeout=timeout, env=stack.env())


@pytest.fixture
def probe(stack, probe_argv):
    stack.start_router()
    stack.spawn("probe", [*probe_argv, "--max-payload-bytes", "4096"])
    stack.wait_alive(["router", "probe"])
    return stack.procs["probe"]


def test_cbgo_up_starts_the_router_reports_ready_and_stops_cleanly(stack):
    up = stack.spawn("up", [*CLI, "up", "--listen", stack.endpoint])
    stack.wait_alive(["router"])
    ready = up.wait_for_line("ready: ", timeout=90)  # every built service, on a loaded machine
    built = [s.name for s in registry.available()]
    assert all(name in ready for name in ["router", *built])
    listing = cli(stack, "ls")
    assert listing.returncode == 0, listing.stderr
    assert "router" in listing.stdout
    code, seconds = stack.stop("up", signal.SIGINT)
    assert code == 0
    assert seconds < 7.0
    assert "router  stopped" in up.log()


def test_cbgo_up_with_no_router_to_reach_still_stops_at_once(stack):
    # nothing listens on the stack's endpoint: up's own session never connects
    up = stack.spawn("up", [*CLI, "up", "--no-router", "--connect", stack.endpoint,
                            "dry-robot"])
    up.wait_for_line("waiting for the Zenoh network")  # its child is up, and waits too
    code, seconds = stack.stop("up", signal.SIGINT)
    assert code == 0, up.log()
    assert seconds < 5.0, up.log()  # not held by the session that never opened
    assert "dry-robot  received SIGTERM" in up.log() and "up | stopped" in up.log()


def test_cbgo_up_restarts_a_router_killed_with_sigkill(stack):
    up = stack.spawn("up", [*CLI, "up", "--router-listen", stack.endpoint])
    stack.wait_alive(["router"])
    first_pid = stack.status("router")["pid"]
    os.kill(first_pid, signal.SIGKILL)
    up.wait_for_line("router exited with code -9")
    up.wait_for_line("restarting router")
    stack.wait_alive(["router"], timeout=30)
    assert stack.status("router")["pid"] != first_pid


def processes_with(marker: str) -> list[int]:
    """The pids of the processes whose environment holds `marker` (ours and our children's)."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/environ", "rb") as f:
                    if marker.encode() in f.read():
                        pids.append(int(entry))
            except OSError:  # gone meanwhile, or not ours to read
                continue
    return pids


def test_cbgo_up_on_a_busy_port_exits_2_at_once_and_starts_nothing(stack):
    stack.start_router()  # another system owns the port
    stack.wait_alive(["router"])
    marker = f"CBGO_TEST_MARK=up-busy-{os.getpid()}-{time.monotonic_ns()}"
    t0 = time.monotonic()
    done = subprocess.run([*CLI, "up", "episode", "--router-listen", stack.endpoint],
                          capture_output=True, text=True, timeout=30,
                          env={**stack.env(), marker.split("=")[0]: marker.split("=")[1]})
    seconds = time.monotonic() - t0
    assert done.returncode == 2, done.stdout + done.stderr
    assert seconds < 5.0
    assert f"port {stack.port} is in use" in done.stderr and "--listen" in done.stderr
    assert f"cbgo up --connect {stack.endpoint} episode" in done.stderr
    assert "Traceback" not in done.stderr + done.stdout and ".rs:" not in done.stderr
    assert processes_with(marker) == []  # no service, no router left behind
    assert "episode" not in stack.alive()  # and none joined the other system's router


def test_cbgo_router_on_a_busy_port_says_which_and_exits_2(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    done = subprocess.run([*CLI, "router", "--listen", stack.endpoint], capture_output=True,
                          text=True, timeout=30, env={**stack.env(), "ZENOH_CONNECT": ""})
    out = done.stdout + done.stderr
    assert done.returncode == 2, out
    assert f"port {stack.port} is in use" in out and "--listen tcp/127.0.0.1:PORT" in out
    assert "Traceback" not in out and "ZError" not in out and ".rs:" not in out


def test_cbgo_up_counts_only_its_own_processes_as_ready(stack):
    zenoh = pytest.importorskip("zenoh")
    stack.start_router()
    stack.start_service("dry-robot")  # another system's dry-robot, on the same router
    stack.wait_alive(["router", "dry-robot"])
    stranger = stack.status("dry-robot")["pid"]
    up = stack.spawn("up", [*CLI, "up", "--no-color", "--connect", stack.endpoint, "dry-robot"])
    line = up.wait_for_line("did not start", timeout=60)
    assert f"pid {stranger} on host" in line
    ready = up.wait_for_line("ready: ", timeout=60)
    assert "ready: dry-robot alive" in ready
    answers = client.replies(stack.session(), stack.keys.ctl("dry-robot", "status"),
                             consolidation=zenoh.ConsolidationMode.NONE, timeout_s=5)
    pids = {wire.decode(r.payload)["pid"] for r in answers if r.ok}
    assert len(pids) == 2 and stranger in pids  # both run; only ours made `up` ready
    code, _seconds = stack.stop("up", signal.SIGINT)
    assert code == 0, up.log()


def test_pub_and_echo_round_trip_a_message_through_the_router(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    echo = stack.spawn("echo", [*CLI, "echo", "user", "--json", "--count", "1", "--timeout",
                                "20", "--connect", stack.endpoint])
    echo.wait_for_line("listening on cbgo/user")
    sent = cli(stack, "pub", "user", '{"user": "alice"}', "--stamp", "--wait", "10")
    assert sent.returncode == 0, sent.stderr
    assert echo.wait(20) == 0
    line = json.loads(echo.log().strip().splitlines()[-1])
    assert line["key"] == "cbgo/user"
    assert line["valid"] is True
    assert line["message"]["user"] == "alice"
    assert line["message"]["v"] == 1


def test_pub_refuses_a_message_that_breaks_the_contract(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    refused = cli(stack, "pub", "user", '{"user": ""}', "--stamp", "--wait", "0")
    assert refused.returncode == 2
    assert "user: expected a non-empty string" in refused.stderr


def test_a_service_answers_its_status_query_with_the_contract_fields(stack, probe):
    status = stack.status("probe")
    wire.validate(status, wire.SERVICE_STATUS, "status")
    assert status["name"] == "probe"
    assert status["pid"] == probe.popen.pid
    assert status["uptime_s"] > 0
    assert status["config"]["settings"] == {"slow_s": 0.0}
    assert status["config"]["zenoh"]["mode"] == "client"
    assert status["inputs"] == ["cbgo/user"]
    assert status["counters"] == {"received": 0, "published": 0, "rejected": 0, "errors": 0,
                                  "dropped": 0}
    assert status["zid"]
    shown = cli(stack, "status", "probe")
    assert shown.returncode == 0 and "counters:" in shown.stdout


def test_cbgo_ls_shows_each_service_with_host_pid_and_keys(stack, probe):
    listing = cli(stack, "ls", "--json")
    assert listing.returncode == 0, listing.stderr
    records = {r["name"]: r for r in map(json.loads, listing.stdout.splitlines())}
    assert set(records) == {"router", "probe"}
    assert records["probe"]["pid"] == probe.popen.pid
    assert records["probe"]["subscriber"] == ["cbgo/user"]
    assert records["probe"]["publisher"] == ["cbgo/episode/event"]
    assert records["probe"]["queryable"] == ["cbgo/intent/infer"]


def test_cbgo_get_of_every_status_answers_for_every_running_service(stack, probe):
    stack.start_service("episode")
    stack.wait_alive(["router", "probe", "episode"])
    got = cli(stack, "get", "@ctl/*/status", "--json", "--timeout", "5")
    assert got.returncode == 0, got.stderr
    replies = [json.loads(line) for line in got.stdout.splitlines()]
    assert {r["key"] for r in replies} >= {"cbgo/@ctl/probe/status",
                                           "cbgo/@ctl/episode/status"}
    assert {r["reply"]["name"] for r in replies} >= {"router", "probe", "episode"}


def test_malformed_messages_are_counted_and_the_service_keeps_working(stack, probe):
    events = stack.collect("episode/event")
    bad = [
        b"\xc1 not msgpack",
        wire.encode({"v": 1, "ts": math.nan, "user": "x"}),
        wire.encode({"v": 1, "ts": 1.0, "user": 42}),
        wire.encode({"v": 1, "ts": 1.0, "user": "x" * 5000}),  # over --max-payload-bytes 4096
        msgpack.packb([1, 2, 3]),
    ]
    for payload in bad:
        stack.put_raw("user", payload)
    stack.put("user", example("user", user="bob"))
    events.wait(timeout=10)
    assert [e["episode"] for e in events.items()] == ["bob"]
    counters = stack.status("probe")["counters"]
    assert counters["rejected"] == len(bad)
    assert counters["received"] == len(bad) + 1
    assert counters["published"] == 1
    assert "rejected input: cbgo/user: ts: expected a finite number" in probe.log()
    assert "exceeds the limit of 4096 bytes" in probe.log()


def test_queries_get_an_answer_or_an_error_reply_never_silence(stack, probe):
    query = example("intent/infer", "query")
    (ok, reply), = stack.query("cbgo/intent/infer", query)
    assert ok and reply["reason"] == "probe saw grab"
    (ok, reason), = stack.query("cbgo/intent/infer", {**query, "user": "nobody"})
    assert not ok and reason == "unknown user 'nobody'"
    (ok, reason), = stack.query("cbgo/intent/infer", {**query, "focus": [0, 0]})
    assert not ok and "rejected: cbgo/intent/infer: focus: expected null or a list of 3" in reason
    assert stack.status("probe")["counters"]["rejected"] == 1


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_service_exits_within_two_seconds_of_a_signal(stack, probe, sig):
    code, seconds = stack.stop("probe", sig)
    assert code == 0
    assert seconds < 2.0


def test_a_service_busy_in_a_long_handler_still_exits_within_two_seconds(stack, probe_argv):
    stack.start_router()
    stack.spawn("probe", [*probe_argv, "--slow-s", "30"])
    stack.wait_alive(["router", "probe"])
    stack.put("user", example("user"))
    time.sleep(0.3)  # the handler is now sleeping
    code, seconds = stack.stop("probe", signal.SIGTERM)
    assert code == 0
    assert seconds < 2.0


def test_a_service_still_waiting_for_its_router_exits_at_sigterm(stack, probe_argv):
    # No router is started: the probe waits in zenoh.open, in native code.
    probe = stack.spawn("probe", probe_argv)
    probe.wait_for_line("waiting for the Zenoh network", timeout=15)
    code, seconds = stack.stop("probe", signal.SIGTERM)
    assert code == 0, probe.log()
    assert seconds < 2.0


def test_the_router_exits_within_two_seconds_of_sigterm(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    code, seconds = stack.stop("router")
    assert code == 0
    assert seconds < 2.0


@pytest.mark.skipif(shutil.which("zenoh", path=os.path.dirname(sys.executable)) is None,
                    reason="zenoh-cli is not installed (pip install 'cbgo[tools]')")
def test_zenoh_cli_decodes_our_messages_with_the_msgpack_codec(stack):
    stack.start_router()
    stack.wait_alive(["router"])
    zenoh_cli = os.path.join(os.path.dirname(sys.executable), "zenoh")
    sub = stack.spawn("zenoh-cli", [zenoh_cli, "--mode", "client", "--connect", stack.endpoint,
                                    "subscribe", "-k", "cbgo/**", "--decoder", "msgpack"])
    message = example("gaze")
    stack.put("gaze", message)
    deadline = time.monotonic() + 15
    while not sub.log().strip() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert json.loads(sub.log().strip().splitlines()[0]) == message
