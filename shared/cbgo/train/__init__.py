"""Trainers behind `cbgo train <name>`: each module has `add_arguments` and `run`.

A trainer of one service's model lives in that service's package; this table is how the CLI
finds it (imported only when run).
"""

# name -> (module, one-line summary)
TRAINERS: dict[str, tuple[str, str]] = {}
