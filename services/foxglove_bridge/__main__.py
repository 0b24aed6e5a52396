"""`python -m cbgo.services.foxglove_bridge` runs the service."""

from cbgo.services.foxglove_bridge.main import main

main()
