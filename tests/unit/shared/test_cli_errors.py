"""Every `cbgo` verb, given bad input, ends non-zero with a short message and no internals.

Each verb of `cbgo.cli.main.VERBS` runs as a real process with input a user gets wrong: a
file that is not there, malformed JSON or YAML, an unknown name, a malformed key, or a router
that is not there (a free local port, a short ``--connect-timeout``). Its output must be a few
lines that name the problem, without a Python traceback, a Zenoh error class or a path into
Zenoh's Rust sources. The processes run in parallel; nothing here depends on timing.
"""

import socket
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

from cbgo.cli.main import VERBS
from cbgo.cli.status import no_answer
from cbgo.client import unreachable
from cbgo.errors import zenoh_reason

CLI = [sys.executable, "-m", "cbgo.cli.main"]
MAX_LINES = 4  # "one or a few lines"; argparse's usage line and error line are two
INTERNALS = ("Traceback", ".rs:", "ZError", "Json5Err")


def free_port() -> int:
    """A local TCP port nothing listens on (bound once, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


ROUTER = "<router>"  # stands for --connect to a port nobody listens on, short timeout
NO_ROUTER = ["no Zenoh router answered", "cbgo up", "cbgo router", "--connect"]

# case -> (argv after `cbgo`, texts the output must contain); paths are in the case's folder.
CASES = {
    "demo: unknown session": (["demo", "--session", "none.yaml", "--no-start"], ["none.yaml"]),
    "up: unknown service": (["up", "nosuch"], ["nosuch"]),
    "router: missing settings file": (["router", "--settings", "none.yaml"], ["none.yaml"]),
    "ls: no router": (["ls", ROUTER], NO_ROUTER),
    "status: no router": (["status", "nosuch", ROUTER], NO_ROUTER),
    "echo: malformed key": (["echo", "hands//frame", ROUTER], ["hands//frame"]),
    "echo: no router": (["echo", "hands/frame", ROUTER], NO_ROUTER),
    "hz: no router": (["hz", "hands/frame", ROUTER], NO_ROUTER),
    "get: malformed JSON": (["get", "intent/infer", "--payload", "{v: 1}", ROUTER],
                            ["not valid JSON", "double quotes"]),
    "get: missing payload file": (["get", "intent/infer", "--payload", "@none.json", ROUTER],
                                  ["none.json", "No such file"]),
    "pub: malformed JSON": (["pub", "user", "{'user': 'alice'}", ROUTER], ["not valid JSON"]),
    "pub: unstamped message": (["pub", "user", '{"user": "alice"}', ROUTER], ["--stamp"]),
    "pub: wrong field type": (["pub", "user", '{"user": 5}', ROUTER],
                              ["user: expected a non-empty string", "--example"]),
    "wait-alive: no router": (["wait-alive", "episode", ROUTER], NO_ROUTER),
    "bench: unknown bench": (["bench", "nosuch"], ["nosuch"]),
    "train: unknown trainer": (["train", "nosuch"], ["nosuch"]),
    "record: malformed key": (["record", "-o", "r.mcap", "a//b", ROUTER], ["a//b"]),
    "replay: missing file": (["replay", "missing.mcap", ROUTER], ["missing.mcap"]),
    "export: missing file": (["export", "missing.mcap", "-o", "out.mcap"], ["missing.mcap"]),
    "foxglove: missing settings file": (["foxglove", "--settings", "none.yaml"],
                                        ["none.yaml"]),
    "data: missing data set": (["data", "intent", "info", "none"], ["none"]),
    "feedback: no router": (["feedback", "--action", "pick_up", ROUTER], NO_ROUTER),
    "mapping: action that never applies": (["mapping", "set", "--user", "ann", "--personal-dir",
                                            ".", "grab", "open", "--on", "cup"],
                                           ["open never applies to a cup", "drawer"]),
    "gestures: unknown action": (["gestures", "nosuch"], ["nosuch"]),
    "sim: malformed scene file": (["sim", "reset", "--scene", "bad.yaml", ROUTER],
                                  ["bad.yaml", "line 3"]),
    "sim: params not an object": (["sim", "act", "pour", "cup1", "--params", "90", ROUTER],
                                  ["--params must be a JSON object"]),
    "plot: missing recording": (["plot", "episode", "missing.mcap"], ["missing.mcap"]),
    "plan: no router": (["plan", "show", ROUTER], NO_ROUTER),
    "web: missing recording": (["web", "--replay", "missing.mcap"], ["missing.mcap"]),
    "certs: unwritable directory": (["certs", "make", "a-file/certs"],
                                    ["a-file", "Not a directory"]),
}


def _argv(argv: list[str], router: list[str]) -> list[str]:
    return [part for arg in argv for part in (router if arg == ROUTER else [arg])]


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory):
    """Runs every case once, in parallel, in one folder; returns {case: finished process}."""
    folder = tmp_path_factory.mktemp("cli-errors")
    (folder / "bad.yaml").write_text("objects:\n  - name: [cup1\n    type: cup\n")
    (folder / "a-file").write_text("")
    router = ["--connect", f"tcp/127.0.0.1:{free_port()}", "--connect-timeout", "0.3"]

    def run(argv: list[str]) -> subprocess.CompletedProcess:
        return subprocess.run([*CLI, *_argv(argv, router)], capture_output=True, text=True,
                              timeout=180, cwd=folder, stdin=subprocess.DEVNULL)

    with ThreadPoolExecutor(max_workers=8) as pool:
        done = pool.map(run, [argv for argv, _ in CASES.values()])
        return dict(zip(CASES, done, strict=True))


def test_every_verb_has_a_bad_input_case():
    covered = {argv[0] for argv, _ in CASES.values()}
    assert covered == set(VERBS), f"verbs without a bad-input case: {set(VERBS) - covered}"


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_ends_with_a_short_message_that_names_the_problem(outcomes, case):
    argv, must_contain = CASES[case]
    done = outcomes[case]
    output = (done.stdout + done.stderr).strip()
    shown = f"cbgo {' '.join(argv)} (exit {done.returncode}):\n{output}"
    assert done.returncode != 0, shown
    for internal in INTERNALS:
        assert internal not in output, shown
    assert 1 <= len(output.splitlines()) <= MAX_LINES, shown
    for text in must_contain:
        assert text in output, f"{text!r} missing from {shown}"


# ------------------------------------------------------------------ messages that need a router


def test_an_unknown_service_name_suggests_the_closest_and_cbgo_ls():
    text = no_answer("episod", "cbgo/@ctl/episod/status", ["episode", "intent", "router"])
    assert "did you mean episode?" in text and "`cbgo ls`" in text
    assert "episode, intent, router" in text


def test_no_live_service_at_all_says_how_to_start_them():
    text = no_answer("episode", "cbgo/@ctl/episode/status", [])
    assert "`cbgo up`" in text and "--prefix" in text


def test_the_no_router_message_keeps_the_endpoint_and_says_how_to_start_one():
    text = unreachable(["tcp/10.0.0.5:7447"], 5.0, "Unable to connect to any of "
                       "[Single(tcp/10.0.0.5:7447)]. Timeout!")
    assert "tcp/10.0.0.5:7447 within 5 s" in text and "Timeout" not in text
    assert "`cbgo up`" in text and "`cbgo router`" in text and "--connect" in text


def test_zenoh_errors_lose_their_rust_source_paths_and_wrappers():
    raw = ('Json5Err(Message { msg: "Endpoints must be of the form <protocol>/<address>: '
           'nonsense at /root/.cargo/git/checkouts/zenoh-9c59/cc83980/commons/zenoh-protocol/'
           'src/core/endpoint.rs:615.", location: Some(Location { line: 1, column: 2 }) }) at '
           '/root/.cargo/git/checkouts/zenoh-9c59/cc83980/zenoh/src/api/config.rs:86.')
    assert zenoh_reason(raw) == "Endpoints must be of the form <protocol>/<address>: nonsense"
    assert zenoh_reason("Invalid Key Expr `a//b`: empty chunks are forbidden at "
                        "/x/borrowed.rs:777.") == "Invalid Key Expr `a//b`: empty chunks are " \
                                                  "forbidden"
