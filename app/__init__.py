"""The inertia-id service: FastAPI in front, SQL rows behind, Celery workers doing the work."""
