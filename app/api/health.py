"""Is the service able to do work? Database, broker and workers, never a 5xx."""

from __future__ import annotations

import logging
import os
import sqlite3
import tempfile
import threading
import time
import weakref
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from celery import Celery
from fastapi import APIRouter
from sqlalchemy import func, select, text
from sqlalchemy.orm import Session
from sqlalchemy.pool import QueuePool

import inertia_id
from service.config import Settings
from service.store.incarnations import LockUnreadable, locks_held
from service.store.models import JobRow, WorkerRow, utcnow
from service.store.session import Database

from ..schemas import (
    ComponentHealth,
    DatabaseHealth,
    GoneWorker,
    HealthOut,
    QueueHealth,
    WarmingWorker,
    WorkersHealth,
    WorkerWithoutLock,
)
from .deps import CeleryDep, DatabaseDep, SettingsDep
from .routing import UniqueKeysRoute

__all__ = ["router"]

log = logging.getLogger(__name__)

router = APIRouter(tags=["health"], route_class=UniqueKeysRoute)

# A worker is alive if it was seen within this many heartbeat intervals.
_HEARTBEATS_OF_GRACE = 3.0
_BROKER_TIMEOUT_S = 2.0


_PROBE_BYTES = 4096


def _write_refused(folder: str) -> str | None:
    """Why a small file cannot be written in ``folder`` (the OS's words), or None when it
    can; the file is removed again. Permission bits alone said "writable" to root on a
    full disk, where every write failed (``os.access`` looks at the mode, not the room)."""
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".health-probe-") as probe:
            probe.write(b"\0" * _PROBE_BYTES)
            probe.flush()
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return None


def _sqlite_write_refused(path: str) -> str | None:
    """Why SQLite refuses to begin a write on the file at ``path`` (its words), or None
    when it takes one; nothing is stored. The folder probe passed with the file (and its
    WAL) immutable or read-only while every write failed: a connection opened after that
    has the file read-only and refuses the first write. A new connection, since a pooled
    one opened before keeps its writable descriptor and fails only at its commit.
    ``timeout=0``: a writer holding the lock makes this SQLITE_BUSY at once, never a
    wait behind it (busy means a writer is writing, so writes are taken)."""
    try:
        # mode=rw: a missing file is an error, not a new empty database.
        uri = f"{Path(path).as_uri()}?mode=rw"
        probe = sqlite3.connect(uri, uri=True, timeout=0, isolation_level=None)
    except sqlite3.Error as exc:
        return str(exc)
    try:
        probe.execute("BEGIN IMMEDIATE")
        (version,) = probe.execute("PRAGMA user_version").fetchone()
        # The same value: the header page is changed in the cache, then rolled back.
        probe.execute(f"PRAGMA user_version = {int(version)}")
        probe.execute("ROLLBACK")
    except sqlite3.Error as exc:
        if exc.sqlite_errorcode & 0xFF in (sqlite3.SQLITE_BUSY, sqlite3.SQLITE_LOCKED):
            return None
        return str(exc)
    finally:
        probe.close()
    return None


def _postgres_write_refused(database: Database) -> str | None:
    """Why a PostgreSQL database takes no writes (a hot standby, or its transactions
    read-only by default), or None when it takes them: every write was a 500 while
    /health said "ok" (SQLSTATE 25006, read_only_sql_transaction). Read, never written:
    the setting and the recovery flag say it without a write to undo.

    A session keeps the ``default_transaction_read_only`` it started with (``ALTER
    DATABASE ... SET`` reaches new sessions only): a pooled connection opened during a
    read-only spell read "on" after it ended, and /health said "takes no writes" for as
    long as it stayed in the pool (the workers stored their beats and results again).
    A pooled connection that reads read-only is checked against a session opened now,
    outside the pool: when that one reads read-only too the database is, and the pool's
    sessions say so rightly and are kept (closing them made every request after a poll
    open its own); else the pool's idle sessions that read read-only are closed."""
    engine = database.engine
    with engine.connect() as connection:
        read_only, in_recovery = connection.execute(text(_PG_WRITES)).one()
        if read_only != "on" or in_recovery:
            return _postgres_refusal(read_only, in_recovery)
        read_only, in_recovery = _postgres_fresh(database)
        if read_only == "on" or in_recovery:
            return _postgres_refusal(read_only, in_recovery)
        connection.invalidate()  # opened during a read-only spell since ended
    pool = engine.pool
    # The others opened then: each idle one is taken once (the pool hands them out in
    # turn), closed if it reads read-only, kept otherwise.
    for _ in range(pool.checkedin() if isinstance(pool, QueuePool) else 0):
        with engine.connect() as connection:
            if connection.execute(text(_PG_WRITES)).one()[0] == "on":
                connection.invalidate()
    return None


