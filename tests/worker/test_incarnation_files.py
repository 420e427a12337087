"""The flock files of worker incarnations beside a SQLite database (worker.incarnation):
those left by workers that died without removing theirs are removed by the next worker
that starts, a live worker's kept; a lock that cannot be taken is logged once, not at
every beat the monitor tries it again; one that cannot be read (a file where the folder
goes) leaves its worker judged alive, logged once, and the beat goes on."""

from __future__ import annotations

import logging
import shutil
from datetime import timedelta
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from service.store import JobRow
from service.store.jobs import claim, start_worker
from service.store.models import utcnow
from worker.incarnation import Life, alive
from worker.monitor import WorkerMonitor

if TYPE_CHECKING:
    from conftest import Store


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
        failures = [r for r in caplog.records if r.levelno >= logging.WARNING]
        # One line naming the reason: an OSError's message says all (no traceback).
        assert len(failures) == 1 and not failures[0].exc_info
        assert "FileExistsError" in failures[0].getMessage()
        (tmp_path / "inertia-id.db.incarnations").unlink()
        caplog.clear()
        assert life.try_hold() and life.held
        assert [r.getMessage() for r in caplog.records] == [
            "took this worker's incarnation lock (after 0 s)"
        ]
        # A later episode (the lock lost, its folder a file again) is logged again. (Lost,
        # not released: a released lock is never taken again.)
        shutil.rmtree(tmp_path / "inertia-id.db.incarnations")
        (tmp_path / "inertia-id.db.incarnations").touch()
        caplog.clear()
        assert [life.keep() for _ in range(3)] == [False, False, False]
        failures = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert len([m for m in failures if m.startswith("could not take")]) == 1, failures
    life.release()


@pytest.mark.parametrize("store", ["sqlite"], indirect=True)
def test_a_twins_beat_with_a_file_for_the_lock_folder_leaves_the_run_and_goes_on(
    store: Store, caplog: pytest.LogCaptureFixture
) -> None:
    # The other incarnation's lock cannot be read: it is not judged dead. Before, alive()
    # raised NotADirectoryError and the beat stopped before its reaper and re-sender.
    running = store.add_job("train", {})
    with store.db.session() as session:
        # The other incarnation's run, silent past two beats (the twin's own test of a
        # restart), its worker's row fresh (the reaper's is not met).
        start_worker(session, "w1@host", "filesystem://", "other")
        assert claim(session, running, "w1@host", "other") is not None
        session.get_one(JobRow, running).heartbeat_at = utcnow() - timedelta(seconds=30)
    unsent = store.add_job("train", {}, created_at=utcnow() - timedelta(minutes=5))
    (store.settings.data_dir / "inertia-id.db.incarnations").touch()
    twin = WorkerMonitor(
        "w1@host", store.settings, Life(store.settings.resolved_database_url, "twin")
    )
    try:
        with caplog.at_level(logging.WARNING, logger="worker.incarnation"):
            for _ in range(3):
                twin.tick()
    finally:
        twin.stop()
    assert store.job(running).status == "running"
    with store.db.session() as session:  # unknown, so not judged dead at a later probe
        assert alive(session, store.settings.resolved_database_url, "other")
    assert store.job(unsent).sent_at is not None  # the re-sender ran
    unreadable = [r for r in caplog.records if "cannot read the incarnation locks" in r.message]
    assert len(unreadable) == 1
