"""dynamic-gesture's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="dynamic-gesture",
    summary="stroke segmentation and dynamic gestures (ProMP + DTW)",
    order=30,
    subscribes=(keys.HANDS_FRAME, keys.USER),
    publishes=(keys.GESTURES_DYNAMIC,),
    controls=("reload",),
    service="cbgo.services.dynamic_gesture.main:DynamicGesture",
    demonstrate=Tool(
        "dynamic", "cbgo.services.dynamic_gesture.demonstrate", "a movement (dynamic-gesture)"
    ),
    calibrate=Tool(
        "dynamic", "cbgo.services.dynamic_gesture.user_pace",
        "the swipes' pace: a slow swiper is heard (dynamic-gesture)"
    ),
)
