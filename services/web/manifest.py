"""web's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest, Tool

MANIFEST = Manifest(
    name="web",
    issue=19,
    summary="a live web page of what cbgo sees and decides; STOP and feedback",
    order=5,
    subscribes=keys.DATA_TOPICS,
    publishes=(keys.ROBOT_STOP, keys.INTENT_FEEDBACK),
    asks=(keys.SIM_INFO,),
    service="cbgo.services.web.main:Web",
    benches=(
        Tool("web", "cbgo.services.web.bench", "web's CPU share under 120 Hz hands, page rates"),
    ),
)
