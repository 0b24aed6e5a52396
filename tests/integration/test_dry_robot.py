"""dry-robot through real processes: the planner drives it, `cbgo up --robot dry` starts it."""

import sys

from test_planner import PAPER_SCENE, PAPER_SEQUENCE, intent, reset, steps

from cbgo import keys, wire
from cbgo.world import workspace_info

CLI = [sys.executable, "-m", "cbgo.cli.main"]


def test_the_paper_example_on_dry_robot_ends_with_the_cup_in_the_drawer(stack):
    stack.start_router()
    stack.start_service("dry-robot", "--action-s", "0.05", "--state-rate-hz", "5",
                        "--robot-rate-hz", "5")
    stack.start_service("planner")
    stack.wait_alive(["router", "dry-robot", "planner"])
    plans = stack.collect("plan/status")
    scenes = stack.collect("scene/state")
    reset(stack, PAPER_SCENE)
    stack.put("intent", intent("put_into", "drawer1"))
    end = plans.first(lambda m: m["state"] != "running", timeout=30)
    assert (end["state"], end["error"]) == ("success", None), (
        end["sequence"], stack.logs(["planner", "dry-robot"]))
    assert steps(end) == PAPER_SEQUENCE
    after = scenes.first(lambda m: any(o.get("inside") == "drawer1" for o in m["objects"]))
    cup = next(o for o in after["objects"] if o["name"] == "cup1")
    assert cup["inside"] == "drawer1" and after["robot"]["holding"] is None
    status = stack.status("dry-robot")
    assert status["actions"] == {"actions": 4, "ok": 4, "refused": 0, "stopped": 0,
                                 "inconsistent": 0}


def test_render_info_and_resets_it_cannot_execute_in_are_answered_with_reasons(stack):
    stack.start_router()
    stack.start_service("dry-robot")
    stack.wait_alive(["router", "dry-robot"])
    (ok, reason), = stack.query(stack.keys.of(keys.SIM_RENDER), {"v": 1})
    assert not ok and reason.startswith("dry-robot has no renderer; ")
    bad = {"objects": [{"name": "box1", "type": "box", "position": [0.4, 0.0, 0.03],
                        "size": 0.05, "on": "box1"}]}
    (ok, reply), = stack.query(stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": bad})
    assert ok and reply["ok"] is False and "box1 stands on 'box1'" in reply["error"]
    wire.validate(reply, wire.SIM_RESET_REPLY, "cbgo/sim/reset")
    far = {"objects": [{"name": "cup1", "type": "cup", "position": [0.44, 0.3, 0.03],
                        "size": 0.06}]}
    (ok, reply), = stack.query(stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": far})
    assert ok and reply["ok"] is False and reply["scene"] is None
    assert reply["error"].startswith("outside the workspace: cup1 at (0.44, 0.30)")
    (ok, reply), = stack.query(stack.keys.of(keys.SIM_INFO), {"v": 1})
    assert ok and reply["robot"] == "dry-robot", reply
    assert reply["workspace"] == workspace_info()


def test_cbgo_up_with_robot_dry_starts_dry_robot_in_place_of_mujoco_sim(stack):
    up = stack.spawn("up", [*CLI, "up", "--robot", "dry", "--router-listen", stack.endpoint,
                            "mujoco-sim"])
    stack.wait_alive(["router", "dry-robot"], timeout=60)
    ready = up.wait_for_line("ready: ", timeout=30)
    assert "mujoco-sim" not in stack.alive()
    assert "mujoco-sim" not in ready.split("ready: ", 1)[1]
    code, _ = stack.stop("up")
    assert code == 0, up.log()
