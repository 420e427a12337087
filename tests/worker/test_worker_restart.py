"""A worker killed whole (``kill -9`` of its process group) and started again under the
same name, as docker restarts a container (it keeps the hostname): the new process is a
new incarnation, and the job the dead one ran is taken at once, with that cause, not
left "running" until the heartbeat timeout blames a task process. A second *live*
worker started under the same name by mistake leaves the first one's job alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from service_support import wait_for
from test_worker_lost_run import ENDLESS_SEARCH, HEARTBEAT_TIMEOUT_S, LOST_RUN_TIMEOUT_S
from test_worker_replacement import REPLACED_JOB_TIMEOUT_S

from service.store import WorkerRow

if TYPE_CHECKING:
    from conftest import Service

RESTARTED = "worker restarted"
QUICK_SEARCH: dict[str, Any] = {
    "method": "random",
    "sequence_length": 2,
    "timesteps": 40,
    "n_realisations": 3,
    "metric": "euclidean",
}


def _worker_row(service: Service, name: str) -> WorkerRow:
    with service.db.session() as session:
        row = session.get(WorkerRow, name)
        assert row is not None, name
        return row


def test_a_worker_restarted_under_its_name_takes_its_dead_run_at_once(
    deployment: Service,
) -> None:
    # The heartbeat timeout is far beyond the waits below: only the restart can explain
    # the job taken from its run within them.
    env = {"INERTIA_ID_HEARTBEAT_TIMEOUT_S": str(HEARTBEAT_TIMEOUT_S)}
    first = deployment.start_worker(**env)
    prefix = first.name.partition("@")[0]
    job_id = deployment.submit("search", ENDLESS_SEARCH, seed=61)
    deployment.wait_for(job_id, ("running",), timeout_s=REPLACED_JOB_TIMEOUT_S)
    with deployment.db.session() as session:
        # A stale stop mark, as a worker that was once told to stop and died left it.
        row = session.get(WorkerRow, first.name)
        assert row is not None
        row.stopping_since = row.last_seen_at
        before = _worker_row(deployment, first.name)
    first.kill()
    again = deployment.start_worker(prefix=prefix, **env)
    try:
        assert again.name == first.name
        history = wait_for(
            lambda: deployment.job(job_id).attempt_history or None,
            LOST_RUN_TIMEOUT_S,
            f"job {job_id} not taken from its dead run",
            again.log,
        )
        (lost,) = history
        assert {k: lost[k] for k in ("attempt", "worker", "outcome", "cause", "then")} == {
            "attempt": 1,
            "worker": first.name,
            "outcome": "lost",
            "cause": RESTARTED,
            "then": "re-queued",
        }, lost
        assert lost["reason"].startswith(
            f"worker {first.name} restarted; its earlier process was lost"
        ), lost
        row = _worker_row(deployment, first.name)
        assert row.started_at > before.started_at
        assert row.stopping_since is None
        assert row.incarnation != before.incarnation
        # The restarted worker runs it again, under its own incarnation.
        job = deployment.wait_for(job_id, ("running",), timeout_s=REPLACED_JOB_TIMEOUT_S)
        assert (job.attempts, job.worker_incarnation) == (2, row.incarnation)
    finally:
        again.kill()


def test_a_live_worker_of_the_same_name_keeps_its_job(deployment: Service) -> None:
    env = {"INERTIA_ID_HEARTBEAT_TIMEOUT_S": str(HEARTBEAT_TIMEOUT_S)}
    first = deployment.start_worker(**env)
    prefix = first.name.partition("@")[0]
    job_id = deployment.submit("search", ENDLESS_SEARCH, seed=62)
    deployment.wait_for(job_id, ("running",), timeout_s=REPLACED_JOB_TIMEOUT_S)
    held_by = deployment.job(job_id).worker_incarnation
    # Up at its first beat (a fresh row of its own incarnation), warm or not: from its
    # next beat the row is the live first worker's again, by design, so a twin still
    # warming at its first beat (a loaded CI) never showed warm there. The probe below
    # runs on it (the first is busy), so it is warm by the end.
    twin = deployment.start_worker(prefix=prefix, warm=False, **env)
    try:
        # The twin's monitor has had its first ticks (each takes the dead runs first)
        # once a job sent after its start has run; the first's job is still its own.
        probe = deployment.submit("search", QUICK_SEARCH, seed=63)
        deployment.wait_for(probe, ("succeeded",), timeout_s=REPLACED_JOB_TIMEOUT_S)
        job = deployment.job(job_id)
        assert (job.status, job.attempts, job.worker_incarnation) == ("running", 1, held_by)
        assert not job.attempt_history, job.attempt_history
    finally:
        twin.kill()
        first.kill()
