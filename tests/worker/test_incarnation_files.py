"""The flock files of worker incarnations beside a SQLite database (worker.incarnation):
those left by workers that died without removing theirs are removed by the next worker
that starts, a live worker's kept; a lock that cannot be taken is logged once, not at
every beat the monitor tries it again."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from worker.incarnation import Life


def test_a_starting_worker_removes_the_lock_files_of_dead_ones_and_keeps_live_ones(
    tmp_path: Path,
) -> None:
    url = f"sqlite:///{tmp_path / 'data dir' / 'inertia-id.db'}"
    live = Life(url, "live")
    assert live.hold()
    folder = tmp_path / "data dir" / "inertia-id.db.incarnations"
    # As `inertia-id serve`'s stop (SIGKILL once the job is handed back) or a kill -9
    # leaves them: the file is there, nobody holds its lock.
    for dead in ("dead1", "dead2"):
        (folder / f"{dead}.lock").touch()
    new = Life(url, "new")
    try:
        assert new.hold()
        assert sorted(p.name for p in folder.iterdir()) == ["live.lock", "new.lock"]
    finally:
        new.release()
        live.release()
    assert list(folder.iterdir()) == []


def test_a_lock_that_cannot_be_taken_is_logged_once_not_at_every_retry(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    url = f"sqlite:///{tmp_path / 'inertia-id.db'}"
    (tmp_path / "inertia-id.db.incarnations").touch()  # a file where the folder goes
    life = Life(url, "one")
    with caplog.at_level(logging.INFO, logger="worker.incarnation"):
        # The worker's start, then the monitor's beats.
        assert [life.try_hold() for _ in range(3)] == [False, False, False]
        failures = [r for r in caplog.records if r.levelno >= logging.ERROR]
        assert len(failures) == 1 and failures[0].exc_info is not None
        (tmp_path / "inertia-id.db.incarnations").unlink()
        caplog.clear()
        assert life.try_hold() and life.held
        assert [r.getMessage() for r in caplog.records] == ["took this worker's incarnation lock"]
    life.release()
