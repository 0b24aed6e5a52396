"""`cbgo demo` through real processes: the paper's story, with MuJoCo and with faults.

Each test runs the CLI as a user does (a child process that starts `cbgo up`: the router and
the seven services), on a free loopback port, and reads what it wrote: its exit code, the
per-step results, the MCAP recording and the figures.

- With mujoco-sim: every scripted step ends as scripted, with renders of the world.
- Against a running `cbgo up --robot dry`, `--no-start` plays on the robot that is alive, and
  asking for the other one ends at once, naming the option that fits.
- With dry-robot and `--faults all`: each of the seven services and the router is killed with
  SIGKILL once mid-session; every one comes back as a new process without restarting anyone
  else, lost episodes are repeated, and the session still ends as scripted.
"""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from cbgo import registry
from cbgo.recording import read_recording
from cbgo.testing import free_port

PNG = b"\x89PNG\r\n\x1a\n"
STORY = [("accepted", "pick_up", "cup1"), ("accepted", "pour", "cup2"),
         ("accepted", "put_into", "drawer1"), ("accepted", "pick_up", "box1"),
         ("accepted", "pick_up", "cup2"), ("accepted", "move_left", None),
         ("accepted", "move_right", None)]


def run_demo(out, *flags, timeout=600):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    done = subprocess.run([sys.executable, "-m", "cbgo.cli.main", "demo", "-o", str(out),
                           "--router-listen", endpoint, *flags],
                          capture_output=True, text=True, timeout=timeout)
    result = json.loads((out / "result.json").read_text()) if (
        out / "result.json").exists() else None
    return done, result


def check_story(done, result):
    assert result is not None, done.stdout[-3000:] + done.stderr[-3000:]
    got = [(s["intent"] or {}).get("status") for s in result["steps"]]
    assert all(s["ok"] for s in result["steps"]), (got, done.stdout[-6000:])
    assert [(s["intent"]["status"], s["intent"]["action"], s["intent"]["object"])
            for s in result["steps"]] == STORY
    assert done.returncode == 0, done.stdout[-3000:]
    assert result["rejected_messages"] == 0  # every message on the followed keys was valid
    put_into = result["steps"][2]["plan"]["sequence"]
    assert ["open", "drawer1", "done"] in put_into  # the tree repaired the closed drawer
    assert put_into[-1] == ["put_into", "drawer1", "done"]
    asked = result["steps"][3]  # the ambiguous grab, asked back and confirmed by gestures
    assert asked["question"]["state"] == "open" and len(asked["question"]["candidates"]) > 1
    assert asked["intent"]["clarification"] == asked["question"]["id"]
    assert asked["answers"] and asked["plan"]["state"] == "success"


def check_recording(out, result):
    messages = list(read_recording(out / "session.mcap"))
    intents = [m.message for m in messages if m.key == "cbgo/intent"]
    episodes = {s["episode"] for s in result["steps"]}
    assert episodes <= {i["episode"] for i in intents}
    assert {m.key for m in messages} >= {"cbgo/hands/frame", "cbgo/gestures/static",
                                         "cbgo/gestures/dynamic", "cbgo/episode/summary",
                                         "cbgo/plan/status", "cbgo/scene/state",
                                         "cbgo/intent/clarify"}
    assert (out / "episode.png").read_bytes().startswith(PNG)
    timeline = (out / "timeline.txt").read_text()
    assert "intent accepted: put_into(drawer1)" in timeline
    assert "intent low_confidence" in timeline


needs_sim = pytest.mark.skipif(not registry.by_name("mujoco-sim").exists(),
                               reason="mujoco-sim is not installed")


@needs_sim
@pytest.mark.timeout(600)
def test_the_demo_tells_the_papers_story_in_mujoco(tmp_path):
    out = tmp_path / "demo"
    done, result = run_demo(out)
    check_story(done, result)
    check_recording(out, result)
    assert result["robot"] == "mujoco-sim"
    for name in ("before.png", "after.png"):
        assert (out / name).read_bytes().startswith(PNG)
    assert (out / "before.png").read_bytes() != (out / "after.png").read_bytes()


@pytest.mark.timeout(900)
def test_the_session_survives_kill_9_of_every_process_with_dry_robot(tmp_path):
    out = tmp_path / "faults"
    done, result = run_demo(out, "--robot", "dry", "--faults", "all")
    check_story(done, result)
    check_recording(out, result)
    assert result["robot"] == "dry-robot"
    faults = {f["target"]: f for f in result["faults"]}
    assert set(faults) == {"router", "leap-bridge", "static-gesture", "dynamic-gesture",
                           "episode", "intent", "planner", "dry-robot"}
    for name, fault in faults.items():
        assert fault["ok"], fault
        assert fault["pid_after"] != fault["pid_before"], name
        assert fault["others_restarted"] == [], name
        assert fault["gone_s"] is not None and fault["back_s"] > fault["gone_s"], fault
    print("\nrecovery after kill -9 (s): " + ", ".join(
        f"{n} {f['back_s']:.2f}" for n, f in sorted(faults.items())))
    assert not (out / "before.png").exists()  # dry-robot has no renderer, and says so
    assert "dry-robot has no renderer" in (out / "timeline.txt").read_text()


@pytest.mark.timeout(600)
def test_the_demo_plays_on_the_robot_of_a_running_system(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with open(tmp_path / "up.log", "wb") as log:
        up = subprocess.Popen([sys.executable, "-m", "cbgo.cli.main", "up", "--robot", "dry",
                               "--no-color", "--router-listen", endpoint], stdout=log,
                              stderr=subprocess.STDOUT, start_new_session=True)
    try:
        demo = [sys.executable, "-m", "cbgo.cli.main", "demo", "--no-start", "--connect",
                endpoint, "--connect-timeout", "60"]
        out = tmp_path / "right"
        done = subprocess.run([*demo, "-o", str(out)], capture_output=True, text=True,
                              timeout=400)
        result = json.loads((out / "result.json").read_text()) if (
            out / "result.json").exists() else None
        check_story(done, result)
        assert result["robot"] == "dry-robot"
        assert "the running system's robot: dry-robot" in done.stdout
        started = time.monotonic()
        wrong = subprocess.run([*demo, "-o", str(tmp_path / "wrong"), "--robot", "mujoco"],
                               capture_output=True, text=True, timeout=240)
        assert wrong.returncode == 1 and "--robot dry" in wrong.stdout, wrong.stdout[-2000:]
        assert time.monotonic() - started < 120  # not the 180 s wait for a robot never there
    finally:
        os.killpg(up.pid, signal.SIGTERM)
        up.wait(30)
