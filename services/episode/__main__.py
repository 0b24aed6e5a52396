"""`python -m cbgo.services.episode` runs the service."""

from cbgo.services.episode.main import main

main()
