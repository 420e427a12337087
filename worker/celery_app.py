"""The worker's Celery app: the queue seam of :mod:`service.queue` plus the worker-side settings.

Start a worker with::

    celery -A worker.celery_app worker --concurrency=1 --loglevel=INFO

and scale out by starting more of them against PostgreSQL and Redis::

    DATABASE_URL=postgresql+psycopg://... BROKER_URL=redis://... \\
        celery -A worker.celery_app worker --concurrency=1 -n worker2@%h
"""

from __future__ import annotations

from typing import Any

from service.config import settings_or_exit
from service.queue import make_celery

__all__ = ["celery"]

# A bad setting ends the worker's start with one line naming it, not a traceback.
settings = settings_or_exit("inertia-id worker")
celery = make_celery(settings)

_worker_conf: dict[str, Any] = {
    # One job at a time per process, nothing reserved that a busy worker would sit on.
    "worker_prefetch_multiplier": 1,
    # The task process is warm (the core imported once, see worker.process) and runs job
    # after job; it is replaced after many jobs, or after a job that left it large, so
    # that a leak cannot grow without bound.
    "worker_max_tasks_per_child": settings.worker_max_jobs_per_process,
    "worker_max_memory_per_child": settings.worker_max_memory_mb * 1024,
    # A task process reports "up" to the worker only after its warm-up (see
    # worker.process), and Celery kills a new one that has not reported in within this
    # many seconds (4 s by default: less than the warm-up, so every replacement was
    # killed in turn). Task processes started with the worker are not timed; those that
    # replace one (killed, or retired after the jobs or memory above) are.
    "worker_proc_alive_timeout": settings.worker_start_timeout_s,
    "task_acks_late": True,
    "task_reject_on_worker_lost": True,
    # A task process that died mid-job is reported (WorkerLostError) only after the pool
    # waits this long for a result it may have sent before dying (Celery's default: 10 s);
    # the worker then takes the run from its job (worker.request). Our results are in the
    # database, not in that message: a report that comes too soon for a job that did
    # finish finds it finished and does nothing (its message, requeued, too).
    "worker_lost_wait": 1.0,
    "include": ["worker.tasks"],
}
if settings.broker_url.startswith("filesystem://"):
    # kombu keeps fanout bindings in a "control" folder relative to the working directory
    # unless told otherwise; keep it with the other broker folders.
    options = dict(celery.conf.broker_transport_options or {})
    options.setdefault("control_folder", str(settings.broker_dir / "control"))
    _worker_conf["broker_transport_options"] = options
celery.conf.update(_worker_conf)

# The worker's own heartbeat, reaper, re-sender and hand-back hang on the worker's
# signals; its task processes start warm and die with it.
from . import monitor, process  # noqa: E402, F401

process.stop_with_launcher()
process.use_launcher_temp_dir()
