"""A worker whose task process is replaced (killed outright, or retired after
``INERTIA_ID_WORKER_MAX_JOBS`` jobs) gets a new one that takes the next job.

The new task process warms up (imports the core, compiles the kernels: seconds, tens of
seconds on a loaded machine) before it tells Celery it is up; Celery's own wait for that,
4 s, used to kill it again and again, and the worker never ran another job.
"""

from __future__ import annotations

import os
import signal
from typing import TYPE_CHECKING, Any

from service_support import wait_for

if TYPE_CHECKING:
    from conftest import Service, WorkerProcess

# A tiny training: well under a second of work.
TINY_TRAIN: dict[str, Any] = {
    "sequence": [[4, 4, 4, 0, 0, 0]] * 4,
    "kind": "nearest-centroid",
    "metric": "euclidean",
    "n_realisations": 3,
}
#: "It did not happen at all" guard: a replaced task process warms up in 7-40 s.
REPLACED_JOB_TIMEOUT_S = 150.0


def _children(pid: int) -> list[int]:
    """Live direct children of ``pid`` (a worker's task processes)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                # "pid (comm) state ppid ...": comm may hold spaces and parentheses.
                fields = stat.read().rpartition(")")[2].split()
        except (OSError, ValueError):
            continue
        if len(fields) >= 2 and fields[1] == str(pid) and fields[0] not in ("Z", "X"):
            found.append(int(entry))
    return found


def _run_one(service: Service, seed: int) -> None:
    job_id = service.submit("train", TINY_TRAIN, seed=seed)
    job = service.wait_for(job_id, timeout_s=REPLACED_JOB_TIMEOUT_S)
    assert job.status == "succeeded", (job.status, job.error, service.logs())


def _task_process(worker: WorkerProcess) -> int:
    found: list[int] = []

    def one() -> bool:
        found[:] = _children(worker.process.pid)
        return len(found) == 1

    wait_for(one, 30, f"worker {worker.name} has no single task process", worker.log)
    return found[0]


def test_a_killed_task_process_is_replaced_and_the_next_job_runs(deployment: Service) -> None:
    worker = deployment.start_worker()
    try:
        _run_one(deployment, seed=1)
        victim = _task_process(worker)
        os.kill(victim, signal.SIGKILL)
        wait_for(
            lambda: victim not in _children(worker.process.pid),
            30,
            f"task process {victim} survived",
            worker.log,
        )
        _run_one(deployment, seed=2)
        assert worker.alive(), worker.log(4000)
        assert "Timed out waiting for UP message" not in worker.log(100_000)
    finally:
        worker.stop()


def test_a_task_process_retired_after_its_jobs_is_replaced(deployment: Service) -> None:
    worker = deployment.start_worker(INERTIA_ID_WORKER_MAX_JOBS="1")
    try:
        first = _task_process(worker)
        _run_one(deployment, seed=3)
        _run_one(deployment, seed=4)
        # The second job ran in a new task process: the first retired after its job.
        assert _task_process(worker) != first
        assert "Timed out waiting for UP message" not in worker.log(100_000)
    finally:
        worker.stop()
