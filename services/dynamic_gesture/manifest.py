"""dynamic-gesture's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="dynamic-gesture",
    issue=5,
    summary="stroke segmentation and dynamic gestures (ProMP + DTW)",
    order=30,
    subscribes=(keys.HANDS_FRAME,),
    publishes=(keys.GESTURES_DYNAMIC,),
    controls=("reload",),
    service="cbgo.services.dynamic_gesture.main:DynamicGesture",
    trainer=Tool(
        "dynamic", "cbgo.services.dynamic_gesture.train", "dynamic-gesture templates + calibration"
    ),
    benches=(
        Tool(
            "dynamic",
            "cbgo.services.dynamic_gesture.bench",
            "dynamic gestures: accuracy, ECE, latency",
        ),
    ),
    demonstrate=Tool(
        "dynamic", "cbgo.services.dynamic_gesture.demonstrate", "a movement (dynamic-gesture)"
    ),
)
