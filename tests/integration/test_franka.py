"""franka against franky-sim: a real libfranka network server, a real arm model, real objects.

Each test starts its own franky-sim (this file run as a script: `serve`) on a loopback address
of its own, with the scene's cups, boxes and drawers added to its MuJoCo world, then the router
and the franka service, and drives it over Zenoh. The objects' positions are read back from
franky-sim's physics (a JSON file the simulator process rewrites at `OBJECTS_HZ`).

franky-sim's measured-pose bug is worked around here, in the simulator process:
`BaseRobot.kinematics` returns pinocchio's shared frame placement, which the desired pose
computed next overwrites, so ``O_T_EE`` would report the *desired* pose. `serve` wraps it to
return a copy, so the TCP the service reads is the measured one.

What else the simulator process changes, each where it is done (docs/design/franka.md gives
the measurements): drawers hang clear of the ground and open either way (`drawer_direction`),
a scene may mark one "locked"; the hand's finger spring reaches the commanded grasp force, as
the real hand presses; cups and boxes have torsional friction. The same script serves a demo
(``--scene paper``).

franky-sim simulates no reflexes, limits or collision errors: the reflex path of the service is
not exercised here. The simulators run one at a time (the tests are serial): one franky-sim
takes most of a core.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cbgo import keys
from cbgo.foxglove.arm import link_points
from cbgo.services.franka.plan import HANDLE_WIDTH
from cbgo.world import drawer_direction
from cbgo.world.scene import DRAWER_FLOOR
from cbgo.world.workspace import DRAWER_HANDLE_OUT, DRAWER_TRAVEL_PER_SIZE

OBJECTS_HZ = 20  # how often the simulator process rewrites the objects' positions
HOST_BLOCK = 20 + os.getpid() % 200  # 127.0.<block>.x: apart from other test sessions
_hosts = itertools.count(10)
LOCKED_TRAVEL = 0.0005  # m a drawer the simulator's scene marks "locked" can move
# N/m per finger of franky-sim's hand: it presses with this spring on the width error, capped
# at the commanded force, where the real hand presses with the commanded force (20 N). Its own
# 1000 N/m gives 6 N for franka's 6 mm squeeze, and a cup turned for a pour slid 4 cm in the
# fingers; 4000 N/m reaches 20 N.
HAND_STIFFNESS = 4000.0

# the declared scene of every test here and of the bad-input battery
SCENE = json.loads((Path(__file__).parents[1] / "fixtures" / "franka" / "scene.json").read_text())


# ============================================================================ the simulator


def _body_xml(sim, obj: dict) -> None:
    """Adds one scene object to franky-sim's MuJoCo world (before it starts)."""
    import xml.etree.ElementTree as ET

    name, size = obj["name"], float(obj["size"])
    x, y, z = (float(v) for v in obj["position"])
    half = size / 2
    if obj["type"] != "drawer":
        body = ET.SubElement(sim.worldbody, "body", name=name, pos=f"{x} {y} {half}")
        ET.SubElement(body, "freejoint", name=f"{name}_free")
        # condim 4: torsional friction, as rubber finger pads have; without it a cup tilted
        # about the fingers' closing axis (a pour) turns freely between them
        ET.SubElement(body, "geom", type="box", size=f"{half} {half} {half}", mass="0.08",
                      friction="1.5 0.01 0.001", condim="4", rgba="0.8 0.4 0.2 1")
        return
    # a drawer: a fixed top plate (what put_on stands things on) and a tray (floor, front
    # panel, a bar handle 3 cm deep) on a slide joint out of the cabinet's front, the handle
    # where the world model grasps it (cbgo.world.workspace: DRAWER_HANDLE_OUT,
    # DRAWER_TRAVEL_PER_SIZE). The tray's floor is DRAWER_FLOOR thick and clear of the ground,
    # as a tray hangs on its rails: on the ground its friction held it against the grasp. The
    # cabinet is built opening towards the robot (-x) and turned by 180° about z where the
    # world model opens it away from the robot (`drawer_direction`), as mujoco-sim does.
    turned = "1 0 0 0" if drawer_direction(x) < 0 else "0 0 0 1"
    cabinet = ET.SubElement(sim.worldbody, "body", name=name, pos=f"{x} {y} {half}",
                            quat=turned)
    ET.SubElement(cabinet, "geom", type="box", pos=f"0 0 {half - 0.005}",
                  size=f"{half} {half} 0.005", rgba="0.5 0.5 0.6 1")
    tray = ET.SubElement(cabinet, "body", name=f"{name}_tray")
    travel = LOCKED_TRAVEL if obj.get("locked") else DRAWER_TRAVEL_PER_SIZE * size
    ET.SubElement(tray, "joint", name=f"{name}_slide", type="slide", axis="-1 0 0",
                  range=f"0 {travel}", damping="5", limited="true")
    floor = DRAWER_FLOOR / 2 - 0.001  # half the floor plate: its top at DRAWER_FLOOR
    ET.SubElement(tray, "geom", type="box", pos=f"0 0 {-half + DRAWER_FLOOR - floor}",
                  size=f"{half} {half - 0.01} {floor}", mass="0.2", friction="1.5 0.01 0.001")
    ET.SubElement(tray, "geom", type="box", pos=f"{-half + 0.005} 0 {-0.01}",
                  size=f"0.005 {half - 0.01} {half - 0.02}", mass="0.1")
    ET.SubElement(tray, "geom", type="box", pos=f"{-half - 0.009} 0 0",
                  size="0.009 0.004 0.004", mass="0.01")
    ET.SubElement(tray, "geom", type="box", pos=f"{-half - DRAWER_HANDLE_OUT} 0 0",
                  size=f"0.015 {HANDLE_WIDTH / 2} 0.008", friction="2 0.01 0.001", mass="0.02",
                  rgba="0.2 0.2 0.2 1")


