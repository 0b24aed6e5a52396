"""`python -m cbgo.services.camera_bridge` runs the service."""

from cbgo.services.camera_bridge.main import main

main()
