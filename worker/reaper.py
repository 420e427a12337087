"""The reaper: a running job whose heartbeat went stale belonged to a worker that died.

Every worker runs :func:`reap_once` at start and then every heartbeat interval. A stale
job is re-queued and its message sent again (its first message died with the worker, or
sits unacknowledged until Redis' visibility timeout), or failed with the reason once it
has had ``max_attempts`` runs. Two reapers at once are harmless: a job is claimed by one
atomic UPDATE, so an extra message for it finds it taken and does nothing.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from celery import Celery
from sqlalchemy import update

from app.config import Settings
from app.db import Database, JobRow
from app.db.jobs import reap_stale
from app.db.models import utcnow
from app.queue import RUN_JOB_TASK

__all__ = ["ReapReport", "reap_once"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReapReport:
    """What one pass of the reaper did.

    :param requeued: ids of the jobs re-queued and sent again.
    :param failed: ids of the jobs ended (failed after ``max_attempts`` runs, or
        cancelled when a cancel had been asked for).
    """

    requeued: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)


def reap_once(settings: Settings, db: Database, celery: Celery) -> ReapReport:
    """Re-queue (and re-send) or fail every running job with a stale heartbeat.

    The database commit comes first: a job is only sent once it is queued again, so the
    message can never find it still marked running.
    """
    with db.session() as session:
        requeued, failed = reap_stale(
            session,
            timeout_s=settings.heartbeat_timeout_s,
            max_attempts=settings.max_attempts,
        )
    sent, unsent = [], []
    for job_id in requeued:
        try:
            celery.send_task(RUN_JOB_TASK, args=[job_id])
        except Exception as exc:
            unsent.append((job_id, f"{type(exc).__name__}: {exc}"))
        else:
            sent.append(job_id)
            logger.warning("re-queued job %s: its worker stopped sending heartbeats", job_id)
    if unsent:
        # A queued job without a message would wait forever: say so on the job instead.
        with db.session() as session:
            for job_id, reason in unsent:
                session.execute(
                    update(JobRow)
                    .where(JobRow.id == job_id, JobRow.status == "queued")
                    .values(
                        status="failed",
                        finished_at=utcnow(),
                        error=f"its worker died and re-sending it to the broker failed: {reason}",
                    )
                )
        logger.error("could not re-send jobs %s to the broker", [j for j, _ in unsent])
    for job_id in failed:
        logger.warning("ended job %s: its worker stopped sending heartbeats", job_id)
    return ReapReport(requeued=sent, failed=[*failed, *(j for j, _ in unsent)])
