"""What a job handler sees, and what it hands back.

A handler is a pure function of its job: ``handler(context) -> Outcome``. The context
carries the typed parameters (:mod:`service.params`) and the inputs the runner resolved
(the scenario, the classifier a sweep names); the outcome carries the result, the metric
points and any trained classifier, which the runner stores with the job's finish.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import KW_ONLY, InitVar, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sqlalchemy import select
from sqlalchemy.exc import DBAPIError

from inertia_id.deadline import time_limit_grace_s
from service.config import Settings
from service.params import StrictModel
from service.store import Database, JobRow
from service.store.jobs import add_metrics, finish, heartbeat, owns, set_progress, touch_worker
from service.store.refusals import unreachable, why_cannot_store

from .episode import Episode

if TYPE_CHECKING:
    # Types only: the worker's main process imports this module and must stay light.
    from inertia_id.classifiers.registry import CandidateClassifier
    from inertia_id.physics.scenario import Scenario
    from inertia_id.pipelines import Trained

__all__ = [
    "CANCEL_POLL_S",
    "DATABASE_SILENT_S",
    "TIME_LIMIT",
    "TIME_LIMIT_GRACE_S",
    "JobContext",
    "JobSpec",
    "JobTimeLimitExceeded",
    "Outcome",
    "broker_label",
    "finite_metrics",
]

logger = logging.getLogger(__name__)

#: Seconds between two reads of a running job's cancel flag. The search polls
#: ``should_stop`` every environment step; the database is asked at most this often.
CANCEL_POLL_S = 1.0
#: The worker's database connections (its beat's, its hand-back's, its runs') are given
#: up after about this many seconds of a silent network (see
#: service.store.session.Database): a connect, or a statement whose packets the server's
#: machine stopped acknowledging (packets dropped: given up after 2.4 s with 2 s, where
#: it waited 25 s and on before). Not a statement that something acknowledges but
#: nothing answers (a frozen proxy): see worker.monitor.STOP_WAIT_S.
DATABASE_SILENT_S = 10.0
#: How long a job may run past its time limit and a search's re-score grace
#: (:func:`~inertia_id.search.loop.time_limit_grace_s`: 10 % of the limit, at least
#: 10 s, at most 300 s; or the grace the job asked for, at most 3600 s) before its
#: heartbeat ends it "failed". A search stopped at its limit still finishes the sequence
#: (NSGA-II: the 16 sequences) it is on, re-scores while the grace lasts and then
#: finishes the piece under way (a prefix's clustering, 16 front members; seconds); a
#: sweep finishes the point it is on; a training stops at its next checkpoint (after the
#: simulation, eigendecomposition or library fit under way). This covers those; a run
#: that still goes on is ended once past it.
TIME_LIMIT_GRACE_S = 600.0


class JobTimeLimitExceeded(Exception):
    """A job whose result is nothing without its end (a training) ran past its time
    limit, and stopped there (the job fails)."""


#: ``jobs.stopped`` of a job its time limit stopped: failed naming the limit, or a
#: search or sweep that succeeded with what it had (the word its result's ``stopped``
#: says, :data:`inertia_id.search.loop.TIME_LIMIT`).
TIME_LIMIT = "time_limit"


def broker_label(settings: Settings) -> str:
    """The broker URL as shown to users: any password masked."""
    from kombu.utils.url import maybe_sanitize_url

    return str(maybe_sanitize_url(settings.broker_url))


@dataclass(frozen=True)
class JobSpec:
    """A claimed job, as its handler needs it.

    :param params: the job's parameters, parsed with its type's model.
    :param attempt: which run of the job this is (1 = first; more after a worker died).
    :param scenario: the job's scenario.
    :param classifier: the stored classifier the job names (a sweep's), loaded.
    """

    id: str
    type: str
    params: StrictModel
    seed: int
    scenario_id: str
    scenario: Scenario
    attempt: int
    classifier: CandidateClassifier | None = None


@dataclass
class Outcome:
    """What a handler hands back; stored with the job's finish, in one transaction.

    :param status: "succeeded" or "cancelled" (a failure is an exception).
    :param result: the job's JSON result.
    :param metrics: (key, step, value) points written with the finish.
    :param classifier: a trained classifier to store (its id and checksum are added to
        the result).
    """

    status: str
    result: dict[str, Any] | None
    metrics: list[tuple[str, int, float]] = field(default_factory=list)
    classifier: Trained | None = None


def finite_metrics(rows: Iterable[tuple[str, int, float]]) -> list[tuple[str, int, float]]:
    # A curve point before any finished episode has NaN means; a metric row holds numbers.
    return [(k, int(s), float(v)) for k, s, v in rows if v is not None and math.isfinite(v)]


# Compared and shown as an object (not by value): a context is one run's, and its
# settings hold the service's secrets.
@dataclass(eq=False, repr=False)
class JobContext:
    """What a handler sees of the service: its job, a place for files, and reporting.

    A handler reads its typed parameters and its resolved inputs from :attr:`spec`,
    reports progress and metrics, asks whether to stop, and may write files under
    :attr:`data_dir`. It has no handle on the store: the runner resolves what a job names
    and persists what it returns.

    :param spec: the claimed job, its parameters typed and its inputs resolved.
    :param db: the job store (the context's own: progress, metrics, cancel flag).
    :param settings: the service settings (data_dir for files).
    :param worker_name: the Celery node name that claimed the job.
    :param clock: monotonic seconds, for the cancel-poll throttle and the time limit.
    :param stopping: whether this worker was told to stop (see :meth:`check_now`).

    The job's time limit (:attr:`time_limit_s`) is its ``time_limit_s`` parameter or the
    service's ceiling (``job_time_limit_s``), whichever is less, counted from the
    context's creation (the claim): a search and a sweep stop themselves there (a
    search re-scores in the grace after it); a job still running
    :data:`TIME_LIMIT_GRACE_S` past the limit and that grace is ended "failed" by its
    heartbeat.
    """

    spec: JobSpec
    db: InitVar[Database]
    settings: Settings
    worker_name: str
    _: KW_ONLY
    clock: InitVar[Callable[[], float]] = time.monotonic
    stopping: InitVar[Callable[[], bool]] = lambda: False
    cancelled: bool = field(default=False, init=False)
    lost: bool = field(default=False, init=False)
    #: The handler has returned and its outcome waits to be stored (worker.runner): the
    #: time limit no longer ends the run; INERTIA_ID_OUTCOME_REFUSED_WAIT_S bounds the wait.
    outcome_held: bool = field(default=False, init=False)
    _beat_refused: str | None = field(default=None, init=False)

    def __post_init__(
        self, db: Database, clock: Callable[[], float], stopping: Callable[[], bool]
    ) -> None:
        # Kept private: a handler reports through the context, it does not use the store.
        self._db = db
        self._clock = clock
        self._stopping = stopping
        self._last_poll = self.started = clock()
        #: Progress that cannot be stored, a cancel flag that cannot be read: each
        #: logged once an episode (see worker.episode).
        self._report_failing = Episode(logger)
        self._poll_failing = Episode(logger)

    def now(self) -> float:
        """The context's monotonic clock, s (a search's time limit runs on it)."""
        return self._clock()

    @property
    def time_limit_s(self) -> float:
        """The job's limit: its ``time_limit_s`` parameter, at most the service's ceiling."""
        asked = getattr(self.spec.params, "time_limit_s", None)
        ceiling = self.settings.job_time_limit_s
        return ceiling if asked is None else min(float(asked), ceiling)

    @property
    def rescore_grace_s(self) -> float:
        """How long a search past :attr:`time_limit_s` may still re-score, s."""
        asked = getattr(self.spec.params, "time_limit_grace_s", None)
        return float(time_limit_grace_s(self.time_limit_s, asked) or 0.0)

    def time_left_s(self) -> float:
        """Seconds of the time limit left (negative past it)."""
        return self.time_limit_s - (self._clock() - self.started)

    def past_time_limit(self) -> bool:
        return self.time_left_s() <= 0

    def time_limit_text(self) -> str:
        """The one-line reason a job past its limit fails with."""
        return f"the job exceeded its time limit of {self.time_limit_s:g} s"

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
        rows = finite_metrics(metrics)
        try:
            with self._db.session() as session:
                if not owns(session, self.spec.id, self.spec.attempt):
                    self.lost = True
                    return
                if rows:
                    add_metrics(session, self.spec.id, rows)
                if progress is not None:
                    set_progress(session, self.spec.id, progress, self.spec.attempt)
        except Exception as exc:
            # Once an episode (worker.episode), as the beat's: a traceback at every
            # report filled the log for as long as the database refused or was down.
            self._report_failing.seen(
                _condition(exc),
                f"job {self.spec.id}: could not store progress (%s); going on",
                exc_info=_unforeseen(exc),
            )
            return
        self._report_failing.cleared(f"job {self.spec.id}: progress is stored again after %.0f s")

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
        """Read the job's cancel flag and ownership now (unthrottled).

        A run whose flag cannot be read once its worker is stopping is given up (True,
        :attr:`lost`): the stop's hand-back takes the job from it, unseen, or, with a
        database that answered neither, the reaper does. Before, it went on: behind a
        frozen proxy its read waited for ever and Celery, waiting for the run, kept a
        plain ``celery worker`` from exiting; its statement is now cut once the stop
        has waited STOP_ANSWER_S for its answer (worker.cut.StopCut, worker.runner).
        """
        try:
            with self._db.session() as session:
                row = session.execute(
                    select(JobRow.status, JobRow.cancel_requested, JobRow.attempts).where(
                        JobRow.id == self.spec.id
                    )
                ).one_or_none()
        except Exception as exc:
            if self._stopping():
                self.lost = True
                logger.warning(
                    "job %s: this worker is stopping and the job's cancel flag cannot be "
                    "read (%s): the run is given up, its job left to the stop's hand-back "
                    "or the reaper",
                    self.spec.id,
                    _condition(exc),
                )
                return True
            # Once an episode: asked every second by a search, a traceback each time.
            self._poll_failing.seen(
                _condition(exc),
                f"job {self.spec.id}: could not read its cancel flag (%s); going on",
                exc_info=_unforeseen(exc),
            )
            return False
        self._poll_failing.cleared(
            f"job {self.spec.id}: its cancel flag is read again after %.0f s"
        )
        if row is None or row.status != "running" or row.attempts != self.spec.attempt:
            # Reaped while we were stalled (and perhaps re-run elsewhere), or deleted.
            self.lost = True
        elif row.cancel_requested:
            self.cancelled = True
        return self.cancelled or self.lost

    def tick(self) -> None:
        """The run's heartbeat ticker's work: :meth:`beat`. A beat the database refuses to
        store (a full disk, a read-only database) is logged once, naming the refusal, not
        as a failed tick's traceback at every beat; the run goes on and beats again once
        it can (its end then stored with the reason, :mod:`worker.runner`)."""
        try:
            self.beat()
        except Exception as exc:
            why = why_cannot_store(exc)
            if why is None and unreachable(exc):
                # The database down: as a refusal, one line, not a failed tick's
                # traceback (some 10 KB) at every beat of the outage.
                why = "unreachable"
            if why is None:
                raise
            if why != self._beat_refused:
                logger.error(
                    "job %s: heartbeat not stored: %s: %s",
                    self.spec.id,
                    "the database cannot be reached"
                    if why == "unreachable"
                    else f"the database refuses writes ({why})",
                    (
                        str(exc.orig if isinstance(exc, DBAPIError) else exc).strip().splitlines()
                        or [""]
                    )[0],
                )
            self._beat_refused = why
            return
        if self._beat_refused is not None:
            logger.warning(
                "job %s: heartbeat stored again (refused for a while: %s)",
                self.spec.id,
                self._beat_refused,
            )
            self._beat_refused = None

    def beat(self) -> None:
        """One heartbeat: this worker's, then the job's; or, for a job
        :data:`TIME_LIMIT_GRACE_S` past its time limit and a search's re-score grace, its
        end ("failed", the limit named). The run then no longer owns the job: a
        cooperative one (a search, a sweep, a training) stops at its next check; one that
        still finishes has its result dropped.

        In that order: a hand-back (:func:`~service.store.jobs.hand_back`) locks the
        worker's row, then its jobs'; a heartbeat that locked the job's row first and the
        worker's second deadlocked against it on PostgreSQL, and the stopping worker's job
        was left running for the reaper (seen in a graceful-restart test)."""
        # Not once the handler has returned: a result computed within the limit, its
        # write refused (a full disk) past the limit and its grace, was failed by the
        # beat as "still running", the result dropped once the database took it.
        overdue = not self.outcome_held and self.time_left_s() < -(
            self.rescore_grace_s + TIME_LIMIT_GRACE_S
        )
        with self._db.session() as session:
            touch_worker(session, self.worker_name, broker_label(self.settings))
            if not overdue:
                heartbeat(session, self.spec.id, self.spec.attempt)
            elif finish(
                session,
                self.spec.id,
                "failed",
                error=f"{self.time_limit_text()} (still running "
                f"{self.rescore_grace_s + TIME_LIMIT_GRACE_S:g} s after it; ended)",
                attempt=self.spec.attempt,
                stopped=TIME_LIMIT,
            ):
                self.lost = True
                logger.warning("job %s ended: %s", self.spec.id, self.time_limit_text())


def _unforeseen(exc: BaseException) -> bool:
    """Whether ``exc`` is neither the database refusing writes nor out of reach: such a
    failure is logged with its traceback (once an episode)."""
    return why_cannot_store(exc) is None and not unreachable(exc)


def _condition(exc: BaseException) -> str:
    """What kept a write or a read from the database, in one line."""
    why = why_cannot_store(exc)
    inner = exc.orig if isinstance(exc, DBAPIError) and exc.orig is not None else exc
    first = (str(inner).strip().splitlines() or [""])[0]
    text = f"{type(inner).__name__}: {first}"
    if why is not None:
        return f"the database refuses writes ({why}): {text}"
    if unreachable(exc):
        return f"the database cannot be reached: {text}"
    return text
