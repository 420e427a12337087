"""The worker's beat while its database is wholly down, on both shapes: the SQLite file
cannot be opened, or the PostgreSQL database takes no connection (``ALLOW_CONNECTIONS
false``, its sessions ended). The outage is logged in one line when it starts, naming
its reason, and in one line when the database answers again; a later outage is an
episode of its own. Before, every beat (every 5 s) logged a traceback of over 100 lines
for as long as the outage lasted, and nothing said when it ended.

Also the lock code's "logged once" warnings: once an episode, not once a process (a
second outage later in the worker's life was never logged).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from service_support import POSTGRES_ADMIN_URL, postgres_database, writes_refused_while
from sqlalchemy import create_engine, event, make_url, text, update

from service.config import Settings
from service.store.models import JobRow, WorkerRow, utcnow
from service.store.refusals import database_label
from service.store.session import upgrade
from worker.episode import Episode
from worker.incarnation import Life, alive
from worker.monitor import WorkerMonitor

if TYPE_CHECKING:
    from conftest import Store

WORKER = "w1@host"


@contextmanager
def _database_down(store: Store, monitor: WorkerMonitor) -> Iterator[None]:
    """The monitor's database wholly down while inside."""
    url = make_url(store.settings.resolved_database_url)
    if url.drivername.startswith("sqlite"):
        path = str(url.database)
        os.rename(path, f"{path}.away")
        os.mkdir(path)  # a folder where the file goes: it cannot be opened
        monitor.db.engine.dispose()  # a pooled connection holds the file open
        try:
            yield
        finally:
            os.rmdir(path)
            os.rename(f"{path}.away", path)
        return
    # The test's own database (never the server's others): no new connection, and its
    # sessions ended, the worker's lock's among them.
    admin = create_engine(POSTGRES_ADMIN_URL, isolation_level="AUTOCOMMIT")
    name = url.database
    try:
        with admin.connect() as connection:
            connection.execute(text(f'ALTER DATABASE "{name}" ALLOW_CONNECTIONS false'))
            connection.execute(
                text(
                    "SELECT pg_terminate_backend(pid, 10000) FROM pg_stat_activity"
                    " WHERE datname = :name AND pid <> pg_backend_pid()"
                ),
                {"name": name},
            )
        yield
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'ALTER DATABASE "{name}" ALLOW_CONNECTIONS true'))
        admin.dispose()


def _lines(caplog: pytest.LogCaptureFixture) -> list[logging.LogRecord]:
    return [r for r in caplog.records if r.name.startswith("worker.")]


def test_a_database_outage_is_logged_once_when_it_starts_and_once_when_it_ends(
    store: Store, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)  # its task process is up
    monitor = WorkerMonitor(WORKER, store.settings, Life(store.settings.resolved_database_url, "a"))
    # What the monitor's thread calls at each beat, its failures caught and logged there.
    beat: Callable[[], None] = monitor._ticker._safe_tick
    try:
        beat()
        with caplog.at_level(logging.INFO, logger="worker"):
            for episode in (1, 2):  # a later outage is logged as the first was
                caplog.clear()
                with _database_down(store, monitor):
                    for _ in range(4):
                        beat()
                    down = _lines(caplog)
                    # Before: an ERROR with a traceback (over 100 lines) at every beat.
                    assert [r for r in down if r.exc_info] == [], [r.getMessage() for r in down]
                    named = f"the database {database_label(monitor.db.url)} is unreachable"
                    outage = [r for r in down if named in r.getMessage()]
                    assert len(outage) == 1, (episode, [r.getMessage() for r in down])
                    assert "OperationalError" in outage[0].getMessage()
                    caplog.clear()
                beat()
                beat()
                back = [r.getMessage() for r in _lines(caplog)]
                assert sum("the database answers again" in m for m in back) == 1, back
    finally:
        monitor.stop()