def _positions(sim, scene: dict) -> dict:
    import mujoco

    out = {}
    for obj in scene["objects"]:
        body = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, obj["name"])
        entry = {"position": [float(v) for v in sim.data.xpos[body]]}
        if obj["type"] == "drawer":
            joint = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, f"{obj['name']}_slide")
            entry["opening"] = float(sim.data.qpos[sim.model.jnt_qposadr[joint]])
        out[obj["name"]] = entry
    return out


def serve(host: str, scene_file: str, objects_out: str) -> None:
    """Runs franky-sim with the scene's objects on `host` until killed."""
    import franky_sim
    from franky_sim.base_simulator import BaseRobot
    from franky_sim.mujoco_simulator import MujocoSimulator

    kinematics = BaseRobot.kinematics
    BaseRobot.kinematics = lambda self, q: kinematics(self, q).copy()  # the measured-pose fix
    if Path(scene_file).is_file():
        scene = json.loads(Path(scene_file).read_text())
    else:  # a bundled demo session's scene
        from cbgo.demo.session import load_session

        scene = load_session(scene_file).scene
    with MujocoSimulator() as sim:
        robot = sim.add_robot()
        robot._kp_hand[:] = HAND_STIFFNESS  # the grasp force reached, as the real hand does
        for obj in scene["objects"]:
            _body_xml(sim, obj)
        with franky_sim.SimulationServer(sim, hostname_candidates=[host]) as server:
            def write_positions():
                while True:
                    tmp = Path(objects_out + ".tmp")
                    tmp.write_text(json.dumps(_positions(sim, scene)))
                    tmp.replace(objects_out)
                    time.sleep(1.0 / OBJECTS_HZ)

            threading.Thread(target=write_positions, daemon=True).start()
            print(f"franky-sim serving on {host}", flush=True)
            server.run_forever()


# ============================================================================ fixtures


