"""leap-bridge's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="leap-bridge",
    issue=3,
    summary="hand frames from a Leap Motion, a recording or a simulated user",
    order=10,
    subscribes=(keys.SCENE_STATE,),
    publishes=(keys.HANDS_FRAME, keys.GAZE, keys.USER),
    controls=("play",),
    service="cbgo.services.leap_bridge.main:LeapBridge",
    benches=(
        Tool(
            "bridge",
            "cbgo.bench.bridge",
            "leap-bridge frame stream: rate and jitter at 30/60/120 Hz",
        ),
    ),
)
