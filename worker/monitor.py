"""The worker process's own beat: "I am alive" (a ``workers`` row), the reaper and the
re-sender, and the hand-back when the worker is told to stop.

Runs in the worker's main process (not in the task process), on a thread started when
the worker is ready: at once and then every ``heartbeat_interval_s`` it upserts this
worker's row and runs :func:`worker.reaper.reap_once` and
:func:`worker.reaper.resend_once`. So dead runs and lost messages are dealt with as soon
as any worker starts, and while any worker lives. On a warm shutdown (SIGTERM) the job
this worker runs goes back to the queue at once (:func:`worker.reaper.hand_back_jobs`).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from celery.signals import worker_init, worker_ready, worker_shutdown, worker_shutting_down
from sqlalchemy import select
from sqlalchemy.exc import DBAPIError, InterfaceError, OperationalError
from sqlalchemy.orm import Session

from service.config import Settings, get_settings
from service.queue import make_celery
from service.store import Database
from service.store.incarnations import LockUnreadable, locks_held
from service.store.jobs import beat_worker, start_worker, touch_twin_row
from service.store.models import WorkerRow, utcnow
from service.store.refusals import database_label, why_cannot_store

from . import incarnation
from .context import DATABASE_SILENT_S, broker_label
from .episode import Episode
from .process import cold_since, mark_stopping, warm
from .reaper import (
    HAND_BACK_RECORD,
    HAND_BACK_SEND,
    hand_back_jobs,
    reap_once,
    resend_left,
    resend_once,
    take_restarted_runs,
)
from .ticker import Ticker

__all__ = ["WorkerMonitor", "current", "may_claim"]

logger = logging.getLogger(__name__)

#: Seconds between two hand-back passes of a stopping worker.
STOPPING_TICK_S = 1.0
#: Seconds from the stop (SIGTERM) that a worker waits for its hand-back and its beat
#: before it lets go of its lock and exits without them. A database that stops
#: answering keeps a statement waiting: its packets dropped, DATABASE_SILENT_S; behind a
#: frozen proxy (the kernel still acknowledging for it) for ever, as neither libpq nor
#: psycopg has a deadline for an answer and the kernel's (TCP keepalive,
#: ``tcp_user_timeout``) do not fire while something acknowledges. Before, such a stop
#: waited 10 s for the hand-back, up to 10 s more for the beat, then the lock's release:
#: 19.9 s and 20.0 s behind a frozen proxy (now 6.1 s to 8.9 s), past `inertia-id
#: serve`'s 10 s grace, when it kills the worker. What a
#: hand-back left undone loses: a run it held is re-queued by the reaper once its
#: heartbeat is stale (``heartbeat_timeout_s``), counting an attempt, and its row is not
#: marked stopping (/health reports its process gone once the server has let go of its
#: lock); a hand-back whose commit re-queued its runs but whose send to the broker hangs
#: left them queued and unsent, for a monitor's send. Celery's own wind-down (its task
#: process's exit) runs meanwhile.
STOP_WAIT_S = 5.0

#: The stop's hand-back waits for a beat under way first (its database work, mostly).
HAND_BACK_BEAT = "beat"


class WorkerMonitor:
    """Worker heartbeat and reaper for the worker named ``name``.

    :param name: the Celery node name (``worker1@host``), the ``workers`` row's key.
    :param settings: database, broker, interval and timeout.
    """

    def __init__(self, name: str, settings: Settings, life: incarnation.Life | None = None) -> None:
        self.name = name
        self.settings = settings
        self.db = Database(settings.resolved_database_url, silent_after_s=DATABASE_SILENT_S)
        #: This worker process's lock (see worker.incarnation): taken before its task
        #: processes can claim a job, or at the first tick.
        self.life = life or incarnation.Life(settings.resolved_database_url, incarnation.current())
        self._started = False
        #: Set by stop(): a hand-back still under way starts no further passes.
        self._stopped = False
        #: Since when this worker's beats have found its lock not held (see tick).
        self._lock_missing_since: datetime | None = None
        #: Where the stop's hand-back is (:data:`HAND_BACK_BEAT`, then reaper's
        #: ``HAND_BACK_*``), and the jobs it re-queued: a stop that cannot wait for it
        #: says which part did not finish. None before the hand-back begins.
        self.hand_back_stage: str | None = None
        self.handed_back: list[str] = []
        #: Judges an earlier incarnation of this name gone (see take_restarted_runs).
        self.witness = incarnation.Witness(2 * settings.heartbeat_interval_s)
        #: When a beat first saw no warm task process and no replacement started (s
        #: since the epoch; None: it has not, or one is warm or started since).
        self._unreplaced_since: float | None = None
        #: When this worker process started (s since the epoch: its ``worker_init``, else
        #: now), until its first task process is warm: that first warm-up is dated from
        #: it. None once a task process has been warm.
        self._booting_since: float | None = _started_at or time.time()
        # Its own app and connections: the reaper publishes from this thread, away from
        # the consumer's event loop.
        self.celery = make_celery(settings)
        #: The database unreachable at this worker's beats, and any other failure of a
        #: beat: each logged once an episode (see worker.episode).
        self._outage = Episode(logger)
        #: The database answering but refusing this worker's beat (full, read-only).
        self._refused = Episode(logger)
        self._failing = Episode(logger)
        #: The database without the service's tables (not migrated yet: `inertia-id
        #: migrate`, or the API as it starts): one clear line, no traceback, until it has them.
        self._no_schema = Episode(logger)
        #: Beats that found the row named by a live twin (see _live_twin).
        self._twin = Episode(logger)
        #: Whether the last beat could not store this worker's row (the database down,
        #: full or read-only), and the monotonic second from which the reaper may judge
        #: runs again after such beats (see tick).
        self._beat_unstored = False
        self._reap_from = 0.0
        self._clock: Callable[[], float] = time.monotonic
        #: Whether the last beat found no warm task process (it was to store the
        #: worker as warming): the next beat comes as soon as one is warm.
        self._beat_cold = False
        self._ticker = Ticker(
            self.beat,
            settings.heartbeat_interval_s,
            name=f"inertia-id monitor {name}",
            immediately=True,
            sooner=self._warmed_since_beat,
        )

    def _warmed_since_beat(self) -> bool:
        """Whether a task process has become warm since a beat that found none: the
        monitor then beats at once, and /health lists the worker warm. Answered yes once
        a beat that found none, whatever that early beat does (one that failed before it
        looked at the task processes would be asked for again at every poll)."""
        if self._beat_cold and warm():
            self._beat_cold = False
            return True
        return False

    def beat(self) -> None:
        """One beat (:meth:`tick`), its failure logged once an episode rather than with
        a traceback at every beat: a database wholly down failed every beat (every
        ``heartbeat_interval_s``) for as long as it was down, each logged in over 100
        lines. Now one line when it starts (with the reason), a reminder every
        :data:`worker.episode.REMIND_EVERY_S`, and one line when it answers again."""
        try:
            self.tick()
        except Exception as exc:
            why = why_cannot_store(exc)
            if no_schema(exc):
                # Before the database is migrated (a worker started before the API): it
                # said "unreachable" (SQLite) or logged a traceback (PostgreSQL).
                self._no_schema.seen(
                    _first_line(exc),
                    f"worker {self.name}: the database {database_label(self.db.url)} has "
                    "no schema yet (%s): run `inertia-id migrate` on it (the API and "
                    "`inertia-id serve` migrate it too as they start); retrying every "
                    f"{self.settings.heartbeat_interval_s:g} s",
                )
            elif why is not None:
                # Answered, but refused: not "unreachable" (which it said of a full disk).
                self._refused.seen(
                    f"{why}: {_first_line(exc)}",
                    f"worker {self.name}: the database {database_label(self.db.url)} refuses "
                    "writes (%s); its beat (heartbeat, reaper, re-sender) tries again every "
                    f"{self.settings.heartbeat_interval_s:g} s",
                )
            elif _database_unreachable(exc):
                self._outage.seen(
                    _first_line(exc),
                    f"worker {self.name}: the database {database_label(self.db.url)} is "
                    "unreachable (%s); its beat "
                    "(heartbeat, reaper, re-sender) tries again every "
                    f"{self.settings.heartbeat_interval_s:g} s",
                )
            else:
                self._failing.seen(
                    _first_line(exc),
                    f"worker {self.name}: its beat failed (%s); trying again every "
                    f"{self.settings.heartbeat_interval_s:g} s",
                    exc_info=True,
                )
            return
        self._no_schema.cleared(f"worker {self.name}: the database has its schema after %.0f s")
        self._refused.cleared(f"worker {self.name}: the database takes writes again after %.0f s")
        self._outage.cleared(f"worker {self.name}: the database answers again after %.0f s")
        self._failing.cleared(f"worker {self.name}: its beat succeeds again after %.0f s")

    def tick(self) -> None:
        try:
            self._store_beat()
        except Exception:
            self._beat_unstored = True
            raise
        if self._beat_unstored:
            # The runs' heartbeats were refused as this beat was (the database down,
            # full or read-only): each is a heartbeat timeout old now, though its task
            # process lives and beats again within an interval. Judged at once, a run
            # that outlived a 2-minute outage was re-queued here as "heartbeat missed
            # ... died or hung" and run twice, its own end (the refusal) dropped.
            self._beat_unstored = False
            self._reap_from = self._clock() + self.settings.heartbeat_timeout_s
            logger.info(
                "worker %s: its beat is stored again; runs are reaped from %g s on, once "
                "their heartbeats could be stored for a heartbeat timeout",
                self.name,
                self.settings.heartbeat_timeout_s,
            )
        # Before the reaper: a run of this name's earlier, dead process is taken within
        # two beats, with its cause, not by the heartbeat timeout as a hung task process.
        take_restarted_runs(
            self.settings, self.db, self.celery, self.name, self.life.incarnation, self.witness
        )
        if self._clock() >= self._reap_from:
            report = reap_once(self.settings, self.db, self.celery)
            if report.requeued or report.failed:
                logger.warning(
                    "reaper: re-queued %s, ended %s",
                    report.requeued or "none",
                    report.failed or "none",
                )
        left_since = self.life.claims_stopped_at
        if left_since is not None and self.life.may_claim():
            # Its lock taken again: what its task processes left meanwhile is sent now
            # (before resend_once, which would send it again a second time), not
            # resend_after_s after it was left.
            resend_left(self.db, self.celery, left_since)
            self.life.claims_stopped_at = None
        resend_once(self.settings, self.db, self.celery)

    def _store_beat(self) -> None:
        """This worker's row: its lock's state and its warm-up, as of now."""
        # Taken again if it was lost while this process lives (see Life.keep).
        self.life.keep()
        # Not held (nor taken again just now): the task processes claim no job, so the
        # row says since when, for /health (see Life.may_claim).
        if self.life.may_claim():
            self._lock_missing_since = None
        elif self._lock_missing_since is None:
            self._lock_missing_since = utcnow()
        is_warm = warm()
        self._beat_cold = not is_warm
        # Listed from its first beat: while a task process warms up (the first one, as
        # the worker starts, or a replacement: the last one retired after its jobs or
        # its memory limit, or was killed), the worker beats as warming. It takes the
        # queued jobs as soon as one is up, so /health need not call it gone (nor
        # absent while it starts), and can tell a warm-up that takes too long.
        warming_since = None if is_warm else self._warming_since()
        with self.db.session() as session:
            twin = self._live_twin(session) if self._started else None
            if twin is not None:
                # A twin: another live process started under this name by mistake. Both
                # wrote their own warm-up and lock state and incarnation on the row they
                # share at each beat, so it switched between them every beat (warming,
                # then warm, then warming...). The row stays the twin's, which beat it
                # last; this one says only that the name lives, and logs why.
                self._twin.seen(
                    twin,
                    f"worker {self.name}: another live process beats under this name "
                    "(incarnation %s): its row is left to it, and this process is not "
                    "listed by /health; give each worker a name of its own",
                )
                touch_twin_row(session, self.name, twin)
            elif self._started:
                self._twin.cleared(
                    f"worker {self.name}: its row is this process's again after %.0f s"
                )
                beat_worker(
                    session,
                    self.name,
                    broker_label(self.settings),
                    warming_since=warming_since,
                    lock_missing_since=self._lock_missing_since,
                    # A twin of this name told to stop marked the row it shares
                    # stopping: this live process's beat takes it back.
                    incarnation=self.life.incarnation,
                )
            else:
                # A new incarnation of the name: a fresh row, not a dead one's.
                start_worker(
                    session,
                    self.name,
                    broker_label(self.settings),
                    self.life.incarnation,
                    warming_since=warming_since,
                    lock_missing_since=self._lock_missing_since,
                )
        self._started = True
        if is_warm:
            self._unreplaced_since = None
            self._booting_since = None

    def _live_twin(self, session: Session) -> str | None:
        """The incarnation of another live process under this name that the row names
        (a twin), or None: the row is this process's, marked stopping (the twin was told
        to stop and hands its row back), or names a process whose lock is free or
        cannot be read (it is taken over, as before twins were told apart)."""
        row = session.execute(
            select(WorkerRow.incarnation, WorkerRow.stopping_since).where(
                WorkerRow.name == self.name
            )
        ).one_or_none()
        if row is None or row.incarnation in (None, self.life.incarnation):
            return None
        if row.stopping_since is not None:
            return None
        try:
            # Read, not tried (on PostgreSQL, pg_locks): a try-lock held the twin's key
            # for a moment, in which a twin that had lost its lock could not take it.
            held = locks_held(session, self.settings.resolved_database_url, [row.incarnation])
        except LockUnreadable:
            return None
        return row.incarnation if held.get(row.incarnation) else None

    def _warming_since(self) -> datetime:
        """Since when the worker has had no warm task process: before its first was
        warm, the worker's own start; later, the start of the replacement warming up
        (or of the first of those killed in turn), else, none started yet, the first
        beat that saw none. The pool starts one within a second of the last one's exit;
        should it never, the age grows past /health's limit (dated "now" at each beat,
        it stayed 0 s and the worker "ok")."""
        since = cold_since()
        if self._booting_since is not None:
            # The first task process starts after the worker: the warm-up an operator
            # sees begins when the worker was started.
            since = self._booting_since if since is None else min(since, self._booting_since)
        if since is None:
            if self._unreplaced_since is None:
                self._unreplaced_since = time.time()
            since = self._unreplaced_since
        else:
            self._unreplaced_since = None
        return datetime.fromtimestamp(since, UTC)

    def hand_back(self) -> list[str]:
        """Give this worker's running job back to the queue (it is stopping): this
        process's, not a live twin's of its name.

        Then, every second until the worker is gone, again: a message fetched just as
        the stop began can still start a job (see :func:`worker.runner._execute`).
        """
        self.hand_back_stage = HAND_BACK_BEAT
        self._ticker.stop()
        handed = hand_back_jobs(
            self.settings,
            self.db,
            self.celery,
            self.name,
            self.life.incarnation,
            stage=self._hand_back_at,
        )
        if self._stopped:  # the stop did not wait for it: no passes after it
            return handed
        self._ticker = Ticker(
            self._hand_back_again,
            STOPPING_TICK_S,
            name=f"inertia-id hand-back {self.name}",
        ).start()
        return handed

    def _hand_back_at(self, stage: str, job_ids: list[str]) -> None:
        self.hand_back_stage, self.handed_back = stage, list(job_ids)

    def hand_back_unfinished(self, wait_s: float) -> tuple[str, bool]:
        """What a stop that waited ``wait_s`` for the hand-back, and waits no longer,
        logs of where it stands; and whether the database answered it (false while the
        part under way is the database's: the beat it waits for, the commit that
        re-queues the runs, the record of their send)."""
        label = database_label(self.db.url)
        stage, jobs = self.hand_back_stage, ", ".join(self.handed_back) or "none"
        lock = "its incarnation lock let go of without waiting on the server's word"
        if stage == HAND_BACK_SEND:
            return (
                f"worker {self.name}: its hand-back re-queued its runs (jobs: {jobs}), but "
                f"the broker {broker_label(self.settings)} did not take their messages "
                f"within {wait_s:g} s of the stop; exiting without it: a worker's monitor "
                "sends a queued job never sent once the broker answers",
                True,
            )
        if stage == HAND_BACK_RECORD:
            return (
                f"worker {self.name}: its hand-back re-queued its runs (jobs: {jobs}) and "
                f"sent their messages, but the database {label} did not answer the record "
                f"of the send within {wait_s:g} s of the stop; exiting without it (a job "
                f"left unsent is sent by a monitor, a second message for one sent is "
                f"harmless), {lock}",
                False,
            )
        what = "the beat under way" if stage == HAND_BACK_BEAT else "its hand-back"
        return (
            f"worker {self.name}: no answer from the database {label} to {what} within "
            f"{wait_s:g} s of the stop; exiting without it (a run it holds is re-queued by "
            f"the reaper once its heartbeat is stale), {lock}",
            False,
        )

    def _hand_back_again(self) -> None:
        hand_back_jobs(self.settings, self.db, self.celery, self.name, self.life.incarnation)

    def start(self) -> WorkerMonitor:
        self._ticker.start()
        return self

    def stop(self, wait_s: float = 10.0, *, answered: bool = True) -> None:
        """Stop beating (a beat under way is waited for up to ``wait_s``), close the
        database's pooled connections and let go of the lock, for good (a beat that
        outlives the wait takes it no more: see Life.release); unless the database
        ``answered`` the stop's hand-back, without waiting on the server's word."""
        self._stopped = True
        self._ticker.stop(wait_s)
        self.db.dispose()
        self.life.release(confirm=answered)

    def forget_after_fork(self) -> None:
        """In a forked task process: let go of the parent's connections without closing
        them (closing would end the parent's sessions on PostgreSQL)."""
        self.db.engine.dispose(close=False)
        self.life.forget_after_fork()


def _database_unreachable(exc: BaseException) -> bool:
    """Whether ``exc`` says the database cannot be reached (refused, down, its session
    ended, its file unopenable) rather than a fault of the statement or of our code."""
    if isinstance(exc, DBAPIError) and exc.connection_invalidated:
        return True
    return isinstance(exc, OperationalError | InterfaceError)


def no_schema(exc: BaseException) -> bool:
    """Whether ``exc`` says a table of the service is missing: the database was not
    migrated yet (PostgreSQL's ``undefined_table``, SQLite's "no such table")."""
    if not isinstance(exc, DBAPIError) or exc.orig is None:
        return False
    if getattr(exc.orig, "sqlstate", None) == "42P01":
        return True
    return isinstance(exc, OperationalError) and str(exc.orig).startswith("no such table")


def _first_line(exc: BaseException) -> str:
    """``exc``'s type and the first line of its driver's message (SQLAlchemy's goes on
    with the statement and a link)."""
    inner = exc.orig if isinstance(exc, DBAPIError) and exc.orig is not None else exc
    return f"{type(inner).__name__}: {(str(inner).strip().splitlines() or [''])[0]}"


_monitor: WorkerMonitor | None = None
#: This process's incarnation lock, taken when the worker starts, before its pool forks
#: (``worker_init``), so no job is claimed under an incarnation that is not held.
_life: incarnation.Life | None = None
#: When this worker process started (s since the epoch; set at ``worker_init``).
_started_at: float | None = None


def _process_started_at() -> float | None:
    """When this process was started (s since the epoch, to a clock tick), from /proc
    (Linux); None elsewhere. A worker's main process takes seconds to import Celery and
    its app before ``worker_init`` (4-6 s measured on the loaded 2-core machine): its
    first warm-up is dated from its start, not from there."""
    try:
        now = time.time()
        with open("/proc/self/stat") as stat:
            # "pid (comm) state ...": field 22, starttime, in clock ticks after boot.
            ticks = int(stat.read().rpartition(")")[2].split()[19])
        with open("/proc/uptime") as uptime:
            # Not /proc/stat's btime: whole seconds, up to 1 s early.
            up_s = float(uptime.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return now - up_s + ticks / os.sysconf("SC_CLK_TCK")


def current() -> WorkerMonitor | None:
    """This worker's monitor, once the worker is ready (in its main process)."""
    return _monitor


def may_claim() -> bool:
    """In a task process: whether its worker holds its incarnation lock, so a job it
    claims now cannot be taken by a twin of its name (see Life.may_claim). True outside
    a worker (no lock was ever wanted)."""
    return _life is None or _life.may_claim()


def _after_fork_in_child() -> None:
    if _monitor is not None:
        _monitor.forget_after_fork()
    elif _life is not None:
        _life.forget_after_fork()


@worker_init.connect
def _hold_incarnation(**_kwargs: Any) -> None:
    global _life, _started_at
    _started_at = _process_started_at() or time.time()
    _life = incarnation.Life(get_settings().resolved_database_url, incarnation.current())
    # The database may not be up yet: the monitor tries again at each tick.
    _life.try_hold()


os.register_at_fork(after_in_child=_after_fork_in_child)


@worker_ready.connect
def _start_monitor(sender: Any = None, **_kwargs: Any) -> None:
    global _monitor
    name = getattr(sender, "hostname", None) or f"celery@{os.uname().nodename}"
    _monitor = WorkerMonitor(name, get_settings(), _life).start()
    logger.info(
        "worker %s: heartbeat and reaper every %g s (stale after %g s)",
        name,
        _monitor.settings.heartbeat_interval_s,
        _monitor.settings.heartbeat_timeout_s,
    )


_hand_back_thread: threading.Thread | None = None
#: When this worker was told to stop (monotonic s): STOP_WAIT_S runs from it.
_stop_began: float | None = None


def _hand_back_now(monitor: WorkerMonitor) -> None:
    try:
        monitor.hand_back()
    except Exception as exc:
        if no_schema(exc):  # not migrated: it holds no job to give back
            logger.info(
                "worker %s: no job to hand back: the database has no schema yet (%s)",
                monitor.name,
                _first_line(exc),
            )
            return
        if _database_unreachable(exc):
            # Out of reach, the database holds no run this worker could have started
            # since (a claim is a write): one line, not a traceback. A run it did start
            # before the outage is re-queued by a reaper once the database answers.
            logger.warning(
                "worker %s: no job handed back: the database %s is unreachable (%s); a run "
                "it holds is re-queued by the reaper once the database answers",
                monitor.name,
                database_label(monitor.db.url),
                _first_line(exc),
            )
            return
        logger.exception("could not hand the running job back; the reaper will")


@worker_shutting_down.connect
def _hand_back(**_kwargs: Any) -> None:
    # Sent in the main process when a warm shutdown starts (SIGTERM, Ctrl-C): Celery
    # would wait for the running job to end, the supervisor would then kill it, and the
    # job would wait a heartbeat timeout and lose an attempt. Instead it is re-queued now;
    # the task process sees that it no longer owns the job and drops it. Raised first:
    # from now on the task process claims no job (one it claimed meanwhile, it hands
    # back itself).
    # Celery sends this from inside its signal handler, on the main thread interrupted
    # wherever it was: database and broker I/O there could wait on a lock the
    # interrupted code holds, so the hand-back runs on a thread of its own.
    global _hand_back_thread, _stop_began
    mark_stopping()
    if _stop_began is None:
        _stop_began = time.monotonic()
    monitor = _monitor
    if monitor is None or _hand_back_thread is not None:
        return
    _hand_back_thread = threading.Thread(
        target=_hand_back_now, args=(monitor,), name="inertia-id hand-back", daemon=True
    )
    _hand_back_thread.start()


@worker_shutdown.connect
def _stop_monitor(**_kwargs: Any) -> None:
    global _monitor
    deadline = (_stop_began if _stop_began is not None else time.monotonic()) + STOP_WAIT_S
    answered = True
    if _hand_back_thread is not None:
        _hand_back_thread.join(max(0.0, deadline - time.monotonic()))
        if _hand_back_thread.is_alive() and _monitor is not None:
            # Which part hangs: the database's (the lock's server is silent too: asking
            # it to unlock would wait LOCK_ANSWER_S more) or the broker's, after the
            # runs were re-queued (the database answered: it is asked to unlock).
            line, answered = _monitor.hand_back_unfinished(STOP_WAIT_S)
            logger.warning("%s", line)
    if _monitor is not None:
        # A release asked of a server silent so far would wait LOCK_ANSWER_S more (3 s,
        # past serve's grace behind a frozen proxy: 9.5 to 9.8 s in all).
        _monitor.stop(max(0.0, deadline - time.monotonic()), answered=answered)
        _monitor = None
