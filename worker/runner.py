"""One job, start to end: claim the row, beat its heart, run its handler, store the outcome.

Whatever happens the job leaves ``running``: a handler's exception fails it with a
one-line reason, a cancel ends it ``cancelled``, and a process that dies outright stops
the heartbeat, so the reaper (:mod:`worker.reaper`) re-queues or fails it.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import select, update
from sqlalchemy.exc import StatementError

from app.config import Settings
from app.db import Database, JobRow, ScenarioRow
from app.db.jobs import (
    add_metrics,
    claim,
    clear_metrics,
    finish,
    hand_back,
    heartbeat,
    owns,
    set_progress,
    touch_worker,
)
from app.db.models import JOB_TYPES

from .monitor import broker_label
from .ticker import Ticker

__all__ = [
    "CANCEL_POLL_S",
    "JobContext",
    "JobSpec",
    "Outcome",
    "execute_job",
    "one_line_error",
    "warm_up",
]

logger = logging.getLogger(__name__)

#: Seconds between two reads of a running job's cancel flag. The search polls
#: ``should_stop`` every environment step; the database is asked at most this often.
CANCEL_POLL_S = 1.0

#: Longest error text stored on a job.
MAX_ERROR_CHARS = 2000


@dataclass(frozen=True)
class JobSpec:
    """A claimed job as its handler needs it, read once at claim time.

    :param attempt: which run of the job this is (1 = first; more after a worker died).
    :param scenario: the scenario document (``ScenarioRow.document``), or None if the row
        is gone.
    """

    id: str
    type: str
    params: dict[str, Any]
    seed: int
    scenario_id: str
    scenario: dict[str, Any] | None
    attempt: int


@dataclass
class Outcome:
    """What a handler hands back; stored with the job's finish, in one transaction.

    :param status: "succeeded" or "cancelled" (a failure is an exception).
    :param result: the job's JSON result.
    :param metrics: (key, step, value) points written with the finish.
    :param rows: ORM rows to store with the finish (e.g. the trained classifier).
    """

    status: str
    result: dict[str, Any] | None
    metrics: list[tuple[str, int, float]] = field(default_factory=list)
    rows: list[Any] = field(default_factory=list)


def one_line_error(exc: BaseException) -> str:
    """``Type: message`` on one line, cut to :data:`MAX_ERROR_CHARS`.

    A database driver's error wrapped by SQLAlchemy is shown as the driver's (without
    the SQL statement and its parameters).
    """
    if isinstance(exc, StatementError) and isinstance(exc.orig, BaseException):
        exc = exc.orig
    message = " ".join(str(exc).split())
    text = f"{type(exc).__name__}: {message}" if message else type(exc).__name__
    return text if len(text) <= MAX_ERROR_CHARS else text[: MAX_ERROR_CHARS - 1] + "…"


def json_safe(value: Any, data_dir: Path | None = None) -> Any:
    """``value`` with NaN and infinities as None, so it is valid JSON for every reader,
    and paths inside ``data_dir`` relative to it: a response names no server path."""
    if isinstance(value, dict):
        return {str(k): json_safe(v, data_dir) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v, data_dir) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, str) and data_dir is not None:
        return without_server_paths(value, data_dir)
    return value


def without_server_paths(text: str, data_dir: Path) -> str:
    """``text`` with the data dir's absolute path taken out (``<data>/x`` -> ``x``)."""
    root = str(data_dir.resolve())
    return text.replace(root + "/", "").replace(root, ".")


def _finite(rows: Iterable[tuple[str, int, float]]) -> list[tuple[str, int, float]]:
    # A curve point before any finished episode has NaN means; a metric row holds numbers.
    return [(k, int(s), float(v)) for k, s, v in rows if v is not None and math.isfinite(v)]


