"""`cbgo demo`: the scripted end-to-end session (see cbgo.cli.demo)."""
