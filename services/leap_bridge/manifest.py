"""leap-bridge's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="leap-bridge",
    summary="hand frames from a Leap Motion, a recording or a simulated user",
    order=10,
    subscribes=(keys.SCENE_STATE,),
    publishes=(keys.HANDS_FRAME, keys.GAZE, keys.USER),
    controls=("play",),
    service="cbgo.services.leap_bridge.main:LeapBridge",
)
