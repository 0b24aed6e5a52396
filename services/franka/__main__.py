"""`python -m cbgo.services.franka` runs the service."""

from cbgo.services.franka.main import main

main()
