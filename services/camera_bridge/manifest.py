"""camera-bridge's manifest: what `shared/` knows of it (`cbgo.manifest`)."""

from cbgo import keys
from cbgo.manifest import Manifest

MANIFEST = Manifest(
    name="camera-bridge",
    summary="hand frames from an ordinary webcam, a video file or images (MediaPipe Hands)",
    order=11,
    replaces="leap-bridge",
    publishes=(keys.HANDS_FRAME, keys.USER, keys.CAMERA_PREVIEW),
    service="cbgo.services.camera_bridge.main:CameraBridge",
)
