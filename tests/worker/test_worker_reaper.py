"""The reaper: stale running jobs are re-queued and re-sent, or ended with the reason."""

from __future__ import annotations

import base64
import json
import re
import time
from datetime import UTC, datetime, timedelta
from typing import TYPE_CHECKING, Any

import pytest
from celery import Celery

from service.queue import RUN_JOB_TASK, make_celery
from service.store.jobs import (
    beat_worker,
    claim,
    finish,
    hand_back,
    heartbeat,
    owns,
    reap_stale,
    set_progress,
    touch_worker,
)
from service.store.models import JobRow, WorkerRow, utcnow
from worker.reaper import hand_back_jobs, idle_workers, reap_once, resend_once, take_lost_run
from worker.request import lost_cause

if TYPE_CHECKING:
    from conftest import Store

TIMEOUT_S = 60.0


def _running(store: Store, *, beat_age_s: float, attempts: int = 1, cancel: bool = False) -> str:
    beat = utcnow() - timedelta(seconds=beat_age_s)
    return store.add_job(
        status="running",
        worker="gone@host",
        attempts=attempts,
        started_at=beat,
        heartbeat_at=beat,
        cancel_requested=cancel,
        progress=0.55,
    )


def test_stale_jobs_are_requeued_failed_or_cancelled_and_live_ones_left_alone(store: Store) -> None:
    retry = _running(store, beat_age_s=600, attempts=1)
    spent = _running(store, beat_age_s=600, attempts=2)
    cancelled = _running(store, beat_age_s=600, cancel=True)
    alive = _running(store, beat_age_s=5)
    queued = store.add_job()
    done = store.add_job(status="succeeded", attempts=1, result={"f1": 1.0})

    with store.db.session() as session:
        requeued, ended = reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=2)
    assert requeued == [retry]
    assert sorted(ended) == sorted([spent, cancelled])

    job = store.job(retry)
    assert job.status == "queued" and job.worker is None and job.attempts == 1
    assert job.error is not None and "re-queued" in job.error and "gone@host" in job.error
    assert job.progress == 0.0  # a queued job is not 55 % done: its next run restarts
    job = store.job(spent)
    assert job.status == "failed" and job.finished_at is not None
    assert job.error is not None and "heartbeat" in job.error and "after 2 attempts" in job.error
    # The last heartbeat's time carries its zone, as every time the service shows.
    assert re.search(r"\(last at \d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d+Z\)", job.error), job.error
    job = store.job(cancelled)
    assert job.status == "cancelled" and job.finished_at is not None
    assert store.job(alive).status == "running"
    assert store.job(queued).status == "queued"
    assert store.job(done).status == "succeeded"

    # A second pass has nothing left to do.
    with store.db.session() as session:
        assert reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=2) == ([], [])


def test_a_job_given_up_after_one_attempt_says_attempt(store: Store) -> None:
    """With INERTIA_ID_MAX_ATTEMPTS=1 a lost run ended its job "gave up after 1 attempts"."""
    spent = _running(store, beat_age_s=600, attempts=1)
    with store.db.session() as session:
        assert reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=1) == ([], [spent])
    error = store.job(spent).error
    assert error is not None and error.endswith("; gave up after 1 attempt"), error


def _sent_job_ids(store: Store) -> list[str]:
    """Job ids of the run_job messages waiting in the filesystem broker's folder."""
    ids = []
    for path in sorted((store.settings.broker_dir / "queue").glob("*.msg")):
        message = json.loads(path.read_text())
        assert message["headers"]["task"] == RUN_JOB_TASK
        args, _kwargs, _embed = json.loads(base64.b64decode(message["body"]))
        ids.extend(args)
    return ids


def test_reap_once_sends_the_requeued_job_again(store: Store) -> None:
    retry = _running(store, beat_age_s=600)
    spent = _running(store, beat_age_s=600, attempts=2)
    settings = store.settings.model_copy(update={"heartbeat_timeout_s": TIMEOUT_S})

    report = reap_once(settings, store.db, make_celery(settings))

    assert report.requeued == [retry] and report.failed == [spent]
    assert _sent_job_ids(store) == [retry]


