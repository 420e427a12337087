"""A worker's incarnation lock lost while the worker lives (worker.incarnation), on both
shapes: its PostgreSQL session ended (``pg_terminate_backend``; a server restart or
``idle_session_timeout`` end it alike), or its lock file removed beside the SQLite file.

Others then find the lock free. Before, a twin of the worker's name judged the live
worker dead and re-queued its running job (run twice), the worker never took its lock
again, and it went on claiming jobs a twin could take the same way. Now its monitor
takes the lock again at its next beat, a run whose lock is found free is taken only when
found free again two beats later, its run silent, and until the lock is held again the
worker's task processes leave new jobs queued.
"""

from __future__ import annotations

import logging
import shutil
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import timedelta
from functools import partial
from typing import TYPE_CHECKING, Any

import pytest
from scenario_support import GOOD_SEQUENCE
from service_support import SilentableProxy, wait_for
from sqlalchemy import Connection, event, text, update
from sqlalchemy.engine import make_url
from test_worker_restart import QUICK_SEARCH

from service.store import JobRow, WorkerRow
from service.store.jobs import claim, start_worker, take_earlier_incarnations
from service.store.models import utcnow
from worker import incarnation
from worker.incarnation import Life, Witness, alive
from worker.monitor import WorkerMonitor
from worker.reaper import ReapReport, take_restarted_runs
from worker.runner import execute_job

if TYPE_CHECKING:
    from conftest import Service, Store

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


@contextmanager
def _kept_from(store: Store, life: Life) -> Iterator[None]:
    """The lock lost, and kept from its worker while inside: another session holds its
    key (PostgreSQL), a file stands where its folder goes (SQLite)."""
    key = _lose(store, life)
    if key is None:
        folder = store.settings.data_dir / "inertia-id.db.incarnations"
        folder.touch()
        try:
            yield
        finally:
            folder.unlink()
        return
    with store.db.engine.connect() as connection:
        assert connection.scalar(text("SELECT pg_try_advisory_lock(:key)"), {"key": key})
        try:
            yield
        finally:
            connection.execute(text("SELECT pg_advisory_unlock(:key)"), {"key": key})


def _alive(store: Store, incarnation: str) -> bool:
    with store.db.session() as session:
        return alive(session, store.settings.resolved_database_url, incarnation)


def _running(store: Store, incarnation: str | None) -> str:
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
        assert _alive(store, "first") and life.held and life.may_claim()
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


def test_a_dead_incarnations_lock_is_probed_while_its_run_falls_silent(
    store: Store,
) -> None:
    """The two waits, the run's silence and the lock's two probes, run side by side:
    the run is taken two beats after the kill, not four. Before, its lock was first
    probed once the run had been silent for two beats, and the deciding probe came two
    beats after that (about 20 s at the default beat)."""
    url = store.settings.resolved_database_url
    dead = Life(url, "dead")
    assert dead.hold()
    job_id = _running(store, "dead")
    killed = utcnow()
    with store.db.session() as session:  # its last beat just before it was killed
        session.execute(update(JobRow).where(JobRow.id == job_id).values(heartbeat_at=killed))
    dead.release()  # as its process's death would
    now = [0.0]
    witness = Witness(10.0, clock=lambda: now[0])
    monitor = WorkerMonitor(WORKER, store.settings, Life(url, "again"))
    try:

        def take(at: float) -> ReapReport:
            now[0] = at
            with store.db.session() as session:
                requeued, ended = take_earlier_incarnations(
                    session,
                    WORKER,
                    "again",
                    alive=lambda other: not witness.gone(other, not _alive(store, other)),
                    max_attempts=store.settings.max_attempts,
                    beat_within_s=10.0,
                    now=killed + timedelta(seconds=at),
                )
            return ReapReport(requeued=requeued, failed=ended)

        assert take(0.0).requeued == []  # the restart's first beat: found free, not silent
        assert take(5.0).requeued == []
        assert take(10.5).requeued == [job_id]  # free at two probes, silent two beats
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


