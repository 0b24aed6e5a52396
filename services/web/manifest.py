"""web's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="web",
    summary="a live web page of what cbgo sees and decides; STOP and feedback",
    order=5,
    subscribes=keys.DATA_TOPICS,
    publishes=(keys.ROBOT_STOP, keys.INTENT_FEEDBACK, keys.INTENT_ANSWER),
    asks=(keys.SIM_INFO,),
    service="cbgo.services.web.main:Web",
)
