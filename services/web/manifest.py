"""web's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="web",
    issue=19,
    summary="a live web page of what cbgo sees and decides; STOP and feedback",
    order=5,
    subscribes=(
        keys.HANDS_FRAME,
        keys.GAZE,
        keys.USER,
        keys.GESTURES_STATIC,
        keys.GESTURES_DYNAMIC,
        keys.EPISODE_EVENT,
        keys.EPISODE_SUMMARY,
        keys.SCENE_STATE,
        keys.INTENT,
        keys.INTENT_FEEDBACK,
        keys.PLAN_STATUS,
        keys.ROBOT_STATE,
        keys.ROBOT_STOP,
    ),
    publishes=(keys.ROBOT_STOP, keys.INTENT_FEEDBACK),
    asks=(keys.SIM_INFO,),
    service="cbgo.services.web.main:Web",
    benches=(
        Tool("web", "cbgo.services.web.bench", "web's CPU share under 120 Hz hands, page rates"),
    ),
)
