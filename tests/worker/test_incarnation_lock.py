"""A worker's incarnation lock lost while the worker lives (worker.incarnation), on both
shapes: its PostgreSQL session ended (``pg_terminate_backend``; a server restart or
``idle_session_timeout`` end it alike), or its lock file removed beside the SQLite file.

Others then find the lock free. Before, a twin of the worker's name judged the live
worker dead and re-queued its running job (run twice), and the worker never took its
lock again. Now its monitor takes the lock again at its next beat, and a run whose lock
is found free is taken only when found free again two beats later, its run silent.
"""

from __future__ import annotations

import shutil
from typing import TYPE_CHECKING

from scenario_support import GOOD_SEQUENCE
from sqlalchemy import text, update

from service.store import JobRow
from service.store.jobs import claim
from service.store.models import utcnow
from worker.incarnation import Life, Witness, alive
from worker.monitor import WorkerMonitor
from worker.reaper import ReapReport, take_restarted_runs

if TYPE_CHECKING:
    from conftest import Store

WORKER = "w1@host"


def _lose(store: Store, life: Life) -> int | None:
    """End the lock as the database or an operator would, the worker living on; on
    PostgreSQL, the lock's key."""
    url = store.settings.resolved_database_url
    if url.startswith("postgresql"):
        with store.db.session() as session:
            # The only advisory lock in this test's own database: the worker's.
            ((pid, key),) = session.execute(
                text(
                    "SELECT pid, (classid::bigint << 32) | objid::bigint FROM pg_locks"
                    " WHERE locktype = 'advisory' AND granted AND database ="
                    " (SELECT oid FROM pg_database WHERE datname = current_database())"
                )
            ).all()
            # Waits (up to 10 s) for the session to end: its locks go with it.
            assert session.scalar(text("SELECT pg_terminate_backend(:pid, 10000)"), {"pid": pid})
        return int(key) - (1 << 64) if key >= 1 << 63 else int(key)
    # The folder beside the database, cleaned out by hand (or a backup restored).
    shutil.rmtree(store.settings.data_dir / "inertia-id.db.incarnations")
    return None


def _alive(store: Store, incarnation: str) -> bool:
    with store.db.session() as session:
        return alive(session, store.settings.resolved_database_url, incarnation)


def _running(store: Store, incarnation: str) -> str:
    job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})
    with store.db.session() as session:
        assert claim(session, job_id, WORKER, incarnation) is not None
    return job_id


def test_a_lock_lost_while_the_worker_lives_is_taken_again_at_its_next_beat(
    store: Store,
) -> None:
    life = Life(store.settings.resolved_database_url, "first")
    monitor = WorkerMonitor(WORKER, store.settings, life)
    try:
        monitor.tick()
        assert _alive(store, "first")
        _lose(store, life)
        assert not _alive(store, "first")  # what a twin's probe sees now
        monitor.tick()
        assert _alive(store, "first") and life.held
    finally:
        monitor.stop()


def test_a_twin_leaves_the_running_job_of_a_live_worker_whose_lock_was_lost(
    store: Store,
) -> None:
    url = store.settings.resolved_database_url
    first = WorkerMonitor(WORKER, store.settings, Life(url, "first"))
    twin = WorkerMonitor(WORKER, store.settings, Life(url, "twin"))
    try:
        first.tick()
        job_id = _running(store, "first")
        _lose(store, first.life)
        # The twin's beat before the first's: it finds the lock free, the run beating.
        twin.tick()
        job = store.job(job_id)
        assert (job.status, job.attempts, job.worker_incarnation) == ("running", 1, "first")
        assert not job.attempt_history, job.attempt_history
        first.tick()
        twin.tick()
        assert store.job(job_id).status == "running"
    finally:
        twin.stop()
        first.stop()


def test_a_dead_incarnations_run_is_taken_once_its_lock_was_free_at_two_probes(
    store: Store,
) -> None:
    url = store.settings.resolved_database_url
    dead = Life(url, "dead")
    assert dead.hold()
    job_id = _running(store, "dead")
    dead.release()  # as its process's death would
    with store.db.session() as session:
        session.execute(
            update(JobRow)
            .where(JobRow.id == job_id)
            .values(heartbeat_at=utcnow().replace(year=2000))
        )
    now = [0.0]
    witness = Witness(10.0, clock=lambda: now[0])
    monitor = WorkerMonitor(WORKER, store.settings, Life(url, "again"))
    try:

        def take() -> ReapReport:
            return take_restarted_runs(
                store.settings, monitor.db, monitor.celery, WORKER, "again", witness
            )

        assert take().requeued == []  # found free once: perhaps a live one's lost lock
        now[0] = 9.0
        assert take().requeued == []
        now[0] = 10.0
        assert take().requeued == [job_id]
        (lost,) = store.job(job_id).attempt_history
        assert (lost["cause"], lost["then"]) == ("worker restarted", "re-queued")
    finally:
        monitor.stop()


def test_a_lock_found_held_again_starts_the_count_afresh() -> None:
    now = [0.0]
    witness = Witness(10.0, clock=lambda: now[0])
    assert not witness.gone("x", lock_free=True)
    now[0] = 6.0
    assert not witness.gone("x", lock_free=False)  # taken again by its live process
    now[0] = 12.0
    assert not witness.gone("x", lock_free=True)
    now[0] = 22.0
    assert witness.gone("x", lock_free=True)
