"""`python -m cbgo.services.web` runs the service."""

from cbgo.services.web.main import main

main()
