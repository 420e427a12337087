"""A real ``inertia-id serve`` (API + one worker, embedded default) and headless Chromium.

Chromium is Debian's (``/usr/bin/chromium``, or ``INERTIA_ID_CHROMIUM``), driven by
Playwright; Playwright's own browser download is never used. Without Chromium or
Playwright the tests skip, or fail when ``INERTIA_ID_REQUIRE_SERVICES=1`` (CI sets it).

Every page records its JavaScript console: a test fails on any console error or
uncaught exception it did not declare with ``console.expect(...)``. Screenshots go to
``artifacts/screenshots/`` (or ``INERTIA_ID_ARTIFACTS_DIR``).
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from dashboard_support import API_KEY, Console, Dashboard, Service
from service_support import serve_app, skip_or_fail

CHROMIUM = os.environ.get("INERTIA_ID_CHROMIUM", "/usr/bin/chromium")


def _missing(what: str) -> None:
    skip_or_fail(f"{what}; the browser tests need it")


@pytest.fixture(scope="session")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    with serve_app(tmp_path_factory.mktemp("dashboard"), api_key=API_KEY) as running:
        yield Service(running.base_url, running.client, running.log_path)


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    if shutil.which(CHROMIUM) is None and not Path(CHROMIUM).is_file():
        _missing(f"Chromium is not installed at {CHROMIUM} (apt-get install -y chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("Playwright is not installed (pip install playwright)")
    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture(scope="module")
def context(browser: Any) -> Iterator[Any]:
    # One browser context per module: the API key saved in localStorage carries over.
    ctx = browser.new_context(viewport={"width": 1440, "height": 900})
    try:
        yield ctx
    finally:
        ctx.close()


@pytest.fixture
def dashboard(context: Any, service: Service) -> Iterator[Dashboard]:
    page = context.new_page()
    page.set_default_timeout(30_000)
    console = Console()
    page.on(
        "console",
        lambda message: (
            console.errors.append(f"console.{message.type}: {message.text}")
            if message.type == "error"
            else None
        ),
    )
    page.on("pageerror", lambda error: console.errors.append(f"uncaught: {error}"))
    try:
        yield Dashboard(page, console, service)
        assert console.unexpected() == [], "JavaScript console errors"
    finally:
        page.close()
