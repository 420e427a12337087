"""Job lifecycle on the ``jobs`` table, shared by the API and the workers.

queued -> running -> succeeded | failed | cancelled. A worker *claims* a queued job
(an atomic conditional UPDATE, so two deliveries of one message never run it twice),
beats its heart while it runs, and finishes it. A running job whose heartbeat is older
than the timeout belonged to a worker that died: :func:`reap_stale` re-queues it (up to
``max_attempts`` runs) or fails it with the reason.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete, func, select, update
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from .models import TERMINAL_STATUSES, JobRow, MetricRow, WorkerRow, utcnow

__all__ = [
    "add_metrics",
    "cancel",
    "claim",
    "clear_metrics",
    "config_hash",
    "finish",
    "heartbeat",
    "is_cancel_requested",
    "reap_stale",
    "set_progress",
    "touch_worker",
]


def config_hash(job_type: str, scenario_id: str, params: dict[str, Any], seed: int) -> str:
    """Identity of a job's work: the same type, scenario, parameters and seed."""
    canonical = json.dumps(
        {"type": job_type, "scenario": scenario_id, "params": params, "seed": seed},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(canonical.encode()).hexdigest()


def claim(session: Session, job_id: str, worker: str) -> JobRow | None:
    """Mark a queued job running for ``worker``; None if it is not queued any more."""
    now = utcnow()
    claimed = session.execute(  # type: ignore[attr-defined]
        update(JobRow)
        .where(JobRow.id == job_id, JobRow.status == "queued", JobRow.cancel_requested.is_(False))
        .values(
            status="running",
            worker=worker,
            started_at=now,
            heartbeat_at=now,
            attempts=JobRow.attempts + 1,
            progress=0.0,
            error=None,
        )
    ).rowcount
    if not claimed:
        # A job cancelled while queued ends here, when its message arrives.
        session.execute(
            update(JobRow)
            .where(JobRow.id == job_id, JobRow.status == "queued", JobRow.cancel_requested)
            .values(status="cancelled", finished_at=now)
        )
        return None
    return session.get(JobRow, job_id)


def heartbeat(session: Session, job_id: str) -> None:
    session.execute(
        update(JobRow)
        .where(JobRow.id == job_id, JobRow.status == "running")
        .values(heartbeat_at=utcnow())
    )


def set_progress(session: Session, job_id: str, progress: float) -> None:
    session.execute(
        update(JobRow)
        .where(JobRow.id == job_id, JobRow.status == "running")
        .values(progress=min(max(float(progress), 0.0), 1.0), heartbeat_at=utcnow())
    )


def add_metrics(session: Session, job_id: str, rows: Iterable[tuple[str, int, float]]) -> None:
    """Append (key, step, value) points to a job's metrics."""
    session.add_all(
        MetricRow(job_id=job_id, key=key, step=int(step), value=float(value))
        for key, step, value in rows
    )


def is_cancel_requested(session: Session, job_id: str) -> bool:
    value = session.execute(
        select(JobRow.cancel_requested).where(JobRow.id == job_id)
    ).scalar_one_or_none()
    return bool(value)


def finish(
    session: Session,
    job_id: str,
    status: str,
    *,
    result: dict[str, Any] | None = None,
    error: str | None = None,
    attempt: int | None = None,
) -> bool:
    """End a running job as succeeded, failed or cancelled.

    :param attempt: the run (``attempts`` at claim) finishing it; when given, the job is
        only finished if it is still that run's, not a later re-run's.

    Returns False when the job was not running (as that run) any more: reaped, or
    finished by another delivery; the caller's work no longer belongs to it.
    """
    if status not in TERMINAL_STATUSES:
        raise ValueError(f"a job finishes as one of {TERMINAL_STATUSES}, not {status!r}")
    values: dict[str, Any] = {"status": status, "finished_at": utcnow(), "error": error}
    if status == "succeeded":
        values["progress"] = 1.0
    if result is not None:
        values["result"] = result
    conditions = [JobRow.id == job_id, JobRow.status == "running"]
    if attempt is not None:
        conditions.append(JobRow.attempts == attempt)
    finished = session.execute(  # type: ignore[attr-defined]
        update(JobRow).where(*conditions).values(**values)
    ).rowcount
    return bool(finished)


def cancel(session: Session, job: JobRow) -> None:
    """Ask a job to stop: a queued job is cancelled now, a running one at its next check."""
    if job.status in TERMINAL_STATUSES:
        return
    job.cancel_requested = True
    if job.status == "queued":
        job.status = "cancelled"
        job.finished_at = utcnow()


def reap_stale(
    session: Session,
    *,
    timeout_s: float,
    max_attempts: int,
    now: datetime | None = None,
) -> tuple[list[str], list[str]]:
    """Deal with running jobs whose heartbeat is older than ``timeout_s``.

    Returns (re-queued job ids, failed job ids). A job that has had ``max_attempts``
    runs, or whose cancel was requested, is not re-queued.
    """
    now = now or utcnow()
    cutoff = now - timedelta(seconds=timeout_s)
    stale = session.scalars(
        select(JobRow)
        .where(
            JobRow.status == "running",
            func.coalesce(JobRow.heartbeat_at, JobRow.started_at) < cutoff,
        )
        # Two workers' reapers may run at once: on PostgreSQL the second skips the rows the
        # first holds (and re-checks the condition after), so a job re-queued and claimed
        # again in between is not re-queued a second time. SQLite serialises writers anyway.
        .with_for_update(skip_locked=True)
    ).all()
    requeued, failed = [], []
    for job in stale:
        beat = job.heartbeat_at or job.started_at
        reason = (
            f"worker {job.worker or '?'} stopped sending heartbeats (last at "
            f"{beat.isoformat() if beat else 'never'}, timeout {timeout_s:g} s)"
        )
        if job.cancel_requested:
            job.status, job.finished_at, job.error = "cancelled", now, reason
            failed.append(job.id)
        elif job.attempts >= max_attempts:
            job.status, job.finished_at = "failed", now
            job.error = f"{reason}; gave up after {job.attempts} attempts"
            failed.append(job.id)
        else:
            job.status, job.worker, job.error = "queued", None, f"re-queued: {reason}"
            requeued.append(job.id)
    return requeued, failed


def clear_metrics(session: Session, job_id: str) -> None:
    """Drop a job's metrics: a re-run (after its worker died) starts a fresh curve."""
    session.execute(delete(MetricRow).where(MetricRow.job_id == job_id))


def touch_worker(session: Session, name: str, broker_url: str) -> None:
    """Record that worker ``name`` is alive now (insert its row, or move last_seen_at)."""
    now = utcnow()
    values = {"name": name, "broker_url": broker_url, "started_at": now, "last_seen_at": now}
    dialect = session.get_bind().dialect.name
    if dialect in ("sqlite", "postgresql"):
        # A worker's main process and its task process beat under one name: an atomic
        # upsert, so neither trips over the other's insert.
        insert = sqlite.insert if dialect == "sqlite" else postgresql.insert
        statement = insert(WorkerRow).values(**values)
        session.execute(
            statement.on_conflict_do_update(
                index_elements=[WorkerRow.name],
                set_={"last_seen_at": now, "broker_url": broker_url},
            )
        )
        return
    row = session.get(WorkerRow, name)
    if row is None:
        session.add(WorkerRow(**values))
    else:
        row.last_seen_at, row.broker_url = now, broker_url
