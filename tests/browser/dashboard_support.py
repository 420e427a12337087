"""What the browser tests share: the running service, a page's console, the dashboard."""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
from service_support import ROOT, tail, wait_for

API_KEY = "browser-" + "k" * 40
#: Where the dashboard keeps the API key (frontend/js/api.js).
KEY_STORAGE = "inertia-id-api-key"
ARTIFACTS = Path(os.environ.get("INERTIA_ID_ARTIFACTS_DIR", ROOT / "artifacts")) / "screenshots"


@dataclass
class Service:
    base_url: str
    client: httpx.Client
    log: Path

    def until(self, predicate: Callable[[], Any], timeout_s: float, what: str) -> Any:
        """Poll ``predicate`` until it returns something truthy; fail with the log."""
        return wait_for(predicate, timeout_s, what, lambda: f"service log:\n{tail(self.log)}")

    def job(self, job_id: str) -> dict[str, Any]:
        return dict(self.client.get(f"/jobs/{job_id}").json())


@dataclass
class Console:
    """What the page wrote to its console, and which errors a test expects."""

    errors: list[str] = field(default_factory=list)
    expected: list[re.Pattern[str]] = field(default_factory=list)

    def expect(self, pattern: str) -> None:
        self.expected.append(re.compile(pattern))

    def unexpected(self) -> list[str]:
        return [e for e in self.errors if not any(p.search(e) for p in self.expected)]


@dataclass
class Dashboard:
    page: Any
    console: Console
    service: Service

    def open(self, route: str) -> None:
        """Go to a dashboard route (``#/jobs``) and wait for its page to be drawn.

        The page drawn now is marked first: from one route to another of the same
        document only the hash changes, goto returns before the hashchange event draws
        the new page, and the old page's h1 passed for the new one (a form filled then
        could be the old page's, or be redrawn under the test). The same address again
        is a reload: a hash that does not change draws nothing."""
        target = f"{self.service.base_url}/{route}"
        self.page.evaluate(
            "() => document.querySelector('#page > div')?.setAttribute('data-left', '')"
        )
        if self.page.url == target:
            self.page.reload()
        else:
            self.page.goto(target)
        self.page.wait_for_selector("#page > div:not([data-left]) h1")

    def screenshot(self, name: str) -> Path:
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        path = ARTIFACTS / f"{name}.png"
        self.page.screenshot(path=str(path), full_page=True)
        return path


def one_held(page: Any, held: list[Any], timeout_s: float = 10.0) -> Any:
    """The request a test's route handler has put in ``held``, taken out of it.

    A route handler runs only while Playwright's sync API waits on something. One
    evaluation's round trip (``wait_for_function("() => true")``) was taken for "the
    handler has run", and in a loaded CI run the list was still empty after it. This
    waits in 10 ms steps, each letting handlers run, until one request is held."""
    deadline = time.monotonic() + timeout_s
    while not held and time.monotonic() < deadline:
        page.wait_for_timeout(10)
    assert len(held) == 1, f"{len(held)} requests held after up to {timeout_s} s: {held}"
    return held.pop()


#: A function of the page that lists layout problems: a Plotly figure wider than its
#: cell; a legend over a plot area, a tick label, an axis title, a title or a colour bar,
#: or within 1 px of an x-axis title;
#: text cut at a figure's edge; a page wider than the window
#: (tests/browser/layout_problems.js).
LAYOUT_PROBLEMS_JS = "\n".join(
    line
    for line in (Path(__file__).parent / "layout_problems.js")
    .read_text(encoding="utf-8")
    .splitlines()
    if not line.startswith("//")
)


#: What axe-core checks: WCAG 2.0 and 2.1, A and AA, and its best practices.
AXE_TAGS = ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa", "best-practice"]


def axe_violations(dashboard: Dashboard) -> list[str]:
    """What axe-core (bundled by axe-playwright-python) finds on the page as it stands."""
    from axe_playwright_python.sync_playwright import Axe

    results = Axe().run(
        dashboard.page,
        options={"runOnly": {"type": "tag", "values": AXE_TAGS}, "resultTypes": ["violations"]},
    )
    return [
        f"{v['id']} ({v['impact']}): {[n['target'] for n in v['nodes']][:3]}"
        for v in results.response["violations"]
    ]
