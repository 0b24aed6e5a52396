"""planner through real processes: against the symbolic robot of tests/fakes, and mujoco-sim.

The symbolic robot (tests/fakes/symbolic_robot.py) always runs, so the planner's process-level
behaviour (intent in, robot/act out, plan/status, robot/stop) is tested even where mujoco-sim is
not built; the mujoco-sim tests skip with the reason when it is not.
"""

import sys
import time
from pathlib import Path

import pytest

from cbgo import keys, registry, wire

FAKES = Path(__file__).parents[1] / "fakes"
PAPER_SCENE = {
    "objects": [
        {"name": "cup1", "type": "cup", "position": [0.44, 0.06, 0.2], "size": 0.06,
         "full": False, "on": None, "inside": None},
        {"name": "drawer1", "type": "drawer", "position": [0.68, -0.18, 0.055], "size": 0.11,
         "open": False},
    ],
    "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": False, "holding": "cup1"},
}
PAPER_SEQUENCE = [("place", "cup1"), ("open", "drawer1"), ("pick_up", "cup1"),
                  ("put_into", "drawer1")]


def intent(action, obj, **params):
    return {"v": 1, "ts": time.time(), "episode": "ep-it", "action": action, "object": obj,
            "params": params, "p_action": {action: 0.9}, "p_object": {obj: 0.9},
            "confidence": 0.9, "status": "accepted", "reason": "", "model": "test"}


def steps(status):
    return [(s["action"], s["object"]) for s in status["sequence"]]


def start(stack, robot_argv, robot_name, timeout=30.0):
    stack.start_router()
    if robot_argv:
        stack.spawn(robot_name, robot_argv)
    else:
        stack.start_service(robot_name)
    stack.start_service("planner")
    stack.wait_alive(["router", robot_name, "planner"], timeout=timeout)


def reset(stack, scene, timeout=60.0):
    replies = stack.query(stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": scene},
                          timeout=timeout)
    assert replies and replies[0][0] and replies[0][1]["ok"], replies
    return replies[0][1]["scene"]


def symbolic(*flags):
    return [sys.executable, str(FAKES / "symbolic_robot.py"), *flags]


# ============================================================== symbolic robot (always runs)


def test_the_paper_example_runs_on_a_symbolic_robot_process(stack):
    start(stack, symbolic("--state-rate-hz", "5", "--robot-rate-hz", "5"), "symbolic-robot")
    plans = stack.collect("plan/status")
    scenes = stack.collect("scene/state")
    reset(stack, PAPER_SCENE)
    show = stack.spawn("plan-show", [sys.executable, "-m", "cbgo.cli.main", "plan", "show",
                                     "--once", "--timeout", "30"])
    show.wait_for_line("listening on", timeout=15)  # printed once it has subscribed
    stack.put("intent", intent("put_into", "drawer1"))
    end = plans.first(lambda m: m["state"] != "running", timeout=30)
    assert (end["state"], end["error"]) == ("success", None), (
        end["sequence"], stack.logs(["planner", "mujoco-sim"]))
    assert steps(end) == PAPER_SEQUENCE
    assert show.wait(10) == 0, show.log()
    assert "plan put_into(drawer1): " in show.log()
    assert all(s["state"] == "done" for s in end["sequence"])
    wire.validate(end, wire.PLAN_STATUS, "cbgo/plan/status")
    after = scenes.first(lambda m: any(o.get("inside") == "drawer1" for o in m["objects"]))
    assert after["robot"]["holding"] is None
    assert stack.status("planner")["plans"]["succeeded"] == 1


def test_a_target_the_robot_refuses_ends_in_a_clear_failure(stack):
    start(stack, symbolic("--refuse", "pick_up"), "symbolic-robot")
    plans = stack.collect("plan/status")
    reset(stack, PAPER_SCENE)
    stack.put("intent", intent("put_into", "drawer1"))
    end = plans.first(lambda m: m["state"] != "running", timeout=30)
    assert end["state"] == "failure"
    assert end["error"] == "pick_up(cup1) failed 2 times: refused: the target is out of reach"
    assert steps(end) == PAPER_SEQUENCE[:3]
    assert [s["state"] for s in end["sequence"]] == ["done", "done", "failed"]


def test_robot_stop_aborts_the_plan_at_once(stack):
    start(stack, symbolic("--delay-s", "3"), "symbolic-robot")
    plans = stack.collect("plan/status")
    reset(stack, PAPER_SCENE)
    stack.put("intent", intent("put_into", "drawer1"))
    plans.wait(lambda m: m["sequence"] and m["sequence"][0]["state"] == "running")
    t0 = time.monotonic()
    stack.put("robot/stop", {"v": 1, "ts": time.time(), "reason": "test"})
    end = plans.first(lambda m: m["state"] != "running", timeout=5)
    assert time.monotonic() - t0 < 2.0  # the action in flight would take 3 s
    assert (end["state"], end["error"]) == ("failure", "stopped: test")
    time.sleep(0.5)
    robot = stack.status("symbolic-robot")
    assert robot["stops"] == 1 and robot["log"] == []  # stopped mid-place; nothing sent after


# ========================================================== mujoco-sim (when installed)

needs_sim = pytest.mark.skipif(not registry.by_name("mujoco-sim").exists(),
                               reason="mujoco-sim is not installed: "
                                      "cbgo.services.mujoco_sim.main does not exist")


@needs_sim
@pytest.mark.timeout(400)
def test_the_paper_example_in_mujoco_ends_with_the_cup_in_the_drawer(stack):
    start(stack, None, "mujoco-sim", timeout=120)
    plans = stack.collect("plan/status")
    scenes = stack.collect("scene/state")
    reset(stack, PAPER_SCENE)
    stack.put("intent", intent("put_into", "drawer1"))
    end = plans.first(lambda m: m["state"] != "running", timeout=300)
    assert (end["state"], end["error"]) == ("success", None), (
        end["sequence"], stack.logs(["planner", "mujoco-sim"]))
    got = steps(end)
    assert got[-1] == ("put_into", "drawer1") and ("open", "drawer1") in got
    assert got in (PAPER_SEQUENCE, PAPER_SEQUENCE[1:]), got  # place first, if the tree says so
    time.sleep(0.5)
    cup = next(o for o in scenes.last()["objects"] if o["name"] == "cup1")
    assert cup["inside"] == "drawer1"


@needs_sim
@pytest.mark.timeout(300)
def test_an_unreachable_cup_in_mujoco_is_refused_at_reset_not_failed_later(stack):
    start(stack, None, "mujoco-sim", timeout=120)
    far = {"objects": [{"name": "cup9", "type": "cup", "position": [1.05, 0.0, 0.03],
                        "size": 0.06, "full": True, "on": None, "inside": None}],
           "robot": {"tcp": [0.44, 0.06, 0.26], "gripper_open": True, "holding": None}}
    (ok, reply), = stack.query(stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": far},
                               timeout=60)
    assert ok and reply["ok"] is False and reply["scene"] is None
    assert reply["error"].startswith("outside the workspace: cup9 at (1.05, 0.00) is outside "
                                     "the workspace"), reply["error"]
    (ok, reply), = stack.query(stack.keys.of(keys.SIM_INFO), {"v": 1})
    assert ok and reply["robot"] == "mujoco-sim" and reply["workspace"]["table_area"] == {
        "x": [0.3, 0.7], "y": [-0.2, 0.2]}
