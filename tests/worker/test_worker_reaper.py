"""The reaper: stale running jobs are re-queued and re-sent, or ended with the reason."""

from __future__ import annotations

import base64
import json
from datetime import timedelta
from typing import TYPE_CHECKING

from app.db.jobs import reap_stale, touch_worker
from app.db.models import WorkerRow, utcnow
from app.queue import RUN_JOB_TASK, make_celery
from worker.reaper import reap_once

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
    job = store.job(spent)
    assert job.status == "failed" and job.finished_at is not None
    assert job.error is not None and "heartbeat" in job.error and "after 2 attempts" in job.error
    job = store.job(cancelled)
    assert job.status == "cancelled" and job.finished_at is not None
    assert store.job(alive).status == "running"
    assert store.job(queued).status == "queued"
    assert store.job(done).status == "succeeded"

    # A second pass has nothing left to do.
    with store.db.session() as session:
        assert reap_stale(session, timeout_s=TIMEOUT_S, max_attempts=2) == ([], [])


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


def test_a_requeued_job_the_broker_refuses_is_failed_not_left_waiting(store: Store) -> None:
    retry = _running(store, beat_age_s=600)
    unreachable = store.settings.model_copy(update={"broker_url": "redis://127.0.0.1:1/0"})
    celery = make_celery(unreachable)
    celery.conf.broker_connection_timeout = 0.5
    celery.conf.task_publish_retry_policy = {"max_retries": 0}

    report = reap_once(store.settings, store.db, celery)

    assert report.requeued == [] and report.failed == [retry]
    job = store.job(retry)
    assert job.status == "failed"
    assert job.error is not None and "re-sending it to the broker failed" in job.error


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
