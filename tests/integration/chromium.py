"""Chromium for the page tests: the browser, pages that keep their errors, screenshots.

A module that tests a page calls `require` at import: without chromium it is skipped, except in
CI (``CI=true``), where that fails. Screenshots go to ``out/test-artifacts/web/`` (or
``$CBGO_TEST_ARTIFACTS/web``).
"""

import contextlib
import os
import shutil
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = "/usr/bin/chromium"
ARTIFACTS = Path(os.environ.get("CBGO_TEST_ARTIFACTS", REPO / "out" / "test-artifacts")) / "web"


def require():
    """Returns ``playwright.sync_api``; skips the calling module without chromium (fails in CI)."""
    if not Path(CHROMIUM).exists() or shutil.which("chromium") is None:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI must run the browser tests: {CHROMIUM} is missing "
                        "(apt-get install -y chromium; .ci/run does)", pytrace=False)
        pytest.skip(f"{CHROMIUM} is missing (apt-get install -y chromium)",
                    allow_module_level=True)
    return pytest.importorskip("playwright.sync_api")


@contextlib.contextmanager
def launched():
    """Headless chromium for as long as the block runs."""
    with require().sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        yield browser
        browser.close()


def open_page(browser, url: str, width: int, height: int):
    """Opens `url` in a new page that collects every page error and console error it logs."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.errors = []
    page.on("pageerror", lambda e: page.errors.append(f"page error: {e}"))
    page.on("console", lambda m: m.type == "error" and page.errors.append(f"console: {m.text}"))
    page.goto(url)
    return page


def shot(page, name: str) -> Path:
    """Saves a full-page screenshot as ``<ARTIFACTS>/<name>.png``; returns its path."""
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path
