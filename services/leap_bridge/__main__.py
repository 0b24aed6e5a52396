"""`python -m cbgo.services.leap_bridge` runs the service."""

from cbgo.services.leap_bridge.main import main

main()
