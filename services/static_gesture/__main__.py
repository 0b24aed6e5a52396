"""`python -m cbgo.services.static_gesture` runs the service."""

from cbgo.services.static_gesture.main import main

main()
