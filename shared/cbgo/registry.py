"""The seven cbgo services: one name used in five places, and whether each exists yet.

A service named ``static-gesture`` lives in ``services/static_gesture/`` (import
``cbgo.services.static_gesture``), runs as the console script ``cbgo-static-gesture`` or
``python -m cbgo.services.static_gesture``, declares ``cbgo/@alive/static-gesture`` and is the
compose service ``static-gesture``. A service exists once its package has a ``main`` module;
`cbgo up` starts only those, and lists nothing it cannot run.
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
    """

    name: str
    issue: int
    summary: str

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


# In pipeline order: the order `cbgo up` starts them in.
SERVICES: tuple[ServiceInfo, ...] = (
    ServiceInfo("leap-bridge", 3,
                "hand frames from a Leap Motion, a recording or a simulated user"),
    ServiceInfo("static-gesture", 4, "per-frame static gesture probabilities (Bayesian MLP)"),
    ServiceInfo("dynamic-gesture", 5, "stroke segmentation and dynamic gestures (ProMP + DTW)"),
    ServiceInfo("episode", 6, "gesture episodes, evidence, the gesture vector g, focus, params"),
    ServiceInfo("intent", 7, "intent (action, object, params) from g and context"),
    ServiceInfo("planner", 9, "behaviour trees that turn an intent into robot actions"),
    ServiceInfo("mujoco-sim", 8, "the Panda table-top world in MuJoCo; executes robot actions"),
)
ROUTER = "router"


def by_name(name: str) -> ServiceInfo:
    """Returns a service by name.

    Raises:
        KeyError: with the list of known names.
    """
    for info in SERVICES:
        if info.name == name:
            return info
    raise KeyError(f"unknown service {name!r}; known: {', '.join(s.name for s in SERVICES)}")


def available() -> list[ServiceInfo]:
    """Returns the services that exist in this installation, in pipeline order."""
    return [s for s in SERVICES if s.exists()]
