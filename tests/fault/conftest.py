"""Fixtures of the fault-injection suite: a fresh deployment per test, on both shapes.

- ``sqlite``: the embedded default, as ``inertia-id serve`` runs with no configuration
  (a SQLite file and the filesystem broker in the data dir);
- ``postgres``: PostgreSQL (a database created on the machine's server for the test and
  dropped after) and Redis (a private ``redis-server`` for this session: these tests
  delete queues and flush, and must not touch anyone else's data).

Without PostgreSQL or redis-server the ``postgres`` cases skip, or fail when
``INERTIA_ID_REQUIRE_SERVICES=1`` (CI sets it).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from faults import (
    FAST_TIMINGS,
    Deployment,
    PostgresCluster,
    RedisServer,
    postgres_database,
    service_env,
)


@pytest.fixture(scope="session")
def redis_server() -> Iterator[RedisServer]:
    """A private Redis for the session's ``postgres`` deployments."""
    root = Path(tempfile.mkdtemp(prefix="inertia-id-redis-"))
    server = RedisServer(root).start()
    try:
        yield server
    finally:
        server.stop()
        shutil.rmtree(root, ignore_errors=True)


def _deployment(kind: str, root: Path, request: pytest.FixtureRequest) -> Iterator[Deployment]:
    databases: Iterator[str] | None = None
    if kind == "sqlite":
        data_dir = (root / "data").resolve()
        env = service_env(data_dir, **FAST_TIMINGS)
        database_url = f"sqlite:///{data_dir / 'inertia-id.db'}"
        deployment = Deployment(kind, root, database_url, env)
    else:
        redis: RedisServer = request.getfixturevalue("redis_server")
        redis.flush()
        databases = postgres_database()
        deployment = Deployment.on_postgres(root, next(databases), redis)
    try:
        yield deployment
    finally:
        deployment.close()
        if databases is not None:
            for _ in databases:
                pass


@pytest.fixture(params=["sqlite", "postgres"])
def deployment(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Deployment]:
    """A fresh data dir on one of the two shapes; no serve yet."""
    yield from _deployment(request.param, tmp_path, request)


@pytest.fixture(scope="module", params=["sqlite", "postgres"])
def module_deployment(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Deployment]:
    """A deployment shared by a module's tests (those that leave the service running)."""
    yield from _deployment(request.param, tmp_path_factory.mktemp(request.param), request)


@pytest.fixture
def private_postgres() -> Iterator[PostgresCluster]:
    """A private PostgreSQL cluster, running, that the test may stop and start."""
    cluster = PostgresCluster().init()
    cluster.start()
    try:
        yield cluster
    finally:
        cluster.remove()
