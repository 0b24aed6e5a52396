"""foxglove-bridge's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="foxglove-bridge",
    issue=20,
    summary="the live traffic, 3D scene and log as a Foxglove WebSocket server",
    order=90,
    optional=True,
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
    service="cbgo.services.foxglove_bridge.main:FoxgloveBridge",
)
