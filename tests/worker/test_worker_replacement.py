"""A worker whose task process is replaced (killed outright, or retired after
``INERTIA_ID_WORKER_MAX_JOBS`` jobs) gets a new one that takes the next job.

The new task process warms up (imports the core, compiles the kernels: seconds, tens of
seconds on a loaded machine) before it tells Celery it is up; Celery's own wait for that,
4 s, used to kill it again and again, and the worker never ran another job.
"""

from __future__ import annotations

import mmap
import os
import signal
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import pytest
from service_support import wait_for

from app.api.health import health
from service.config import Settings
from worker import process

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


def _in_child(*steps: Callable[[], None], hold: bool = False) -> tuple[int, int]:
    """Fork a process (a task process, as the pool forks it) that runs ``steps`` and
    exits, or with ``hold`` waits until its pipe is closed; its pid and that pipe (-1
    without ``hold``)."""
    read, write = os.pipe()
    done_read, done_write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        try:
            os.close(write)
            os.close(done_read)
            for step in steps:
                step()
            os.close(done_write)
            if hold:
                os.read(read, 1)
        finally:
            os._exit(0)
    os.close(read)
    os.close(done_write)
    os.read(done_read, 1)  # its steps are done
    os.close(done_read)
    if hold:
        return pid, write
    os.close(write)
    os.waitpid(pid, 0)
    return pid, -1


def test_a_worker_is_cold_from_the_start_of_the_first_replacement_until_one_is_warm(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The shared pages a worker's main process maps before forking, fresh for this test.
    monkeypatch.setattr(process, "_WARM", mmap.mmap(-1, len(process._WARM)))
    monkeypatch.setattr(process, "_COLD_SINCE", mmap.mmap(-1, len(process._COLD_SINCE)))
    first, hold = _in_child(process.mark_starting, process.mark_warm, hold=True)
    assert process.warm() and process.cold_since() is None
    os.close(hold)  # it retires after its jobs
    os.waitpid(first, 0)
    # Gone, and its replacement not started yet: cold, since a moment not known here.
    assert not process.warm() and process.cold_since() is None
    before = time.time()
    _in_child(process.mark_starting)  # a replacement killed before it was warm
    since = process.cold_since()
    assert since is not None and before <= since <= time.time()
    # The next replacement: still cold since the first one started.
    _, hold = _in_child(process.mark_starting, hold=True)
    assert process.cold_since() == since
    os.close(hold)
    _, hold = _in_child(process.mark_starting, process.mark_warm, hold=True)
    assert process.warm() and process.cold_since() is None
    os.close(hold)


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


def test_health_stays_ok_while_a_retired_task_process_is_replaced(deployment: Service) -> None:
    """After a routine job the task process retires and its replacement warms up for
    seconds; a job queued meanwhile waits for it. /health called the worker gone and the
    service "degraded" for that while (after every job, with one worker); now it lists it
    as warming and says "ok", and the queued job runs as soon as it is warm."""
    # Beats every 0.5 s: /health's window (1.5 s) is shorter than any warm-up, so before
    # the worker left the list every time. A long timeout: a warm-up on a loaded machine
    # (38 s measured) stays within the warming limit.
    beats = {"INERTIA_ID_HEARTBEAT_INTERVAL_S": "0.5", "INERTIA_ID_HEARTBEAT_TIMEOUT_S": "300"}
    worker = deployment.start_worker(INERTIA_ID_WORKER_MAX_JOBS="1", **beats)
    settings = Settings(
        INERTIA_ID_DATA_DIR=deployment.settings.data_dir,
        DATABASE_URL=deployment.settings.database_url,
        BROKER_URL=deployment.settings.broker_url,
        **beats,
    )
    try:
        _run_one(deployment, seed=5)
        waiting = deployment.submit("train", TINY_TRAIN, seed=6)
        seen = []
        # Until the replacement is warm and has taken the job.
        deadline = time.monotonic() + REPLACED_JOB_TIMEOUT_S
        while deployment.job(waiting).status == "queued" and time.monotonic() < deadline:
            report = health(settings, deployment.db, deployment.celery).model_dump()
            workers = report["workers"]
            seen.append(
                (
                    report["status"],
                    workers["names"],
                    [w["name"] for w in workers.get("warming", [])],
                    workers.get("detail") or report["queue"]["detail"],
                )
            )
            time.sleep(0.1)
        job = deployment.wait_for(waiting, timeout_s=REPLACED_JOB_TIMEOUT_S)
        assert job.status == "succeeded", (job.status, job.error, deployment.logs())
        not_ok = [s for s in seen if s[0] != "ok" or s[1] != [worker.name]]
        assert not not_ok, (len(not_ok), len(seen), not_ok[:3])
        # The replacement's warm-up was seen as such, not missed between two polls.
        assert any(s[2] == [worker.name] for s in seen), seen
    finally:
        worker.stop()
