"""The one task: run the job whose id the message carries.

The message is only a pointer; everything about the job is read from its row, and every
outcome written back to it (see :mod:`worker.runner`).
"""

from __future__ import annotations

import logging
import os
from typing import Any

from celery.exceptions import Reject

from service.config import get_settings
from service.queue import RUN_JOB_TASK

from .celery_app import celery
from .monitor import may_claim
from .process import stopping
from .request import RunJobRequest
from .runner import HANDED_BACK, execute_job

__all__ = ["HandedBack", "run_job"]


class HandedBack(Reject):
    """The job's message goes back to the broker untouched: the worker could not reach
    its database (said in one line by :mod:`worker.runner`)."""


class _WithoutHandBackTraceback(logging.Filter):
    """Celery logs every rejected message with the traceback of the ``Reject``; a hand-back
    is no fault, and the runner has said why in one line."""

    def filter(self, record: logging.LogRecord) -> bool:
        return not (record.exc_info and isinstance(record.exc_info[1], HandedBack))


logging.getLogger("celery.app.trace").addFilter(_WithoutHandBackTraceback())


# A run whose task process dies is taken from its job at once (worker.request).
@celery.task(name=RUN_JOB_TASK, bind=True, Request=RunJobRequest)
def run_job(self: Any, job_id: str) -> str:
    """Claim job ``job_id``, run it, and store its outcome; returns the status it ended in.

    A message for a job that is not queued any more (finished, cancelled, or claimed by
    another delivery of the same message) does nothing.
    """
    worker_name = self.request.hostname or f"celery@{os.uname().nodename}"
    status = execute_job(
        job_id,
        settings=get_settings(),
        worker_name=worker_name,
        stopping=stopping,
        may_claim=may_claim,
    )
    if status == HANDED_BACK:
        # Requeued, not acknowledged: before, the task failed with the driver's
        # traceback and its message was spent.
        raise HandedBack(f"job {job_id}: the database cannot be reached", requeue=True)
    return status
