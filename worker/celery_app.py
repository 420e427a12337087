"""The worker's Celery app: the queue seam of :mod:`app.queue` plus the worker-side settings.

Start a worker with::

    celery -A worker.celery_app worker --concurrency=1 --loglevel=INFO

and scale out by starting more of them against PostgreSQL and Redis::

    DATABASE_URL=postgresql+psycopg://... BROKER_URL=redis://... \\
        celery -A worker.celery_app worker --concurrency=1 -n worker2@%h
"""

from __future__ import annotations

from typing import Any

from app.config import get_settings
from app.queue import make_celery

__all__ = ["celery"]

settings = get_settings()
celery = make_celery(settings)

_worker_conf: dict[str, Any] = {
    # One job at a time per process, nothing reserved that a busy worker would sit on.
    "worker_prefetch_multiplier": 1,
    # Each job gets a fresh process: torch and numba never carry state (threads, memory)
    # from one job into the next, and a leak dies with its job.
    "worker_max_tasks_per_child": 1,
    "task_acks_late": True,
    "task_reject_on_worker_lost": True,
    "include": ["worker.tasks"],
}
if settings.broker_url.startswith("filesystem://"):
    # kombu keeps fanout bindings in a "control" folder relative to the working directory
    # unless told otherwise; keep it with the other broker folders.
    options = dict(celery.conf.broker_transport_options or {})
    options.setdefault("control_folder", str(settings.broker_dir / "control"))
    _worker_conf["broker_transport_options"] = options
celery.conf.update(_worker_conf)

# The worker's own heartbeat and reaper hang on the worker's signals.
from . import monitor  # noqa: E402, F401
