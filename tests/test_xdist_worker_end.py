"""The end of a pytest-xdist worker: short enough that execnet never sends it SIGINT."""

from __future__ import annotations

import gc
import time

import pytest


def _full_collection_s() -> float:
    start = time.perf_counter()
    gc.collect()
    return time.perf_counter() - start


def test_a_worker_s_garbage_is_collected_before_it_reports_its_end(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Once a worker has reported its end, execnet gives the rest of its run 5 s, then
    sends it SIGINT; pytest's ``gc.collect()`` at unconfigure, over a worker's heap after
    six API modules, took over 8 s, and the SIGINT was reported as an unraisable
    KeyboardInterrupt (in SQLAlchemy's ``_collection_gced``) after the summary. The
    worker's ``pytest_sessionfinish`` (before the report) now collects and freezes what
    is left, so that the collection after it traverses only what is new."""
    import conftest

    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw9")
    full = min(_full_collection_s() for _ in range(2))
    try:
        conftest.pytest_sessionfinish(request.session)
        after = _full_collection_s()
        assert gc.get_freeze_count() > 0
    finally:
        conftest.pytest_unconfigure(request.config)
    assert gc.get_freeze_count() == 0
    # This process's heap: about 0.3-0.6 s a full collection; a few ms once frozen.
    assert after < full / 4, (after, full)
