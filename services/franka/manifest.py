"""franka's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="franka",
    summary="a Franka Research 3 through franky-control, on mujoco-sim's keys (optional extra "
    "'franka'; --dry-run plans without a robot)",
    order=72,
    replaces="mujoco-sim",
    subscribes=(keys.ROBOT_STOP,),
    publishes=(keys.SCENE_STATE, keys.ROBOT_STATE),
    answers=(keys.ROBOT_ACT, keys.SIM_RESET, keys.SIM_RENDER, keys.SIM_INFO),
    service="cbgo.services.franka.main:Franka",
)
