"""mujoco-sim through real processes: reset, state streams, act, malformed act, render, stop."""

import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cbgo import wire

SCENES = Path(__file__).parents[1] / "artifacts" / "scenes"


def _one(replies):
    assert len(replies) == 1, replies
    return replies[0]


def _start(stack, *flags):
    stack.start_router()
    stack.start_service("mujoco-sim", *flags)
    stack.wait_alive(["router", "mujoco-sim"], timeout=60)


def test_reset_publishes_the_scene_and_pick_up_holds_the_cup(stack):
    _start(stack, "--seed", "2")
    scenes = stack.collect("scene/state")
    robots = stack.collect("robot/state")
    ok, reply = _one(stack.query("cbgo/sim/reset", {"v": 1, "seed": 5}, timeout=30))
    assert ok and reply["ok"], reply
    wire.validate(reply, wire.SIM_RESET_REPLY, "cbgo/sim/reset")
    names = [o["name"] for o in reply["scene"]["objects"]]
    scenes.wait(lambda m: [o["name"] for o in m["objects"]] == names)
    for message in robots.wait():
        wire.validate(message, wire.ROBOT_STATE, "cbgo/robot/state")

    fixed = json.loads((SCENES / "fixed.json").read_text())
    ok, reply = _one(stack.query("cbgo/sim/reset", {"v": 1, "scene": fixed}, timeout=30))
    assert ok and reply["ok"], reply
    ok, reply = _one(stack.query("cbgo/robot/act", {"v": 1, "action": "pick_up",
                                                    "object": "cup1", "params": {}}, timeout=60))
    assert ok and reply["ok"], reply
    assert reply["scene"]["robot"]["holding"] == "cup1"
    scenes.wait(lambda m: m["robot"]["holding"] == "cup1")

    ok, reason = _one(stack.query("cbgo/robot/act", {"v": 1, "object": "cup1", "params": {}}))
    assert not ok and reason.startswith("rejected: ") and "action" in reason


def test_render_gives_a_png_and_stop_halts_a_paced_action(stack, tmp_path):
    _start(stack, "--realtime", "1")
    fixed = json.loads((SCENES / "fixed.json").read_text())
    ok, reply = _one(stack.query("cbgo/sim/reset", {"v": 1, "scene": fixed}, timeout=30))
    assert ok and reply["ok"], reply
    ok, reply = _one(stack.query("cbgo/sim/render", {"v": 1, "width": 160, "height": 120},
                                 timeout=30))
    if not ok and "cannot render" in reply:
        pytest.skip(f"no headless OpenGL (MUJOCO_GL=egl) here: {reply}")
    assert ok and reply["ok"] and reply["png"].startswith(b"\x89PNG\r\n\x1a\n")
    out = tmp_path / "snap" / "scene.png"
    done = subprocess.run([sys.executable, "-m", "cbgo.cli.main", "sim", "snapshot", "-o",
                           str(out), "--camera", "top", "--width", "64", "--height", "48"],
                          env=stack.env(), capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert out.read_bytes().startswith(b"\x89PNG") and f"wrote {out}" in done.stdout

    replies = []
    act = threading.Thread(target=lambda: replies.extend(stack.query(
        "cbgo/robot/act", {"v": 1, "action": "open", "object": "drawer1", "params": {}},
        timeout=30)))
    act.start()
    time.sleep(1.0)
    stop = stack.publisher("robot/stop")
    t0 = time.monotonic()
    stop.put(wire.encode({"v": 1, "ts": time.time(), "reason": "test"}))
    act.join(30)
    ok, reply = _one(replies)
    assert ok and not reply["ok"] and reply["error"] == "stopped", reply
    assert time.monotonic() - t0 < 1.0
    assert 0.1 < reply["duration_s"] < 2.5  # paced at real time: stopped after about 1 s