_PG_WRITES = "SELECT current_setting('transaction_read_only'), pg_is_in_recovery()"


#: How long what a session opened for the probe read answers for: polls at once during a
#: read-only spell share it (each opened its own: 20 pollers, up to 20 sessions beyond the
#: pool's), and it is late by no more than this after the spell ends.
_FRESH_FOR_S = 1.0
_clock = time.monotonic
_fresh_lock = threading.Lock()
_fresh: weakref.WeakKeyDictionary[Database, tuple[float, tuple[str, bool]]] = (
    weakref.WeakKeyDictionary()
)


def _postgres_fresh(database: Database) -> tuple[str, bool]:
    """:data:`_PG_WRITES` as a session opened now reads it: one opened at most
    :data:`_FRESH_FOR_S` ago, or one opened here, outside the pool (one at a time)."""
    with _fresh_lock:
        found = _fresh.get(database)
        if found is not None and _clock() - found[0] < _FRESH_FOR_S:
            return found[1]
        read = _postgres_opened_now(database)
        _fresh[database] = (_clock(), read)
        return read


def _postgres_opened_now(database: Database) -> tuple[str, bool]:
    """:data:`_PG_WRITES` read on a session opened now, outside the pool, and closed."""
    dialect = database.engine.dialect
    args, kwargs = dialect.create_connect_args(database.engine.url)
    raw = dialect.connect(*args, **kwargs)
    try:
        cursor = raw.cursor()
        cursor.execute(_PG_WRITES)
        row = cursor.fetchone()
        assert row is not None  # one row: the SELECT has no FROM
        return str(row[0]), bool(row[1])
    finally:
        raw.close()


def _postgres_refusal(read_only: str, in_recovery: bool) -> str | None:
    if in_recovery:
        return "it is a standby in recovery (pg_is_in_recovery())"
    if read_only == "on":
        return "its transactions are read-only (transaction_read_only is on)"
    return None


#: Said of a database that answers but refuses writes: what an operator meets.
_WRITES_REFUSED = "; workers' heartbeats and results cannot be stored until it takes writes"


def _database(database: Database, reachable: bool) -> DatabaseHealth:
    """Reachable, and whether it takes writes. The probes write nothing that stays: on
    PostgreSQL two settings read; on SQLite a 4 KiB file written and removed beside the
    database (a full disk or read-only folder refuses it) and a write begun on the file
    and rolled back (a read-only or immutable file refuses it); both cost a few ms."""
    dialect = database.engine.dialect.name
    if not reachable:
        return DatabaseHealth(ok=False, detail=f"{dialect} unreachable")
    if dialect == "postgresql":
        try:
            refused = _postgres_write_refused(database)
        except Exception as exc:  # reported, never raised: /health is always a 200
            return DatabaseHealth(ok=False, detail=f"{dialect} unreachable: {exc}")
        if refused is not None:
            return DatabaseHealth(
                ok=False,
                takes_writes=False,
                detail=f"{dialect} reachable, but it takes no writes: {refused}" + _WRITES_REFUSED,
            )
    # A SQLite file is read while its disk is full or its folder read-only, but nothing
    # can be stored: every write was a 503 and every worker's beat failed.
    path = database.engine.url.database if dialect == "sqlite" else None
    if path and path != ":memory:" and not path.startswith("file:"):
        refused = _write_refused(os.path.dirname(os.path.abspath(path)))
        if refused is not None:
            return DatabaseHealth(
                ok=False,
                takes_writes=False,
                detail=f"{dialect} reachable, but the folder of its file takes no writes: "
                f"{refused}" + _WRITES_REFUSED,
            )
        refused = _sqlite_write_refused(os.path.abspath(path))
        if refused is not None:
            return DatabaseHealth(
                ok=False,
                takes_writes=False,
                detail=f"{dialect} reachable, but its file takes no writes: {refused}"
                + _WRITES_REFUSED,
            )
    return DatabaseHealth(ok=True, takes_writes=True, detail=f"{dialect} reachable")


