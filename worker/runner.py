"""One job, start to end: claim the row, resolve its inputs, beat its heart, run its
handler, store the outcome.

The runner is the only part of the worker that reads and writes the store for a job:
it parses the job's parameters with their typed model, resolves what they name (the
scenario, the classifier a sweep uses) and stores what the handler returns (result,
metrics, a trained classifier) with the job's finish, in one transaction. Handlers stay
pure functions of their typed parameters (:mod:`worker.handlers`).

Whatever happens the job leaves ``running``: a handler's exception fails it with a
one-line reason, a cancel ends it ``cancelled``, and a task process that dies outright
(``kill -9``, the OOM killer) is reported to its worker's main process, which re-queues or
fails the job at once (:mod:`worker.request`); were the whole worker lost, its stopped
heartbeat has the reaper (:mod:`worker.reaper`) do so.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select, update
from sqlalchemy.exc import OperationalError, StatementError

from service.config import Settings
from service.params import parse_params
from service.store import ClassifierRow, Database, JobRow, ScenarioRow
from service.store.jobs import (
    add_metrics,
    claim,
    clear_metrics,
    finish,
    hand_back,
)
from service.store.models import JOB_TYPES, new_id, utcnow
from service.store.refusals import database_label, unreachable, why_cannot_store

from .context import (
    CANCEL_POLL_S,
    DATABASE_SILENT_S,
    TIME_LIMIT,
    JobContext,
    JobSpec,
    JobTimeLimitExceeded,
    Outcome,
    finite_metrics,
)
from .cut import StopCut
from .episode import Episode
from .incarnation import current as current_incarnation
from .ticker import Ticker

__all__ = [
    "CANCEL_POLL_S",
    "HANDED_BACK",
    "JobContext",
    "JobSpec",
    "Outcome",
    "execute_job",
    "one_line_error",
    "warm_up",
]

logger = logging.getLogger(__name__)

#: Longest error text stored on a job.
MAX_ERROR_CHARS = 2000


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
    """Import the handlers and compile the numba kernels now, before any job arrives."""
    _import_handlers()
    from inertia_id import warm_up as compile_kernels

    compile_kernels()


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
    may_claim: Callable[[], bool] = lambda: True,
) -> str:
    """Run job ``job_id`` if it is still queued; returns the status it ends in.

    "missing" when there is no such job; the current status when it was not queued
    (already run, cancelled, or claimed by another delivery); "lost" when the job was
    taken from this run (reaped after a stall) before it finished; "passed on" when
    ``stopping()`` says this worker is stopping: the job is left queued, unsent, for
    another worker's monitor to send again (a claim made as the stop came is handed
    back, at no cost of an attempt); "passed on" too when ``may_claim()`` says no:
    this worker does not hold its incarnation lock (see :mod:`worker.incarnation`), so
    a twin of its name could judge its run dead and run the job again; the job is left
    queued, its message spent, and sent again once a worker that holds its lock is idle
    (see :func:`worker.reaper.resend_once`); :data:`HANDED_BACK` when the database
    could not be reached before the claim: nothing of the job was touched, and the
    caller gives its message back to the broker (after a wait, see :func:`_back_off`).
    """
    db = Database(settings.resolved_database_url, silent_after_s=DATABASE_SILENT_S)
    # Once the worker stops, a statement the database leaves unanswered is cut and the
    # run given up (see worker.cut.StopCut): Celery waits for the run before it exits.
    cut = StopCut(db, stopping).start()
    try:
        status = _execute(job_id, db, settings, worker_name, stopping, may_claim)
    except _OutOfReach as out:
        return _back_off(job_id, db, out.error, stopping)
    finally:
        db.dispose()
        cut.stop()
    _ended_outage()
    return status


#: :func:`execute_job`'s status for a job whose database could not be reached before it
#: was claimed: nothing of it was touched, and its message goes back to the broker.
HANDED_BACK = "handed back"

#: Longest wait (s) of a task process between two jobs handed back for an unreachable
#: database; the first waits 1 s, each next one twice the last.
UNREACHABLE_BACKOFF_MAX_S = 30.0


class _OutOfReach(Exception):
    """The database could not be reached before the job was claimed."""

    def __init__(self, error: BaseException) -> None:
        super().__init__(one_line_error(error))
        self.error = error


#: This task process's outage (see worker.episode): the database out of reach as jobs
#: came, logged once when it starts and once when it ends; and how many jobs in a row
#: were handed back, which sets the next wait.
_outage = Episode(logger)
_handed_back_in_a_row = 0


def _back_off(job_id: str, db: Database, error: BaseException, stopping: Callable[[], bool]) -> str:
    """A job whose database is out of reach: said once an outage (the database named,
    its password masked, and why), then a wait that doubles with each job handed back
    in a row (cut short when the worker stops), so that the worker neither spins on the
    broker nor fails jobs for a passing outage. Before, the task failed with a traceback
    of the driver's error and its message was spent; the job waited for the re-sender.
    """
    global _handed_back_in_a_row
    _handed_back_in_a_row += 1
    wait_s = min(UNREACHABLE_BACKOFF_MAX_S, 2.0 ** (_handed_back_in_a_row - 1))
    label = database_label(db.url).replace("%", "%%")
    _outage.seen(
        one_line_error(error),
        f"this worker cannot reach its database {label} (%s): the jobs it is sent go back "
        "to the queue untouched, and it takes them again once the database answers, "
        f"trying again after a wait that doubles up to {UNREACHABLE_BACKOFF_MAX_S:g} s",
    )
    logger.info("job %s handed back to the queue untouched; next try in %g s", job_id, wait_s)
    deadline = time.monotonic() + wait_s
    while not stopping() and time.monotonic() < deadline:
        time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
    return HANDED_BACK


def _ended_outage() -> None:
    global _handed_back_in_a_row
    _handed_back_in_a_row = 0
    _outage.cleared("this worker reaches its database again after %.0f s")


def _pass_on(db: Database, job_id: str, worker_name: str) -> str:
    with db.session() as session:
        # Claimed just as the stop came (the main process's hand-back may have missed
        # it): back to the queue, uncounted. Else still queued: marked unsent.
        hand_back(
            session,
            worker_name,
            f"worker {worker_name} was asked to stop",
            current_incarnation(),
        )
        session.execute(
            update(JobRow)
            .where(JobRow.id == job_id, JobRow.status == "queued")
            .values(sent_at=None)
        )
    logger.warning("job %s left to another worker: this worker is stopping", job_id)
    return "passed on"


def _leave_unclaimed(db: Database, job_id: str) -> str:
    with db.session() as session:
        # Its message is spent: dated as sent now, the re-sender sends it again once it
        # is older than resend_after_s and a worker that holds its lock sits idle (see
        # worker.reaper.idle_workers). Marked unsent, it was sent again at every beat,
        # to this worker too, and left again each time.
        session.execute(
            update(JobRow)
            .where(JobRow.id == job_id, JobRow.status == "queued")
            .values(sent_at=utcnow())
        )
    logger.warning(
        "job %s left queued: this worker does not hold its incarnation lock, so another "
        "worker of its name could take the run from it; it is sent again once a worker "
        "that holds its lock is idle",
        job_id,
    )
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
    may_claim: Callable[[], bool],
) -> str:
    try:
        taken = _take(job_id, db, worker_name, stopping, may_claim)
    except Exception as exc:
        # Nothing of the job was written (the claim is one transaction): it can go back
        # to the queue as it came.
        if unreachable(exc):
            raise _OutOfReach(exc) from exc
        raise
    if isinstance(taken, str):
        return taken
    handlers, claimed = taken
    if stopping():
        # The stop came between the check above and the claim.
        return _pass_on(db, job_id, worker_name)
    logger.info(
        "job %s (%s, attempt %d) claimed by %s",
        job_id,
        claimed.type,
        claimed.attempt,
        worker_name,
    )
    try:
        spec = _resolve(db, claimed)
    except Exception as exc:
        logger.exception("job %s: its inputs cannot be resolved", job_id)
        return _end(db, claimed.id, claimed.attempt, "failed", error=_error_text(exc, settings))
    context = JobContext(spec, db, settings, worker_name, stopping=stopping)
    beat = Ticker(context.tick, settings.heartbeat_interval_s, name=f"heartbeat {job_id}")
    beat.start()
    try:
        return _run(context, db, handlers, stopping)
    finally:
        # A stopping worker's run does not wait for a beat under way: it may be opening
        # a connection to a database that gave the run no answer (up to
        # DATABASE_SILENT_S; see worker.cut.StopCut).
        beat.stop(0.0 if stopping() else 10.0)


@dataclass(frozen=True)
class _Claimed:
    """The job row as claimed, before its inputs are resolved."""

    id: str
    type: str
    params: dict[str, Any]
    seed: int
    scenario_id: str
    attempt: int


def _take(
    job_id: str,
    db: Database,
    worker_name: str,
    stopping: Callable[[], bool],
    may_claim: Callable[[], bool],
) -> str | tuple[dict[str, Callable[[JobContext], Outcome]], _Claimed]:
    """Claim job ``job_id``: the handlers and the claimed row, or the status to return
    when it is not claimed (see :func:`execute_job`)."""
    status = _status(db, job_id)
    if status is None:
        logger.warning("job %s does not exist; message dropped", job_id)
        return "missing"
    if status != "queued":
        logger.info("job %s is %s, not queued; nothing to do", job_id, status)
        return status
    if stopping():
        return _pass_on(db, job_id, worker_name)
    if not may_claim():
        return _leave_unclaimed(db, job_id)
    try:
        handlers = _import_handlers()
    except Exception as exc:
        # Claimed and failed below, with the reason, rather than left queued for ever.
        logger.exception("the worker cannot import the job handlers")
        handlers = _broken_handlers(exc)
    with db.session() as session:
        job = claim(session, job_id, worker_name, current_incarnation())
        if job is None:
            claimed = None
        else:
            claimed = _Claimed(
                id=job.id,
                type=job.type,
                params=dict(job.params or {}),
                seed=int(job.seed),
                scenario_id=job.scenario_id,
                attempt=int(job.attempts),
            )
            if job.attempts > 1:
                clear_metrics(session, job_id)
    if claimed is None:
        status = _status(db, job_id) or "missing"
        logger.info("job %s was not claimed (now %s)", job_id, status)
        return status
    return handlers, claimed


def _resolve(db: Database, claimed: _Claimed) -> JobSpec:
    """Typed parameters, and what they name read from the store (a missing scenario or
    classifier, or parameters that no longer parse, fail the job with the reason)."""
    from inertia_id import InputError, classifier_from_json
    from inertia_id.physics.scenario import Scenario

    params = parse_params(claimed.type, claimed.params)
    with db.session() as session:
        scenario_row = session.get(ScenarioRow, claimed.scenario_id)
        scenario_document = None if scenario_row is None else dict(scenario_row.document)
        classifier_id = getattr(params, "classifier_id", None)
        classifier_document = None
        if classifier_id is not None:
            classifier_document = session.scalar(
                select(ClassifierRow.document).where(ClassifierRow.id == classifier_id)
            )
    if scenario_document is None:
        raise InputError(f"scenario {claimed.scenario_id!r} of the job does not exist")
    if classifier_id is not None and classifier_document is None:
        raise InputError(f"classifier {classifier_id!r} does not exist")
    return JobSpec(
        id=claimed.id,
        type=claimed.type,
        params=params,
        seed=claimed.seed,
        scenario_id=claimed.scenario_id,
        scenario=Scenario.model_validate(scenario_document),
        attempt=claimed.attempt,
        classifier=None
        if classifier_document is None
        else classifier_from_json(classifier_document),
    )


def _error_text(exc: BaseException, settings: Settings) -> str:
    return without_server_paths(one_line_error(exc), settings.data_dir)


def _classifier_row(spec: JobSpec, outcome: Outcome) -> ClassifierRow | None:
    """The row of a trained classifier the outcome carries; its id and checksum go into
    the result."""
    if outcome.classifier is None:
        return None
    document = outcome.classifier.model.to_json()
    checksum = json.loads(document).get("sha256") or hashlib.sha256(document.encode()).hexdigest()
    summary = outcome.classifier.summary()
    row = ClassifierRow(
        id=new_id(),
        job_id=spec.id,
        scenario_id=spec.scenario_id,
        kind=summary["kind"],
        metric=summary["metric"],
        f1=summary["f1"],
        accuracy=summary["accuracy"],
        sequence=summary["sequence"],
        candidate_names=summary["candidate_names"],
        confusion=summary["confusion"],
        document=document,
        sha256=checksum,
    )
    outcome.result = {**(outcome.result or {}), "classifier_id": row.id, "sha256": checksum}
    return row


def _stop_behind(exc: BaseException) -> BaseException | None:
    """The SystemExit or KeyboardInterrupt in ``exc``'s chain of causes, if any."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, SystemExit | KeyboardInterrupt):
            return current
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return None


