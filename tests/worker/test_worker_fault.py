"""A worker killed mid-job: the job is re-run by the next worker, nothing else is touched."""

from __future__ import annotations

import time
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

from sqlalchemy import select

from service.store import ClassifierRow, JobRow
from service.store.jobs import add_metrics, config_hash
from service.store.models import utcnow

if TYPE_CHECKING:
    from conftest import Service

TRAIN = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean", "n_realisations": 5}
# A PPO search that reports every 16 steps and runs for a few seconds.
LONG_SEARCH = {
    "method": "ppo",
    "sequence_length": 2,
    "timesteps": 320,
    "n_realisations": 5,
    "metric": "euclidean",
    "sakoe_chiba_radius": 2,
    "fuel_weight": 0.0,
    "patience_episodes": None,
    "max_sequences": 100_000,
    "ppo": {"n_steps": 16, "batch_size": 8, "n_epochs": 1},
}


def _snapshot(service: Service, job_id: str) -> dict[str, Any]:
    """Everything stored about a finished job: its row, metrics and classifier."""
    with service.db.session() as session:
        job = session.get(JobRow, job_id)
        classifiers = session.scalars(
            select(ClassifierRow).where(ClassifierRow.job_id == job_id)
        ).all()
        return {
            "job": {c.name: getattr(job, c.name) for c in JobRow.__table__.columns},
            "classifiers": [
                {c.name: getattr(row, c.name) for c in ClassifierRow.__table__.columns}
                for row in classifiers
            ],
            "metrics": service.metrics(job_id),
        }


def _finished_train_job(service: Service) -> str:
    """A train job that ended before the fault, with its metrics and classifier."""
    with service.db.session() as session:
        job = JobRow(
            type="train",
            scenario_id=service.scenario_id,
            params=TRAIN,
            config_hash=config_hash("train", service.scenario_id, TRAIN, 1),
            seed=1,
            status="succeeded",
            attempts=1,
            worker="earlier@host",
            progress=1.0,
            started_at=utcnow(),
            finished_at=utcnow(),
            heartbeat_at=utcnow(),
        )
        session.add(job)
        session.flush()
        classifier = ClassifierRow(
            job_id=job.id,
            scenario_id=service.scenario_id,
            metric="euclidean",
            f1=1.0,
            accuracy=1.0,
            sequence=TRAIN["sequence"],
            candidate_names=["a", "b"],
            confusion=[[5, 0], [0, 5]],
            document="{}",
            sha256="0" * 64,
        )
        session.add(classifier)
        session.flush()
        job.result = {"classifier_id": classifier.id, "f1": 1.0, "accuracy": 1.0}
        add_metrics(session, job.id, [("f1", 0, 1.0), ("accuracy", 0, 1.0)])
        return job.id


def test_a_job_whose_worker_was_killed_is_rerun_and_nothing_else_changes(
    deployment: Service,
) -> None:
    finished = _finished_train_job(deployment)
    before = _snapshot(deployment, finished)
    first = deployment.start_worker()

    job_id = deployment.submit("search", LONG_SEARCH, seed=7)
    # Running and part-way through: it has written some of its learning curve.
    deployment.wait_for(job_id, ("running",), timeout_s=60)
    while not deployment.metrics(job_id):
        assert deployment.job(job_id).status == "running", deployment.logs()
        time.sleep(0.05)
    first.kill()
    orphan = deployment.job(job_id)
    assert orphan.status == "running" and orphan.attempts == 1
    assert orphan.worker == first.name

    # A fresh worker with a short timeout finds the stale heartbeat, re-queues the job
    # and runs it again.
    second = deployment.start_worker(
        INERTIA_ID_HEARTBEAT_TIMEOUT_S="3", INERTIA_ID_HEARTBEAT_INTERVAL_S="0.5"
    )
    job = deployment.wait_for(job_id, timeout_s=120)
    assert job.status == "succeeded", (job.status, job.error, deployment.logs())
    assert job.attempts == 2 and job.worker == second.name and job.error is None
    # The first run is not overwritten by the second: when it started, that its worker
    # was lost, and what followed.
    (lost,) = job.attempt_history or []
    assert (lost["attempt"], lost["worker"], lost["outcome"], lost["cause"], lost["then"]) == (
        1,
        first.name,
        "lost",
        "worker lost",
        "re-queued",
    )
    assert orphan.started_at is not None
    assert datetime.fromisoformat(lost["started_at"]) == orphan.started_at.replace(
        tzinfo=orphan.started_at.tzinfo or UTC
    )
    result = job.result or {}
    assert result["method"] == "ppo" and result["timesteps"] == 320

    # The re-run's curve replaced the dead run's: one point per key and step, and the
    # steps are the re-run's rollouts.
    metrics = deployment.metrics(job_id)
    keys_steps = [(key, step) for key, step, _ in metrics]
    assert len(keys_steps) == len(set(keys_steps))
    steps = sorted({step for key, step, _ in metrics if key == "mean_f1"})
    assert steps == list(range(16, 320 + 1, 16))

    assert _snapshot(deployment, finished) == before
