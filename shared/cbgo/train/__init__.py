"""Trainers behind `cbgo train <name>`: each module has `add_arguments` and `run`.

A trainer of one service's model lives in that service's package and is declared in its
manifest (`cbgo.manifest`); the CLI finds it there (imported only when run).
"""

from cbgo import registry

# name -> (module, one-line summary), from the services' manifests (``trainer``)
TRAINERS: dict[str, tuple[str, str]] = registry.tools("trainer")