def _run(
    context: JobContext,
    db: Database,
    handlers: dict[str, Callable[[JobContext], Outcome]],
    stopping: Callable[[], bool] = lambda: False,
) -> str:
    spec = context.spec
    try:
        handler = handlers.get(spec.type)
        if handler is None:
            raise ValueError(f"job type must be one of {sorted(handlers)}, got {spec.type!r}")
        outcome = handler(context)
    except Exception as exc:
        stop = _stop_behind(exc)
        if stop is not None:
            # The task process was told to stop (SIGTERM raises SystemExit in it) while
            # compiled code ran, which wrapped the SystemExit in another error (numba's
            # and CPython's "returned a result with an exception set" SystemError): a
            # stop, not the job's fault. Raised as the stop it is, the main process hands
            # the job back. Before, the job was failed, an attempt spent: a job running
            # when a Redis worker's process group got SIGTERM failed in 5 of 10 stops.
            logger.warning(
                "job %s: stopped while it ran (%s); handing it back", spec.id, one_line_error(exc)
            )
            raise stop from exc
        if context.lost:
            logger.warning("job %s was taken from this run; dropping its error", spec.id)
            return "lost"
        if context.cancelled:
            return _end(db, spec.id, spec.attempt, "cancelled", error=None)
        from inertia_id import InputError

        if isinstance(exc, InputError | JobTimeLimitExceeded):
            # The job's own inputs cannot give a result (e.g. no sequence meets its
            # constraints), or it outran its time limit: the job says why; not a fault
            # of the worker's to trace.
            logger.warning("job %s failed: %s", spec.id, exc)
        else:
            logger.exception("job %s failed", spec.id)
        # A field, so that a client need not match the error's words.
        stopped = TIME_LIMIT if isinstance(exc, JobTimeLimitExceeded) else None
        return _end(
            db,
            spec.id,
            spec.attempt,
            "failed",
            error=_error_text(exc, context.settings),
            stopped=stopped,
        )
    if context.lost:
        logger.warning("job %s was taken from this run; dropping its result", spec.id)
        return "lost"
    context.outcome_held = True
    # The outcome is kept while the database cannot take it (out of reach, or refusing
    # writes: a full disk, a read-only database) and stored whole once it can, tried
    # every heartbeat interval; the run's heartbeat goes on meanwhile, so the reaper
    # leaves it alone. Before, a refused outcome failed the job ("could not store the
    # result: ... database or disk is full") once writes were accepted again: the work
    # was thrown away for a passing condition. A refusal that outlasts
    # outcome_refused_wait_s (a result larger than the room left) fails the job, named.
    interval_s = context.settings.heartbeat_interval_s
    reported: str | None = None
    refused_since: float | None = None
    while True:
        try:
            if not _store_outcome(context, db, outcome):
                return "lost"
            break
        except Exception as exc:
            error = f"could not store the result: {one_line_error(exc)}"
            why = why_cannot_store(exc)
            if why is None and not unreachable(exc):
                logger.exception("job %s: could not store its outcome", spec.id)
                return _end(db, spec.id, spec.attempt, "failed", error=error)
            condition = (
                "the database cannot be reached"
                if why is None
                else f"the database refuses writes ({why})"
            )
            if stopping():
                logger.error(
                    "job %s: could not store its outcome: %s: %s; this worker is stopping",
                    spec.id,
                    condition,
                    one_line_error(exc),
                )
                return _end_once_writable(context, db, stopping, "failed", error=error)
            # A cancel asked for (or the run reaped) while the outcome waits: honoured at
            # once, the outcome dropped. Before, the flag was never read again: a result
            # too large for the room a full disk had left, whose cancel (a one-row
            # write) was stored, held the job "running" and its worker's slot for up to
            # INERTIA_ID_OUTCOME_REFUSED_WAIT_S, then failed it as refused.
            if context.check_now():
                if context.lost:
                    logger.warning("job %s was taken from this run; dropping its result", spec.id)
                    return "lost"
                logger.warning(
                    "job %s: cancelled while its outcome was refused (%s); the outcome is dropped",
                    spec.id,
                    condition,
                )
                return _end_once_writable(context, db, stopping, "cancelled", error=None)
            if why is not None:
                now = time.monotonic()
                refused_since = now if refused_since is None else refused_since
                wait_s = context.settings.outcome_refused_wait_s
                if now - refused_since >= wait_s:
                    logger.error(
                        "job %s: its outcome was refused for %.0f s (%s); the job fails",
                        spec.id,
                        now - refused_since,
                        condition,
                    )
                    return _end_once_writable(
                        context,
                        db,
                        stopping,
                        "failed",
                        error=f"could not store the result: {condition} for {wait_s:g} s "
                        f"(INERTIA_ID_OUTCOME_REFUSED_WAIT_S): {one_line_error(exc)}",
                    )
            if condition != reported:
                logger.error(
                    "job %s: could not store its outcome: %s (%s); kept, and stored once "
                    "the database takes it, tried every %g s",
                    spec.id,
                    condition,
                    one_line_error(exc),
                    interval_s,
                )
                reported = condition
            time.sleep(interval_s)
    if reported is not None:
        logger.warning("job %s: its outcome is stored (the database takes writes again)", spec.id)
    logger.info("job %s %s", spec.id, outcome.status)
    return outcome.status


