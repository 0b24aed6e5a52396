"""The cbgo services: one name used in five places, whether each exists, and alternatives.

A service named ``static-gesture`` lives in ``services/static_gesture/`` (import
``cbgo.services.static_gesture``), runs as the console script ``cbgo-static-gesture`` or
``python -m cbgo.services.static_gesture``, declares ``cbgo/@alive/static-gesture`` and is the
compose service ``static-gesture``. Each service declares itself in its folder's
``manifest.py`` (`cbgo.manifest`); `discover` finds them, so `shared/` holds no table of
services or figures: `tools` collects them from the manifests (benchmarks and trainers are
`cbgo_tools.registry`'s).

The seven pipeline services and web (the live page) are the default set. An *alternative*
(``replaces`` set) is another implementation of a default service's keys, e.g. dry-robot for
mujoco-sim: it is never started by default, and never together with the service it replaces
(two answers on ``cbgo/robot/act`` would be wrong); `swap` puts it in that service's place.

An *optional* service (``optional`` set) is an extra that serves people rather than the
pipeline, e.g. foxglove-bridge (the live Foxglove viewer connection): it is started only
when asked for (``cbgo up --foxglove``, or by name), never by default.
"""

from __future__ import annotations

import importlib
import pkgutil

from cbgo.manifest import Manifest, Tool


def discover() -> tuple[Manifest, ...]:
    """Returns the manifest of every service package installed, in pipeline order.

    A service is a package under `cbgo.services` with a ``manifest`` module (`cbgo.manifest`);
    no table here names them, so a new service folder is found without touching `shared/`.
    """
    import cbgo.services

    found = []
    for module in pkgutil.iter_modules(cbgo.services.__path__):
        if not module.ispkg:
            continue
        name = f"cbgo.services.{module.name}.manifest"
        try:
            found.append(importlib.import_module(name).MANIFEST)
        except ModuleNotFoundError as e:
            if e.name != name:
                raise  # a manifest that fails to import is a bug, not a missing service
    return tuple(sorted(found, key=lambda m: (m.order, m.name)))


# In pipeline order: the order `cbgo up` starts them in. web, which only watches (and
# forwards STOP and feedback from its page), comes first so that it sees the others' first
# messages.
SERVICES: tuple[Manifest, ...] = discover()
ROUTER = "router"
# `cbgo up --robot NAME`: which service answers cbgo/robot/act.
ROBOTS: dict[str, str] = {"mujoco": "mujoco-sim", "dry": "dry-robot", "franka": "franka"}


def tools(kind: str) -> dict[str, tuple[str, str]]:
    """Returns the services' tools of one kind: name -> (module, summary).

    Args:
        kind: ``figures``, ``demonstrate`` or ``calibrate`` (a `Manifest` field).

    Raises:
        ValueError: two services bring a tool of the same name.
    """
    out: dict[str, tuple[str, str]] = {}
    for manifest in SERVICES:
        value = getattr(manifest, kind)
        for tool in (value,) if isinstance(value, Tool) else value or ():
            if tool.name in out:
                raise ValueError(f"two services bring the {kind} tool {tool.name!r}")
            out[tool.name] = (tool.module, tool.summary)
    return out


def by_name(name: str) -> Manifest:
    """Returns a service by name.

    Raises:
        KeyError: with the list of known names.
    """
    for info in SERVICES:
        if info.name == name:
            return info
    raise KeyError(f"unknown service {name!r}; known: {', '.join(s.name for s in SERVICES)}")


def defaults() -> list[Manifest]:
    """Returns the default services (alternatives and optional ones left out), in order."""
    return [s for s in SERVICES if s.replaces is None and not s.optional]


def available() -> list[Manifest]:
    """Returns the default services that exist in this installation, in pipeline order."""
    return [s for s in defaults() if s.exists()]


def alternatives(name: str) -> list[Manifest]:
    """Returns the services that can replace the named default service."""
    return [s for s in SERVICES if s.replaces == name]


def swap(services: list[Manifest], chosen: Manifest) -> list[Manifest]:
    """Returns `services` with whichever serves `chosen`'s keys replaced by `chosen`.

    The list is unchanged when none of them serves those keys.
    """
    return [chosen if s.role == chosen.role else s for s in services]


def clashes(services: list[Manifest]) -> list[tuple[Manifest, Manifest]]:
    """Returns the pairs of services that would both answer the same keys."""
    out = []
    for i, first in enumerate(services):
        out += [(first, other) for other in services[i + 1:] if other.role == first.role]
    return out
