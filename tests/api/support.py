"""Helpers of the API tests: settings independent of the environment, a client wrapper."""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import FastAPI
from scenario_support import GOOD_SEQUENCE

from inertia_id import InertiaClassifier
from service.config import Settings
from service.store import ClassifierRow, Database

with warnings.catch_warnings():
    # Starlette nudges towards httpx2; the TestClient works the same with httpx.
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

__all__ = ["GOOD_SEQUENCE", "Api", "TestClient", "make_settings"]


def make_settings(data_dir: Path, database_url: str, **overrides: Any) -> Settings:
    """Settings independent of the environment the tests run in."""
    values: dict[str, Any] = {
        "INERTIA_ID_DATA_DIR": data_dir,
        "DATABASE_URL": database_url,
        "BROKER_URL": "filesystem://",
        "INERTIA_ID_API_KEY": None,
        "INERTIA_ID_MAX_BODY_BYTES": 5_000_000,
        "INERTIA_ID_MAX_PAGE_SIZE": 200,
        "INERTIA_ID_MAX_METRIC_POINTS": 2000,
        "INERTIA_ID_HEARTBEAT_INTERVAL_S": 5.0,
        "INERTIA_ID_CLASSIFIER_CACHE": 32,
        # The verdict process as shipped, started by the first identify (not by every
        # app a test builds).
        "INERTIA_ID_VERDICT_PROCESS": "lazy",
        # The test client's Host header, besides the loopback names.
        "INERTIA_ID_ALLOWED_HOSTS": "testserver,127.0.0.1,localhost",
    }
    values.update(overrides)
    return Settings(**values)


@dataclass
class Api:
    """A test client with the app's key, and shortcuts to its state."""

    client: TestClient
    app: FastAPI
    key: str

    @property
    def auth(self) -> dict[str, str]:
        return {"X-API-Key": self.key}

    @property
    def settings(self) -> Settings:
        settings: Settings = self.app.state.settings
        return settings

    @property
    def db(self) -> Database:
        database: Database = self.app.state.db
        return database

    def post(self, url: str, **kwargs: Any) -> Any:
        return self.client.post(url, headers=self.auth, **kwargs)

    def post_raw_json(self, url: str, content: Any) -> Any:
        """POST ``content`` as a JSON body exactly as written: ``json=`` would encode it
        itself and cannot carry NaN/Infinity tokens, malformed text or a streamed body."""
        return self.client.post(
            url, content=content, headers={**self.auth, "content-type": "application/json"}
        )

    def delete(self, url: str, **kwargs: Any) -> Any:
        return self.client.delete(url, headers=self.auth, **kwargs)

    def get(self, url: str, **kwargs: Any) -> Any:
        return self.client.get(url, **kwargs)

    def get_with_key(self, url: str, **kwargs: Any) -> Any:
        """A read that costs CPU, and so needs the key."""
        return self.client.get(url, headers=self.auth, **kwargs)

    def queued_messages(self) -> list[Path]:
        return sorted((self.settings.broker_dir / "queue").glob("*.msg"))

    def create_scenario(self, **overrides: Any) -> dict[str, Any]:
        response = self.post("/scenarios", json={"preset": "paper", "overrides": overrides})
        assert response.status_code == 201, response.text
        result: dict[str, Any] = response.json()
        return result

    def submit(self, job_type: str, scenario_id: str, **fields: Any) -> Any:
        return self.post("/jobs", json={"type": job_type, "scenario_id": scenario_id, **fields})

    def insert_classifier(self, scenario_id: str, model: InertiaClassifier) -> str:
        """Store a trained classifier the way a train job would."""
        document = model.to_json()
        row = ClassifierRow(
            scenario_id=scenario_id,
            metric=model.metric,
            f1=model.f1_,
            accuracy=model.accuracy_,
            sequence=np.asarray(model.sequence_).tolist(),
            candidate_names=list(model.candidate_names_),
            confusion=model.confusion_.tolist(),
            document=document,
            sha256=json.loads(document)["sha256"],
        )
        with self.db.session() as session:
            session.add(row)
            session.flush()
            return row.id