class JobContext:
    """What a handler sees of the service: its job, a place for files, and reporting.

    :param spec: the claimed job.
    :param db: the job store.
    :param settings: the service settings (data_dir for files).
    :param worker_name: the Celery node name that claimed the job.
    :param clock: monotonic seconds, for the cancel-poll throttle.
    """

    def __init__(
        self,
        spec: JobSpec,
        db: Database,
        settings: Settings,
        worker_name: str,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.spec = spec
        self.db = db
        self.settings = settings
        self.worker_name = worker_name
        self.cancelled = False
        self.lost = False
        self._clock = clock
        self._last_poll = clock()

    @property
    def data_dir(self) -> Path:
        return self.settings.data_dir.resolve()

    def report(
        self,
        *,
        progress: float | None = None,
        metrics: Iterable[tuple[str, int, float]] = (),
    ) -> None:
        """Store progress (0..1) and metric points now, so the API can show them live.

        Only while this run owns the job: a run that was handed back or reaped (and may
        be running again elsewhere) must not add points to the new run's curve.
        A failed write is logged, not raised: a live curve is not worth the job, and the
        result is written at the end anyway.
        """
        rows = _finite(metrics)
        try:
            with self.db.session() as session:
                if not owns(session, self.spec.id, self.spec.attempt):
                    self.lost = True
                    return
                if rows:
                    add_metrics(session, self.spec.id, rows)
                if progress is not None:
                    set_progress(session, self.spec.id, progress, self.spec.attempt)
        except Exception:
            logger.exception("job %s: could not store progress; going on", self.spec.id)

    def should_stop(self) -> bool:
        """True once a cancel was asked for, or the job stopped being this run's.

        Cheap enough for every environment step: the row is read at most every
        :data:`CANCEL_POLL_S` seconds.
        """
        if self.cancelled or self.lost:
            return True
        now = self._clock()
        if now - self._last_poll < CANCEL_POLL_S:
            return False
        self._last_poll = now
        return self.check_now()

    def check_now(self) -> bool:
        """Read the job's cancel flag and ownership now (unthrottled)."""
        try:
            with self.db.session() as session:
                row = session.execute(
                    select(JobRow.status, JobRow.cancel_requested, JobRow.attempts).where(
                        JobRow.id == self.spec.id
                    )
                ).one_or_none()
        except Exception:
            logger.exception("job %s: could not read its cancel flag; going on", self.spec.id)
            return False
        if row is None or row.status != "running" or row.attempts != self.spec.attempt:
            # Reaped while we were stalled (and perhaps re-run elsewhere), or deleted.
            self.lost = True
        elif row.cancel_requested:
            self.cancelled = True
        return self.cancelled or self.lost

    def beat(self) -> None:
        """One heartbeat: the job's and this worker's."""
        with self.db.session() as session:
            heartbeat(session, self.spec.id, self.spec.attempt)
            touch_worker(session, self.worker_name, broker_label(self.settings))


_handlers: dict[str, Callable[[JobContext], Outcome]] | None = None


def _import_handlers() -> dict[str, Callable[[JobContext], Outcome]]:
    """The job handlers, imported once per process.

    torch, numba, tslearn: seconds of imports. A worker's task process pays them once,
    when it starts (:func:`warm_up`, on Celery's ``worker_process_init``), never per job
    and never in the worker's main process: torch's OpenMP threads do not survive a fork,
    so the main process, which forks task processes, must not start them.
    """
    global _handlers
    if _handlers is None:
        import torch
        from threadpoolctl import threadpool_limits

        torch.set_num_threads(1)
        from .handlers import HANDLERS

        # One job is one process on one core: BLAS threads would only fight the other
        # workers (measured: a covariance fit 60 times slower with another process
        # busy). After the imports, so that every BLAS the handlers load is limited.
        threadpool_limits(1)
        _handlers = HANDLERS
    return _handlers


def warm_up() -> None:
    """Import the handlers now, before any job arrives."""
    _import_handlers()


def _broken_handlers(error: Exception) -> dict[str, Callable[[JobContext], Outcome]]:
    def fail(_context: JobContext) -> Outcome:
        raise RuntimeError(
            f"this worker cannot load the science core ({one_line_error(error)})"
        ) from error

    return {job_type: fail for job_type in JOB_TYPES}


def execute_job(
    job_id: str,
    *,
    settings: Settings,
    worker_name: str,
    stopping: Callable[[], bool] = lambda: False,
) -> str:
    """Run job ``job_id`` if it is still queued; returns the status it ends in.

    "missing" when there is no such job; the current status when it was not queued
    (already run, cancelled, or claimed by another delivery); "lost" when the job was
    taken from this run (reaped after a stall) before it finished; "passed on" when
    ``stopping()`` says this worker is stopping: the job is left queued, unsent, for
    another worker's monitor to send again (a claim made as the stop came is handed
    back, at no cost of an attempt).
    """
    db = Database(settings.resolved_database_url)
    try:
        return _execute(job_id, db, settings, worker_name, stopping)
    finally:
        db.dispose()


def _pass_on(db: Database, job_id: str, worker_name: str) -> str:
    with db.session() as session:
        # Claimed just as the stop came (the main process's hand-back may have missed
        # it): back to the queue, uncounted. Else still queued: marked unsent.
        hand_back(session, worker_name, f"worker {worker_name} was asked to stop")
        session.execute(
            update(JobRow)
            .where(JobRow.id == job_id, JobRow.status == "queued")
            .values(sent_at=None)
        )
    logger.warning("job %s left to another worker: this worker is stopping", job_id)
    return "passed on"


def _status(db: Database, job_id: str) -> str | None:
    with db.session() as session:
        return session.scalar(select(JobRow.status).where(JobRow.id == job_id))


def _execute(
    job_id: str,
    db: Database,
    settings: Settings,
    worker_name: str,
    stopping: Callable[[], bool],
) -> str:
    status = _status(db, job_id)
    if status is None:
        logger.warning("job %s does not exist; message dropped", job_id)
        return "missing"
    if status != "queued":
        logger.info("job %s is %s, not queued; nothing to do", job_id, status)
        return status
    if stopping():
        return _pass_on(db, job_id, worker_name)
    try:
        handlers = _import_handlers()
    except Exception as exc:
        # Claimed and failed below, with the reason, rather than left queued for ever.
        logger.exception("the worker cannot import the job handlers")
        handlers = _broken_handlers(exc)
    with db.session() as session:
        job = claim(session, job_id, worker_name)
        if job is None:
            spec = None
        else:
            scenario = session.get(ScenarioRow, job.scenario_id)
            spec = JobSpec(
                id=job.id,
                type=job.type,
                params=dict(job.params or {}),
                seed=int(job.seed),
                scenario_id=job.scenario_id,
                scenario=None if scenario is None else dict(scenario.document),
                attempt=int(job.attempts),
            )
            if job.attempts > 1:
                clear_metrics(session, job_id)
    if spec is None:
        status = _status(db, job_id) or "missing"
        logger.info("job %s was not claimed (now %s)", job_id, status)
        return status
    if stopping():
        # The stop came between the check above and the claim.
        return _pass_on(db, job_id, worker_name)
    logger.info(
        "job %s (%s, attempt %d) claimed by %s", job_id, spec.type, spec.attempt, worker_name
    )
    context = JobContext(spec, db, settings, worker_name)
    beat = Ticker(context.beat, settings.heartbeat_interval_s, name=f"heartbeat {job_id}")
    beat.start()
    try:
        return _run(context, handlers)
    finally:
        beat.stop()


def _run(context: JobContext, handlers: dict[str, Callable[[JobContext], Outcome]]) -> str:
    spec, db = context.spec, context.db
    try:
        handler = handlers.get(spec.type)
        if handler is None:
            raise ValueError(f"job type must be one of {sorted(handlers)}, got {spec.type!r}")
        if spec.scenario is None:
            raise ValueError(f"scenario {spec.scenario_id!r} of the job does not exist")
        outcome = handler(context)
    except Exception as exc:
        if context.lost:
            logger.warning("job %s was taken from this run; dropping its error", spec.id)
            return "lost"
        if context.cancelled:
            return _end(context, "cancelled", error=None)
        logger.exception("job %s failed", spec.id)
        return _end(
            context, "failed", error=without_server_paths(one_line_error(exc), context.data_dir)
        )
    if context.lost:
        logger.warning("job %s was taken from this run; dropping its result", spec.id)
        return "lost"
    try:
        with db.session() as session:
            session.add_all(outcome.rows)
            session.flush()
            add_metrics(session, spec.id, _finite(outcome.metrics))
            result = None if outcome.result is None else json_safe(outcome.result, context.data_dir)
            if not finish(session, spec.id, outcome.status, result=result, attempt=spec.attempt):
                session.rollback()
                logger.warning("job %s was taken from this run; dropping its result", spec.id)
                return "lost"
    except Exception as exc:
        logger.exception("job %s: could not store its outcome", spec.id)
        return _end(context, "failed", error=f"could not store the result: {one_line_error(exc)}")
    logger.info("job %s %s", spec.id, outcome.status)
    return outcome.status


def _end(context: JobContext, status: str, *, error: str | None) -> str:
    spec = context.spec
    with context.db.session() as session:
        if not finish(session, spec.id, status, error=error, attempt=spec.attempt):
            logger.warning("job %s was taken from this run; not marking it %s", spec.id, status)
            return "lost"
    return status
