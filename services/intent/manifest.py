"""intent's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="intent",
    summary="intent (action, object, params) from g and context",
    order=50,
    subscribes=(keys.EPISODE_SUMMARY, keys.SCENE_STATE, keys.USER, keys.INTENT_FEEDBACK,
                keys.INTENT_ANSWER),
    publishes=(keys.INTENT, keys.INTENT_CLARIFY),
    answers=(keys.INTENT_INFER,),
    controls=("last", "reload", "mapping"),
    service="cbgo.services.intent.main:Intent",
)
