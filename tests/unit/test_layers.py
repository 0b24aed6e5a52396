"""The layers point one way (docs/architecture.md): library <- services <- CLI, demo, tools.

- The library (``shared/cbgo``: wire, keys, runtime, client, config, world, hands, ...) imports
  no service, no CLI, no demo and no offline tool. `cbgo.registry` alone names the services'
  package, to read their manifests (declarations that import only the library).
- A service (``services/<name>``) imports the library and its own modules only: never another
  service, the CLI, the demo or an offline tool.
- The CLI (``cbgo.cli``), the demo (``cbgo.demo``) and the offline tools (``tools/cbgo_tools``)
  sit on top and may import anything.

Every import counts, at the top of a module or inside a function.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SOURCES = {"cbgo": ROOT / "shared" / "cbgo", "cbgo.services": ROOT / "services",
           "cbgo_tools": ROOT / "tools" / "cbgo_tools"}
TOP = ("cbgo.cli", "cbgo.demo", "cbgo.__main__", "cbgo_tools")


def module_names() -> dict[str, Path]:
    """Every module of the three source roots: dotted name -> file."""
    found = {}
    for package, folder in SOURCES.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            name = ".".join((package, *parts))
            if package == "cbgo" and name.startswith("cbgo.services"):
                continue
            found[name] = path
    return found


MODULES = module_names()


def imports_of(name: str, path: Path) -> set[str]:
    """The absolute names a module imports (relative imports resolved)."""
    out = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*parent, *([base] if base else [])])
            out.add(base)
            out |= {f"{base}.{alias.name}" for alias in node.names}
    return {m for m in out if m.split(".")[0] in ("cbgo", "cbgo_tools")}


def layer(name: str) -> str:
    """``top``, ``service:<name>`` or ``library``."""
    if any(name == top or name.startswith(top + ".") for top in TOP):
        return "top"
    if name.startswith("cbgo.services."):
        return "service:" + name.split(".")[2]
    if name == "cbgo.services":
        return "services-package"
    return "library"


def violations(name: str, imported: set[str]) -> list[str]:
    """The imports of one module that break the rule of its layer."""
    own = layer(name)
    bad = []
    for target in sorted(imported):
        other = layer(target)
        if own == "top" or other == "library" or other == own:
            continue
        if name == "cbgo.registry" and (target == "cbgo.services"
                                        or target.endswith(".manifest")):
            continue  # discovery reads the manifests, declarations of library types only
        if other == "services-package" and own.startswith("service:"):
            continue
        bad.append(f"{name} ({own}) imports {target} ({other})")
    return bad


def test_the_sources_are_found():
    assert "cbgo.wire" in MODULES and "cbgo.services.intent.main" in MODULES
    assert "cbgo_tools.registry" in MODULES and "cbgo.cli.main" in MODULES


@pytest.mark.parametrize("name", sorted(n for n in MODULES if layer(n) != "top"))
def test_every_module_imports_only_what_its_layer_may(name):
    assert violations(name, imports_of(name, MODULES[name])) == []


def test_the_rule_fails_a_library_module_that_imports_a_service():
    assert violations("cbgo.wire", {"cbgo.services.episode.builder"})
    assert violations("cbgo.world.scene", {"cbgo.cli.common"})
    assert violations("cbgo.hands.model", {"cbgo_tools.data.shrec"})


def test_the_rule_fails_a_service_that_imports_another_or_a_tool():
    assert violations("cbgo.services.web.views", {"cbgo.services.episode.evidence"})
    assert violations("cbgo.services.intent.main", {"cbgo_tools.intent.train"})
    assert violations("cbgo.services.planner.main", {"cbgo.cli.common"})
    assert not violations("cbgo.services.web.views", {"cbgo.evidence", "cbgo.services.web.x"})