def _broker(settings: Settings, celery: Celery) -> ComponentHealth:
    scheme = settings.broker_url.split("://", 1)[0]
    if scheme == "filesystem":
        options: dict[str, Any] = celery.conf.broker_transport_options or {}
        folder = options.get("data_folder_in") or str(settings.broker_dir)
        # The folder is named relative to the data dir: no server path in a response.
        if os.path.isdir(folder) and os.access(folder, os.W_OK | os.X_OK):
            # Where a message is written first (service.queue); no consumer reads a
            # name like the probe's in either folder.
            staging = options.get("staging_folder") or folder
            refused = _write_refused(staging if os.path.isdir(staging) else folder)
            if refused is None:
                return ComponentHealth(ok=True, detail="filesystem broker folder writable")
            return ComponentHealth(
                ok=False,
                detail=f"filesystem broker folder (broker/ in the data dir) takes no writes: "
                f"{refused}",
            )
        return ComponentHealth(
            ok=False,
            detail="filesystem broker folder (broker/queue in the data dir) is missing or "
            "not writable",
        )
    try:
        with celery.connection_for_write(connect_timeout=_BROKER_TIMEOUT_S) as connection:
            connection.ensure_connection(
                max_retries=1, interval_start=0, interval_step=0, timeout=_BROKER_TIMEOUT_S
            )
    except Exception as exc:  # any transport error means unreachable, reported not raised
        return ComponentHealth(ok=False, detail=f"{scheme} broker unreachable: {exc}")
    return ComponentHealth(ok=True, detail=f"{scheme} broker reachable")


def _age_s(now: datetime, since: datetime) -> float:
    if since.tzinfo is None:  # SQLite hands back naive UTC
        since = since.replace(tzinfo=UTC)
    return max(0.0, (now - since).total_seconds())


def _queue(
    settings: Settings, database: Database, database_ok: bool, live_workers: int
) -> QueueHealth:
    """Queued jobs, whether any waits for a message that is not coming, and whether the
    oldest has waited long while a live worker had no job (a worker that beats but takes
    nothing: its task process cannot start, its consumer is stuck)."""
    if not database_ok:
        return QueueHealth(ok=False, queued=0, running=0, unsent=0, oldest_queued_s=None)
    now = utcnow()
    overdue = now - timedelta(seconds=3 * settings.unsent_grace_s)
    try:
        with database.session() as session:
            queued = session.scalar(
                select(func.count()).select_from(JobRow).where(JobRow.status == "queued")
            )
            running = session.scalar(
                select(func.count()).select_from(JobRow).where(JobRow.status == "running")
            )
            unsent = session.scalar(
                select(func.count())
                .select_from(JobRow)
                .where(
                    JobRow.status == "queued",
                    JobRow.sent_at.is_(None),
                    JobRow.created_at < overdue,
                )
            )
            oldest = session.scalar(
                select(func.min(JobRow.created_at)).where(JobRow.status == "queued")
            )
    except Exception:  # the database went away between the ping and the query
        log.exception("could not read the jobs table")
        return QueueHealth(ok=False, queued=0, running=0, unsent=0, oldest_queued_s=None)
    age = None if oldest is None else _age_s(now, oldest)
    idle_workers = live_workers - int(running or 0)
    # A worker with no job takes a queued job within a poll of its broker; one that
    # just finished a long job may be caught for that moment, hence the long threshold.
    stalled = age is not None and age > settings.queue_stall_s and idle_workers > 0
    details = []
    if unsent:
        details.append(f"{unsent} queued job(s) without a message for a while")
    if stalled:
        details.append(
            f"the oldest queued job has waited {age:.0f} s (over {settings.queue_stall_s:g} s) "
            f"while {idle_workers} live worker(s) had no job: they are not taking jobs"
        )
    return QueueHealth(
        ok=not unsent and not stalled,
        queued=int(queued or 0),
        running=int(running or 0),
        unsent=int(unsent or 0),
        oldest_queued_s=age,
        stalled=stalled,
        detail="; ".join(details) or None,
    )


