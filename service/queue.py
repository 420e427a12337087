"""The one seam to the queue: a Celery app configured from the settings.

The API only sends tasks by name (:data:`RUN_JOB_TASK`); the worker package registers
the task under that name on an app made here, so both ends agree on the broker.
"""

from __future__ import annotations

import sys

from celery import Celery

from .config import Settings

__all__ = ["RUN_JOB_TASK", "make_celery", "worker_command"]

RUN_JOB_TASK = "inertia_id.run_job"


def make_celery(settings: Settings) -> Celery:
    """A Celery app on ``settings.broker_url`` (``filesystem://`` folders created)."""
    celery = Celery("inertia_id", broker=settings.broker_url)
    conf: dict[str, object] = {
        "task_serializer": "json",
        "accept_content": ["json"],
        "task_acks_late": True,
        "task_reject_on_worker_lost": True,
        "worker_prefetch_multiplier": 1,
        "broker_connection_retry_on_startup": True,
        "task_ignore_result": True,
    }
    if settings.broker_url.startswith("filesystem://"):
        folder = settings.broker_dir / "queue"
        processed = settings.broker_dir / "processed"
        control = settings.broker_dir / "control"
        for path in (folder, processed, control):
            path.mkdir(parents=True, exist_ok=True)
        conf["broker_transport_options"] = {
            "data_folder_in": str(folder),
            "data_folder_out": str(folder),
            "processed_folder": str(processed),
            "control_folder": str(control),
            "store_processed": False,
            # The transport polls its folder (kombu's default: every second); listing a
            # folder ten times a second is cheap, and a job starts within 0.1 s.
            "polling_interval": 0.1,
        }
    elif settings.broker_url.startswith(("redis://", "rediss://")):
        # Longer than the longest job: an unacknowledged message is redelivered after it.
        conf["broker_transport_options"] = {"visibility_timeout": 12 * 3600}
    celery.conf.update(conf)
    return celery


def worker_command(name: str, *, log_level: str = "INFO", pool: str | None = None) -> list[str]:
    """The command line of one worker process: a ``celery worker`` on the app of
    :mod:`worker.celery_app`, in this interpreter, running one job at a time, named
    ``name@<host>``; ``pool`` is Celery's ``--pool`` (its own default when None)."""
    command = [sys.executable, "-m", "celery", "-A", "worker.celery_app", "worker"]
    command += ["--concurrency=1", "-n", f"{name}@%h", f"--loglevel={log_level}"]
    return command if pool is None else [*command, f"--pool={pool}"]
