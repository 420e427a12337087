"""Job lifecycle on the ``jobs`` table, shared by the API and the workers.

queued -> running -> succeeded | failed | cancelled. :func:`create_job` inserts a job,
or hands back the identical one that exists (a unique index settles races). A
worker *claims* a queued job (an atomic conditional UPDATE, so two deliveries of one
message never run it twice), beats its heart while it runs, and finishes it. Every write
of a run is conditional on the run still owning the job (``attempts`` is the run's token).

Nothing is lost or stuck:

- a running job whose task process died (``kill -9``, the OOM killer) is re-queued at once
  by :func:`task_process_lost`, when its worker sees the death, or failed with the reason
  after ``max_attempts`` runs;
- a running job whose worker died (its heartbeat and its worker's both went quiet) is
  re-queued by :func:`reap_stale` by the same rule;
- a worker asked to stop hands its running job back at once (:func:`hand_back`), which
  costs no attempt;
- a queued job whose message never reached the broker, or was lost there, is picked by
  :func:`due_for_sending` and sent again; a duplicate message is harmless (the claim).

A run taken from its job (reaped or handed back) leaves a record in the job's
``attempt_history`` (:func:`lost_run`): the next claim overwrites ``started_at``,
``worker`` and ``error``, and a flight team auditing a result must still see that a
worker died during it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Iterable
from datetime import UTC, datetime, timedelta
from typing import Any

from sqlalchemy import and_, case, delete, func, or_, select, update
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from inertia_id.wording import counted as counted_text

from ..summaries import summarise
from .models import (
    REUSABLE_STATUSES,
    STOPPED_REASONS,
    TERMINAL_STATUSES,
    JobRow,
    JobTagRow,
    MetricRow,
    ScenarioRow,
    WorkerRow,
    utcnow,
)

__all__ = [
    "ASKED_TO_STOP",
    "HEARTBEAT_MISSED",
    "WORKER_LOST",
    "WORKER_RESTARTED",
    "ScenarioGone",
    "add_metrics",
    "announce_worker",
    "beat_worker",
    "cancel",
    "claim",
    "clear_metrics",
    "config_hash",
    "create_job",
    "due_for_sending",
    "finish",
    "forget_announced_worker",
    "hand_back",
    "heartbeat",
    "is_cancel_requested",
    "keep_announced_workers",
    "lost_run",
    "mark_sent",
    "owns",
    "reap_stale",
    "send_again_since",
    "set_labels",
    "set_progress",
    "start_worker",
    "take_earlier_incarnations",
    "task_process_lost",
    "touch_twin_row",
    "touch_worker",
]


#: Why a run was taken from its job (``attempt_history[].cause``): its whole worker went
#: quiet (killed, its machine lost); its own heartbeat stopped while its worker still
#: reported (its task process hung, or died unseen); its worker was told to stop and
#: handed it back. A task process whose death its worker saw names how it died instead
#: ("task process killed by signal 9 (SIGKILL)", see :func:`task_process_lost`).
WORKER_LOST = "worker lost"
HEARTBEAT_MISSED = "heartbeat missed"
ASKED_TO_STOP = "asked to stop"
#: Its worker started again under the same name, and the earlier process, which ran it,
#: is gone (see :func:`take_earlier_incarnations`).
WORKER_RESTARTED = "worker restarted"


class ScenarioGone(LookupError):
    """The job's scenario was deleted while the job was being submitted."""


