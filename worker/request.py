"""The job task's request in the worker's main process: a run whose task process died is
dealt with at once.

When a task process dies while it runs a job (``kill -9``, the kernel's OOM killer, a
crash), Celery's pool tells the worker's main process within a second, as a
``WorkerLostError`` ("Worker exited prematurely: signal 9 (SIGKILL)") handed to the
request's ``on_failure``. The job's row still says "running", and before only the
reaper saw it, once the run's heartbeat was older than the heartbeat timeout (60 s),
recording the cause as "heartbeat missed". Here the worker takes the run from the job
at once (:func:`worker.reaper.take_lost_run`, on a thread of its own: the main process's
loop must not wait on the database), naming how the process died.

Celery's ``task_failure`` signal is not sent for this: with ``task_reject_on_worker_lost``
the message is rejected and requeued instead, so the hook is a custom request class,
Celery's documented seam for a task's failure in the main process.
"""

from __future__ import annotations

import logging
import re
import signal
import threading
from datetime import datetime
from typing import Any

from billiard.einfo import ExceptionWithTraceback
from billiard.exceptions import WorkerLostError
from celery.worker.request import Request

from service.store.models import utcnow

__all__ = ["RunJobRequest", "lost_cause", "take_lost_run_soon"]

logger = logging.getLogger(__name__)

_SIGNAL = re.compile(r"\bsignal (\d+)")
_EXIT_CODE = re.compile(r"\bexitcode (-?\d+)")


def lost_cause(error: BaseException) -> str:
    """How the task process died, from billiard's ``WorkerLostError`` text:
    "task process killed by signal 9 (SIGKILL)", "task process exited with code 1"."""
    text = str(error)
    if match := _SIGNAL.search(text):
        number = int(match.group(1))
        try:
            return f"task process killed by signal {number} ({signal.Signals(number).name})"
        except ValueError:
            return f"task process killed by signal {number}"
    if match := _EXIT_CODE.search(text):
        return f"task process exited with code {match.group(1)}"
    return "task process lost"


def _take_lost_run(job_id: str, worker: str, lost_at: datetime, error: BaseException) -> None:
    from . import monitor
    from .reaper import take_lost_run

    current = monitor.current()
    if current is None:
        logger.warning("job %s lost its task process; no monitor yet, the reaper will", job_id)
        return
    cause = lost_cause(error)
    message = " ".join(str(error).split())
    reason = (
        f"{cause} while it ran the job, seen by its worker {worker} at once "
        f"({type(error).__name__}: {message})"
    )
    try:
        take_lost_run(
            current.settings,
            current.db,
            current.celery,
            job_id,
            worker=worker,
            lost_at=lost_at,
            cause=cause,
            reason=reason,
        )
    except Exception:
        logger.exception(
            "could not re-queue job %s after its task process died; the reaper will", job_id
        )


def take_lost_run_soon(
    job_id: str, *, worker: str, lost_at: datetime, error: BaseException
) -> threading.Thread:
    """Take job ``job_id``'s run on ``worker`` from it on a thread of its own, now."""
    thread = threading.Thread(
        target=_take_lost_run,
        args=(job_id, worker, lost_at, error),
        name=f"inertia-id lost run {job_id}",
        daemon=True,
    )
    thread.start()
    return thread


class _WithoutLostRunTraceback(logging.Filter):
    """Celery logs a task process's death ("Task handler raised error: WorkerLostError(...
    signal 9 (SIGKILL)...)") with billiard's traceback, which names no fault of ours and
    read, after a ``kill -9``, as a crash the worker had not dealt with. The line and its
    cause stay; the traceback goes, and the worker says in one line what it did with the
    job (:func:`_take_lost_run`). Any other error keeps its traceback."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        if isinstance(error, ExceptionWithTraceback):
            error = error.exc
        if isinstance(error, WorkerLostError):
            record.exc_info = None
            record.exc_text = None
        return True


logging.getLogger("celery.worker.request").addFilter(_WithoutLostRunTraceback())


class RunJobRequest(Request):
    """Celery's request, which also takes a job from a run whose task process died."""

    def on_failure(
        self, exc_info: Any, send_failed_event: bool = True, return_ok: bool = False
    ) -> Any:
        lost_at = utcnow()
        error = exc_info.exception
        if isinstance(error, ExceptionWithTraceback):
            error = error.exc
        if isinstance(error, WorkerLostError) and self.args:
            try:
                take_lost_run_soon(
                    str(self.args[0]), worker=self.hostname, lost_at=lost_at, error=error
                )
            except Exception:
                logger.exception("could not start the hand-over of a lost run; the reaper will")
        return super().on_failure(
            exc_info, send_failed_event=send_failed_event, return_ok=return_ok
        )