class Cell:
    """One franky-sim, the router and the franka service, with helpers to drive them."""

    def __init__(self, stack, tmp_path: Path, scene: dict):
        self.stack, self.tmp = stack, tmp_path
        self.host = f"127.0.{HOST_BLOCK}.{next(_hosts)}"
        self.scene_file = tmp_path / "scene.json"
        self.scene_file.write_text(json.dumps(scene))
        self.objects_file = tmp_path / "objects.json"
        self.sims = 0

    def start_sim(self, scene: dict | None = None, nice: int = 0):
        """Starts franky-sim (with `scene`'s objects, default the declared scene's).

        `nice`: its scheduling niceness, so that on a small machine processes that must keep
        pace with a clock (the gesture pipeline) come first.
        """
        self.sims += 1
        path = self.scene_file
        if scene is not None:
            path = self.tmp / f"sim-scene-{self.sims}.json"
            path.write_text(json.dumps(scene))
        sim = self.stack.spawn(f"franky-sim-{self.sims}", [
            *(["nice", "-n", str(nice)] if nice else []), sys.executable, __file__,
            "--host", self.host, "--scene", str(path), "--objects-out", str(self.objects_file)])
        sim.wait_for_line(f"franky-sim serving on {self.host}", timeout=60)
        return sim

    def start_service(self, *flags: str):
        self.stack.start_router()
        self.stack.start_service("franka", "--robot-ip", self.host, "--scene",
                                 str(self.scene_file), "--dynamics", "0.3", "--state-rate-hz", "10",
                                 "--robot-rate-hz", "50", *flags)
        self.stack.wait_alive(["router", "franka"], timeout=60)

    def act(self, action: str, obj: str | None = None, timeout: float = 240.0, **params):
        (ok, reply), = self.stack.query(self.stack.keys.of(keys.ROBOT_ACT), {
            "v": 1, "action": action, "object": obj, "params": params}, timeout=timeout)
        assert ok, reply
        return reply

    def objects(self) -> dict:
        """The objects as franky-sim's physics has them now."""
        deadline = time.monotonic() + 10
        while not self.objects_file.exists():
            assert time.monotonic() < deadline, "franky-sim wrote no object positions"
            time.sleep(0.05)
        return json.loads(self.objects_file.read_text())


@pytest.fixture
def cell(stack, tmp_path):
    return Cell(stack, tmp_path, SCENE)


def names(scene: dict) -> set[str]:
    return {o["name"] for o in scene["objects"]}


# ============================================================================ tests


@pytest.mark.timeout(240)
def test_pick_up_and_place_move_the_box_in_franky_sims_physics(cell):
    cell.start_sim()
    cell.start_service()
    states = cell.stack.collect("robot/state")
    start = cell.objects()["box1"]["position"]
    reply = cell.act("pick_up", "box1")
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))
    assert reply["scene"]["robot"]["holding"] == "box1"
    lifted = cell.objects()["box1"]["position"]
    assert lifted[2] > start[2] + 0.1, (start, lifted)  # in the fingers, at travel height
    width = states.last()["gripper_width"]
    assert width == pytest.approx(0.05, abs=0.006)
    state = states.last()  # the arm the viewers draw from the joints ends at the measured TCP
    assert link_points(state["joints"])[-1] == pytest.approx(state["tcp"], abs=0.005)
    reply = cell.act("place")
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))
    box = {o["name"]: o for o in reply["scene"]["objects"]}["box1"]
    placed = cell.objects()["box1"]["position"]
    assert placed[:2] == pytest.approx(box["position"][:2], abs=0.015), (placed, box)
    assert placed[2] == pytest.approx(0.025, abs=0.01)
    assert reply["scene"]["robot"]["holding"] is None and reply["scene"]["unknown"] == []


STORY = [("move_down", None), ("move_left", None), ("move_right", None), ("move_up", None),
         ("pick_up", "cup1"), ("pour", "cup2"), ("place", None), ("pick_up", "box1"),
         ("put_on", "drawer1"), ("open", "drawer1"), ("pick_up", "cup2"),
         ("put_into", "drawer1"), ("close", "drawer1")]


@pytest.mark.timeout(900)  # 105 s on an idle machine; a pour took over 90 s on a busy one
@pytest.mark.xfail(strict=False, reason="in one whole-suite run of a clean clone franky's "
                   "motion planner refused pick_up(cup1) (error code -111); it passed in every "
                   "other run, and a probe of 150 motions did not reproduce it")
