"""The service layer shared by the API (``app``) and the workers (``worker``).

- :mod:`service.config`: settings from the environment;
- :mod:`service.store`: the SQL store (models, sessions, Alembic migrations, the job
  lifecycle);
- :mod:`service.queue`: the one seam to the broker (a Celery app that sends by task name);
- :mod:`service.params`: the typed job parameters, parsed by the API when a job is
  submitted and by the worker when it runs it.

Arrows point one way: ``app -> service -> inertia_id`` and ``worker -> service ->
inertia_id``; ``app`` and ``worker`` never import each other.
"""
