"""The end of a pytest-xdist worker: short enough that execnet never sends it SIGINT."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest


def test_a_worker_s_garbage_is_collected_before_it_reports_its_end(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Once a worker has reported its end, execnet gives the rest of its run 5 s, then
    sends it SIGINT; pytest's ``gc.collect()`` at unconfigure, over a worker's heap after
    six API modules, took over 8 s, and the SIGINT was reported as an unraisable
    KeyboardInterrupt (in SQLAlchemy's ``_collection_gced``) after the summary. The
    worker's ``pytest_sessionfinish`` (before the report) now collects and freezes what
    is left, so that the collection after it traverses only what is new. Counted in
    objects, not timed: a collection's time is what they cost, and timings on a shared
    machine are noise."""
    # The suite's own conftest as pytest loaded it (``import conftest`` may give another
    # directory's, whichever of them a module of this worker imported last).
    here = Path(__file__).with_name("conftest.py")
    conftest = next(
        plugin
        for plugin in request.config.pluginmanager.get_plugins()
        if Path(getattr(plugin, "__file__", None) or "/") == here
    )
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw9")
    tracked = len(gc.get_objects())
    try:
        conftest.pytest_sessionfinish(request.session)
        frozen = gc.get_freeze_count()
        # What a full collection still traverses: the generations, not the frozen ones.
        left = len(gc.get_objects())
    finally:
        conftest.pytest_unconfigure(request.config)
    assert gc.get_freeze_count() == 0
    assert frozen > tracked / 2, (frozen, tracked)
    assert left < tracked / 100, (left, tracked)