def test_the_eleven_actions_on_a_scene_checked_in_franky_sims_physics(stack, tmp_path):
    scene = {**SCENE, "objects": [*SCENE["objects"], {
        "name": "cup2", "type": "cup", "position": [0.56, 0.18, 0.03], "size": 0.06}]}
    scene["objects"][1] = {**scene["objects"][1], "full": True}
    cell = Cell(stack, tmp_path, scene)
    cell.start_sim()
    cell.start_service()
    moved = []
    for action, obj in STORY:
        reply = cell.act(action, obj)
        assert reply["ok"], (action, obj, reply["error"], cell.stack.logs(["franka"]))
        moved.append(reply["scene"]["robot"]["tcp"])
        if action == "open":  # the tray really came out (the handle may slip a few mm)
            assert cell.objects()["drawer1"]["opening"] > 0.07, cell.objects()
    # the moves: one cell each, measured (franky-sim's arm sags up to 2.5 cm under gravity)
    assert moved[1][1] == pytest.approx(moved[0][1] - 0.12, abs=0.03)
    assert moved[3][2] == pytest.approx(moved[2][2] + 0.10, abs=0.03)
    world = {o["name"]: o for o in reply["scene"]["objects"]}
    physics = cell.objects()
    for name in ("cup1", "box1"):  # placed on the table, stacked on the cabinet
        assert physics[name]["position"] == pytest.approx(world[name]["position"], abs=0.02), (
            name, physics[name], world[name])
    assert world["box1"]["on"] == "drawer1" and physics["box1"]["position"][2] > 0.11
    assert world["cup2"]["inside"] == "drawer1" and not world["drawer1"]["open"]
    assert physics["drawer1"]["opening"] < 0.02
    tray = physics["drawer1"]["position"][0]  # the cup rode the tray back into the cabinet
    assert abs(physics["cup2"]["position"][0] - tray) < 0.05, physics
    assert reply["scene"]["unknown"] == []


@pytest.mark.timeout(300)
def test_a_drawer_opening_away_from_the_robot_and_a_locked_one_in_franky_sims_physics(
        stack, tmp_path):
    away = {"name": "drawer2", "type": "drawer", "position": [0.44, -0.18, 0.055], "size": 0.11}
    declared = {**SCENE, "objects": [away, {**SCENE["objects"][2], "position": [0.68, 0.18,
                                                                              0.055]}]}
    simulated = {**declared, "objects": [away, {**declared["objects"][1], "locked": True}]}
    cell = Cell(stack, tmp_path, declared)
    cell.start_sim(simulated)
    cell.start_service()
    reply = cell.act("open", "drawer2")  # nearer than 0.50 m: it opens away (+x)
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))
    assert cell.objects()["drawer2"]["opening"] > 0.07, cell.objects()
    reply = cell.act("close", "drawer2")
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))
    assert cell.objects()["drawer2"]["opening"] < 0.02, cell.objects()
    reply = cell.act("open", "drawer1")  # stuck: the handle slips out of the fingers
    assert not reply["ok"]
    assert reply["error"].startswith("the handle of drawer1 slipped out of the fingers: "), (
        reply["error"], cell.stack.logs(["franka"]))
    unknown, = reply["scene"]["unknown"]
    assert unknown["name"] == "drawer1" and "open(drawer1)" in unknown["why"]
    assert cell.objects()["drawer1"]["opening"] <= LOCKED_TRAVEL + 1e-4


@pytest.mark.timeout(180)
def test_a_target_outside_the_safety_box_is_refused_before_anything_moves(cell):
    cell.start_sim()
    cell.start_service("--box", "0.25,0.75,-0.30,0.30,0.005,0.30")
    states = cell.stack.collect("robot/state")
    before = states.first(lambda m: True)["joints"]
    reply = cell.act("pick_up", "box1")
    assert not reply["ok"]
    assert reply["error"].startswith("refused: the TCP target ") and "safety box" in reply[
        "error"], reply["error"]
    assert reply["duration_s"] == 0
    status = cell.stack.status("franka")
    assert status["actions"]["refused"] == 1
    later = states.first(lambda m: m["seq"] > 5)["joints"]
    assert later == pytest.approx(before, abs=1e-3)


