"""Each service's manifest says what its setup() declares, and the tools it names exist."""

import importlib
import importlib.util
import re

import pytest

from cbgo import registry
from cbgo.testing import FakeBus
from cbgo_tools.docs import readme_tables

# settings a unit test needs so that nothing binds a fixed port of this host
QUIET_SETTINGS = {"web": {"http_port": 0}, "foxglove-bridge": {"ws_port": 0}}


def suffixes(keys, prefix="cbgo/"):
    return {k[len(prefix):] for k in keys if not k.startswith(prefix + "@")}


@pytest.fixture(scope="module", params=registry.SERVICES, ids=lambda m: m.name)
def declared(request):
    """The manifest and what the service declared in setup() on a FakeBus."""
    manifest = request.param
    cls = manifest.service_class()
    bus = FakeBus(cls(cls.settings_class(**QUIET_SETTINGS.get(manifest.name, {}))))
    yield manifest, bus.ctx
    bus.stop()


def test_the_service_class_is_the_one_of_the_manifests_name(declared):
    manifest, ctx = declared
    assert ctx.service.name == manifest.name
    assert manifest.settings_class() is type(ctx.service.settings)


def test_the_manifest_lists_exactly_the_keys_setup_declares(declared):
    manifest, ctx = declared
    assert suffixes(ctx.inputs) == {t.suffix for t in manifest.subscribes}
    assert suffixes(ctx.outputs) == {t.suffix for t in manifest.publishes}
    assert suffixes(ctx.queryables) == {t.suffix for t in manifest.answers}


def test_the_manifest_lists_exactly_the_control_verbs_besides_status(declared):
    manifest, ctx = declared
    verbs = {k.rsplit("/", 1)[1] for k in ctx.queryables if "/@ctl/" in k}
    assert verbs == {"status", *manifest.controls}


def offline_tools(kind: str) -> dict[str, tuple[str, str]]:
    from cbgo_tools import registry as offline

    return {"trainer": offline.TRAINERS, "benches": offline.BENCHES}[kind]


@pytest.mark.parametrize("kind", ["trainer", "benches", "figures", "demonstrate"])
def test_every_tool_a_manifest_names_is_a_module_with_what_the_cli_calls(kind):
    tools = offline_tools(kind) if kind in ("trainer", "benches") else registry.tools(kind)
    for name, (module, summary) in tools.items():
        assert summary, f"{kind} {name} has no summary"
        assert importlib.util.find_spec(module) is not None, f"{kind} {name}: no {module}"
        if kind != "demonstrate":
            loaded = importlib.import_module(module)
            assert callable(loaded.add_arguments) and callable(loaded.run), module


def test_services_are_found_from_their_folders_in_pipeline_order():
    names = [m.name for m in registry.SERVICES]
    assert len(names) == len(set(names))
    assert names.index("leap-bridge") < names.index("static-gesture") < names.index("episode")
    assert names.index("intent") < names.index("planner") < names.index("mujoco-sim")
    for manifest in registry.SERVICES:
        folder = manifest.package.rsplit(".", 1)[1]
        assert folder == manifest.name.replace("-", "_")
        assert manifest.exists()


# --- the READMEs ------------------------------------------------------------------------------

SECTIONS = {"Subscribes": "subscribes", "Publishes": "publishes", "Answers": "answers"}


def section(text: str, heading: str) -> str:
    """The body of a README's ``## heading`` section ('' when there is none)."""
    parts = text.split(f"\n## {heading}\n", 1)
    return parts[1].split("\n## ", 1)[0] if len(parts) == 2 else ""


def table_keys(body: str) -> set[str]:
    """The keys in the first column of the tables of a section."""
    return {m.group(1) for m in re.finditer(r"^\| `cbgo/([^`]+)`", body, re.M)}


def named_keys(body: str) -> set[str]:
    """Every key a section names in backticks, in tables or prose."""
    return set(re.findall(r"`cbgo/([^`]+)`", body))


@pytest.mark.parametrize("manifest", registry.SERVICES, ids=lambda m: m.name)
def test_the_readme_tables_are_generated_from_the_manifest_and_in_step(manifest):
    text = readme_tables.readme_of(manifest).read_text()
    assert readme_tables.updated(text, manifest) == text, (
        "run: make docs")


@pytest.mark.parametrize("manifest", registry.SERVICES, ids=lambda m: m.name)
def test_the_readme_prose_names_the_keys_of_the_manifest(manifest):
    # A section's table lists exactly the manifest's keys; a section in prose names them all.
    text = readme_tables.readme_of(manifest).read_text()
    for heading, field in SECTIONS.items():
        declared = {t.suffix for t in getattr(manifest, field)}
        if field == "answers":
            declared |= {f"@ctl/{manifest.name}/{v}" for v in ("status", *manifest.controls)}
        body = section(text, heading)
        if table_keys(body):
            assert table_keys(body) == declared, f"## {heading} of {manifest.name}'s README"
        else:
            assert declared <= named_keys(body), f"## {heading} of {manifest.name}'s README"
