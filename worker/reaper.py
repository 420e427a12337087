"""Nothing lost, nothing stuck: the reaper, the re-sender and the hand-back.

Every worker's main process runs :func:`reap_once` and :func:`resend_once` at start and
then every heartbeat interval (see :mod:`worker.monitor`), and :func:`hand_back_jobs`
when it is told to stop.

- **Reaper**: a running job whose run died (its heartbeat went stale, or its whole worker
  went quiet) is re-queued and its message sent again, or failed with the reason once it
  has had ``max_attempts`` runs.
- **Re-sender**: a queued job whose message never reached the broker (the API died
  between commit and send, the broker was down) or was lost there (a deleted queue, a
  broker restarted empty) is sent again.
- **Hand-back**: a stopping worker puts its running job back in the queue at once,
  without spending one of the job's attempts.
- **Lost run**: a worker whose task process died while running a job (``kill -9``, the
  OOM killer) re-queues or fails that job at once, by the reaper's rule
  (:func:`take_lost_run`, called from :mod:`worker.request`); the reaper stays the
  backstop for a worker lost whole, which cannot tell anyone.

Two monitors at once are harmless: a job is claimed by one atomic UPDATE, so an extra
message for it finds it taken and does nothing, and each send is claimed the same way.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from celery import Celery
from sqlalchemy import func, select, update

from service.config import Settings
from service.queue import RUN_JOB_TASK
from service.store import Database, JobRow, WorkerRow
from service.store.jobs import (
    due_for_sending,
    hand_back,
    mark_sent,
    reap_stale,
    send_again_since,
    take_earlier_incarnations,
    task_process_lost,
)
from service.store.models import utcnow

from . import incarnation

__all__ = [
    "WORKER_SILENCE_BEATS",
    "ReapReport",
    "hand_back_jobs",
    "idle_workers",
    "reap_once",
    "resend_left",
    "resend_once",
    "take_lost_run",
    "take_restarted_runs",
]

logger = logging.getLogger(__name__)

#: A worker is gone when its row has not been beaten for this many heartbeat intervals.
WORKER_SILENCE_BEATS = 3.0


@dataclass(frozen=True)
class ReapReport:
    """What one pass of the reaper did.

    :param requeued: ids of the jobs re-queued and sent again.
    :param failed: ids of the jobs ended (failed after ``max_attempts`` runs, or
        cancelled when a cancel had been asked for).
    """

    requeued: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)


def _send(celery: Celery, job_ids: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
    sent, unsent = [], []
    for job_id in job_ids:
        try:
            celery.send_task(RUN_JOB_TASK, args=[job_id])
        except Exception as exc:
            unsent.append((job_id, f"{type(exc).__name__}: {exc}"))
        else:
            sent.append(job_id)
    return sent, unsent


def _unmark(db: Database, unsent: list[tuple[str, str]]) -> None:
    """Jobs whose send failed: back to "not sent", so a later pass tries again."""
    with db.session() as session:
        for job_id, _reason in unsent:
            session.execute(
                update(JobRow)
                .where(JobRow.id == job_id, JobRow.status == "queued")
                .values(sent_at=None)
            )
    logger.error(
        "could not send jobs to the broker (will try again): %s",
        "; ".join(f"{job_id}: {reason}" for job_id, reason in unsent),
    )


#: What a stopping worker's hand-back (:func:`hand_back_jobs`) is doing, in order: its
#: database commit that re-queues the runs, the send of their messages to the broker,
#: the database write that records what was sent, then nothing more. A stop that cannot
#: wait for it says which (:mod:`worker.monitor`): the runs are re-queued from the send on.
HAND_BACK_REQUEUE, HAND_BACK_SEND, HAND_BACK_RECORD, HAND_BACK_DONE = (
    "re-queue",
    "send",
    "record",
    "done",
)


def _dispatch(
    db: Database,
    celery: Celery,
    job_ids: list[str],
    *,
    mark: bool,
    stage: Callable[[str], None] | None = None,
) -> list[str]:
    """Send the jobs' messages; those sent marked sent now with ``mark`` (false where
    :func:`due_for_sending` marked them already), those not sent back to "not sent".
    The ids sent. ``stage`` is told of the send and of the write after it."""
    if stage is not None:
        stage(HAND_BACK_SEND)
    sent, unsent = _send(celery, job_ids)
    if stage is not None:
        stage(HAND_BACK_RECORD)
    if mark and sent:
        with db.session() as session:
            for job_id in sent:
                mark_sent(session, job_id)
    if unsent:
        _unmark(db, unsent)
    return sent


def reap_once(settings: Settings, db: Database, celery: Celery) -> ReapReport:
    """Re-queue (and re-send) or fail every running job whose run died.

    The database commit comes first: a job is only sent once it is queued again, so the
    message can never find it still marked running. A job whose send fails stays
    queued and unsent; :func:`resend_once` sends it when the broker is back.
    """
    with db.session() as session:
        requeued, failed = reap_stale(
            session,
            timeout_s=settings.heartbeat_timeout_s,
            max_attempts=settings.max_attempts,
            worker_silence_s=WORKER_SILENCE_BEATS * settings.heartbeat_interval_s,
        )
    for job_id in _dispatch(db, celery, requeued, mark=True):
        logger.warning("re-queued job %s: its worker stopped sending heartbeats", job_id)
    for job_id in failed:
        logger.warning("ended job %s: its worker stopped sending heartbeats", job_id)
    return ReapReport(requeued=requeued, failed=failed)


def idle_workers(settings: Settings, db: Database) -> int:
    """Live workers (seen within the silence window, not stopping, not warming, holding
    their incarnation lock) minus running jobs, at least 0. A warming worker takes no
    message until its task process is up: a message waiting for it is not lost. One
    without its lock claims no job (see :mod:`worker.incarnation`): counted idle, the
    jobs it left were sent to it again at every beat, each time left again."""
    cutoff = utcnow() - timedelta(seconds=WORKER_SILENCE_BEATS * settings.heartbeat_interval_s)
    with db.session() as session:
        live = session.scalar(
            select(func.count())
            .select_from(WorkerRow)
            .where(
                WorkerRow.last_seen_at >= cutoff,
                WorkerRow.stopping_since.is_(None),
                WorkerRow.warming_since.is_(None),
                WorkerRow.lock_missing_since.is_(None),
            )
        )
        running = session.scalar(
            select(func.count()).select_from(JobRow).where(JobRow.status == "running")
        )
    return max(0, int(live or 0) - int(running or 0))


def resend_once(settings: Settings, db: Database, celery: Celery) -> list[str]:
    """Send the messages of queued jobs that never had one or lost theirs; their ids."""
    idle = idle_workers(settings, db)
    with db.session() as session:
        due = due_for_sending(
            session,
            unsent_grace_s=settings.unsent_grace_s,
            resend_after_s=settings.resend_after_s,
            idle_workers=idle,
        )
    sent = _dispatch(db, celery, due, mark=False)
    for job_id in sent:
        logger.warning("sent job %s (again): it was queued without a message", job_id)
    return sent


def resend_left(db: Database, celery: Celery, since: datetime) -> list[str]:
    """Send again the messages of the queued jobs spent at or after ``since``: the jobs
    this worker's task processes left, from ``since`` on, because it held no incarnation
    lock (see :func:`worker.runner.execute_job`), called at the beat that takes it again.
    Left to :func:`resend_once`, they waited ``resend_after_s`` (30 s) after they were
    left, the worker idle meanwhile. Their ids."""
    with db.session() as session:
        due = send_again_since(session, since)
    sent = _dispatch(db, celery, due, mark=False)
    for job_id in sent:
        logger.warning("sent job %s again: it was left while this worker held no lock", job_id)
    return sent


def hand_back_jobs(
    settings: Settings,
    db: Database,
    celery: Celery,
    worker: str,
    incarnation: str,
    *,
    stage: Callable[[str, list[str]], None] | None = None,
) -> list[str]:
    """Re-queue and re-send the jobs ``worker`` runs as ``incarnation`` (this process;
    not a live twin's of its name), at no cost of an attempt. ``stage`` is told of each
    step as it begins (``HAND_BACK_*``), with the jobs re-queued so far."""
    job_ids: list[str] = []

    def note(step: str) -> None:
        if stage is not None:
            stage(step, job_ids)

    note(HAND_BACK_REQUEUE)
    with db.session() as session:
        job_ids = hand_back(session, worker, f"worker {worker} was asked to stop", incarnation)
    _dispatch(db, celery, job_ids, mark=True, stage=note)
    note(HAND_BACK_DONE)
    for job_id in job_ids:
        logger.warning("handed job %s back to the queue: this worker is stopping", job_id)
    return job_ids


def take_lost_run(
    settings: Settings,
    db: Database,
    celery: Celery,
    job_id: str,
    *,
    worker: str,
    lost_at: datetime,
    cause: str,
    reason: str,
) -> str | None:
    """Re-queue and re-send, or end, job ``job_id`` whose run on ``worker`` lost its task
    process (seen by the worker at ``lost_at``), by the reaper's ``max_attempts`` rule.
    What became of the job, or None when the run no longer held it (the reaper or a
    hand-back took it first, or it had finished)."""
    with db.session() as session:
        then = task_process_lost(
            session,
            job_id,
            worker=worker,
            lost_at=lost_at,
            cause=cause,
            reason=reason,
            max_attempts=settings.max_attempts,
        )
    if then == "re-queued":
        _dispatch(db, celery, [job_id], mark=True)
    if then is not None:
        logger.warning("%s job %s at once: its %s", then, job_id, cause)
    return then


def take_restarted_runs(
    settings: Settings,
    db: Database,
    celery: Celery,
    worker: str,
    current: str,
    witness: incarnation.Witness,
) -> ReapReport:
    """Re-queue and re-send, or end, the jobs still running under ``worker``'s name for
    an earlier process of that name that is gone (incarnation ``current`` is this one):
    a worker killed whole and started again under its name, as docker restarts a
    container. By the reaper's ``max_attempts`` rule, within two beats rather than the
    heartbeat timeout: gone means its lock found free at two of ``witness``'s probes
    two beats apart, and its run silent for two beats, the two waits side by side (the
    lock is probed from this worker's first beat, the run's silence counted from its
    last heartbeat); a live process of the same name
    keeps its jobs, also while it takes again a lock it lost (see
    :mod:`worker.incarnation`)."""
    url = settings.resolved_database_url
    probed: list[str] = []

    def alive(other: str) -> bool:
        probed.append(other)
        return not witness.gone(other, not incarnation.alive(session, url, other))

    with db.session() as session:
        requeued, ended = take_earlier_incarnations(
            session,
            worker,
            current,
            alive=alive,
            max_attempts=settings.max_attempts,
            beat_within_s=2 * settings.heartbeat_interval_s,
        )
    witness.keep_only(probed)
    for job_id in _dispatch(db, celery, requeued, mark=True):
        logger.warning("re-queued job %s: worker %s restarted, its run was lost", job_id, worker)
    for job_id in ended:
        logger.warning("ended job %s: worker %s restarted, its run was lost", job_id, worker)
    return ReapReport(requeued=requeued, failed=ended)