def test_a_worker_without_its_lock_leaves_a_job_queued_and_runs_it_once_held(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor

    # As the worker's start (worker_init) makes it, read by its task processes.
    life = Life(store.settings.resolved_database_url, "first")
    monkeypatch.setattr(worker.monitor, "_life", life)
    monitor = WorkerMonitor(WORKER, store.settings, life)
    job_id = store.add_job("train", {"sequence": "not a sequence"}, sent_at=utcnow())
    try:
        monitor.tick()
        with _kept_from(store, life):
            monitor.tick()  # finds it lost, cannot take it again
            assert not life.held and not worker.monitor.may_claim()
            status = execute_job(
                job_id,
                settings=store.settings,
                worker_name=WORKER,
                may_claim=worker.monitor.may_claim,
            )
            assert status == "passed on"
            job = store.job(job_id)
            assert (job.status, job.attempts, job.worker) == ("queued", 0, None)
        monitor.tick()
        assert life.held and _alive(store, "first")
        status = execute_job(
            job_id, settings=store.settings, worker_name=WORKER, may_claim=worker.monitor.may_claim
        )
        assert status == "failed" and store.job(job_id).attempts == 1
    finally:
        monitor.stop()


def test_a_job_left_by_a_worker_without_its_lock_is_not_sent_to_it_at_every_beat(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)  # its task process is up
    life = Life(store.settings.resolved_database_url, "first")
    monkeypatch.setattr(worker.monitor, "_life", life)
    monitor = WorkerMonitor(WORKER, store.settings, life)
    job_id = store.add_job("train", {"sequence": "not a sequence"}, sent_at=utcnow())
    try:
        monitor.tick()
        with _kept_from(store, life):
            monitor.tick()  # finds it lost, cannot take it again
            status = execute_job(
                job_id,
                settings=store.settings,
                worker_name=WORKER,
                may_claim=worker.monitor.may_claim,
            )
            assert status == "passed on"
            # Its message spent, it waits long: no worker that may claim it sits idle.
            # Before: marked unsent, then sent again at every beat (and left again).
            assert store.job(job_id).sent_at is not None
            with store.db.session() as session:
                session.execute(update(JobRow).values(sent_at=utcnow() - timedelta(minutes=5)))
            long_ago = store.job(job_id).sent_at
            monitor.tick()
            monitor.tick()
            assert store.job(job_id).sent_at == long_ago  # before: sent again
        monitor.tick()  # holds its lock again: idle, its lost message sent again
        assert life.held and store.job(job_id).sent_at != long_ago
    finally:
        monitor.stop()


def test_a_job_left_by_a_worker_without_its_lock_is_sent_again_at_the_beat_that_retakes_it(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)  # its task process is up
    life = Life(store.settings.resolved_database_url, "first")
    monkeypatch.setattr(worker.monitor, "_life", life)
    monitor = WorkerMonitor(WORKER, store.settings, life)
    job_id = store.add_job("train", {"sequence": "not a sequence"}, sent_at=utcnow())
    try:
        monitor.tick()
        with _kept_from(store, life):
            monitor.tick()  # finds it lost, cannot take it again
            status = execute_job(
                job_id,
                settings=store.settings,
                worker_name=WORKER,
                may_claim=worker.monitor.may_claim,
            )
            assert status == "passed on"
            left_at = store.job(job_id).sent_at
            monitor.tick()
            assert store.job(job_id).sent_at == left_at  # not sent to it at every beat
        monitor.tick()  # takes its lock again
        # Before: sent again only resend_after_s (30 s) after it was left.
        assert life.held and store.job(job_id).sent_at != left_at
        sent_at = store.job(job_id).sent_at
        monitor.tick()
        assert store.job(job_id).sent_at == sent_at  # once
    finally:
        monitor.stop()


def test_health_names_a_lone_worker_whose_beat_finds_it_without_its_lock(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor
    from app.api.health import health

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)  # its task process is up
    life = Life(store.settings.resolved_database_url, "first")
    monitor = WorkerMonitor(WORKER, store.settings, life)

    def status() -> tuple[str, str | None]:
        answer = health(store.settings, store.db, monitor.celery)
        return answer.status, answer.workers.detail

    try:
        monitor.tick()
        assert status() == ("ok", None)
        with _kept_from(store, life):
            monitor.tick()  # finds it lost, cannot take it again: claims no job
            state, detail = status()
            assert state == "degraded", detail  # before: "ok"
            assert f"worker {WORKER} has not held its incarnation lock" in (detail or "")
        monitor.tick()
        assert status() == ("ok", None)
    finally:
        monitor.stop()


def test_a_stopping_worker_hands_back_its_own_runs_not_a_live_twins(store: Store) -> None:
    first = WorkerMonitor(
        WORKER, store.settings, Life(store.settings.resolved_database_url, "first")
    )
    mine, older, twins = _running(store, "first"), _running(store, None), _running(store, "twin")
    with store.db.session() as session:
        start_worker(session, WORKER, "filesystem://", "twin")  # the twin started last
    try:
        # The main process's hand-back (SIGTERM); a job claimed before incarnations
        # were recorded keeps the old rule (its worker's name).
        assert sorted(first.hand_back()) == sorted([mine, older])
        # A task process given a message as the stop came passes it on the same way.
        fetched = store.add_job("train", {"sequence": GOOD_SEQUENCE})
        stopping = execute_job(
            fetched, settings=store.settings, worker_name=WORKER, stopping=lambda: True
        )
        assert stopping == "passed on"
    finally:
        first.stop()
    job = store.job(twins)
    assert (job.status, job.worker_incarnation, job.handbacks) == ("running", "twin", 0)
    with store.db.session() as session:
        assert session.get_one(WorkerRow, WORKER).stopping_since is None  # the twin's row


def test_a_twin_told_to_stop_leaves_the_live_twin_listed(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor
    from app.api.health import health

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)  # their task processes are up
    url = store.settings.resolved_database_url
    first = WorkerMonitor(WORKER, store.settings, Life(url, "first"))
    twin = WorkerMonitor(WORKER, store.settings, Life(url, "twin"))

    def row() -> tuple[str | None, bool]:
        with store.db.session() as session:
            worker_row = session.get_one(WorkerRow, WORKER)
            return worker_row.incarnation, worker_row.stopping_since is not None

    try:
        first.tick()
        twin.tick()  # started last: the shared row names it
        twin.hand_back()  # told to stop: marks the row it names stopping
        assert row() == ("twin", True)
        first.tick()  # before: the row stayed stopping, /health left the live twin out
        assert row() == ("first", False)
        twin._hand_back_again()  # its repeats, every second until it is gone
        assert row() == ("first", False)
        assert health(store.settings, store.db, first.celery).workers.names == [WORKER]
    finally:
        twin.stop()
        first.stop()


def _block_worker_lock(deployment: Service, timeout_s: float) -> Callable[[], None]:
    """Take a running worker's lock from it and keep it so (as in _kept_from, for a
    worker process); the function that gives it back."""
    folder = deployment.settings.data_dir / "inertia-id.db.incarnations"
    if deployment.kind == "filesystem":
        while True:
            shutil.rmtree(folder, ignore_errors=True)
            try:
                folder.touch(exist_ok=False)
            except FileExistsError:
                continue  # the worker made it again first, at a beat
            return folder.unlink
    connection = deployment.db.engine.connect()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        row = connection.execute(
            text(
                # The worker's: the one advisory lock held long in this module's
                # database (an alive() probe holds one for a moment, never the worker's).
                "SELECT pid, (classid::bigint << 32) | objid::bigint FROM pg_locks"
                " WHERE locktype = 'advisory' AND granted AND pid <> pg_backend_pid()"
                " AND database = (SELECT oid FROM pg_database WHERE datname = current_database())"
            )
        ).first()
        if row is not None:
            pid, key = int(row[0]), int(row[1])
            key = key - (1 << 64) if key >= 1 << 63 else key
            connection.execute(text("SELECT pg_terminate_backend(:pid, 10000)"), {"pid": pid})
            # The worker may take it again first, at its next beat: then again.
            if connection.scalar(text("SELECT pg_try_advisory_lock(:key)"), {"key": key}):
                connection.commit()
                return partial(_unlock, connection, key)
        connection.rollback()
        time.sleep(0.05)
    connection.close()
    raise AssertionError("could not take the worker's lock from it")


def _unlock(connection: Connection, key: int) -> None:
    # By hand: a pooled connection's session, and its locks, outlive close().
    connection.execute(text("SELECT pg_advisory_unlock(:key)"), {"key": key})
    connection.close()


def test_a_worker_whose_lock_is_taken_from_it_runs_no_job_until_it_holds_it_again(
    deployment: Service,
) -> None:
    beat = {
        "INERTIA_ID_HEARTBEAT_INTERVAL_S": "0.5",
        "INERTIA_ID_UNSENT_GRACE_S": "0.5",
        # The job left queued is sent again this long after, once the worker is back.
        "INERTIA_ID_RESEND_AFTER_S": "2",
    }
    worker = deployment.start_worker(**beat)
    try:
        give_back = _block_worker_lock(deployment, 30.0)
        try:
            # Seen lost at a beat, and not taken again (the worker may have taken it
            # back before _block_worker_lock held it: "lost" alone is not enough).
            wait_for(
                lambda: "could not take this worker's incarnation lock" in worker.log(20_000),
                30.0,
                "the worker did not find its lock lost and kept from it",
                worker.log,
            )
            job_id = deployment.submit("search", QUICK_SEARCH, seed=64)
            wait_for(
                lambda: f"job {job_id} left queued" in worker.log(20_000),
                60.0,
                f"job {job_id} was not left queued",
                worker.log,
            )
            job = deployment.job(job_id)
            assert (job.status, job.attempts) == ("queued", 0), (job.status, job.attempts)
        finally:
            give_back()
        job = deployment.wait_for(job_id)
        assert (job.status, job.attempts) == ("succeeded", 1), worker.log()
    finally:
        worker.kill()


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
@pytest.mark.parametrize(
    "failure",
    ["SELECT 1/0", "SELECT pg_terminate_backend(pg_backend_pid())"],
    ids=["statement-error", "session-ended"],
)
def test_a_twins_beat_whose_lock_probe_fails_leaves_the_run_and_goes_on(
    store: Store, failure: str, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.incarnation

    monkeypatch.setattr(worker.incarnation, "_UNREADABLE", {})  # logged once an episode
    # The probe of the other incarnation's lock fails on the server (an error, or its
    # session ended as at a restart): the lock's state is unknown, so the run is left.
    # Before, alive() raised out of the beat, before its reaper and re-sender.
    running = _running(store, "other")
    with store.db.session() as session:
        start_worker(session, WORKER, "filesystem://", "other")
        session.get_one(JobRow, running).heartbeat_at = utcnow() - timedelta(seconds=30)
    unsent = store.add_job("train", {}, created_at=utcnow() - timedelta(minutes=5))
    twin = WorkerMonitor(WORKER, store.settings, Life(store.settings.resolved_database_url, "twin"))

    def fail_the_probe(
        _conn: Any, _cursor: Any, statement: str, parameters: Any, *_: Any
    ) -> tuple[str, Any]:
        if "pg_try_advisory_lock" in statement:
            return failure, {}
        return statement, parameters

    event.listen(twin.db.engine, "before_cursor_execute", fail_the_probe, retval=True)
    try:
        with caplog.at_level(logging.WARNING, logger="worker.incarnation"):
            for _ in range(3):
                twin.tick()
            with twin.db.session() as session:  # unknown: not judged dead at a later probe
                assert alive(session, store.settings.resolved_database_url, "other")
    finally:
        twin.stop()
    assert store.job(running).status == "running"
    assert store.job(unsent).sent_at is not None  # the re-sender ran
    unknown = [r for r in caplog.records if "cannot read the incarnation locks" in r.message]
    assert len(unknown) == 1, [r.message for r in unknown]


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
@pytest.mark.parametrize("unlock", ["SELECT 1/0", "SELECT false"], ids=["fails", "releases-none"])
def test_a_probe_whose_unlock_fails_leaves_the_probed_lock_free(store: Store, unlock: str) -> None:
    # A probe finds the other incarnation's lock free (its session just ended, as at a
    # server restart) and so takes it for a moment; its unlock then fails without the
    # connection dropping. A session advisory lock outlives the rollback: before, the
    # pooled connection kept the other's lock, which its live process then could never
    # take again (its beats found it "held by another database session").
    url = store.settings.resolved_database_url

    def fail_the_unlock(
        _conn: Any, _cursor: Any, statement: str, parameters: Any, *_: Any
    ) -> tuple[str, Any]:
        if "pg_advisory_unlock" in statement:
            return unlock, {}
        return statement, parameters

    event.listen(store.db.engine, "before_cursor_execute", fail_the_unlock, retval=True)
    with store.db.session() as session:
        found_alive = alive(session, url, "other")
        session.execute(text("SELECT 1"))  # the caller's session goes on
    event.remove(store.db.engine, "before_cursor_execute", fail_the_unlock)

    def nobody_holds_it() -> bool:
        with store.db.session() as session:
            return not session.scalar(
                text(
                    "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND granted"
                    " AND database = (SELECT oid FROM pg_database"
                    " WHERE datname = current_database())"
                )
            )

    # The closed session's locks go when the server sees it gone: a moment.
    wait_for(nobody_holds_it, 10.0, "the probed lock was kept by the probe's session", str)
    other = Life(url, "other")
    try:
        assert other.hold()
    finally:
        other.release()
    assert not found_alive  # it was found free (a second probe, two beats on, decides)


def test_a_released_lock_is_free_at_once_to_every_other_session(store: Store) -> None:
    """A clean stop's release: another session finds the lock free as soon as release()
    returns. Before, it only closed the lock's PostgreSQL session, and the server let
    go of the lock as that session's process exited, after close() had returned: pg_locks
    read at once still listed it in 20 of 200 releases on the loaded 2-core machine, and
    /health, reading it, called a stopped worker alive (the flaky
    test_a_worker_whose_process_is_gone_is_listed_gone_not_warming[postgresql])."""
    from service.store.incarnations import locks_held

    url = store.settings.resolved_database_url
    still_held = []
    for index in range(60):
        life = Life(url, f"released-{index}")
        assert life.hold()
        life.release()
        with store.db.session() as session:
            if locks_held(session, url, [life.incarnation])[life.incarnation]:
                still_held.append(index)
    assert still_held == []


def _within(seconds: float, call: Callable[[], Any], what: str) -> Any:
    """What ``call`` returns, called on a thread of its own; a failure if it still
    waits after ``seconds`` (a bound well past the one it is meant to keep)."""
    outcome: list[Any] = []
    thread = threading.Thread(target=lambda: outcome.append(call()), daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive() or not outcome:
        pytest.fail(f"{what} still waited {seconds:g} s after the database fell silent")
    return outcome[0]


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_a_lock_whose_database_falls_silent_is_let_go_of_without_waiting_on_it(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The lock's server stops answering, its packets lost rather than refused. Before,
    a stop's release() waited on its unlock's answer for ever (past serve's 10 s grace,
    when it kills the worker; a plain celery worker never ended), and a beat's check
    (keep(), lost()) likewise. Now each statement gets LOCK_ANSWER_S (1 s here), and
    a connection at most 2 s (libpq's least connect_timeout); the connection is then
    cut: a released lock goes when the server sees its session end, said in one line."""
    monkeypatch.setattr(incarnation, "LOCK_ANSWER_S", 1.0, raising=False)
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        stopping, beating = Life(through, "stopping"), Life(through, "beating")
        assert stopping.hold() and beating.hold()
        proxy.silence()
        with caplog.at_level(logging.WARNING, logger="worker.incarnation"):
            _within(10.0, stopping.release, "release()")
            assert not stopping.held
            assert [r.message for r in caplog.records] == [
                "could not confirm the release of this worker's incarnation lock (no answer "
                "within 1 s): its session's connection is closed, and the server lets go of "
                "the lock as it sees that session end"
            ]
            caplog.clear()
            # The beat: its check finds no answer, and taking the lock again finds none.
            assert _within(10.0, beating.keep, "a beat's keep()") is False
            assert not beating.may_claim()
            assert "lock was lost: its database session gave no answer within 1 s" in (
                caplog.records[0].message
            )
            beating.release()
    finally:
        proxy.close()
    # The server ends the cut sessions as the proxy closes: their locks are free. Asked
    # by a probe, not by a take under the same name: that ends the session itself
    # (see worker.incarnation._end_own_sessions), whether the server let go or not.
    never = "the silent session's lock was never let go of"
    wait_for(lambda: not _alive(store, "stopping"), 10.0, never, str)


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_a_lock_cut_in_a_silence_the_server_never_heard_of_is_taken_again(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A beat's check gets no answer, so the lock's connection is cut; the network comes
    back, but the server never heard the goodbye (lost in the silence), and its session
    holds the lock on until the server's TCP keepalive ends it (hours by default).
    Before, each beat found the lock "held by another database session" and the live
    worker claimed no job meanwhile; now the take ends that session, which is this
    process's own (its application_name names this incarnation), and holds the lock."""
    monkeypatch.setattr(incarnation, "LOCK_ANSWER_S", 1.0, raising=False)
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        life = Life(through, "cut")
        assert life.hold()
        proxy.silence()
        assert not _within(10.0, life.keep, "keep()")  # its check cut, the take unanswered
        proxy.speak_again(forget=True)
        assert _alive(store, "cut")  # the old session holds it still
        assert life.keep() and life.may_claim()
        assert _alive(store, "cut")
        life.release()
        assert not _alive(store, "cut")
    finally:
        proxy.close()


class _AnsweredAtTheDeadline:
    """A lock connection (its socket one end of a pair) whose answer comes as the deadline
    cuts it, and that its caller closes, its descriptor's number soon another socket's,
    while the cut has still to reach the socket: :func:`connection.fileno` on the
    deadline's thread waits until the test says the number is reused."""

    def __init__(self) -> None:
        self.sock, self.peer = socket.socketpair()
        self.cutting = threading.Event()
        self.reused = threading.Event()

    def fileno(self) -> int:
        number = self.sock.fileno()
        if isinstance(threading.current_thread(), threading.Timer):
            self.cutting.set()
            self.reused.wait(5.0)
        return number

    def execute(self, statement: str, params: tuple[Any, ...]) -> Any:
        # Answered once the deadline has begun its cut (or ended it).
        timers = [t for t in threading.enumerate() if isinstance(t, threading.Timer)]
        while not self.cutting.wait(0.01) and any(t.is_alive() for t in timers):
            pass
        return self

    def fetchone(self) -> tuple[int]:
        return (1,)


def test_a_deadline_met_as_the_answer_came_cuts_no_other_socket(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Before, _ask returned (LockSilent) as soon as its deadline had begun the cut, which
    then looked up the connection's descriptor number and shut down whatever socket had
    that number by then: the caller closes the connection and connects again at once
    (keep()), so that could be the lock's new connection, or any socket of the process
    (the broker's). Now the cut works on a duplicate taken before the statement, and
    _ask returns only once the cut is over."""
    monkeypatch.setattr(incarnation, "LOCK_ANSWER_S", 0.05, raising=False)
    connection = _AnsweredAtTheDeadline()
    with pytest.raises(incarnation.LockSilent):
        incarnation._ask(connection, "SELECT 1", ())
    number = connection.sock.fileno()
    connection.sock.close()  # the caller closes the connection...
    connection.peer.close()
    other, far = socket.socketpair()  # ...and the process opens another socket
    try:
        if other.fileno() != number:
            pytest.skip(f"descriptor {number} was not reused ({other.fileno()})")
        connection.reused.set()
        for thread in threading.enumerate():
            if isinstance(thread, threading.Timer):
                thread.join(5.0)
        try:
            other.sendall(b"x")
            far.settimeout(5.0)
            answer = far.recv(1)
        except OSError as exc:
            answer = repr(exc).encode()
        assert answer == b"x", f"the deadline's cut shut down another socket ({answer!r})"
    finally:
        connection.reused.set()
        other.close()
        far.close()


class _RefusingConnection:
    """A lock connection on which ending a session is refused (no right to, or a server
    before PostgreSQL 14, which lacks pg_terminate_backend's timeout)."""

    def __init__(self) -> None:
        self.sock, self.peer = socket.socketpair()

    def fileno(self) -> int:
        return self.sock.fileno()

    def execute(self, statement: str, params: Any) -> Any:
        raise RuntimeError("permission denied to terminate process")


def test_a_refusal_to_end_the_workers_earlier_lock_session_is_a_warning_once(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Before, the refusal was logged at DEBUG only, so an operator saw just "held by
    another database session" at each beat, for as long as the server kept the session
    (hours). Now the first refusal in a process is a warning that says what the worker
    waits for; the ones after it (one a beat) stay at DEBUG."""
    monkeypatch.setattr(incarnation, "_COULD_NOT_END", [], raising=False)
    connection = _RefusingConnection()
    try:
        with caplog.at_level(logging.DEBUG, logger=incarnation.logger.name):
            for _ in range(3):
                assert not incarnation._end_own_sessions(connection, "inertia-id lock x", 7)
    finally:
        connection.sock.close()
        connection.peer.close()
    said = [r for r in caplog.records if "earlier incarnation lock session" in r.getMessage()]
    assert [r.levelno for r in said] == [logging.WARNING, logging.DEBUG, logging.DEBUG], said
    assert "permission denied to terminate process" in said[0].getMessage()
    assert "claims no job until the server ends it" in said[0].getMessage()


def test_a_beat_under_way_as_the_stop_releases_the_lock_does_not_take_it_again(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A stop waits for the monitor's beat only so long (its lock statements each take up
    to LOCK_ANSWER_S on a silent server), then releases the lock. Before, a beat still
    taking the lock again (it found it lost) went on after the release and held it: the
    stopped worker's lock stayed held, its task processes free to claim, until the
    process exited. Now the release is for good: the late take lets go of what it got."""
    import psycopg

    url = store.settings.resolved_database_url
    life = Life(url, "stopping")
    assert life.hold()
    _lose(store, life)  # the beat finds it lost and takes it again
    taking, released = threading.Event(), threading.Event()

    def when_released(take: Callable[..., Any]) -> Callable[..., Any]:
        def late(*args: Any, **kwargs: Any) -> Any:
            taking.set()
            assert released.wait(10.0)
            return take(*args, **kwargs)

        return late

    if url.startswith("postgresql"):
        monkeypatch.setattr(psycopg, "connect", when_released(psycopg.connect))
    else:
        monkeypatch.setattr(incarnation, "_open_locked", when_released(incarnation._open_locked))
    beat: list[bool] = []
    thread = threading.Thread(target=lambda: beat.append(life.keep()), daemon=True)
    thread.start()
    assert taking.wait(10.0)
    life.release()
    released.set()
    thread.join(10.0)
    assert beat == [False]
    assert not life.held and not life.may_claim()
    assert not _alive(store, "stopping")
    if not url.startswith("postgresql"):
        assert list((store.settings.data_dir / "inertia-id.db.incarnations").glob("*.lock")) == []


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_the_workers_database_gives_up_a_connect_to_a_silent_server(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The worker's own connections (its beat's, its hand-back's, its runs') to a server
    that does not answer: before, a connect waited for ever (libpq's default), and so did
    a beat, or a stop's hand-back, that needed a new connection. Now libpq gives it up
    after DATABASE_SILENT_S (2 s here, libpq's least)."""
    from service.config import Settings
    from worker import monitor as monitor_module

    monkeypatch.setattr(monitor_module, "DATABASE_SILENT_S", 2.0, raising=False)
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    proxy.silence()
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        settings = Settings(
            INERTIA_ID_DATA_DIR=store.settings.data_dir,
            DATABASE_URL=through,
            BROKER_URL="filesystem://",
        )
        monitor = WorkerMonitor(WORKER, settings, Life(through, "connecting"))
        try:
            assert _within(10.0, monitor.db.ping, "the worker's connect") is False
        finally:
            monitor.db.dispose()
    finally:
        proxy.close()


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_a_runs_database_gives_up_a_connect_to_a_silent_server(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A task process's run (its claim, its heartbeat, its outcome) on its own engine,
    the server silent as the job comes: libpq gives the connect up after
    DATABASE_SILENT_S (2 s here, libpq's least), and the job's message goes back to the
    broker, the job untouched. With libpq's defaults the connect waited for ever, and the
    task process with it."""
    from service.config import Settings
    from worker import runner

    monkeypatch.setattr(runner, "DATABASE_SILENT_S", 2.0)
    monkeypatch.setattr(runner, "_handed_back_in_a_row", 0)  # its back-off: 1 s
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    proxy.silence()
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        settings = Settings(
            INERTIA_ID_DATA_DIR=store.settings.data_dir,
            DATABASE_URL=through,
            BROKER_URL="filesystem://",
        )
        job_id = store.add_job("train", {"sequence": GOOD_SEQUENCE})
        status = _within(
            10.0,
            lambda: execute_job(job_id, settings=settings, worker_name=WORKER),
            "the run's connect",
        )
        assert status == runner.HANDED_BACK
        job = store.job(job_id)
        assert (job.status, job.attempts, job.worker) == ("queued", 0, None)
    finally:
        proxy.close()


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_a_stop_whose_database_falls_silent_exits_without_waiting_on_it(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The worker told to stop (SIGTERM) as its database stops answering, its packets
    lost rather than refused. Before, the stop waited 10 s for the hand-back (its
    statement waiting on the answer for ever), then the beat, then the lock's release: a
    real worker behind a frozen proxy took 20 s to exit, past serve's 10 s grace. Now
    the hand-back and the beat are waited for STOP_WAIT_S (1 s here) from the stop, which
    then goes on, saying so in one line: the reaper re-queues what was left."""
    from service.config import Settings
    from worker import monitor as monitor_module
    from worker import process

    monkeypatch.setattr(incarnation, "LOCK_ANSWER_S", 1.0, raising=False)
    monkeypatch.setattr(monitor_module, "STOP_WAIT_S", 1.0, raising=False)
    monkeypatch.setattr(monitor_module, "_hand_back_thread", None)
    monkeypatch.setattr(monitor_module, "_stop_began", None, raising=False)
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        settings = Settings(
            INERTIA_ID_DATA_DIR=store.settings.data_dir,
            DATABASE_URL=through,
            BROKER_URL="filesystem://",
        )
        monitor = WorkerMonitor(WORKER, settings, Life(through, "silent"))
        monitor.tick()  # its pool keeps a connection through the proxy; its lock is held
        monkeypatch.setattr(monitor_module, "_monitor", monitor)
        proxy.silence()
        with caplog.at_level(logging.WARNING, logger="worker.monitor"):
            monitor_module._hand_back()  # at SIGTERM: the hand-back starts on its thread
            _within(8.0, monitor_module._stop_monitor, "the stop")  # as Celery exits
        assert not monitor.life.held
        assert any(
            "no answer from the database" in r.message
            and "to its hand-back within 1 s" in r.message
            for r in caplog.records
        ), [r.message for r in caplog.records]
    finally:
        process._STOPPING[0] = 0
        proxy.close()


def test_a_stop_whose_broker_hangs_after_the_hand_back_commit_blames_the_broker(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The hand-back's commit re-queued the run, then its send to the broker hung past
    STOP_WAIT_S (1 s here). The stop's warning said "no answer from the database" and
    that the reaper would re-queue the run (it was re-queued already), and the lock was
    let go of without asking the healthy server to unlock. Now it names the broker and
    the job, and the lock is released as in a clean exit."""
    from worker import monitor as monitor_module
    from worker import process

    monkeypatch.setattr(monitor_module, "STOP_WAIT_S", 1.0, raising=False)
    monkeypatch.setattr(monitor_module, "_hand_back_thread", None)
    monkeypatch.setattr(monitor_module, "_stop_began", None, raising=False)
    monitor = WorkerMonitor(
        WORKER, store.settings, Life(store.settings.resolved_database_url, "hung")
    )
    monitor.tick()  # its lock is held
    job_id = _running(store, "hung")
    broker = threading.Event()
    monkeypatch.setattr(monitor.celery, "send_task", lambda *a, **k: broker.wait(30))
    releases: list[bool] = []
    release = monitor.life.release
    monkeypatch.setattr(
        monitor.life,
        "release",
        lambda *, confirm=True: (releases.append(confirm), release(confirm=confirm)),
    )
    monkeypatch.setattr(monitor_module, "_monitor", monitor)
    try:
        with caplog.at_level(logging.WARNING, logger="worker.monitor"):
            monitor_module._hand_back()  # at SIGTERM: the hand-back starts on its thread
            _within(8.0, monitor_module._stop_monitor, "the stop")  # as Celery exits
        warnings = [r.message for r in caplog.records if r.name == "worker.monitor"]
        assert len(warnings) == 1, warnings
        assert f"re-queued its runs (jobs: {job_id})" in warnings[0], warnings
        assert "but the broker filesystem:" in warnings[0], warnings
        assert "did not take their messages within 1 s of the stop" in warnings[0], warnings
        assert "database" not in warnings[0] and "reaper" not in warnings[0], warnings
        assert releases == [True] and not monitor.life.held
        job = store.job(job_id)
        assert (job.status, job.worker, job.sent_at) == ("queued", None, None)
    finally:
        broker.set()
        process._STOPPING[0] = 0


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_a_run_whose_database_falls_silent_as_its_worker_stops_gives_itself_up(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """A search running as its worker is told to stop and its database stops answering,
    its packets lost rather than refused. Before, its cancel poll waited on the answer
    for ever, and Celery, which waits for its run before it exits, kept a plain
    ``celery worker`` running (76 s after SIGTERM, then killed). Now a statement still
    unanswered STOP_ANSWER_S (0.5 s here) into the stop has the run's connections cut,
    and the run, its cancel flag unread, gives itself up: its job is left running, its
    heartbeat stale, for the reaper (or the stop's hand-back, had the database heard
    it)."""
    from service.config import Settings
    from worker import cut

    monkeypatch.setattr(cut, "STOP_ANSWER_S", 0.5, raising=False)
    url = make_url(store.settings.resolved_database_url)
    proxy = SilentableProxy(url.host or "127.0.0.1", url.port or 5432)
    stop = threading.Event()
    try:
        through = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
        settings = Settings(
            INERTIA_ID_DATA_DIR=store.settings.data_dir,
            DATABASE_URL=through,
            BROKER_URL="filesystem://",
        )
        long_search = {**QUICK_SEARCH, "timesteps": 400, "n_realisations": 50, "time_limit_s": 120}
        job_id = store.add_job("search", long_search)
        statuses: list[str] = []
        run = threading.Thread(
            target=lambda: statuses.append(
                execute_job(job_id, settings=settings, worker_name=WORKER, stopping=stop.is_set)
            ),
            daemon=True,
        )
        run.start()
        deadline = time.monotonic() + 120.0
        while store.job(job_id).status != "running" and run.is_alive():
            assert time.monotonic() < deadline, "the search was never claimed"
            time.sleep(0.1)
        time.sleep(2.5)  # its cancel flag read, through the proxy, at least once more
        proxy.silence()
        stop.set()
        with caplog.at_level(logging.WARNING):
            run.join(15.0)
            if run.is_alive():
                pytest.fail("the run still waited 15 s after the database fell silent")
        assert statuses == ["lost"]
        job = store.job(job_id)
        assert (job.status, job.attempts, job.worker) == ("running", 1, WORKER)
        assert any("the run given up" in r.message for r in caplog.records), [
            r.message for r in caplog.records
        ]
    finally:
        proxy.close()
