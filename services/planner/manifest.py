"""planner's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="planner",
    summary="behaviour trees that turn an intent into robot actions",
    order=60,
    subscribes=(keys.INTENT, keys.SCENE_STATE, keys.ROBOT_STOP),
    publishes=(keys.PLAN_STATUS,),
    asks=(keys.ROBOT_ACT,),
    service="cbgo.services.planner.main:Planner",
)
