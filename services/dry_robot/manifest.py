"""dry-robot's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="dry-robot",
    summary="the robot on the symbolic world model, no physics (no MuJoCo needed; "
    "fast plan checks)",
    order=71,
    replaces="mujoco-sim",
    subscribes=(keys.ROBOT_STOP,),
    publishes=(keys.SCENE_STATE, keys.ROBOT_STATE),
    answers=(keys.ROBOT_ACT, keys.SIM_RESET, keys.SIM_RENDER, keys.SIM_INFO),
    service="cbgo.services.dry_robot.main:DryRobot",
)
