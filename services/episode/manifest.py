"""episode's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="episode",
    summary="gesture episodes, evidence, the gesture vector g, focus, params",
    order=40,
    subscribes=(
        keys.HANDS_FRAME,
        keys.GESTURES_STATIC,
        keys.GESTURES_DYNAMIC,
        keys.GAZE,
        keys.USER,
    ),
    publishes=(keys.EPISODE_EVENT, keys.EPISODE_SUMMARY),
    service="cbgo.services.episode.main:Episode",
    figures=(
        Tool(
            "episode",
            "cbgo.services.episode.plot",
            "gesture likelihoods, evidence, hand visibility and triggers of one episode",
        ),
    ),
)
