"""Celery workers: claim a job row, run the inertia_id core on it, store progress and results.

Start one with ``celery -A worker.celery_app worker --concurrency=1 --loglevel=INFO``
(``inertia-id serve`` starts them for you). The ``jobs`` table is the source of truth;
the broker only says which job to look at. Nothing heavy is imported here: torch and
numba are imported inside the task process (see :mod:`worker.tasks`).
"""
