"""/health (never a 5xx), the OpenAPI document and the interactive docs."""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

from service.config import Settings
from service.store.models import WorkerRow, utcnow
from service.store.session import Database

from .support import Api, make_settings


def add_worker(api: Api, name: str, seconds_ago: float) -> None:
    seen = utcnow() - timedelta(seconds=seconds_ago)
    with api.db.session() as session:
        session.add(
            WorkerRow(name=name, broker_url="filesystem://", started_at=seen, last_seen_at=seen)
        )


def test_health_without_workers_is_degraded(api: Api) -> None:
    response = api.get("/health")
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "degraded"
    assert health["database"]["ok"] is True
    assert health["broker"]["ok"] is True
    assert "filesystem" in health["broker"]["detail"]
    assert health["workers"] == {
        "ok": False,
        "count": 0,
        "names": [],
        "window_s": 3 * api.settings.heartbeat_interval_s,
    }


def test_health_counts_recently_seen_workers(api: Api) -> None:
    add_worker(api, "celery@alive", seconds_ago=1.0)
    add_worker(api, "celery@gone", seconds_ago=3600.0)
    health = api.get("/health").json()
    assert health["status"] == "ok"
    assert health["workers"]["names"] == ["celery@alive"]
    assert health["workers"]["count"] == 1


def test_health_reports_an_unreachable_redis_broker(
    make_api: Callable[[Settings], Api], tmp_path: Path, database_url: str
) -> None:
    # Port 1 on localhost: connection refused at once.
    api = make_api(make_settings(tmp_path, database_url, BROKER_URL="redis://127.0.0.1:1/0"))
    add_worker(api, "celery@alive", seconds_ago=0.0)
    response = api.get("/health")
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "degraded"
    assert health["broker"]["ok"] is False
    assert "redis broker unreachable" in health["broker"]["detail"]
    assert health["database"]["ok"] is True


def test_health_reports_an_unreachable_database(api: Api) -> None:
    api.app.state.db = Database("postgresql+psycopg://postgres@127.0.0.1:1/nowhere")
    try:
        response = api.get("/health")
    finally:
        api.app.state.db.dispose()
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "degraded"
    assert health["database"] == {"ok": False, "detail": "postgresql unreachable"}
    assert health["workers"]["ok"] is False


def test_openapi_and_docs_are_served(api: Api) -> None:
    docs = api.get("/docs")
    assert docs.status_code == 200
    assert "swagger" in docs.text.lower()
    # A screen reader needs the page's language (axe-core's html-has-lang).
    assert (
        docs.text.lstrip().lower().startswith("<!doctype html>") and '<html lang="en">' in docs.text
    )
    spec = api.get("/openapi.json").json()
    assert spec["info"]["title"] == "inertia-id"
    assert {
        "/scenarios",
        "/scenarios/{scenario_id}",
        "/jobs",
        "/jobs/{job_id}",
        "/jobs/{job_id}/metrics",
        "/jobs/{job_id}/cancel",
        "/classifiers",
        "/classifiers/{classifier_id}",
        "/classifiers/{classifier_id}/download",
        "/identify",
        "/health",
    } <= set(spec["paths"])
    identify = spec["paths"]["/identify"]["post"]["requestBody"]["content"]
    assert set(identify) == {"application/json", "multipart/form-data"}
    schemas = spec["components"]["schemas"]
    assert {"IdentifyRequest", "Telemetry", "SearchParams", "TrainParams", "SweepParams"} <= set(
        schemas
    )
    assert "APIKeyHeader" in spec["components"]["securitySchemes"]