def _gone_incarnations(session: Session, database_url: str, incarnations: list[str]) -> set[str]:
    """Those of ``incarnations`` (the last beats' of worker rows) whose processes are
    gone: their incarnation locks are free, all read at once (see
    :func:`service.store.incarnations.locks_held`). A lock that cannot be read, or a
    database without locks: none known gone."""
    try:
        held = locks_held(session, database_url, incarnations)
    except LockUnreadable:  # its workers log why, once
        return set()
    return {incarnation for incarnation, is_held in held.items() if is_held is False}


def _last_known(session: Session, window: float) -> tuple[datetime | None, list[str], int]:
    """While the database refuses writes: the last beat it stored (any worker's not told
    to stop), the workers that beat within ``window`` of it, and the jobs running then."""
    last = session.scalar(
        select(func.max(WorkerRow.last_seen_at)).where(WorkerRow.stopping_since.is_(None))
    )
    running = session.scalar(
        select(func.count()).select_from(JobRow).where(JobRow.status == "running")
    )
    if last is None:
        return None, [], int(running or 0)
    names = session.scalars(
        select(WorkerRow.name)
        .where(
            WorkerRow.last_seen_at >= last - timedelta(seconds=window),
            WorkerRow.stopping_since.is_(None),
        )
        .order_by(WorkerRow.name)
    ).all()
    return last, list(names), int(running or 0)


def _seconds_z(moment: datetime) -> str:
    """An instant in UTC to the second, ``Z``, as the API writes times."""
    return moment.isoformat(timespec="seconds").replace("+00:00", "Z")


def _unknown_detail(last: datetime | None, names: list[str], running: int) -> str:
    """The workers' state, in words, while the database refuses their beats."""
    if last is None:
        said = "no worker's beat is stored, and none can be while the database refuses writes"
    else:
        stamp = (last if last.tzinfo else last.replace(tzinfo=UTC)).astimezone(UTC)
        said = (
            f"the workers' state is unknown since {_seconds_z(stamp)} "
            "(their last beat stored): the database refuses writes, their heartbeats "
            "included"
        )
        if names:
            said += f"; live then: {', '.join(names)}"
    if running:
        said += (
            f"; {running} job(s) running as last stored: a run that finished since keeps "
            "its result and stores it once the database takes writes"
        )
    return said