def _battery():
    """The bad-input battery of tests/unit/franka/test_franka_bad_input.py."""
    import importlib.util

    path = Path(__file__).parents[1] / "unit" / "franka" / "test_franka_bad_input.py"
    spec = importlib.util.spec_from_file_location("franka_bad_input", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.timeout(240)
def test_the_bad_input_battery_against_franky_sim_kills_nothing(cell):
    from cbgo import client

    battery = _battery()
    cell.start_sim()
    cell.start_service()
    for payload in battery.STOP_JUNK:
        cell.stack.put_raw("robot/stop", payload)
    session = cell.stack.session()
    for label, suffix, payload in battery.battery():
        got = client.replies(session, cell.stack.keys.resolve(suffix), payload, timeout_s=30)
        assert len(got) == 1, (label, got)
        assert not got[0].ok or suffix != "robot/act" or b"refused" in bytes(got[0].payload), (
            label, got[0])
    held = {**battery.SCENE, "robot": {"holding": "cup1", "gripper_open": False}}
    (ok, reply), = cell.stack.query(cell.stack.keys.of(keys.SIM_RESET), {"v": 1, "scene": held},
                                    timeout=30)
    assert ok and not reply["ok"] and "the fingers are" in reply["error"], reply
    status = cell.stack.status("franka")
    assert status["counters"]["errors"] == 0 and status["counters"]["rejected"] > 0, status
    assert status["connected"] and status["actions"]["ok"] == 0
    reply = cell.act("move_down")  # still driving the arm
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))


@pytest.mark.timeout(180)
def test_robot_stop_halts_a_running_motion(cell):
    cell.start_sim()
    cell.start_service()
    states = cell.stack.collect("robot/state")
    replies = []
    worker = threading.Thread(target=lambda: replies.append(cell.act("move_down", distance=0.3)))
    worker.start()
    first = states.first(lambda m: m["moving"], timeout=30)
    states.first(lambda m: m["moving"] and abs(m["tcp"][2] - first["tcp"][2]) > 0.02,
                 timeout=30)
    t_stop = time.time()
    cell.stack.put("robot/stop", {"v": 1, "ts": t_stop, "reason": "test"})
    worker.join(30)
    assert replies and replies[0]["error"] == "stopped", replies
    # halted: the measured TCP stays put from some moment on; that moment is the stop latency.
    # Where it rests is read half a second after the action ended (the arm's own stop ends the
    # motion; a state stamped then says where it stays).
    t_end = time.time()
    states.first(lambda m: m["ts"] >= t_end + 0.5, timeout=30)
    trail = [m for m in states.items() if m["ts"] >= t_stop]
    last = trail[-1]["tcp"]
    still_since = next(m["ts"] for m in trail
                       if all(abs(a - b) < 0.002 for a, b in zip(m["tcp"], last, strict=True)))
    # the figure (goal: 0.5 s) is printed, not asserted: on a loaded machine franky-sim's
    # physics runs slower than the wall clock; halted it must be, short of its target
    print(f"robot/stop to a still TCP: {still_since - t_stop:.3f} s")
    assert last[2] > 0.06 + 0.05  # stopped well before the 3 cells down


@pytest.mark.timeout(180)
def test_a_grasp_of_nothing_is_reported_failed_and_the_object_becomes_unknown(cell):
    empty = {**SCENE, "objects": [o for o in SCENE["objects"] if o["name"] != "box1"]}
    cell.start_sim(empty)  # the user declares box1, but it is not there
    cell.start_service()
    reply = cell.act("pick_up", "box1")
    assert not reply["ok"]
    assert reply["error"].startswith("the grasp of box1 failed: the fingers closed to "), reply
    assert "box1" not in names(reply["scene"])
    unknown, = reply["scene"]["unknown"]
    assert unknown["name"] == "box1" and "pick_up(box1)" in unknown["why"]
    refused = cell.act("move_up")
    assert refused["error"].startswith("refused: the place of box1 is unknown"), refused


