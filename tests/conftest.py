"""Shared fixtures, and the test tiers.

`stack` starts real processes (router, services) and always cleans up.

Every test gets the marker of its tier, from its folder (`TIERS`): ``unit`` (in-process, no
router), ``deploy`` (compose and TLS files read, no engine), ``packaging`` (the wheel built and
installed), ``integration`` (real processes through a real router), ``compose`` (a real Docker
engine). ``make test-fast`` runs ``-m "unit or deploy"``; ``make test`` runs everything.
"""

import sys
from pathlib import Path

import pytest

from cbgo.testing import Stack

FAKES = Path(__file__).parent / "fakes"
TIERS = ("unit", "deploy", "packaging", "integration", "compose")


def pytest_collection_modifyitems(config, items):
    """Marks each test with its tier, the first folder under tests/."""
    root = Path(__file__).parent
    for item in items:
        parts = Path(item.path).resolve().relative_to(root).parts
        if parts and parts[0] in TIERS:
            item.add_marker(getattr(pytest.mark, parts[0]))


@pytest.fixture
def stack(tmp_path):
    """A `cbgo.testing.Stack` on a free loopback port; every process is stopped at the end."""
    with Stack(tmp_path) as s:
        yield s


@pytest.fixture
def probe_argv():
    """The command line of the test-only probe service (tests/fakes/probe_service.py)."""
    return [sys.executable, str(FAKES / "probe_service.py")]
