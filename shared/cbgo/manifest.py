"""A service's manifest: everything `shared/` needs to know about it, declared in its own folder.

Each service folder has a ``manifest.py`` with one ``MANIFEST = Manifest(...)``: its name and
summary, its place in the pipeline, what it replaces, the keys it reads, writes and answers,
its service class (and so its settings), and the user-facing tools it brings (figures drawn from
recordings, gestures by demonstration). `cbgo.registry` discovers the manifests (no table of
services in `shared/`), and from them come `cbgo up --list`, `cbgo plot`, `cbgo gestures`, and
the key and config tables of each service's README (`make docs`). Benchmarks,
trainers and data-set converters are offline tools: they live in `tools/` (the ``cbgo_tools``
package, outside the wheel), which declares them in ``cbgo_tools.registry``. A test holds
each manifest's keys against what the service's ``setup()`` declares.

A manifest module imports only this module and `cbgo.keys`: reading every manifest is cheap
(no torch, no MuJoCo), and a tool's module is imported only when it runs.
"""

from __future__ import annotations

import importlib
import importlib.util
from dataclasses import dataclass

from cbgo.keys import Topic


@dataclass(frozen=True)
class Tool:
    """A command a service brings: ``cbgo plot <name>``, or demonstration.

    Attributes:
        name: the name on the command line (``static`` in ``cbgo train static``).
        module: the module with ``add_arguments(parser)`` and ``run(args)`` (for
            demonstration: the module `cbgo gestures record` drives), imported only when run.
        summary: one line for ``--help``.
    """

    name: str
    module: str
    summary: str


@dataclass(frozen=True)
class Manifest:
    """One service, as `shared/` sees it.

    Attributes:
        name: kebab-case service name (folder, console script, liveliness token, compose).
        summary: what it does, in one line.
        order: its place in the pipeline: `cbgo up` starts services in this order.
        replaces: the default service whose keys it answers instead (an alternative
            implementation, never started with it); None for a default service.
        optional: an extra, started only when asked for (by name or its own `cbgo up`
            flag), never in the default set.
        subscribes: the topics it reads.
        publishes: the topics it writes.
        answers: the query topics it answers.
        asks: the query topics it sends (not checked against ``setup()``: queries are made
            at run time).
        controls: its ``@ctl`` verbs besides ``status``.
        service: ``module:Class`` of its `cbgo.runtime.Service` (and so of its settings).
        figures: ``cbgo plot <name>``.
        demonstrate: ``cbgo gestures record --<name>``: learning a gesture by demonstration.
        calibrate: ``cbgo gestures calibrate``: fitting the recogniser to one person from a few
            demonstrations of the gestures it knows.
    """

    name: str
    summary: str
    order: int
    replaces: str | None = None
    optional: bool = False
    subscribes: tuple[Topic, ...] = ()
    publishes: tuple[Topic, ...] = ()
    answers: tuple[Topic, ...] = ()
    asks: tuple[Topic, ...] = ()
    controls: tuple[str, ...] = ()
    service: str = ""
    figures: tuple[Tool, ...] = ()
    demonstrate: Tool | None = None
    calibrate: Tool | None = None

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
        """Returns whether the service can run here (its ``main`` module is importable)."""
        try:
            return importlib.util.find_spec(self.package + ".main") is not None
        except ModuleNotFoundError:
            return False

    def service_class(self) -> type:
        """Imports and returns the service class (imports the service's main module)."""
        module, _, name = self.service.partition(":")
        return getattr(importlib.import_module(module), name)

    def settings_class(self) -> type:
        """Imports and returns the settings dataclass."""
        return self.service_class().settings_class

