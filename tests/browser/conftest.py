"""A real ``inertia-id serve`` (API + one worker, embedded default) and headless Chromium.

Chromium is Debian's (``/usr/bin/chromium``, or ``INERTIA_ID_CHROMIUM``), driven by
Playwright; Playwright's own browser download is never used. Without Chromium or
Playwright the tests skip, or fail when ``INERTIA_ID_REQUIRE_SERVICES=1`` (CI sets it).

Every page records its JavaScript console: a test fails on any console error or
uncaught exception it did not declare with ``console.expect(...)``. Screenshots go to
``artifacts/screenshots/`` (or ``INERTIA_ID_ARTIFACTS_DIR``).

Every test has a browser context of its own, with the API key saved as a user who
entered it once has it (``@pytest.mark.without_api_key``: none saved), so that a test
passes alone and in any order: with one context per module, the tests that write from
the page passed only after the module's first test had typed the key in.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from dashboard_support import API_KEY, KEY_STORAGE, Console, Dashboard, Service
from service_support import serve_app, skip_or_fail

CHROMIUM = os.environ.get("INERTIA_ID_CHROMIUM", "/usr/bin/chromium")


def _missing(what: str) -> None:
    skip_or_fail(f"{what}; the browser tests need it")


@pytest.fixture(scope="session")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    with serve_app(tmp_path_factory.mktemp("dashboard"), api_key=API_KEY) as running:
        yield Service(running.base_url, running.client, running.log_path)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Chromium under Playwright's sync API, for one test module.

    Module-scoped, not session: between its sync calls Playwright leaves its asyncio
    loop marked as running in the main thread, so while it lives every other test in
    this process sees "a running event loop" (``anyio.run`` in tests/api/test_capacity.py
    raised "Already running asyncio in this thread" when it ran after the browser
    module in the same pytest-xdist worker). Ended with the module, nothing leaks.
    """
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


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "without_api_key: the test's browser starts with no API key saved"
    )


@pytest.fixture
def context(browser: Any, service: Service, request: pytest.FixtureRequest) -> Iterator[Any]:
    # A context per test: nothing one test leaves in the browser's storage reaches another.
    keyless = request.node.get_closest_marker("without_api_key") is not None
    saved = [] if keyless else [{"name": KEY_STORAGE, "value": API_KEY}]
    ctx = browser.new_context(
        viewport={"width": 1440, "height": 900},
        storage_state={
            "cookies": [],
            "origins": [{"origin": service.base_url, "localStorage": saved}],
        },
    )
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