def _store_outcome(context: JobContext, db: Database, outcome: Outcome) -> bool:
    """Store the run's outcome (its classifier, metrics, result and status) in one
    transaction; False, nothing stored, when the job is no longer this run's."""
    spec = context.spec
    with db.session() as session:
        row = _classifier_row(spec, outcome)
        if row is not None:
            session.add(row)
            session.flush()
        add_metrics(session, spec.id, finite_metrics(outcome.metrics))
        result = None if outcome.result is None else json_safe(outcome.result, context.data_dir)
        # A search or sweep past its limit succeeds with what it had; its result says so.
        stopped = TIME_LIMIT if (result or {}).get("stopped") == TIME_LIMIT else None
        if not finish(
            session,
            spec.id,
            outcome.status,
            result=result,
            attempt=spec.attempt,
            stopped=stopped,
        ):
            session.rollback()
            logger.warning("job %s was taken from this run; dropping its result", spec.id)
            return False
    return True


def _end_once_writable(
    context: JobContext,
    db: Database,
    stopping: Callable[[], bool],
    status: str,
    *,
    error: str | None,
) -> str:
    """End the run with ``error`` as soon as the database takes writes again (a full
    disk freed, a read-only database made writable), trying every heartbeat interval.

    The end was tried once and its write refused too: the job was left running, and once
    the database took writes the reaper said "heartbeat missed ... task process died or
    hung", the cause lost. The heartbeat goes on meanwhile (beating once it can), so the
    reaper leaves the run alone. A database out of reach meanwhile (an OperationalError)
    is waited for too. A stopping worker gives up (logged): its job is handed back or
    reaped as before."""
    spec = context.spec
    while True:
        try:
            return _end(db, spec.id, spec.attempt, status, error=error)
        except Exception as exc:
            why = why_cannot_store(exc)
            if why is None and not isinstance(exc, OperationalError):
                raise
            if stopping():
                logger.error(
                    "job %s: its end (%s: %s) could not be stored before this worker stopped: %s",
                    spec.id,
                    status,
                    error,
                    one_line_error(exc),
                )
                raise
        time.sleep(context.settings.heartbeat_interval_s)


def _end(
    db: Database,
    job_id: str,
    attempt: int,
    status: str,
    *,
    error: str | None,
    stopped: str | None = None,
) -> str:
    with db.session() as session:
        if not finish(session, job_id, status, error=error, attempt=attempt, stopped=stopped):
            logger.warning("job %s was taken from this run; not marking it %s", job_id, status)
            return "lost"
    return status
