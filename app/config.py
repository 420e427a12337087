"""Service settings, from the environment (pydantic-settings).

The embedded default needs nothing installed: a SQLite file and Celery's filesystem
broker, both under ``INERTIA_ID_DATA_DIR``. Scale-out is configuration only:
``DATABASE_URL=postgresql+psycopg://...`` and ``BROKER_URL=redis://...``.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["Settings", "get_settings"]


class Settings(BaseSettings):
    """Every knob of the service; each can be set by an environment variable."""

    model_config = SettingsConfigDict(extra="ignore", populate_by_name=True)

    data_dir: Path = Field(default=Path("inertia-id-data"), alias="INERTIA_ID_DATA_DIR")
    database_url: str | None = Field(default=None, alias="DATABASE_URL")
    broker_url: str = Field(default="filesystem://", alias="BROKER_URL")
    api_key: str | None = Field(default=None, alias="INERTIA_ID_API_KEY")
    host: str = Field(default="127.0.0.1", alias="INERTIA_ID_HOST")
    port: int = Field(default=8000, alias="INERTIA_ID_PORT")
    max_body_bytes: int = Field(default=5_000_000, alias="INERTIA_ID_MAX_BODY_BYTES")
    max_page_size: int = Field(default=200, alias="INERTIA_ID_MAX_PAGE_SIZE")
    max_metric_points: int = Field(default=2000, alias="INERTIA_ID_MAX_METRIC_POINTS")
    heartbeat_interval_s: float = Field(default=5.0, alias="INERTIA_ID_HEARTBEAT_INTERVAL_S")
    heartbeat_timeout_s: float = Field(default=60.0, alias="INERTIA_ID_HEARTBEAT_TIMEOUT_S")
    max_attempts: int = Field(default=2, alias="INERTIA_ID_MAX_ATTEMPTS")
    classifier_cache_size: int = Field(default=32, alias="INERTIA_ID_CLASSIFIER_CACHE")
    frontend_dir: Path | None = Field(default=None, alias="INERTIA_ID_FRONTEND_DIR")

    @property
    def resolved_database_url(self) -> str:
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'inertia-id.db').resolve()}"

    @property
    def resolved_frontend_dir(self) -> Path:
        """The dashboard's files: ``INERTIA_ID_FRONTEND_DIR``, else the checkout's ``frontend/``."""
        if self.frontend_dir is not None:
            return self.frontend_dir.resolve()
        return Path(__file__).resolve().parent.parent / "frontend"

    @property
    def broker_dir(self) -> Path:
        """Folder of the filesystem broker's messages (embedded default)."""
        return (self.data_dir / "broker").resolve()


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    return Settings()