def test_a_database_that_refuses_writes_is_named_so_not_unreachable_once_an_episode(
    store: Store, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before: a full disk's beat logged "the database is unreachable (OperationalError:
    # database or disk is full)", though the database answered and refused the write
    # (seen under inertia-id serve, its SQLite file on a filled 40 MiB tmpfs).
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)
    monitor = WorkerMonitor(WORKER, store.settings, Life(store.settings.resolved_database_url, "a"))
    beat: Callable[[], None] = monitor._ticker._safe_tick
    refusing = threading.Event()
    try:
        beat()
        with writes_refused_while(refusing), caplog.at_level(logging.INFO, logger="worker"):
            refusing.set()
            monitor.db.engine.dispose()  # connections checked out from now on
            for _ in range(4):
                beat()
            down = [r.getMessage() for r in _lines(caplog)]
            refusing.clear()
            monitor.db.engine.dispose()
            beat()
            beat()
        lines = [r.getMessage() for r in _lines(caplog)]
    finally:
        monitor.stop()
    assert not any("unreachable" in m for m in lines), lines
    refused = [m for m in down if "refuses writes (read-only" in m]
    assert len(refused) == 1, down
    label = make_url(store.settings.resolved_database_url)
    name = str(label.database) if label.drivername.startswith("sqlite") else label.database
    assert str(name) in refused[0], refused[0]
    assert sum("the database takes writes again" in m for m in lines) == 1, lines
    assert not [r for r in _lines(caplog) if r.exc_info]


def _unreadable(caplog: pytest.LogCaptureFixture) -> int:
    return sum("cannot read the incarnation locks" in r.getMessage() for r in caplog.records)


def test_a_lock_unreadable_again_later_is_logged_again(
    store: Store, caplog: pytest.LogCaptureFixture
) -> None:
    url = store.settings.resolved_database_url
    broken = [False]
    if url.startswith("postgresql"):

        def fail_the_probe(
            _conn: Any, _cursor: Any, statement: str, parameters: Any, *_: Any
        ) -> tuple[str, Any]:
            if broken[0] and "pg_try_advisory_lock" in statement:
                return "SELECT 1/0", {}
            return statement, parameters

        event.listen(store.db.engine, "before_cursor_execute", fail_the_probe, retval=True)

        def break_it(on: bool) -> None:
            broken[0] = on
    else:
        folder = store.settings.data_dir / "inertia-id.db.incarnations"

        def break_it(on: bool) -> None:
            if on:
                folder.touch()  # a file where the folder goes
            else:
                folder.unlink()

    def probe() -> bool:
        with store.db.session() as session:
            return alive(session, url, "other")

    with caplog.at_level(logging.INFO, logger="worker.incarnation"):
        for outage in (1, 2):
            break_it(True)
            assert probe() and probe()  # unknown: taken to be alive
            # Before: logged at the first outage only, for the process's life.
            assert _unreadable(caplog) == outage, outage
            break_it(False)
            assert not probe()  # read: never taken, so free
    back = [r.getMessage() for r in caplog.records if "can read the incarnation locks" in r.message]
    assert len(back) == 2, back


def test_an_episode_is_logged_when_it_starts_for_each_new_reason_as_a_reminder_and_when_it_ends(
    caplog: pytest.LogCaptureFixture,
) -> None:
    now = [0.0]
    episode = Episode(logging.getLogger("worker.test"), remind_every_s=60.0, clock=lambda: now[0])
    with caplog.at_level(logging.INFO, logger="worker.test"):
        assert episode.seen("A", "down (%s)")
        now[0] = 30.0
        assert not episode.seen("A", "down (%s)")
        assert episode.seen("B", "down (%s)")  # a new reason
        assert not episode.seen("A", "down (%s)")  # not new in this episode
        now[0] = 89.0
        assert not episode.seen("A", "down (%s)")  # 59 s after the last line
        now[0] = 91.0
        assert episode.seen("A", "down (%s)")  # the reminder
        now[0] = 100.0
        assert episode.cleared("up after %.0f s")
        assert not episode.cleared("up after %.0f s")
        assert episode.seen("A", "down (%s)")  # a new episode
    assert [r.getMessage() for r in caplog.records] == [
        "down (A)",
        "down (B)",
        "still, for 91 s: down (A)",
        "up after 100 s",
        "down (A)",
    ]


