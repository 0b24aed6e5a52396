"""`python -m cbgo.services.planner` runs the service."""

from cbgo.services.planner.main import main

main()
