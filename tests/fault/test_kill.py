"""``kill -9``: of a worker mid-job, and of ``serve`` itself.

A worker killed outright is noticed by the other worker (its own row went quiet), its job
re-run from the start with a clean curve; a killed ``serve`` leaves nothing running (its
workers stop on their own and hand their job back), and the next ``serve`` on the same
data dir finishes the job and counts only its own workers.
"""

from __future__ import annotations

import os
import signal
from typing import Any

from faults import (
    Deployment,
    alive,
    assert_settled,
    children_of,
    processes_of,
    random_search,
    wait_for,
)

# A PPO search that writes a curve point every 16 steps, 6 points in all.
PPO_SEARCH: dict[str, Any] = {
    **random_search(96),
    "method": "ppo",
    "ppo": {"n_steps": 16, "batch_size": 8, "n_epochs": 1},
}


def test_a_worker_killed_mid_job_has_its_job_rerun_by_another(deployment: Deployment) -> None:
    serve = deployment.serve(workers=2)
    with serve.client() as client:
        scenario = deployment.scenario(client)
        job_id = deployment.submit(client, scenario, "search", PPO_SEARCH, seed=7)

        # Running and part-way through: some of its learning curve is stored.
        def part_way() -> bool:
            job = deployment.job(job_id)
            assert job.status in ("queued", "running"), (job.status, job.error)
            return job.status == "running" and bool(deployment.metrics(job_id))

        wait_for(part_way, 180, "the search did not start writing its curve", deployment.logs)
        victim = (deployment.job(job_id).worker or "").partition("@")[0]
        pid = serve.worker_pids()[victim]
        task_processes = children_of(pid)
        assert task_processes, f"worker {victim} (pid {pid}) has no task process"
        os.kill(pid, signal.SIGKILL)

        # Its task process does not run on unsupervised: the kernel kills it too.
        wait_for(
            lambda: not any(alive(p) for p in task_processes),
            30,
            f"task processes {task_processes} of the killed worker still alive",
            deployment.logs,
        )
        job = deployment.wait_job(job_id, timeout_s=300)

    assert job.status == "succeeded", (job.status, job.error, deployment.logs())
    assert (job.worker or "").partition("@")[0] != victim
    assert job.attempts == 2 and job.handbacks == 0, (job.attempts, job.handbacks)
    # The curve is the re-run's alone: one point per key and step, every rollout once.
    points = deployment.metrics(job_id)
    assert len(points) == len(set(points)), points
    steps = sorted(step for key, step in points if key == "mean_f1")
    assert steps == list(range(16, 96 + 1, 16)), steps
    assert_settled(deployment)


def test_a_killed_serve_leaves_no_process_and_the_next_serve_finishes_its_job(
    deployment: Deployment,
) -> None:
    first = deployment.serve(workers=1)
    with first.client() as client:
        scenario = deployment.scenario(client)
        job_id = deployment.submit(client, scenario, "search", random_search(6000), seed=3)
    deployment.wait_job(job_id, ("running",), timeout_s=120)
    workers = first.worker_pids()
    left = set(processes_of(deployment.data_dir)) - {first.process.pid}
    assert set(workers.values()) <= left and len(left) > len(workers), (workers, left)

    first.kill()
    # The workers are told (PR_SET_PDEATHSIG) and stop, and their task processes with them.
    deployment.wait_gone(90, "processes of the killed serve are still running")
    # Stopping, the worker handed its job back: queued again, and no attempt spent.
    job = deployment.job(job_id)
    assert job.status == "queued", (job.status, job.error, deployment.logs())
    assert job.attempts - job.handbacks == 0, (job.attempts, job.handbacks)

    second = deployment.serve(workers=1)
    job = deployment.wait_job(job_id, timeout_s=300)
    assert job.status == "succeeded", (job.status, job.error, deployment.logs())
    assert job.attempts - job.handbacks == 1, (job.attempts, job.handbacks)

    # /health counts the new serve's workers only, once the dead ones' rows go quiet.
    new = set(second.worker_pids())
    with second.client() as client:

        def only_new() -> bool:
            workers = client.get("/health").json()["workers"]
            return {n.partition("@")[0] for n in workers["names"]} == new and workers[
                "count"
            ] == len(new)

        wait_for(only_new, 30, "/health still counts the killed serve's workers", second.log)
    assert_settled(deployment)
