"""`python -m cbgo.services.dry_robot` runs the service."""

from cbgo.services.dry_robot.main import main

main()
