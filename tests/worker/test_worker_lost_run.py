"""A task process killed mid-job (``kill -9``, the OOM killer): its worker re-queues or
fails the job at once, naming the signal, instead of waiting for the heartbeat timeout.
"""

from __future__ import annotations

import os
import signal
from typing import TYPE_CHECKING, Any

from service_support import wait_for
from test_worker_replacement import REPLACED_JOB_TIMEOUT_S, _children

if TYPE_CHECKING:
    from conftest import Service, WorkerProcess

# A PPO search of many rollouts: minutes of work, so it is still running when killed.
ENDLESS_SEARCH: dict[str, Any] = {
    "method": "ppo",
    "sequence_length": 2,
    "timesteps": 1_000_000,
    "n_realisations": 5,
    "metric": "euclidean",
    "sakoe_chiba_radius": 2,
    "fuel_weight": 0.0,
    "patience_episodes": None,
    "max_sequences": 100_000,
    "ppo": {"n_steps": 16, "batch_size": 8, "n_epochs": 1},
}
#: Far beyond any wait below: only the worker's own report of the dead task process can
#: explain a job taken from its run within them (its main process beats on, so the
#: reaper's "worker lost" rule does not apply either).
HEARTBEAT_TIMEOUT_S = 3600
#: "It did not happen at all" guard for the worker's report (it comes within a second).
LOST_RUN_TIMEOUT_S = 90.0
KILLED = "task process killed by signal 9 (SIGKILL)"


def _kill_task_process_running(service: Service, worker: WorkerProcess, job_id: str) -> int:
    """SIGKILL the worker's task process once it runs the job; its pid."""
    service.wait_for(job_id, ("running",), timeout_s=REPLACED_JOB_TIMEOUT_S)
    (victim,) = wait_for(
        lambda: _children(worker.process.pid) if len(_children(worker.process.pid)) == 1 else None,
        30,
        f"worker {worker.name} has no single task process",
        worker.log,
    )
    os.kill(victim, signal.SIGKILL)
    return victim


def _history(service: Service, job_id: str, runs: int) -> list[dict[str, Any]] | None:
    history = service.job(job_id).attempt_history or []
    return history if len(history) >= runs else None


def test_a_killed_task_process_has_its_job_requeued_then_failed_at_once(
    deployment: Service,
) -> None:
    worker = deployment.start_worker(
        INERTIA_ID_HEARTBEAT_TIMEOUT_S=str(HEARTBEAT_TIMEOUT_S), INERTIA_ID_MAX_ATTEMPTS="2"
    )
    try:
        job_id = deployment.submit("search", ENDLESS_SEARCH, seed=53)
        first = _kill_task_process_running(deployment, worker, job_id)
        (lost,) = wait_for(
            lambda: _history(deployment, job_id, 1),
            LOST_RUN_TIMEOUT_S,
            f"job {job_id} not taken from its killed run",
            worker.log,
        )
        assert {k: lost[k] for k in ("attempt", "worker", "outcome", "cause", "then")} == {
            "attempt": 1,
            "worker": worker.name,
            "outcome": "lost",
            "cause": KILLED,
            "then": "re-queued",
        }, lost
        assert lost["reason"].startswith(f"{KILLED} while it ran the job, seen by its worker ")
        job = deployment.job(job_id)
        assert (job.status, job.attempts) in (("queued", 1), ("running", 2)), (
            job.status,
            job.attempts,
        )

        # The replacement task process runs it again; killed too, the job has had its
        # two attempts and fails, naming the signal.
        deployment.wait_for(job_id, ("running",), timeout_s=REPLACED_JOB_TIMEOUT_S)
        second = _kill_task_process_running(deployment, worker, job_id)
        assert second != first
        job = deployment.wait_for(job_id, ("failed",), timeout_s=LOST_RUN_TIMEOUT_S)
        assert job.attempts == 2, job.attempts
        assert job.error == f"{KILLED} (worker {worker.name}); gave up after 2 attempts"
        history = job.attempt_history or []
        assert [(run["attempt"], run["cause"], run["then"]) for run in history] == [
            (1, KILLED, "re-queued"),
            (2, KILLED, "failed"),
        ]
        assert worker.alive(), worker.log(4000)
    finally:
        worker.stop()
