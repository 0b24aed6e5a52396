"""`python -m cbgo.services.intent` runs the service."""

from cbgo.services.intent.main import main

main()