def _workers(
    settings: Settings, database: Database, database_ok: bool, refusing: bool = False
) -> WorkersHealth:
    """The workers as their beats say; ``refusing``: the database refuses writes, so
    their beats are not stored either, and no beat in the window says nothing of them."""
    window = _HEARTBEATS_OF_GRACE * settings.heartbeat_interval_s
    # Past the heartbeat timeout a warm-up is as stuck as a run that stopped beating;
    # past the start timeout Celery has killed the replacement and started another.
    limit = min(settings.heartbeat_timeout_s, settings.worker_start_timeout_s)
    rows: list[tuple[str, datetime | None, datetime | None]] = []
    gone: list[GoneWorker] = []
    #: Live rows another live process of the same name beat within the window (twins).
    twins: list[tuple[str, float]] = []
    unknown: tuple[datetime | None, list[str], int] | None = None
    now = utcnow()
    if database_ok:
        cutoff = now - timedelta(seconds=window)
        try:
            with database.session() as session:
                seen = session.execute(
                    select(
                        WorkerRow.name,
                        WorkerRow.warming_since,
                        WorkerRow.lock_missing_since,
                        WorkerRow.incarnation,
                        WorkerRow.last_seen_at,
                        WorkerRow.twin_seen_at,
                    )
                    # A worker told to stop (SIGTERM) takes no job any more: it
                    # leaves the list at once, not a silence window later.
                    .where(WorkerRow.last_seen_at >= cutoff, WorkerRow.stopping_since.is_(None))
                    .order_by(WorkerRow.name)
                ).all()
                # A row without an incarnation (stored before them) is not known gone.
                gone_incarnations = _gone_incarnations(
                    session,
                    settings.resolved_database_url,
                    [row.incarnation for row in seen if row.incarnation is not None],
                )
                for name, since, lock_missing_since, incarnation, last_seen, twin_at in seen:
                    # Killed (kill -9, its machine lost): its lock went with its process,
                    # and its row, which it can no longer beat, says what it was
                    # (warming, say) until the silence window ends. A worker that knows
                    # its lock is missing says so (lock_missing_since) and is live.
                    if lock_missing_since is None and incarnation in gone_incarnations:
                        gone.append(GoneWorker(name=name, silent_s=_age_s(now, last_seen)))
                    else:
                        rows.append((name, since, lock_missing_since))
                        if twin_at is not None and _age_s(now, twin_at) <= window:
                            twins.append((name, _age_s(now, twin_at)))
                if refusing and not rows:
                    unknown = _last_known(session, window)
        except Exception:  # the database went away between the ping and the query
            log.exception("could not read the workers table")
    warming = [
        WarmingWorker(name=name, warming_s=_age_s(now, since))
        for name, since, _ in rows
        if since is not None
    ]
    without_lock = [
        WorkerWithoutLock(name=name, without_lock_s=_age_s(now, since))
        for name, _, since in rows
        if since is not None
    ]
    overdue = [w for w in warming if w.warming_s > limit]
    # Each live worker lacks its lock: none claims a job (each sent to one stays queued).
    # One that holds it takes them all in turn, so the others alone are no fault.
    none_locked = bool(rows) and len(without_lock) == len(rows)
    details = []
    if not database_ok:
        details.append("the database is unreachable: no worker can be read")
    elif unknown is not None:
        # Said "no worker seen" while the workers beat on, their beats refused, and one
        # held a finished run's result for the database to take.
        details.append(_unknown_detail(*unknown))
    elif not rows:
        details.append(f"no worker seen in the last {window:g} s")
    if not rows:
        details += [
            f"worker {w.name}'s process is gone (its incarnation lock is free; "
            f"its last beat {w.silent_s:.0f} s ago)"
            for w in gone
        ]
    details += [
        f"worker {w.name} has been warming up for {w.warming_s:.0f} s (over {limit:g} s): "
        "its task process does not start"
        for w in overdue
    ]
    if none_locked:
        details += [
            f"worker {w.name} has not held its incarnation lock for {w.without_lock_s:.0f} s: "
            "it claims no job until it takes it again (its log says why it cannot)"
            for w in without_lock
        ]
    # Not a fault of the service (both processes take jobs), but the list shows one of
    # them: the other's state (warming, its lock) is in its own log only.
    details += [
        f"worker {name}: a second live process beats under this name ({age:.0f} s ago), "
        "and this list shows only one of them: give each worker its own name (celery -n)"
        for name, age in twins
    ]
    return WorkersHealth(
        ok=bool(rows) and not overdue and not none_locked,
        count=len(rows),
        duplicates_seen=len(twins),
        names=[name for name, _, _ in rows],
        window_s=window,
        warming=warming,
        without_lock=without_lock,
        gone=gone,
        warming_limit_s=limit,
        state_unknown_since=None if unknown is None else unknown[0],
        last_known=[] if unknown is None else unknown[1],
        detail="; ".join(details) or None,
    )


def _takers(workers: WorkersHealth) -> int:
    """The live workers that can take a job now: warm and holding their lock."""
    unable = {w.name for w in workers.warming} | {w.name for w in workers.without_lock}
    return sum(1 for name in workers.names if name not in unable)


@router.get("/health")
def health(settings: SettingsDep, database: DatabaseDep, celery: CeleryDep) -> HealthOut:
    """Database reachable, broker reachable, workers seen recently (one whose task
    process warms up, as the worker starts or as a replacement, counts, as warming,
    unless its warm-up takes too long; one
    without its incarnation lock is listed, and no worker holding its lock is a fault), no
    queued job left without a message nor waiting long while a worker sits idle: "ok",
    else "degraded".

    Always 200: the body says what is wrong.
    """
    # A database that is read but takes no writes (a full disk) still lists its workers
    # and jobs: those say whether the workers beat through it.
    reachable = database.ping()
    db = _database(database, reachable)
    broker = _broker(settings, celery)
    workers = _workers(settings, database, reachable, refusing=db.takes_writes is False)
    # A warming worker takes no job until it is warm, one without its incarnation lock
    # none until it takes it again (listed, and a fault when none holds it): neither is
    # idle. Counted, a lockless worker beside a busy one made a long queue "stalled",
    # blamed on a stuck task process, while workers.without_lock names the cause.
    queue = _queue(settings, database, reachable, _takers(workers))
    return HealthOut(
        status="ok" if db.ok and broker.ok and workers.ok and queue.ok else "degraded",
        version=inertia_id.__version__,
        database=db,
        broker=broker,
        workers=workers,
        queue=queue,
    )