def config_hash(job_type: str, scenario_id: str, params: dict[str, Any], seed: int) -> str:
    """Identity of a job's work: the same type, scenario, parameters and seed."""
    canonical = json.dumps(
        {"type": job_type, "scenario": scenario_id, "params": params, "seed": seed},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(canonical.encode()).hexdigest()


def _reusable(session: Session, digest: str) -> JobRow | None:
    return session.scalars(
        select(JobRow).where(
            JobRow.config_hash == digest,
            JobRow.status.in_(REUSABLE_STATUSES),
            JobRow.superseded.is_(False),
        )
    ).first()


def _standing_ids(session: Session, digest: str) -> set[str]:
    """The ids of the reusable jobs of configuration ``digest`` now."""
    return set(
        session.scalars(
            select(JobRow.id).where(
                JobRow.config_hash == digest,
                JobRow.superseded.is_(False),
                JobRow.status.in_(REUSABLE_STATUSES),
            )
        )
    )


#: A plain rerun is handed an identical job in these statuses: it has not finished, so
#: its result will be as fresh as a new run's (same seed, same result).
UNFINISHED_STATUSES = ("queued", "running")


def _being_cancelled(job: JobRow) -> bool:
    """Whether ``job`` is queued or running but asked to stop: it will end cancelled."""
    return job.status in UNFINISHED_STATUSES and bool(job.cancel_requested)


def _replaced_already(
    standing: JobRow, rerun_of: str | None, asked_over: set[str], asked_at: datetime | None
) -> bool:
    """Whether the job ``standing`` now already answers a rerun: it replaces the one the
    rerun named, or (a plain rerun) it is unfinished or was made since the rerun was
    asked."""
    if rerun_of is not None:
        return standing.id != rerun_of
    # A plain rerun cannot say which job it saw, and the API takes up a burst of them
    # over hundreds of milliseconds under load: by "made since asked" alone a burst of
    # 15 made 1 to 9 jobs. A job that has not finished (and is not being cancelled)
    # answers it whenever it is taken up: a second run could only repeat its result.
    if standing.status in UNFINISHED_STATUSES and not _being_cancelled(standing):
        return True
    return standing.id not in asked_over or (
        asked_at is not None and _aware(standing.created_at) >= _aware(asked_at)
    )


def create_job(
    session: Session,
    *,
    job_type: str,
    scenario_id: str,
    params: dict[str, Any],
    seed: int,
    rerun: bool = False,
    rerun_of: str | None = None,
    name: str | None = None,
    tags: Iterable[str] = (),
    asked_at: datetime | None = None,
    on_insert: Callable[[JobRow], None] | None = None,
) -> tuple[JobRow, bool]:
    """Insert a queued job and commit it; or return the identical job that stands.

    Returns ``(job, reused)``. Without ``rerun`` an identical queued, running or
    succeeded job is returned (``reused``), its name and tags as they were, unless it is
    queued or running but asked to stop (it will end cancelled, with no result): a new
    job replaces it, as a rerun naming it would; with ``rerun``, the
    new job takes that job's place for later submissions, unless an identical job that
    has not finished (queued or running, not asked to stop) or one made since the rerun
    was asked (an identical rerun at the same time) stands already: that one is returned
    (``reused``), so identical reruns, at once or while their job waits or runs, make
    one new job. ``asked_at``,
    when the caller received the request (the API: when its handler began), widens "made
    since": a job created at or after it counts, though committed before this call read
    what stood (the API's checks of a submission take a while, and ten reruns sent at
    once reach this call one after another). Concurrent identical
    submissions make one job: the unique index on reusable configurations refuses all
    inserts but one, and the others return that one. ``name`` and ``tags`` label the new
    job; they are not part of its identity (:func:`config_hash`), and a job returned
    (``reused``) keeps its own (the API's ``reused_note`` says which were not applied).

    ``rerun_of`` (a rerun: ``rerun`` need not be set too) names the job the caller saw
    standing and wants replaced, which makes a rerun idempotent whenever it is taken
    up: a new job is made only while that job still stands (or while none stands, as
    after it failed or was cancelled); once another job stands in its place (an
    identical rerun's, at once or long since) that one is returned (``reused``). The
    caller checks that ``rerun_of`` is a job of this configuration, which it replaces
    even while that job is queued or running (the caller asked for exactly that).

    ``on_insert`` is called with the new job, flushed, before the commit that makes it:
    what it writes in ``session`` is committed with the job or not at all (the API stores
    an ``Idempotency-Key``'s answer there, so a request that fails or dies once its job
    is made is answered with that job when it is retried, and makes no second one).

    :raises ScenarioGone: the scenario was deleted meanwhile (its foreign key failed).
    """
    digest = config_hash(job_type, scenario_id, params, seed)
    standing = JobRow.config_hash == digest, JobRow.superseded.is_(False)
    asked_over: set[str] = set()
    rerun = rerun or rerun_of is not None
    if rerun:
        # The jobs a rerun asks to replace, unless it names one: those that stood when it
        # was asked. Read in a transaction of its own, ended here (with any reads of the
        # caller's), so the write below starts (on SQLite) from what is committed when it
        # gets the lock, not from an older snapshot.
        if rerun_of is None:
            asked_over = _standing_ids(session, digest)
        session.commit()
    for _ in range(3):
        if not rerun:
            existing = _reusable(session, digest)
            if existing is not None and not _being_cancelled(existing):
                return existing, True
            if existing is not None:
                # It ends cancelled, with no result: replaced, as a rerun naming it would
                # (identical submissions at once make one job: the later ones find it).
                rerun, rerun_of = True, existing.id
                # The write below starts from what is committed then (see above).
                session.commit()
        if rerun:
            # Identical reruns at once take turns from here: a no-op write takes the
            # standing rows' locks (PostgreSQL) or the database's write lock (SQLite).
            # One that finds a job made since it was asked (another rerun's) takes it:
            # concurrent identical reruns make one new job, as identical submissions do.
            session.execute(update(JobRow).where(*standing).values(superseded=JobRow.superseded))
            fresh = _reusable(session, digest)
            if fresh is not None and _replaced_already(fresh, rerun_of, asked_over, asked_at):
                session.commit()
                return fresh, True
            session.execute(update(JobRow).where(*standing).values(superseded=True))
        job = JobRow(
            type=job_type,
            status="queued",
            scenario_id=scenario_id,
            params=params,
            seed=seed,
            config_hash=digest,
            name=name,
            tag_rows=[JobTagRow(tag=tag) for tag in dict.fromkeys(tags)],
        )
        session.add(job)
        try:
            if on_insert is not None:
                session.flush()
                on_insert(job)
            # The row must be committed before a message can reach a worker that claims it.
            session.commit()
        except IntegrityError:
            session.rollback()
            existing = _reusable(session, digest)
            if existing is not None:
                # Another submission of the same configuration won the race.
                return existing, True
            if session.get(ScenarioRow, scenario_id) is None:
                raise ScenarioGone(scenario_id) from None
            # The winner ended (failed, cancelled) between our insert and our look-up.
            continue
        return job, False
    raise RuntimeError(f"could not insert job {digest[:12]} after 3 tries")


def set_labels(
    session: Session,
    job: JobRow,
    *,
    name: str | None = None,
    tags: Iterable[str] | None = None,
    rename: bool = False,
) -> None:
    """Rename (``rename``: set ``name``, None clears it) and retag (``tags`` not None:
    replace them) a job. Labels only: its parameters, seed and identity stay."""
    # Take the job's row lock (PostgreSQL) or the database's write lock (SQLite) before
    # reading its tags, and read them again: two retags at once then run one after the
    # other, the second on what the first wrote (each had read the same tags, and the
    # second's insert of a tag the first had added was a unique violation: a 500).
    session.execute(update(JobRow).where(JobRow.id == job.id).values(name=JobRow.name))
    session.refresh(job, attribute_names=["name", "tag_rows"])
    if rename:
        job.name = name
    if tags is not None:
        wanted = list(dict.fromkeys(tags))
        kept = [row for row in job.tag_rows if row.tag in wanted]
        have = {row.tag for row in kept}
        job.tag_rows = kept + [JobTagRow(tag=tag) for tag in wanted if tag not in have]


def mark_sent(session: Session, job_id: str) -> None:
    """Record that the job's message went to the broker now."""
    session.execute(update(JobRow).where(JobRow.id == job_id).values(sent_at=utcnow()))


def due_for_sending(
    session: Session,
    *,
    unsent_grace_s: float,
    resend_after_s: float,
    idle_workers: int,
    now: datetime | None = None,
) -> list[str]:
    """Queued jobs whose message must be sent (again), marked as sent now.

    - never sent (``sent_at`` NULL) for ``unsent_grace_s``: the API died between its
      commit and its send, the broker was down then, or a hand-back is waiting;
    - sent more than ``resend_after_s`` ago while ``idle_workers`` > 0: a live worker
      with nothing to do would have taken the message long since, so it was lost (a
      deleted queue, a broker restarted without persistence). At most ``idle_workers``
      of these, oldest first, per call: a queue that is merely long is left alone.

    Each job is marked by a conditional UPDATE before it is returned, so two monitors
    never both send it.
    """
    now = now or utcnow()
    never = and_(
        JobRow.sent_at.is_(None),
        JobRow.created_at < now - timedelta(seconds=unsent_grace_s),
    )
    stale = JobRow.sent_at < now - timedelta(seconds=resend_after_s)
    due = list(
        session.scalars(
            select(JobRow.id).where(JobRow.status == "queued", never).order_by(JobRow.created_at)
        )
    )
    if idle_workers > 0:
        due += list(
            session.scalars(
                select(JobRow.id)
                .where(JobRow.status == "queued", stale)
                .order_by(JobRow.sent_at)
                .limit(idle_workers)
            )
        )
    taken = []
    for job_id in due:
        marked = session.execute(  # type: ignore[attr-defined]
            update(JobRow)
            .where(JobRow.id == job_id, JobRow.status == "queued", or_(never, stale))
            .values(sent_at=now)
        ).rowcount
        if marked:
            taken.append(job_id)
    return taken


def send_again_since(
    session: Session, since: datetime, *, now: datetime | None = None
) -> list[str]:
    """Queued jobs whose message was spent at or after ``since`` (and before ``now``),
    oldest first, marked as sent now: those a worker's task processes left while it held
    no incarnation lock, its lock taken again now (see :mod:`worker.incarnation`). Each
    is marked by a conditional UPDATE before it is returned, so two monitors never both
    send it. A job sent at that time whose message still waits in the broker gets a
    second message: harmless (a claim is one atomic UPDATE; the later message finds the
    job taken and does nothing)."""
    now = now or utcnow()
    left = and_(JobRow.status == "queued", JobRow.sent_at >= since, JobRow.sent_at < now)
    taken = []
    for job_id in session.scalars(select(JobRow.id).where(left).order_by(JobRow.sent_at)).all():
        marked = session.execute(  # type: ignore[attr-defined]
            update(JobRow).where(JobRow.id == job_id, left).values(sent_at=now)
        ).rowcount
        if marked:
            taken.append(job_id)
    return taken


def claim(
    session: Session, job_id: str, worker: str, incarnation: str | None = None
) -> JobRow | None:
    """Mark a queued job running for ``worker`` (its process ``incarnation``, see
    :func:`start_worker`); None if it is not queued any more."""
    now = utcnow()
    claimed = session.execute(  # type: ignore[attr-defined]
        update(JobRow)
        .where(JobRow.id == job_id, JobRow.status == "queued", JobRow.cancel_requested.is_(False))
        .values(
            status="running",
            worker=worker,
            worker_incarnation=incarnation,
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


def _run_of(job_id: str, attempt: int | None) -> list[Any]:
    conditions = [JobRow.id == job_id, JobRow.status == "running"]
    if attempt is not None:
        conditions.append(JobRow.attempts == attempt)
    return conditions


def owns(session: Session, job_id: str, attempt: int) -> bool:
    """Whether run ``attempt`` still owns the job (it is running as that run).

    Locks the row on PostgreSQL until the transaction ends, so a hand-back or a reap
    cannot slip between this check and the run's next write in the same transaction.
    """
    row = session.execute(
        select(JobRow.id).where(*_run_of(job_id, attempt)).with_for_update()
    ).first()
    return row is not None


def heartbeat(session: Session, job_id: str, attempt: int | None = None) -> None:
    session.execute(update(JobRow).where(*_run_of(job_id, attempt)).values(heartbeat_at=utcnow()))


def set_progress(
    session: Session, job_id: str, progress: float, attempt: int | None = None
) -> None:
    session.execute(
        update(JobRow)
        .where(*_run_of(job_id, attempt))
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
    stopped: str | None = None,
) -> bool:
    """End a running job as succeeded, failed or cancelled.

    :param attempt: the run (``attempts`` at claim) finishing it; when given, the job is
        only finished if it is still that run's, not a later re-run's.
    :param stopped: "time_limit" when the job's time limit stopped it (it failed naming
        the limit, or succeeded with what it had then); None when it ran to its end,
        failed otherwise or was cancelled.

    Returns False when the job was not running (as that run) any more: reaped, or
    finished by another delivery; the caller's work no longer belongs to it.
    """
    if status not in TERMINAL_STATUSES:
        raise ValueError(f"a job finishes as one of {TERMINAL_STATUSES}, not {status!r}")
    if stopped is not None and stopped not in STOPPED_REASONS:
        raise ValueError(f"a job is stopped by one of {STOPPED_REASONS}, not {stopped!r}")
    values: dict[str, Any] = {
        "status": status,
        "finished_at": utcnow(),
        "error": error,
        "stopped": stopped,
    }
    if status == "succeeded":
        values["progress"] = 1.0
    if result is not None:
        values["result"] = result
        job_type = session.scalar(select(JobRow.type).where(JobRow.id == job_id))
        values["summary"] = summarise(job_type or "", result)
    finished = session.execute(  # type: ignore[attr-defined]
        update(JobRow).where(*_run_of(job_id, attempt)).values(**values)
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


def hand_back(
    session: Session, worker: str, reason: str, incarnation: str | None = None
) -> list[str]:
    """Re-queue every job that ``worker`` is running, at no cost of an attempt.

    For a worker told to stop (SIGTERM: a restart, ``docker stop``): its job goes back
    to the queue at once instead of waiting for the heartbeat timeout, and the run it
    had, cut short through no fault of the job, does not count against ``max_attempts``.
    The run notices (it no longer owns the job) and drops whatever it was doing. The
    caller sends the returned jobs' messages. The worker is marked stopping, so that
    it claims nothing more (a message it already fetched included).

    With ``incarnation`` (the stopping process's, see :func:`start_worker`), only its
    own runs, and those claimed before incarnations were recorded (NULL): a live
    process started under the same name (a twin) keeps its runs, which would otherwise
    run twice; its row is marked stopping only while it names this incarnation (or
    none).
    """
    own_row = WorkerRow.name == worker
    own_runs = and_(JobRow.worker == worker, JobRow.status == "running")
    if incarnation is not None:
        own_row = and_(
            own_row, or_(WorkerRow.incarnation == incarnation, WorkerRow.incarnation.is_(None))
        )
        own_runs = and_(
            own_runs,
            or_(JobRow.worker_incarnation == incarnation, JobRow.worker_incarnation.is_(None)),
        )
    session.execute(
        update(WorkerRow)
        .where(own_row, WorkerRow.stopping_since.is_(None))
        .values(stopping_since=utcnow())
    )
    jobs = session.scalars(select(JobRow).where(own_runs).with_for_update()).all()
    now = utcnow()
    for job in jobs:
        lost_run(job, now=now, cause=ASKED_TO_STOP, reason=f"handed back: {reason}")
        job.status, job.worker, job.sent_at = "queued", None, None
        job.worker_incarnation = None
        job.progress = 0.0  # a queued job at 55 % read as half done; the next run restarts
        job.handbacks = (job.handbacks or 0) + 1
        job.error = f"handed back: {reason}"
    return [job.id for job in jobs]


def _aware(moment: datetime) -> datetime:
    """``moment`` in UTC with its zone: SQLite hands back naive UTC."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def _utc_text(moment: datetime) -> str:
    """An instant as ISO-8601 with its zone, ``Z``: the databases hand back naive UTC."""
    return _aware(moment).isoformat().replace("+00:00", "Z")


def lost_run(
    job: JobRow, *, now: datetime, cause: str, reason: str, then: str = "re-queued"
) -> None:
    """Record in ``job.attempt_history`` that its current run is taken from it, before
    the job's run fields are overwritten: the attempt, its worker, when it started and
    last beat, when and why (``cause``, one of :data:`WORKER_LOST`,
    :data:`HEARTBEAT_MISSED`, :data:`ASKED_TO_STOP` or how its task process died, and
    ``reason`` in words) and what
    became of the job (``then``: re-queued, failed, cancelled). Times in ISO-8601 UTC
    with their zone, as the API gives every time."""
    record = {
        "attempt": job.attempts,
        "worker": job.worker,
        "started_at": _utc_text(job.started_at) if job.started_at else None,
        "last_heartbeat_at": _utc_text(job.heartbeat_at) if job.heartbeat_at else None,
        "ended_at": _utc_text(now),
        "outcome": "handed back" if cause == ASKED_TO_STOP else "lost",
        "cause": cause,
        "reason": reason,
        "then": then,
    }
    # A new list, not an append: the JSON column is not mutation-tracked.
    job.attempt_history = [*(job.attempt_history or []), record]


def _why_lost(
    job: JobRow,
    *,
    seen: datetime | None,
    silent_since: datetime | None,
    timeout_s: float,
) -> tuple[str, str]:
    """The cause and the words for a dead run: its worker gone quiet too (``seen``, its
    worker's last report, before ``silent_since``, or never) or its heartbeat alone."""
    worker = job.worker or "?"
    last = job.heartbeat_at or job.started_at
    beat = _utc_text(last) if last else "never"
    if silent_since is not None and (seen is None or _aware(seen) < silent_since):
        heard = f"last reported at {_utc_text(seen)}" if seen else "not reporting"
        return WORKER_LOST, (
            f"worker lost: worker {worker} {heard}, the run's last heartbeat at {beat} "
            "(the worker was killed or its machine lost)"
        )
    alive = (
        f"; its worker {worker} still reported at {_utc_text(seen)}, so the run's task "
        "process died or hung"
        if seen
        else " (the run died or hung)"
    )
    return HEARTBEAT_MISSED, (
        f"heartbeat missed: the run's last heartbeat at {beat}, more than {timeout_s:g} s "
        f"before{alive}"
    )


def reap_stale(
    session: Session,
    *,
    timeout_s: float,
    max_attempts: int,
    worker_silence_s: float | None = None,
    now: datetime | None = None,
) -> tuple[list[str], list[str]]:
    """Deal with running jobs whose run died.

    A run is dead when its heartbeat is older than ``timeout_s``; or, sooner, when both
    its heartbeat and its worker's (the ``workers`` row, beaten by the worker's main
    process, which a busy job cannot starve) are older than ``worker_silence_s``: the
    whole worker is gone (``kill -9``, a lost machine).

    Returns (re-queued job ids, failed job ids). A job that has had ``max_attempts``
    runs (hand-backs not counted), or whose cancel was requested, is not re-queued.
    """
    now = now or utcnow()
    beat = func.coalesce(JobRow.heartbeat_at, JobRow.started_at)
    dead = beat < now - timedelta(seconds=timeout_s)
    if worker_silence_s is not None:
        silent = now - timedelta(seconds=worker_silence_s)
        worker_alive = (
            select(WorkerRow.name)
            .where(WorkerRow.name == JobRow.worker, WorkerRow.last_seen_at >= silent)
            .exists()
        )
        dead = or_(dead, and_(beat < silent, ~worker_alive))
    if session.get_bind().dialect.name == "sqlite":
        # SQLite's reads take no lock: the database's write lock first, so that a run
        # taken meanwhile by another writer (a task process's death seen by its worker,
        # see task_process_lost; a hand-back) is read as it is now, not taken twice.
        session.execute(
            update(JobRow).where(JobRow.status == "running", dead).values(status=JobRow.status)
        )
    stale = session.scalars(
        select(JobRow)
        .where(JobRow.status == "running", dead)
        # Two workers' reapers may run at once: on PostgreSQL the second skips the rows the
        # first holds (and re-checks the condition after), so a job re-queued and claimed
        # again in between is not re-queued a second time. SQLite serialises writers anyway.
        .with_for_update(skip_locked=True)
    ).all()
    names = {job.worker for job in stale if job.worker}
    seen: dict[str, datetime] = {
        name: last_seen
        for name, last_seen in session.execute(
            select(WorkerRow.name, WorkerRow.last_seen_at).where(WorkerRow.name.in_(names))
        )
    }
    silent_since = None if worker_silence_s is None else now - timedelta(seconds=worker_silence_s)
    requeued: list[str] = []
    failed: list[str] = []
    for job in stale:
        last = job.heartbeat_at or job.started_at
        error = (
            f"worker {job.worker or '?'} stopped sending heartbeats (last at "
            f"{_utc_text(last) if last else 'never'})"
        )
        cause, why = _why_lost(
            job, seen=seen.get(job.worker or ""), silent_since=silent_since, timeout_s=timeout_s
        )
        then = _take_run(
            job, now=now, cause=cause, reason=why, error=error, max_attempts=max_attempts
        )
        (requeued if then == "re-queued" else failed).append(job.id)
    return requeued, failed


def _take_run(
    job: JobRow, *, now: datetime, cause: str, reason: str, error: str, max_attempts: int
) -> str:
    """Take its dead run from a running job, recorded in its history: re-queued (unsent),
    or ended once it has had ``max_attempts`` runs (hand-backs not counted) or its cancel
    was asked for. ``error`` is the job's error in words. What became of it: "re-queued",
    "failed" or "cancelled"."""
    counted = job.attempts - (job.handbacks or 0)
    if job.cancel_requested:
        lost_run(job, now=now, cause=cause, reason=reason, then="cancelled")
        job.status, job.finished_at, job.error = "cancelled", now, error
        return "cancelled"
    if counted >= max_attempts:
        lost_run(job, now=now, cause=cause, reason=reason, then="failed")
        job.status, job.finished_at = "failed", now
        job.error = f"{error}; gave up after {counted_text(counted, 'attempt')}"
        return "failed"
    lost_run(job, now=now, cause=cause, reason=reason)
    job.status, job.worker, job.error = "queued", None, f"re-queued: {error}"
    job.worker_incarnation = None
    job.sent_at, job.progress = None, 0.0  # the next run starts from nothing
    return "re-queued"


def task_process_lost(
    session: Session,
    job_id: str,
    *,
    worker: str,
    lost_at: datetime,
    cause: str,
    reason: str,
    max_attempts: int,
) -> str | None:
    """Take job ``job_id`` from its run on ``worker`` whose task process died (killed by
    a signal, the OOM killer, an exit), as that worker saw it at ``lost_at``: re-queued
    or ended by the reaper's rule (:func:`reap_stale`), at once rather than after the
    heartbeat timeout. ``cause`` names how the process died.

    Returns what became of the job ("re-queued", "failed", "cancelled"), or None when the
    run does not hold it any more: the reaper or a hand-back took it first, or it
    finished; a run claimed after ``lost_at`` (by the worker's next task process) is
    another run and is left alone.
    """
    run = (
        JobRow.id == job_id,
        JobRow.status == "running",
        JobRow.worker == worker,
        JobRow.started_at <= lost_at,
    )
    # A write first: it takes the row's lock (PostgreSQL) or the database's write lock
    # (SQLite, whose reads take none) before the row is read, so a reaper cannot take
    # the run between this read and the write below, nor this one after the reaper's.
    held = session.execute(  # type: ignore[attr-defined]
        update(JobRow).where(*run).values(status=JobRow.status)
    ).rowcount
    job = session.scalars(select(JobRow).where(*run)).first() if held else None
    if job is None:
        return None
    return _take_run(
        job,
        now=utcnow(),
        cause=cause,
        reason=reason,
        error=f"{cause} (worker {worker})",
        max_attempts=max_attempts,
    )


def take_earlier_incarnations(
    session: Session,
    worker: str,
    incarnation: str,
    *,
    alive: Callable[[str], bool],
    max_attempts: int,
    beat_within_s: float = 0.0,
    now: datetime | None = None,
) -> tuple[list[str], list[str]]:
    """Take the jobs still running under ``worker``'s name for an earlier incarnation
    (another worker process of that name, see :func:`start_worker`) that is not
    ``alive`` any more: the worker was killed whole and started again under its name
    (docker keeps a container's hostname across a restart). Re-queued or ended by the
    reaper's rule (:func:`reap_stale`), sooner than the heartbeat timeout, with the
    cause :data:`WORKER_RESTARTED`. The jobs of a live incarnation (a second worker
    started under the same name by mistake) are left to it; so are the jobs claimed
    before incarnations were recorded (NULL: the reaper takes them), and a run that beat
    within ``beat_within_s``: its process lives, whatever its lock says (a live process
    whose lock's database session ended takes the lock again at its next beat; see
    :mod:`worker.incarnation`).

    Returns (re-queued job ids, ended job ids).
    """
    now = now or utcnow()
    others = and_(
        JobRow.status == "running",
        JobRow.worker == worker,
        JobRow.worker_incarnation.is_not(None),
        JobRow.worker_incarnation != incarnation,
    )
    # Every earlier incarnation with a run is asked, silent or not, so that the two
    # waits run side by side: ``alive`` may want the lock found free twice, two beats
    # apart (worker.incarnation.Witness), and the run must be silent for two beats.
    # Asked only once its run was silent, the two added up (about 20 s, not 10).
    earlier = set(session.scalars(select(JobRow.worker_incarnation).where(others)))
    gone = sorted(other for other in earlier if other is not None and not alive(other))
    if not gone:
        return [], []
    lost = and_(
        others,
        JobRow.worker_incarnation.in_(gone),
        func.coalesce(JobRow.heartbeat_at, JobRow.started_at)
        < now - timedelta(seconds=beat_within_s),
    )
    # As in reap_stale: the write lock (SQLite) or the rows' (PostgreSQL, skipping those
    # another taker holds) before the read, so no run is taken twice.
    if session.get_bind().dialect.name == "sqlite":
        session.execute(update(JobRow).where(lost).values(status=JobRow.status))
    jobs = session.scalars(select(JobRow).where(lost).with_for_update(skip_locked=True)).all()
    requeued: list[str] = []
    ended: list[str] = []
    for job in jobs:
        last = job.heartbeat_at or job.started_at
        beat = _utc_text(last) if last else "never"
        then = _take_run(
            job,
            now=now,
            cause=WORKER_RESTARTED,
            reason=(
                f"worker {worker} restarted; its earlier process was lost (the run's last "
                f"heartbeat at {beat})"
            ),
            error=f"worker {worker} restarted; its earlier process was lost",
            max_attempts=max_attempts,
        )
        (requeued if then == "re-queued" else ended).append(job.id)
    return requeued, ended


def clear_metrics(session: Session, job_id: str) -> None:
    """Drop a job's metrics: a re-run (after its worker died) starts a fresh curve."""
    session.execute(delete(MetricRow).where(MetricRow.job_id == job_id))


def start_worker(
    session: Session,
    name: str,
    broker_url: str,
    incarnation: str,
    *,
    warming_since: datetime | None = None,
    lock_missing_since: datetime | None = None,
) -> None:
    """Record that a worker process started under ``name`` as ``incarnation``: a new
    row, or the name's row made new (``started_at`` now, no ``stopping_since`` left from
    an earlier process of that name, which stopped or died). ``warming_since`` (its
    first task process not warm yet) and ``lock_missing_since``: as in
    :func:`beat_worker`."""
    now = utcnow()
    values = {
        "name": name,
        "broker_url": broker_url,
        "started_at": now,
        "last_seen_at": now,
        "stopping_since": None,
        "incarnation": incarnation,
        "warming_since": warming_since,
        "lock_missing_since": lock_missing_since,
    }
    dialect = session.get_bind().dialect.name
    if dialect in ("sqlite", "postgresql"):
        insert = sqlite.insert if dialect == "sqlite" else postgresql.insert
        session.execute(
            insert(WorkerRow)
            .values(**values)
            .on_conflict_do_update(
                index_elements=[WorkerRow.name],
                set_={key: value for key, value in values.items() if key != "name"},
            )
        )
        return
    row = session.get(WorkerRow, name)
    if row is None:
        session.add(WorkerRow(**values))
    else:
        for key, value in values.items():
            setattr(row, key, value)


def touch_worker(session: Session, name: str, broker_url: str) -> None:
    """Record that worker ``name`` is alive now (insert its row, or move last_seen_at)."""
    _upsert_worker(session, name, broker_url, {})


def beat_worker(
    session: Session,
    name: str,
    broker_url: str,
    *,
    warming_since: datetime | None,
    lock_missing_since: datetime | None = None,
    incarnation: str | None = None,
) -> None:
    """The worker's main process's beat: alive now, since when it has had no warm task
    process (a replacement importing the core), None when it has one, and since when it
    has not held its incarnation lock (it claims no job meanwhile), None when it holds
    it.

    With ``incarnation`` (the beating process's): the row names it (its last beater),
    and a row marked stopping by another incarnation of the name is no longer stopping.
    Two live processes started under one name by mistake (twins) share the row; the one
    it names, told to stop, marks it stopping (see :func:`hand_back`), and /health left
    the other out while it lived and beat; and /health finds a row that names a dead
    process gone, as when one twin was killed. While the row names a live twin, the
    worker's monitor beats with :func:`touch_twin_row` instead, so the row is not
    switched between the twins at every beat."""
    _upsert_worker(
        session,
        name,
        broker_url,
        {"warming_since": warming_since, "lock_missing_since": lock_missing_since},
        incarnation=incarnation,
    )


def announce_worker(session: Session, name: str, broker_url: str) -> None:
    """Record that a worker process was just started under ``name`` (by ``inertia-id
    serve``), before it can beat: listed as warming since now, with no incarnation (none
    is known yet: never judged gone). A row that exists is left alone (the worker beat
    first). Its own first beat makes the row its own (:func:`start_worker`)."""
    now = utcnow()
    values = {
        "name": name,
        "broker_url": broker_url,
        "started_at": now,
        "last_seen_at": now,
        "warming_since": now,
    }
    dialect = session.get_bind().dialect.name
    if dialect in ("sqlite", "postgresql"):
        insert = sqlite.insert if dialect == "sqlite" else postgresql.insert
        session.execute(
            insert(WorkerRow).values(**values).on_conflict_do_nothing(index_elements=["name"])
        )
    elif session.get(WorkerRow, name) is None:
        session.add(WorkerRow(**values))


def keep_announced_workers(session: Session, names: list[str]) -> None:
    """Seen now: those of the workers ``names`` (announced by :func:`announce_worker`,
    their processes alive) that have not beaten yet (no incarnation on their rows)."""
    session.execute(
        update(WorkerRow)
        .where(WorkerRow.name.in_(names), WorkerRow.incarnation.is_(None))
        .values(last_seen_at=utcnow())
    )


def forget_announced_worker(session: Session, name: str) -> bool:
    """Worker ``name``'s process (started by ``inertia-id serve``) has ended: remove its
    row if the process never beat (it crashed while importing: a bad setting, a broken
    install), the row :func:`announce_worker` wrote; whether it ever beat (its row has
    an incarnation, and is left alone). /health then says at once that no worker is
    seen, where the announced row said "warming" until its silence window ended, and
    serve's restarts, each under a name of its own, kept it "ok" with a warming worker
    for as long as serve ran."""
    session.execute(
        delete(WorkerRow).where(WorkerRow.name == name, WorkerRow.incarnation.is_(None))
    )
    return session.get(WorkerRow, name) is not None


def touch_twin_row(session: Session, name: str, twin: str) -> None:
    """A beat of a process under ``name`` whose row another live process of that name
    (a twin, incarnation ``twin``) beat last: the name is seen now, and the rest of the
    row (its incarnation, warm-up and lock state) stays the twin's, and ``twin_seen_at``
    says that a second process beats under the name (``/health`` counts it). Only while
    the row still names ``twin`` and is not marked stopping (else the next beat takes it)."""
    now = utcnow()
    session.execute(
        update(WorkerRow)
        .where(
            WorkerRow.name == name,
            WorkerRow.incarnation == twin,
            WorkerRow.stopping_since.is_(None),
        )
        .values(last_seen_at=now, twin_seen_at=now)
    )


def _upsert_worker(
    session: Session,
    name: str,
    broker_url: str,
    updates: dict[str, Any],
    *,
    incarnation: str | None = None,
) -> None:
    """Insert worker ``name``'s row, or set ``updates`` on it; with ``incarnation``, the
    row becomes ``incarnation``'s, and one marked stopping by another incarnation is no
    longer stopping (see :func:`beat_worker`)."""
    now = utcnow()
    updates = {"last_seen_at": now, "broker_url": broker_url, **updates}
    values = {"name": name, "started_at": now, **updates}
    taken_over: dict[str, Any] = {}
    if incarnation is not None:
        values["incarnation"] = incarnation
        stopped_by_other = and_(
            WorkerRow.stopping_since.is_not(None),
            WorkerRow.incarnation.is_distinct_from(incarnation),
        )
        # Expressions of the row's old values, in one statement: a twin's hand-back
        # cannot slip between the read and the write. The row names its last beater:
        # /health finds a row that names a dead process (its lock free) gone, which a
        # live twin's beat makes its own again.
        taken_over = {
            "stopping_since": case((stopped_by_other, None), else_=WorkerRow.stopping_since),
            "incarnation": incarnation,
            # A twin seen was this process, deferring to the one that beat the row: it
            # says nothing once the row is this process's.
            "twin_seen_at": case(
                (WorkerRow.incarnation.is_distinct_from(incarnation), None),
                else_=WorkerRow.twin_seen_at,
            ),
        }
    dialect = session.get_bind().dialect.name
    if dialect in ("sqlite", "postgresql"):
        # A worker's main process and its task process beat under one name: an atomic
        # upsert, so neither trips over the other's insert.
        insert = sqlite.insert if dialect == "sqlite" else postgresql.insert
        statement = insert(WorkerRow).values(**values)
        session.execute(
            statement.on_conflict_do_update(
                index_elements=[WorkerRow.name], set_={**updates, **taken_over}
            )
        )
        return
    row = session.get(WorkerRow, name)
    if row is None:
        session.add(WorkerRow(**values))
        return
    if incarnation is not None:
        if row.stopping_since is not None and row.incarnation != incarnation:
            row.stopping_since = None
        if row.incarnation != incarnation:
            row.twin_seen_at = None
        row.incarnation = incarnation
    for key, value in updates.items():
        setattr(row, key, value)