def _unreachable_celery(store: Store) -> Celery:
    unreachable = store.settings.model_copy(update={"broker_url": "redis://127.0.0.1:1/0"})
    celery = make_celery(unreachable)
    celery.conf.broker_connection_timeout = 0.5
    celery.conf.task_publish_retry_policy = {"max_retries": 0}
    return celery


def test_a_requeued_job_the_broker_refuses_waits_queued_and_is_sent_when_it_is_back(
    store: Store,
) -> None:
    retry = _running(store, beat_age_s=600)

    report = reap_once(store.settings, store.db, _unreachable_celery(store))

    assert report.requeued == [retry] and report.failed == []
    job = store.job(retry)
    assert job.status == "queued" and job.sent_at is None
    assert _sent_job_ids(store) == []
    # The broker is back: the re-sender sends it, once.
    settings = store.settings.model_copy(update={"unsent_grace_s": 0.0})
    celery = make_celery(settings)
    assert resend_once(settings, store.db, celery) == [retry]
    assert resend_once(settings, store.db, celery) == []
    assert _sent_job_ids(store) == [retry]
    assert store.job(retry).sent_at is not None


def test_a_job_never_sent_is_sent_after_the_grace_and_not_before(store: Store) -> None:
    fresh = store.add_job(status="queued")
    old = store.add_job(status="queued", created_at=utcnow() - timedelta(seconds=60))
    sent = store.add_job(
        status="queued",
        created_at=utcnow() - timedelta(seconds=60),
        sent_at=utcnow() - timedelta(seconds=1),
    )
    settings = store.settings.model_copy(update={"unsent_grace_s": 10.0})
    assert resend_once(settings, store.db, make_celery(settings)) == [old]
    assert _sent_job_ids(store) == [old]
    assert store.job(fresh).sent_at is None and store.job(sent).status == "queued"


def test_a_lost_message_is_sent_again_only_while_a_worker_is_idle(store: Store) -> None:
    long_ago = utcnow() - timedelta(seconds=600)
    lost = store.add_job(status="queued", created_at=long_ago, sent_at=long_ago)
    settings = store.settings.model_copy(update={"resend_after_s": 30.0})
    celery = make_celery(settings)
    # No live worker: nobody would take it; a message now would only pile up.
    assert idle_workers(settings, store.db) == 0
    assert resend_once(settings, store.db, celery) == []
    # One live worker, busy with another job: the queue is merely long.
    with store.db.session() as session:
        touch_worker(session, "w1@host", "filesystem://")
    busy = store.add_job(status="running", worker="w1@host", heartbeat_at=utcnow())
    assert idle_workers(settings, store.db) == 0
    assert resend_once(settings, store.db, celery) == []
    # The worker is idle and the message went out long ago: it was lost.
    with store.db.session() as session:
        session.get(JobRow, busy).status = "succeeded"  # type: ignore[union-attr]
    assert idle_workers(settings, store.db) == 1
    assert resend_once(settings, store.db, celery) == [lost]
    assert _sent_job_ids(store) == [lost]
    # Just sent: not again until resend_after_s has passed once more.
    assert resend_once(settings, store.db, celery) == []


def test_a_dead_workers_job_is_reaped_as_soon_as_the_worker_goes_quiet(store: Store) -> None:
    quiet = utcnow() - timedelta(seconds=30)
    with store.db.session() as session:
        touch_worker(session, "dead@host", "filesystem://")
        touch_worker(session, "alive@host", "filesystem://")
        session.get(WorkerRow, "dead@host").last_seen_at = quiet  # type: ignore[union-attr]
    dead = store.add_job(
        status="running", worker="dead@host", attempts=1, started_at=quiet, heartbeat_at=quiet
    )
    # Its heartbeat is as old, but its worker's main process beats: a busy job, not a death.
    starved = store.add_job(
        status="running", worker="alive@host", attempts=1, started_at=quiet, heartbeat_at=quiet
    )
    with store.db.session() as session:
        requeued, ended = reap_stale(
            session, timeout_s=TIMEOUT_S, max_attempts=2, worker_silence_s=15.0
        )
    assert requeued == [dead] and ended == []
    assert store.job(starved).status == "running"