def test_a_run_the_outage_kept_from_beating_is_not_reaped_when_the_database_answers_again(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before: the first beat after a 2-minute outage (a full disk, here the database
    # wholly down) re-queued the run as "heartbeat missed ... died or hung": its last
    # heartbeat was 2 minutes old, though its task process lived and had only been
    # refused. It ran twice, and the end its run was waiting to store was dropped.
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)
    monitor = WorkerMonitor(WORKER, store.settings, Life(store.settings.resolved_database_url, "a"))
    now = [1000.0]
    monitor._clock = lambda: now[0]
    beat: Callable[[], None] = monitor._ticker._safe_tick
    timeout_s = store.settings.heartbeat_timeout_s
    job_id = store.add_job(
        status="running", worker=WORKER, worker_incarnation="a", attempts=1, heartbeat_at=utcnow()
    )
    try:
        beat()
        with _database_down(store, monitor):
            beat()
            beat()
        # The outage lasted twice the heartbeat timeout: the run's last beat is that old.
        stale = utcnow() - timedelta(seconds=2 * timeout_s)
        with store.db.session() as session:
            session.execute(update(JobRow).where(JobRow.id == job_id).values(heartbeat_at=stale))
        beat()
        assert store.job(job_id).status == "running"
        now[0] += timeout_s / 2
        beat()
        assert store.job(job_id).status == "running"
        # A run still silent a heartbeat timeout after the database answered is reaped.
        now[0] += timeout_s / 2
        beat()
        job = store.job(job_id)
        assert (job.status, job.attempts) == ("queued", 1)
    finally:
        monitor.stop()


@pytest.fixture(params=["sqlite", "postgresql"])
def unmigrated(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Settings]:
    """Settings on a database that exists but has no schema: a fresh SQLite file, or an
    empty PostgreSQL database (dropped after)."""
    databases: Iterator[str] | None = None
    (tmp_path / "data").mkdir()
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'data' / 'inertia-id.db'}"
    else:
        databases = postgres_database(prefix="inertia_id_worker_unmigrated")
        url = next(databases)
    try:
        yield Settings(
            INERTIA_ID_DATA_DIR=tmp_path / "data", DATABASE_URL=url, BROKER_URL="filesystem://"
        )
    finally:
        if databases is not None:
            for _ in databases:
                pass


def test_a_worker_started_before_the_schema_says_so_in_one_line_and_beats_once_it_is_there(
    unmigrated: Settings, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before: PostgreSQL's beat logged "its beat failed (UndefinedTable ...)" with a
    # traceback, SQLite's "the database is unreachable (... no such table: workers)";
    # stopped before the schema came, both logged "could not hand the running job back"
    # with a traceback.
    import worker.monitor

    monkeypatch.setattr(worker.monitor, "warm", lambda: True)
    url = unmigrated.resolved_database_url
    monitor = WorkerMonitor(WORKER, unmigrated, Life(url, "a"))
    beat: Callable[[], None] = monitor._ticker._safe_tick
    try:
        with caplog.at_level(logging.INFO, logger="worker"):
            for _ in range(3):
                beat()
            worker.monitor._hand_back_now(monitor)
            before = _lines(caplog)
            caplog.clear()
            upgrade(url)
            beat()
            beat()
            after = [r.getMessage() for r in _lines(caplog)]
        with monitor.db.session() as session:
            row = session.get(WorkerRow, WORKER)
            assert row is not None and row.incarnation == "a"
    finally:
        monitor.stop()
    messages = [r.getMessage() for r in before]
    assert [r for r in before if r.exc_info or r.levelno >= logging.ERROR] == [], messages
    assert not any("unreachable" in m or "beat failed" in m for m in messages), messages
    no_schema = [m for m in messages if "has no schema yet (" in m and "hand back" not in m]
    assert len(no_schema) == 1, messages
    # It names the command that migrates (before: "start the API first", the only way).
    assert "run `inertia-id migrate`" in no_schema[0] and "workers" in no_schema[0], no_schema
    assert sum("no job to hand back: the database has no schema yet" in m for m in messages) == 1
    assert sum("the database has its schema after" in m for m in after) == 1, after
