"""Shared fixtures: `stack` starts real processes (router, services) and always cleans up."""

import sys
from pathlib import Path

import pytest

from cbgo.testing import Stack

FAKES = Path(__file__).parent / "fakes"


@pytest.fixture
def stack(tmp_path):
    """A `cbgo.testing.Stack` on a free loopback port; every process is stopped at the end."""
    with Stack(tmp_path) as s:
        yield s


@pytest.fixture
def probe_argv():
    """The command line of the test-only probe service (tests/fakes/probe_service.py)."""
    return [sys.executable, str(FAKES / "probe_service.py")]
