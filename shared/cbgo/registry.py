"""The cbgo services: one name used in five places, whether each exists, and alternatives.

A service named ``static-gesture`` lives in ``services/static_gesture/`` (import
``cbgo.services.static_gesture``), runs as the console script ``cbgo-static-gesture`` or
``python -m cbgo.services.static_gesture``, declares ``cbgo/@alive/static-gesture`` and is the
compose service ``static-gesture``. A service exists once its package has a ``main`` module;
`cbgo up` starts only those, and lists nothing it cannot run.

The seven pipeline services and web (the live page) are the default set. An *alternative*
(``replaces`` set) is another implementation of a default service's keys, e.g. dry-robot for
mujoco-sim: it is never started by default, and never together with the service it replaces
(two answers on ``cbgo/robot/act`` would be wrong); `swap` puts it in that service's place.

An *optional* service (``optional`` set) is an extra that serves people rather than the
pipeline, e.g. foxglove-bridge (the live Foxglove viewer connection): it is started only
when asked for (``cbgo up --foxglove``, or by name), never by default.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass


@dataclass(frozen=True)
class ServiceInfo:
    """One service of the pipeline.

    Attributes:
        name: kebab-case service name.
        issue: the issue that builds it.
        summary: what it does, in one line.
        replaces: the default service whose keys it answers instead, for an alternative
            implementation; None for a default service.
        optional: an extra started only when asked for (by name or its own `cbgo up` flag),
            never in the default set.
    """

    name: str
    issue: int
    summary: str
    replaces: str | None = None
    optional: bool = False

    @property
    def role(self) -> str:
        """The keys it serves, named by the default service that serves them."""
        return self.replaces or self.name

    @property
    def package(self) -> str:
        """The import name, e.g. ``cbgo.services.static_gesture``."""
        return "cbgo.services." + self.name.replace("-", "_")

    @property
    def script(self) -> str:
        """The console script, e.g. ``cbgo-static-gesture``."""
        return "cbgo-" + self.name

    def exists(self) -> bool:
        """Returns whether the service has been built (its ``main`` module is importable)."""
        try:
            return importlib.util.find_spec(self.package + ".main") is not None
        except ModuleNotFoundError:
            return False


# In pipeline order: the order `cbgo up` starts them in. web, which only watches (and
# forwards STOP and feedback from its page), comes first so that it sees the others' first
# messages.
SERVICES: tuple[ServiceInfo, ...] = (
    ServiceInfo("web", 19, "a live web page of what cbgo sees and decides; STOP and feedback"),
    ServiceInfo("leap-bridge", 3,
                "hand frames from a Leap Motion, a recording or a simulated user"),
    ServiceInfo("static-gesture", 4, "per-frame static gesture probabilities (Bayesian MLP)"),
    ServiceInfo("dynamic-gesture", 5, "stroke segmentation and dynamic gestures (ProMP + DTW)"),
    ServiceInfo("episode", 6, "gesture episodes, evidence, the gesture vector g, focus, params"),
    ServiceInfo("intent", 7, "intent (action, object, params) from g and context"),
    ServiceInfo("planner", 9, "behaviour trees that turn an intent into robot actions"),
    ServiceInfo("mujoco-sim", 8, "the Panda table-top world in MuJoCo; executes robot actions"),
    ServiceInfo("dry-robot", 10, "the robot on the symbolic world model, no physics (no "
                "MuJoCo needed; fast plan checks)", replaces="mujoco-sim"),
    ServiceInfo("foxglove-bridge", 20, "the live traffic, 3D scene and log as a Foxglove "
                "WebSocket server", optional=True),
)
ROUTER = "router"
# `cbgo up --robot NAME`: which service answers cbgo/robot/act.
ROBOTS: dict[str, str] = {"mujoco": "mujoco-sim", "dry": "dry-robot"}


def by_name(name: str) -> ServiceInfo:
    """Returns a service by name.

    Raises:
        KeyError: with the list of known names.
    """
    for info in SERVICES:
        if info.name == name:
            return info
    raise KeyError(f"unknown service {name!r}; known: {', '.join(s.name for s in SERVICES)}")


def defaults() -> list[ServiceInfo]:
    """Returns the default services (alternatives and optional ones left out), in order."""
    return [s for s in SERVICES if s.replaces is None and not s.optional]


def available() -> list[ServiceInfo]:
    """Returns the default services that exist in this installation, in pipeline order."""
    return [s for s in defaults() if s.exists()]


def alternatives(name: str) -> list[ServiceInfo]:
    """Returns the services that can replace the named default service."""
    return [s for s in SERVICES if s.replaces == name]


def swap(services: list[ServiceInfo], chosen: ServiceInfo) -> list[ServiceInfo]:
    """Returns `services` with whichever serves `chosen`'s keys replaced by `chosen`.

    The list is unchanged when none of them serves those keys.
    """
    return [chosen if s.role == chosen.role else s for s in services]


def clashes(services: list[ServiceInfo]) -> list[tuple[ServiceInfo, ServiceInfo]]:
    """Returns the pairs of services that would both answer the same keys."""
    out = []
    for i, first in enumerate(services):
        out += [(first, other) for other in services[i + 1:] if other.role == first.role]
    return out
