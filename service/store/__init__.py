"""The job store: SQLAlchemy 2 models, engine/session set-up and Alembic migrations."""

from .models import (
    ApiKey,
    Base,
    ClassifierRow,
    IdempotencyKeyRow,
    JobRow,
    JobTagRow,
    MetricRow,
    ScenarioRow,
    WorkerRow,
)
from .session import Database, upgrade

__all__ = [
    "ApiKey",
    "Base",
    "ClassifierRow",
    "Database",
    "IdempotencyKeyRow",
    "JobRow",
    "JobTagRow",
    "MetricRow",
    "ScenarioRow",
    "WorkerRow",
    "upgrade",
]
