"""A worker started against a database it cannot reach (a PostgreSQL URL to a port
nobody listens on, a SQLite path that is a folder), on both shapes.

Before: it took the job's message from the broker and the task failed with a traceback
(``OperationalError: connection ... refused``), its message spent (acknowledged); on
stop it logged "could not hand the running job back" with another traceback. The job
waited for the re-sender to send it again. Now the message goes back to the broker
untouched, with one line naming the database (password masked) and the cause, and the
next worker that reaches the database runs the job from that same message.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from service_support import free_port

if TYPE_CHECKING:
    from conftest import Service, WorkerProcess

TRAIN = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean", "n_realisations": 5}


def _unreachable_url(deployment: Service) -> str:
    if deployment.kind == "filesystem":
        # A folder where the file goes: SQLite cannot open it.
        folder = deployment.root / "not-a-database"
        folder.mkdir(exist_ok=True)
        return f"sqlite:///{folder}"
    return f"postgresql+psycopg://postgres:s3cret@127.0.0.1:{free_port()}/inertia_id"


def _wait_for_log(worker: WorkerProcess, *needles: str, timeout_s: float = 90.0) -> str:
    """The worker's log once it has any of ``needles``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        text = worker.log_path.read_text(errors="replace")
        if any(needle in text for needle in needles):
            return text
        time.sleep(0.2)
    raise AssertionError(f"none of {needles!r} logged\n{worker.log(6000)}")


def test_a_worker_that_cannot_reach_its_database_hands_the_job_back_untouched(
    deployment: Service,
) -> None:
    job_id = deployment.submit("train", TRAIN, seed=7)
    sent_at = deployment.job(job_id).sent_at
    url = _unreachable_url(deployment)
    cut_off = deployment.spawn_worker(DATABASE_URL=url)
    try:
        # The task took the message and tried the database (before: it failed).
        _wait_for_log(cut_off, "cannot reach its database", "raised unexpected")
    finally:
        cut_off.stop()
    log = cut_off.log_path.read_text(errors="replace")
    assert "Traceback" not in log, cut_off.log(8000)
    assert "could not hand the running job back" not in log, cut_off.log(8000)
    assert "s3cret" not in log, cut_off.log(8000)
    [line] = {line for line in log.splitlines() if "cannot reach its database" in line}
    shown = url.replace("s3cret", "***") if deployment.kind == "redis" else url.split("///")[1]
    assert shown in line, line
    # Untouched: still queued, never started, its message not re-sent.
    job = deployment.job(job_id)
    assert (job.status, job.attempts, job.sent_at) == ("queued", 0, sent_at)
    deployment.start_worker()
    job = deployment.wait_for(job_id)
    assert (job.status, job.attempts, job.error) == ("succeeded", 1, None), deployment.logs()
    # Run from the message the cut-off worker handed back, not from one sent again.
    assert job.sent_at == sent_at
