"""static-gesture's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="static-gesture",
    summary="per-frame static gesture probabilities (Bayesian MLP)",
    order=20,
    subscribes=(keys.HANDS_FRAME, keys.USER),
    publishes=(keys.GESTURES_STATIC,),
    controls=("reload",),
    service="cbgo.services.static_gesture.main:StaticGesture",
    demonstrate=Tool(
        "static", "cbgo.services.static_gesture.demonstrate", "a hand pose (static-gesture)"
    ),
)
