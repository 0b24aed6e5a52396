"""The workspace in mujoco-sim: what the arm reaches, scenes refused at reset, sim/info, and
the scene it reports when a held object hangs in a drawer."""

import itertools

import mujoco
import numpy as np
import pytest

from cbgo import keys, wire
from cbgo.services.mujoco_sim import observe, scenes
from cbgo.services.mujoco_sim.build import HOME_Q
from cbgo.services.mujoco_sim.ik import top_down
from cbgo.services.mujoco_sim.main import MujocoSim, MujocoSimSettings
from cbgo.services.mujoco_sim.plan import tcp_below_top
from cbgo.testing import FakeBus
from cbgo.world import DEFAULT_GRID, check_consistent, table_area, workspace_info


def test_the_arm_reaches_every_corner_of_the_table_area_top_down_from_the_table_to_the_top(
        fixed_scene):
    ik = scenes.load(fixed_scene).sim.ik
    area = table_area()
    top = DEFAULT_GRID.position((0, 0, DEFAULT_GRID.shape[2] - 1))[2]
    missed = []
    for x, y, z in itertools.product(area.x, area.y, (0.02, 0.05, 0.08, top)):
        if not ik.solve(np.array([x, y, z]), top_down(0.0), HOME_Q, iterations=100).ok:
            missed.append((x, y, z))
    assert missed == []


def test_a_scene_with_an_object_off_the_table_area_is_refused_before_it_is_built(fixed_scene):
    for spec in fixed_scene["objects"]:
        if spec["name"] == "drawer1":
            spec["position"] = [0.6, 0.3, 0.055]
    with pytest.raises(scenes.SceneError, match=r"^outside the workspace: drawer1 at "
                                                r"\(0\.60, 0\.30\) is outside the workspace"):
        scenes.load(fixed_scene)


def test_reset_refuses_a_scene_outside_the_workspace_and_keeps_the_world(fixed_scene):
    bus = FakeBus(MujocoSim(MujocoSimSettings()))
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": fixed_scene})
    assert ok and reply["ok"], reply
    far = {**fixed_scene, "objects": [dict(o) for o in fixed_scene["objects"]]}
    far["objects"][0]["position"] = [0.44, -0.3, 0.03]
    ok, reply = bus.query(keys.SIM_RESET, {"v": 1, "scene": far})
    assert ok and reply["ok"] is False and reply["scene"] is None
    assert reply["error"].startswith("outside the workspace: cup1 at (0.44, -0.30)")
    assert bus.service.status_extra()["scene_source"] == "scene"
    kept = {o["name"]: o for o in observe.observe_objects(bus.service.sim)}
    assert kept["cup1"]["position"][1] == pytest.approx(-0.18, abs=0.005)
    bus.stop()


def test_info_answers_the_same_workspace_as_the_world_model():
    bus = FakeBus(MujocoSim(MujocoSimSettings()))
    ok, reply = bus.query(keys.SIM_INFO, {"v": 1})
    assert ok, reply
    wire.validate(reply, wire.SIM_INFO_REPLY, "cbgo/sim/info")
    assert reply["robot"] == "mujoco-sim" and reply["workspace"] == workspace_info()
    bus.stop()


def test_a_held_cup_hanging_in_an_open_drawer_is_held_not_inside(scene_file):
    sim = scenes.load(scene_file("put_into")).sim  # cup1 held, drawer1 open
    item = sim.items["cup1"]
    # Where a put_into that stopped short leaves it: in the gripper, 1 cm over the tray.
    cup = scenes.tray_spot(sim, "drawer1", item.dims.half_height) + [0.0, 0.0, 0.01]
    tcp = cup + [0.0, 0.0, item.dims.half_height - tcp_below_top(item)]
    solved = sim.ik.solve(tcp, top_down(0.0), sim.q, iterations=100)
    assert solved.ok
    sim.data.qpos[sim.built.arm_qpos] = solved.q
    sim.data.qpos[item.qpos:item.qpos + 3] = cup
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.holding == "cup1"
    assert observe.inside_of(sim, "cup1") == "drawer1"  # geometrically, its centre is in there
    message = observe.scene_state(sim, 1)
    objects = {o["name"]: o for o in message["objects"]}
    assert objects["cup1"]["inside"] is None and objects["drawer1"]["contains"] == []
    assert message["robot"]["holding"] == "cup1"
    assert check_consistent(message) == []
