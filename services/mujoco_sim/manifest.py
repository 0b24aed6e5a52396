"""mujoco-sim's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="mujoco-sim",
    summary="the Panda table-top world in MuJoCo; executes robot actions",
    order=70,
    subscribes=(keys.ROBOT_STOP,),
    publishes=(keys.SCENE_STATE, keys.ROBOT_STATE),
    answers=(keys.ROBOT_ACT, keys.SIM_RESET, keys.SIM_RENDER, keys.SIM_INFO),
    service="cbgo.services.mujoco_sim.main:MujocoSim",
)