@pytest.mark.timeout(240)
def test_a_lost_connection_is_reported_and_a_reset_reconnects(cell):
    sim = cell.start_sim()
    cell.start_service()
    states = cell.stack.collect("robot/state")
    replies = []
    worker = threading.Thread(target=lambda: replies.append(cell.act("move_down", distance=0.3)))
    worker.start()
    states.first(lambda m: m["moving"], timeout=30)
    sim.signal(signal.SIGKILL)
    worker.join(60)
    assert replies and replies[0]["error"].startswith("connection: "), replies
    states.first(lambda m: m.get("connected") is False, timeout=10)
    status = cell.stack.status("franka")
    assert status["connected"] is False and status["lost"]
    refused = cell.act("move_up")
    assert refused["error"].startswith("refused: not connected to the robot at "), refused
    cell.start_sim()
    (ok, reply), = cell.stack.query(cell.stack.keys.of(keys.SIM_RESET), {"v": 1}, timeout=30)
    assert ok and reply["ok"], reply
    assert cell.stack.status("franka")["connects"] == 2
    reply = cell.act("move_down")  # the fresh simulator's arm starts above the top level
    assert reply["ok"], (reply["error"], cell.stack.logs(["franka"]))


@pytest.mark.timeout(900)
@pytest.mark.xfail(strict=False, reason="franky-sim's arm sometimes does not finish a motion of "
                   "the pour (step 2): 'the motion did not end within 60 s', the held cup found "
                   "back on the table; in 2 whole-suite runs of a clean clone (it passed in "
                   "CI's and in every run on its own; the service answers it safely: the pour "
                   "fails, the cups become unknown, later steps are refused)")
def test_cbgo_demo_plays_the_papers_story_on_franky_sim(stack, tmp_path):
    from cbgo.demo.session import load_session
    from cbgo.testing import free_port

    story = load_session("paper")
    cell = Cell(stack, tmp_path, story.scene)
    cell.start_sim(nice=10)  # the simulated users' gestures must be read in real time
    out = tmp_path / "demo"
    done = subprocess.run([
        sys.executable, "-m", "cbgo.cli.main", "demo", "--robot", "franka", "--robot-ip",
        cell.host, "-o", str(out), "--router-listen", f"tcp/127.0.0.1:{free_port()}"],
        capture_output=True, text=True, timeout=840, env={**os.environ, "CBGO_DYNAMICS": "0.3"})
    result = json.loads((out / "result.json").read_text()) if (
        out / "result.json").exists() else None
    assert result is not None, done.stdout[-3000:] + done.stderr[-3000:]
    assert [s["ok"] for s in result["steps"]] == [True] * 7, done.stdout[-6000:]
    assert done.returncode == 0 and result["robot"] == "franka", done.stdout[-3000:]
    put_into = result["steps"][2]["plan"]["sequence"]
    assert ["open", "drawer1", "done"] in put_into  # the tree opened the closed drawer first
    physics = cell.objects()  # cup1 rests in the drawer's tray, the drawer stays open
    assert physics["drawer1"]["opening"] > 0.07, physics
    assert physics["cup1"]["position"][0] == pytest.approx(0.68 - 0.08, abs=0.03), physics
    assert physics["cup1"]["position"][2] < 0.06, physics


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="franky-sim with a scene's objects, for the "
                                                 "franka tests (see the module docstring)")
    parser.add_argument("--host", required=True, help="loopback address to serve on")
    parser.add_argument("--scene", required=True, help="a contract scene body (JSON), or a "
                                                      "bundled demo session's name (paper)")
    parser.add_argument("--objects-out", required=True, help="file the positions go to")
    args = parser.parse_args()
    serve(args.host, args.scene, args.objects_out)
