"""intent's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="intent",
    issue=7,
    summary="intent (action, object, params) from g and context",
    order=50,
    subscribes=(keys.EPISODE_SUMMARY, keys.SCENE_STATE, keys.USER, keys.INTENT_FEEDBACK),
    publishes=(keys.INTENT,),
    answers=(keys.INTENT_INFER,),
    controls=("last", "reload"),
    service="cbgo.services.intent.main:Intent",
    trainer=Tool(
        "intent", "cbgo.services.intent.train", "intent model (order-invariant Bayesian) on D4"
    ),
    benches=(
        Tool(
            "intent", "cbgo.services.intent.bench", "paper's M1-M5 vs ours on D1-D5, learning curve"
        ),
    ),
)
