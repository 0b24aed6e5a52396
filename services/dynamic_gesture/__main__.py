"""`python -m cbgo.services.dynamic_gesture` runs the service."""

from cbgo.services.dynamic_gesture.main import main

main()
