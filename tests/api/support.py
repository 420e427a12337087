"""Helpers of the API tests: settings independent of the environment, a client wrapper,
and an app served by a real uvicorn server in a thread."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import uvicorn
from fastapi import FastAPI, Request
from scenario_support import GOOD_SEQUENCE
from service_support import classifier_row, clean_env, free_port, tail, wait_for
from sqlalchemy import create_engine, text

from inertia_id import InertiaClassifier, Scenario
from service.config import Settings
from service.store import Database, ScenarioRow

with warnings.catch_warnings():
    # Starlette nudges towards httpx2; the TestClient works the same with httpx.
    warnings.simplefilter("ignore")
    from fastapi.testclient import TestClient

__all__ = [
    "GOOD_SEQUENCE",
    "Api",
    "InThread",
    "TestClient",
    "add_body_size_route",
    "keyed_app",
    "make_settings",
    "serve_api_only",
    "served_in_thread",
]


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


def keyed_app(tmp_path: Path, api_key: str) -> FastAPI:
    """The app on SQLite in ``tmp_path``, with ``api_key`` and no verdict process: for a
    real server (:func:`served_in_thread`), to which test routes may be added."""
    from app.main import create_app

    settings = make_settings(
        tmp_path / "data",
        f"sqlite:///{tmp_path / 'inertia-id.db'}",
        INERTIA_ID_API_KEY=api_key,
        INERTIA_ID_VERDICT_PROCESS="off",
    )
    return create_app(settings)


def add_body_size_route(app: FastAPI, entered: threading.Event | None = None) -> None:
    """A test route, ``POST /test/body-size``, that reads the whole body and answers its
    size (``{"size": N}``); ``entered`` is set when a request reaches it."""

    async def body_size(request: Request) -> dict[str, int]:
        if entered is not None:
            entered.set()
        return {"size": len(await request.body())}

    app.add_api_route("/test/body-size", body_size, methods=["POST"])


@dataclass(frozen=True)
class InThread:
    """A uvicorn server running in a thread of this process."""

    server: uvicorn.Server
    thread: threading.Thread


@contextmanager
def served_in_thread(app: FastAPI, config: uvicorn.Config) -> Iterator[InThread]:
    """``config``'s uvicorn server (serving ``app``) in a thread of this process, once it
    has started; stopped at the end, and the app's broker and database closed."""
    served = uvicorn.Server(config)
    thread = threading.Thread(target=served.run, name="uvicorn under test", daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not served.started:
        assert thread.is_alive() and time.monotonic() < deadline, "uvicorn did not start"
        time.sleep(0.02)
    try:
        yield InThread(served, thread)
    finally:
        served.should_exit = True
        thread.join(15)
        app.state.celery.close()
        app.state.db.dispose()


@contextmanager
def serve_api_only(root: Path, api_workers: int, **env: str) -> Iterator[tuple[int, Path]]:
    """``python -m app.serve`` as shipped but with no workers (``--workers 0``) and
    ``api_workers`` API processes, data in ``root/data``, ``env`` added to a clean
    environment; its port and log file once ``/health`` answers 200. SIGTERM at the end
    (SIGKILL, and a failure, when that is ignored for 40 s)."""
    port = free_port()
    log = root / "serve.log"
    argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
    argv += ["--workers", "0", "--api-workers", str(api_workers)]
    with open(log, "wb") as out:
        server = subprocess.Popen(
            argv, env=clean_env(**env), cwd=root, stdout=out, stderr=subprocess.STDOUT
        )
    try:

        def healthy() -> bool:
            try:
                return httpx.get(f"http://127.0.0.1:{port}/health", timeout=5).status_code == 200
            except httpx.TransportError:
                return False

        wait_for(healthy, 90, "serve did not answer /health", lambda: tail(log))
        yield port, log
    finally:
        server.terminate()
        try:
            server.wait(40)
        except subprocess.TimeoutExpired:
            server.kill()
            raise


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

    def insert_scenario(self, scenario: Scenario, name: str = "stored before") -> str:
        """Store a scenario as a row stored by older code is, past the checks that
        ``POST /scenarios`` runs today."""
        with self.db.session() as session:
            row = ScenarioRow(name=name, document=scenario.model_dump(mode="json"))
            session.add(row)
            session.flush()
            return str(row.id)

    def submit(self, job_type: str, scenario_id: str, **fields: Any) -> Any:
        return self.post("/jobs", json={"type": job_type, "scenario_id": scenario_id, **fields})

    def insert_classifier(
        self, scenario_id: str, model: InertiaClassifier, *, with_job: bool = False
    ) -> str:
        """Store a trained classifier the way a train job would; ``with_job``: with the
        succeeded training job row it names as its ``job_id``."""
        row = classifier_row(scenario_id, model)
        with self.db.session() as session:
            if with_job:
                from service.store.models import JobRow

                job = JobRow(
                    type="train", status="succeeded", scenario_id=scenario_id, config_hash="0" * 64
                )
                session.add(job)
                session.flush()
                row.job_id = job.id
            session.add(row)
            session.flush()
            return row.id


@contextmanager
def read_only_postgres(api: Api) -> Iterator[Callable[[], None]]:
    """The test's PostgreSQL database with its transactions read-only by default, as an
    operator sets one (``ALTER DATABASE ... SET default_transaction_read_only``) and as a
    hot standby takes every transaction: a write is SQLSTATE 25006. Set and reset from
    the server's maintenance database; the pool is emptied so connections pick it up.
    Yields the reset, for a test that makes the database writable again inside the block
    (the pool then kept as it is: its sessions still read-only, as after a real reset)."""
    url = api.db.engine.url
    name = url.database
    admin = create_engine(url.set(database="postgres"), isolation_level="AUTOCOMMIT")

    def reset() -> None:
        with admin.connect() as connection:
            connection.execute(text(f'ALTER DATABASE "{name}" RESET default_transaction_read_only'))

    try:
        with admin.connect() as connection:
            connection.execute(
                text(f'ALTER DATABASE "{name}" SET default_transaction_read_only = on')
            )
        api.db.engine.dispose()
        yield reset
    finally:
        reset()
        admin.dispose()
        api.db.engine.dispose()
