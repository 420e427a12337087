"""The one task: run the job whose id the message carries.

The message is only a pointer; everything about the job is read from its row, and every
outcome written back to it (see :mod:`worker.runner`).
"""

from __future__ import annotations

import os
from typing import Any

from service.config import get_settings
from service.queue import RUN_JOB_TASK

from .celery_app import celery
from .monitor import may_claim
from .process import stopping
from .request import RunJobRequest
from .runner import execute_job

__all__ = ["run_job"]


# A run whose task process dies is taken from its job at once (worker.request).
@celery.task(name=RUN_JOB_TASK, bind=True, Request=RunJobRequest)
def run_job(self: Any, job_id: str) -> str:
    """Claim job ``job_id``, run it, and store its outcome; returns the status it ended in.

    A message for a job that is not queued any more (finished, cancelled, or claimed by
    another delivery of the same message) does nothing.
    """
    worker_name = self.request.hostname or f"celery@{os.uname().nodename}"
    return execute_job(
        job_id,
        settings=get_settings(),
        worker_name=worker_name,
        stopping=stopping,
        may_claim=may_claim,
    )
