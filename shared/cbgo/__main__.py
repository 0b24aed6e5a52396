"""`python -m cbgo` is the `cbgo` command."""

from cbgo.cli.main import main

main()