def test_a_handed_back_job_is_queued_at_once_and_costs_no_attempt(store: Store) -> None:
    job_id = store.add_job(status="running", worker="w1@host", attempts=2, heartbeat_at=utcnow())
    other = store.add_job(status="running", worker="w2@host", attempts=1, heartbeat_at=utcnow())
    report = hand_back_jobs(
        store.settings, store.db, make_celery(store.settings), "w1@host", "first"
    )
    assert report == [job_id]
    job = store.job(job_id)
    assert job.status == "queued" and job.worker is None and job.handbacks == 1
    assert job.error is not None and "handed back" in job.error and job.sent_at is not None
    assert _sent_job_ids(store) == [job_id]
    assert store.job(other).status == "running"
    # Two runs started, one handed back: one attempt spent, so a dead run is re-queued.
    with store.db.session() as session:
        claimed = claim(session, job_id, "w3@host")
        assert claimed is not None and claimed.attempts == 3
        claimed.heartbeat_at = utcnow() - timedelta(seconds=600)
    with store.db.session() as session:
        requeued, _ended = reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=2)
    # attempts 3 - handbacks 1 = 2 spent: the second real failure ends it.
    assert requeued == []
    assert store.job(job_id).status == "failed"


def test_a_run_that_lost_its_job_writes_nothing_more(store: Store) -> None:
    job_id = store.add_job(status="queued")
    with store.db.session() as session:
        job = claim(session, job_id, "w1@host")
        assert job is not None
    with store.db.session() as session:
        assert owns(session, job_id, 1)
        set_progress(session, job_id, 0.5, 1)
        hand_back(session, "w1@host", "stopping")
    assert store.job(job_id).progress == 0.0  # queued again, from nothing
    with store.db.session() as session:
        assert not owns(session, job_id, 1)
        job = claim(session, job_id, "w2@host")
        assert job is not None and job.attempts == 2
    with store.db.session() as session:
        # The first run's late heartbeat, progress and finish touch the second run's row
        # not at all.
        heartbeat(session, job_id, 1)
        set_progress(session, job_id, 0.9, 1)
        assert not finish(session, job_id, "succeeded", result={"late": True}, attempt=1)
    job = store.job(job_id)
    assert job.status == "running" and job.progress == 0.0 and job.result is None


def test_touch_worker_inserts_then_moves_last_seen(store: Store) -> None:
    with store.db.session() as session:
        touch_worker(session, "w1@host", "filesystem://")
    with store.db.session() as session:
        first = session.get(WorkerRow, "w1@host")
        assert first is not None
        started, seen = first.started_at, first.last_seen_at
    with store.db.session() as session:
        touch_worker(session, "w1@host", "redis://127.0.0.1:6379/0")
    with store.db.session() as session:
        row = session.get(WorkerRow, "w1@host")
        assert row is not None
        assert row.started_at == started and row.last_seen_at > seen
        assert row.broker_url == "redis://127.0.0.1:6379/0"


def test_a_workers_beat_says_since_when_it_is_warming(store: Store) -> None:
    def warming_since() -> datetime | None:
        with store.db.session() as session:
            row = session.get(WorkerRow, "w1@host")
            assert row is not None
            since = row.warming_since
        # SQLite hands back naive UTC.
        return since if since is None or since.tzinfo else since.replace(tzinfo=UTC)

    began = utcnow() - timedelta(seconds=7)
    with store.db.session() as session:
        beat_worker(session, "w1@host", "filesystem://", warming_since=began)
    assert warming_since() == began
    # A task process's beat (mid-job) leaves it as the main process last said.
    with store.db.session() as session:
        touch_worker(session, "w1@host", "filesystem://")
    assert warming_since() == began
    with store.db.session() as session:
        beat_worker(session, "w1@host", "filesystem://", warming_since=None)
    assert warming_since() is None


def test_a_warming_worker_is_not_idle_for_the_re_sender(store: Store) -> None:
    # Its task process is being replaced: a message waits in the broker until the new
    # one is up. It is not lost, and is not sent again.
    long_ago = utcnow() - timedelta(seconds=600)
    waiting = store.add_job(status="queued", created_at=long_ago, sent_at=long_ago)
    settings = store.settings.model_copy(update={"resend_after_s": 30.0})
    celery = make_celery(settings)
    with store.db.session() as session:
        beat_worker(session, "w1@host", "filesystem://", warming_since=utcnow())
    assert idle_workers(settings, store.db) == 0
    assert resend_once(settings, store.db, celery) == []
    with store.db.session() as session:
        beat_worker(session, "w1@host", "filesystem://", warming_since=None)
    assert idle_workers(settings, store.db) == 1
    assert resend_once(settings, store.db, celery) == [waiting]


