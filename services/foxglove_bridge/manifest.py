"""foxglove-bridge's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="foxglove-bridge",
    summary="the live traffic, 3D scene and log as a Foxglove WebSocket server",
    order=90,
    optional=True,
    subscribes=keys.DATA_TOPICS,
    service="cbgo.services.foxglove_bridge.main:FoxgloveBridge",
)