def test_a_heartbeat_during_a_hand_back_does_not_deadlock(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A job's heartbeat and its worker's hand-back take the same rows in the same order.

    The heartbeat locked the job's row, then the worker's; the hand-back the worker's,
    then the job's: on PostgreSQL the two deadlocked, and the stopping worker's job was
    left running (a graceful-restart test caught it). Here the heartbeat stops after its
    first statement, holding that row, while a hand-back starts; then it goes on.
    """
    import threading
    from types import SimpleNamespace

    import worker.context as context_module

    worker = "w1@host"
    with store.db.session() as session:
        touch_worker(session, worker, "filesystem://")
    job_id = store.add_job(status="running", worker=worker, attempts=1, heartbeat_at=utcnow())
    paused, resume = threading.Event(), threading.Event()

    def pausing(real: Any) -> Any:
        def first_statement_then_wait(*args: Any, **kwargs: Any) -> Any:
            done = real(*args, **kwargs)
            if not paused.is_set():
                paused.set()
                resume.wait(10)
            return done

        return first_statement_then_wait

    monkeypatch.setattr(context_module, "touch_worker", pausing(context_module.touch_worker))
    monkeypatch.setattr(context_module, "heartbeat", pausing(context_module.heartbeat))
    beating = SimpleNamespace(
        _db=store.db,
        spec=SimpleNamespace(id=job_id, attempt=1),
        worker_name=worker,
        settings=store.settings,
        # Well within its time limit: a plain heartbeat (past it, beat ends the job).
        time_left_s=lambda: 3600.0,
        rescore_grace_s=10.0,
        outcome_held=False,  # its handler still running
    )
    errors: list[BaseException] = []

    def run(work: Any) -> threading.Thread:
        def guarded() -> None:
            try:
                work()
            except BaseException as exc:  # a deadlock victim's OperationalError
                errors.append(exc)

        thread = threading.Thread(target=guarded)
        thread.start()
        return thread

    beat = run(lambda: context_module.JobContext.beat(beating))  # type: ignore[arg-type]
    assert paused.wait(10)
    back = run(
        lambda: hand_back_jobs(
            store.settings, store.db, make_celery(store.settings), worker, "first"
        )
    )
    time.sleep(1.5)  # the hand-back is now waiting on the row the heartbeat holds
    resume.set()
    beat.join(30)
    back.join(30)
    assert errors == []
    job = store.job(job_id)
    assert job.status == "queued" and job.handbacks == 1


def test_each_run_taken_from_a_job_is_recorded_not_overwritten(store: Store) -> None:
    """After a task process was killed (``kill -9``) the job was re-queued and its second
    run's claim overwrote ``started_at`` and cleared ``error``: only ``attempts: 2`` said a
    run had died. Each run taken from the job now stays in ``attempt_history``: when it
    started and last beat, when and why it was taken (its heartbeat alone stopped, its
    whole worker went quiet, its worker handed it back), its worker and what followed."""
    long_ago = utcnow() - timedelta(seconds=600)
    with store.db.session() as session:
        # Its main process still beats: the run's task process died.
        touch_worker(session, "alive@host", "filesystem://")
        touch_worker(session, "killed@host", "filesystem://")
        session.get(WorkerRow, "killed@host").last_seen_at = long_ago  # type: ignore[union-attr]
    job_id = store.add_job(
        status="running",
        worker="alive@host",
        attempts=1,
        started_at=long_ago,
        heartbeat_at=long_ago + timedelta(seconds=5),
    )

    def reap() -> tuple[list[str], list[str]]:
        with store.db.session() as session:
            return reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=2, worker_silence_s=15.0)

    def run_again(worker: str, *, stale: bool) -> datetime:
        with store.db.session() as session:
            job = claim(session, job_id, worker)
            assert job is not None and job.started_at is not None
            if stale:
                job.heartbeat_at = job.started_at = long_ago + timedelta(seconds=60)
            return job.started_at

    assert reap() == ([job_id], [])
    # A second run, handed back by its worker (told to stop), a third, whose worker died.
    second_started = run_again("alive@host", stale=False)
    with store.db.session() as session:
        hand_back(session, "alive@host", "worker alive@host was asked to stop")
    third_started = run_again("killed@host", stale=True)
    assert reap() == ([], [job_id])  # 3 runs, 1 handed back: 2 attempts spent

    job = store.job(job_id)
    assert job.status == "failed" and job.attempts == 3
    first, second, third = job.attempt_history or []
    assert {key: first[key] for key in ("attempt", "worker", "outcome", "cause", "then")} == {
        "attempt": 1,
        "worker": "alive@host",
        "outcome": "lost",
        "cause": "heartbeat missed",
        "then": "re-queued",
    }
    assert first["started_at"] == _iso(long_ago)
    assert first["last_heartbeat_at"] == _iso(long_ago + timedelta(seconds=5))
    assert first["ended_at"] > first["last_heartbeat_at"] and first["ended_at"].endswith("Z")
    assert first["reason"].startswith("heartbeat missed: the run's last heartbeat at ")
    assert "; its worker alive@host still reported at " in first["reason"]
    assert first["reason"].endswith("so the run's task process died or hung")
    assert (second["attempt"], second["outcome"], second["cause"], second["then"]) == (
        2,
        "handed back",
        "asked to stop",
        "re-queued",
    )
    assert second["started_at"] == _iso(second_started)
    assert second["reason"] == "handed back: worker alive@host was asked to stop"
    assert (third["attempt"], third["worker"], third["cause"], third["then"]) == (
        3,
        "killed@host",
        "worker lost",
        "failed",
    )
    assert third["started_at"] == _iso(third_started)
    assert third["reason"].startswith(
        f"worker lost: worker killed@host last reported at {_iso(long_ago)}"
    )


def _iso(moment: datetime) -> str:
    """As the store writes an instant: ISO-8601 in UTC with ``Z``."""
    aware = moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)
    return aware.isoformat().replace("+00:00", "Z")


KILLED = "task process killed by signal 9 (SIGKILL)"


def test_the_cause_names_how_the_task_process_died() -> None:
    from billiard.exceptions import WorkerLostError

    def cause(status: str) -> str:
        return lost_cause(WorkerLostError(f"Worker exited prematurely: {status} Job: 0."))

    assert cause("signal 9 (SIGKILL)") == KILLED
    assert cause("signal 11 (SIGSEGV)") == "task process killed by signal 11 (SIGSEGV)"
    assert cause("signal 99") == "task process killed by signal 99"
    assert cause("exitcode 1") == "task process exited with code 1"
    assert lost_cause(WorkerLostError("gone")) == "task process lost"


def test_a_task_process_death_is_logged_in_one_line_without_billiards_traceback() -> None:
    """Celery logs a task process's death ("Task handler raised error: WorkerLostError")
    with billiard's traceback, which an operator reads as a crash of ours after a
    ``kill -9`` the worker handles at once: the line and its cause stay, the traceback
    goes (another error's stays)."""
    import io
    import logging

    from billiard.einfo import ExceptionWithTraceback
    from billiard.exceptions import WorkerLostError

    import worker.request  # noqa: F401  (installs the filter)

    logger = logging.getLogger("celery.worker.request")
    written = io.StringIO()
    handler = logging.StreamHandler(written)
    logger.addHandler(handler)
    try:
        lost = WorkerLostError("Worker exited prematurely: signal 9 (SIGKILL) Job: 13.")
        # As Celery logs it: the lost error in the text, the error raised (billiard's
        # wrapper, or the error itself) as exc_info.
        for error in (lost, ExceptionWithTraceback(lost, "Traceback (most recent call last):")):
            try:
                raise error
            except BaseException:
                logger.error("Task handler raised error: %r", lost, exc_info=True)
        try:
            raise ValueError("a fault of the job's own")
        except ValueError:
            logger.error("Task handler raised error", exc_info=True)
    finally:
        logger.removeHandler(handler)
    lines = written.getvalue().splitlines()
    assert sum("signal 9 (SIGKILL)" in line for line in lines) == 2
    assert sum("Traceback" in line for line in lines) == 1  # the ValueError's alone
    assert "ValueError: a fault of the job's own" in lines[-1]


def test_a_run_whose_task_process_died_is_taken_at_once_and_only_once(store: Store) -> None:
    """The worker that saw its task process die re-queues the job by the reaper's rule
    (failed after max_attempts, cancelled when asked), names the signal, and sends its
    message; whichever of it and the reaper comes second finds nothing to take."""
    celery = make_celery(store.settings)
    started = utcnow() - timedelta(seconds=5)

    def running(**values: Any) -> str:
        values.setdefault("attempts", 1)
        return store.add_job(
            status="running", worker="w1@host", started_at=started, heartbeat_at=started, **values
        )

    def take(job_id: str, *, worker: str = "w1@host", lost_at: datetime | None = None) -> Any:
        return take_lost_run(
            store.settings,
            store.db,
            celery,
            job_id,
            worker=worker,
            lost_at=lost_at or utcnow(),
            cause=KILLED,
            reason=f"{KILLED} while it ran the job",
        )

    def reap() -> tuple[list[str], list[str]]:
        with store.db.session() as session:
            return reap_stale(session, timeout_s=1.0, max_attempts=2)

    retry, spent, cancelled = running(), running(attempts=2), running(cancel_requested=True)
    assert take(retry, worker="w2@host") is None  # another worker's run
    assert take(retry, lost_at=started - timedelta(seconds=1)) is None  # a later claim's
    assert take(retry) == "re-queued"
    assert take(retry) is None
    assert take(spent) == "failed"
    assert take(cancelled) == "cancelled"
    assert reap() == ([], [])  # nothing left for the reaper

    job = store.job(retry)
    assert (job.status, job.worker, job.progress) == ("queued", None, 0.0)
    assert job.sent_at is not None  # its message went again
    assert job.error == f"re-queued: {KILLED} (worker w1@host)"
    (lost,) = job.attempt_history or []
    assert (lost["attempt"], lost["worker"], lost["cause"], lost["then"]) == (
        1,
        "w1@host",
        KILLED,
        "re-queued",
    )
    assert lost["reason"] == f"{KILLED} while it ran the job"
    job = store.job(spent)
    assert job.status == "failed"
    assert job.error == f"{KILLED} (worker w1@host); gave up after 2 attempts"
    assert [run["then"] for run in job.attempt_history or []] == ["failed"]
    assert store.job(cancelled).status == "cancelled"

    # The reaper first (the worker's report came late): the run is taken once.
    late = running()
    assert reap() == ([late], [])
    assert take(late) is None
    assert [run["cause"] for run in store.job(late).attempt_history or []] == ["heartbeat missed"]


def test_a_worker_whose_task_process_is_not_replaced_ages_as_warming(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The main process beats on while no task process is warm. Until a replacement
    # starts (cold_since None) the warm-up was dated "now" at every beat, so a pool that
    # never started one stayed "warming 0 s", /health "ok", with no process to take a
    # job. Now it is dated from the first beat that saw none, and ages past the limit.
    from worker import monitor

    def warming_since() -> datetime | None:
        with store.db.session() as session:
            row = session.get(WorkerRow, "w1@host")
            assert row is not None
            since = row.warming_since
        return since if since is None or since.tzinfo else since.replace(tzinfo=UTC)

    beats = monitor.WorkerMonitor("w1@host", store.settings)
    try:
        monkeypatch.setattr(monitor, "warm", lambda: True)
        beats.tick()  # seen once warm
        assert warming_since() is None
        monkeypatch.setattr(monitor, "warm", lambda: False)
        monkeypatch.setattr(monitor, "cold_since", lambda: None)
        beats.tick()
        first = warming_since()
        assert first is not None
        time.sleep(0.01)
        beats.tick()
        assert warming_since() == first
        # A replacement starts: its warm-up is dated from its own start.
        started = time.time()
        monkeypatch.setattr(monitor, "cold_since", lambda: started)
        beats.tick()
        assert warming_since() == datetime.fromtimestamp(started, UTC)
        # Warm again, then gone with none started: dated from that beat, not the first.
        monkeypatch.setattr(monitor, "warm", lambda: True)
        beats.tick()
        assert warming_since() is None
        monkeypatch.setattr(monitor, "warm", lambda: False)
        monkeypatch.setattr(monitor, "cold_since", lambda: None)
        beats.tick()
        again = warming_since()
        assert again is not None and again > first
    finally:
        beats.stop()
