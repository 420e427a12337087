"""Fixtures of the API tests: a real database (SQLite file and PostgreSQL) and broker.

Every test that takes ``api`` runs twice: on a fresh SQLite file and on a PostgreSQL
database created for this test session (tables emptied before each test). The broker is
Celery's ``filesystem://`` in the test's folder, so a submitted job is a message file
there and no worker is needed.

PostgreSQL is expected at 127.0.0.1:5432 (user postgres, trust auth, database ``test``;
``INERTIA_ID_TEST_POSTGRES_URL`` points elsewhere).
If it is unreachable those tests skip, or fail when ``INERTIA_ID_REQUIRE_SERVICES=1``.
"""

from __future__ import annotations

import os
import secrets
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import create_engine, text
from sqlalchemy.exc import OperationalError

from app.main import create_app
from inertia_id import InertiaClassifier, Scenario, train
from service.config import Settings
from service.store import upgrade
from service.store.models import Base

from .support import GOOD_SEQUENCE, Api, TestClient, make_settings

# The server's maintenance database; each session creates (and drops) its own next to it.
PG_ADMIN_URL = os.environ.get(
    "INERTIA_ID_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test"
)
REQUIRE_SERVICES = os.environ.get("INERTIA_ID_REQUIRE_SERVICES") == "1"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Give each schemathesis operation test an id of its own.

    schemathesis names its items ``test_no_server_errors[GET /health]`` but sets the id
    through ``Function._nodeid``, which pytest 9 no longer reads (it reads ``_id``), so
    all 26 shared one id. pytest-xdist keys the tests it hands out by id: under
    ``-n 2`` only one of the 26 operations ran (2,643 tests reported against 2,668 in
    one process). Here the id is made from the item's name again.
    """
    from _pytest.nodeid import NodeId  # pytest 9's structured id (no public setter)

    for item in items:
        if "[" in item.name and not item.nodeid.endswith("]") and hasattr(item, "_id"):
            parent = item.parent.nodeid if item.parent is not None else ""
            item._id = NodeId.parse(f"{parent}::{item.name}")


@contextmanager
def _new_postgres_database(prefix: str) -> Iterator[str]:
    """A fresh, uniquely named PostgreSQL database with no tables, dropped afterwards."""
    admin = create_engine(
        PG_ADMIN_URL, isolation_level="AUTOCOMMIT", connect_args={"connect_timeout": 5}
    )
    try:
        with admin.connect() as connection:
            connection.execute(text("SELECT 1"))
    except OperationalError as exc:
        admin.dispose()
        message = f"PostgreSQL unreachable at {PG_ADMIN_URL}: {exc}"
        if REQUIRE_SERVICES:
            pytest.fail(message)
        pytest.skip(message)
    name = f"{prefix}_{secrets.token_hex(6)}"
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield admin.url.set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


@pytest.fixture(scope="session")
def postgres_url() -> Iterator[str]:
    """A fresh, uniquely named PostgreSQL database for this test session."""
    with _new_postgres_database("inertia_api") as url:
        upgrade(url)
        yield url


@pytest.fixture(params=["sqlite", "postgresql"])
def empty_database_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """A database with no tables yet, to migrate step by step (the session's PostgreSQL
    database is at head already)."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'migrating.db'}"
        return
    with _new_postgres_database("inertia_migrating") as url:
        yield url


def _empty_tables(url: str) -> None:
    """Delete every row of the models' tables, those that reference others first.

    Not ``TRUNCATE``: it gives each table a new file, which took 0.1-0.35 s before every
    PostgreSQL test under load, where deleting the few rows a test leaves takes about
    0.01 s. Neither resets a sequence (``TRUNCATE`` without ``RESTART IDENTITY``)."""
    engine = create_engine(url)
    try:
        with engine.begin() as connection:
            for table in reversed(Base.metadata.sorted_tables):
                connection.execute(table.delete())
    finally:
        engine.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def database_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A database at head with empty tables: on SQLite a fresh copy of the session's
    migrated file (a migration per test cost about 0.4 s under load), on PostgreSQL the
    session's database emptied. ``empty_database_url`` is the one to migrate."""
    if request.param == "sqlite":
        path = tmp_path / "inertia-id.db"
        shutil.copyfile(request.getfixturevalue("migrated_sqlite"), path)
        return f"sqlite:///{path}"
    url: str = request.getfixturevalue("postgres_url")
    _empty_tables(url)
    return url


@pytest.fixture
def settings(tmp_path: Path, database_url: str) -> Settings:
    return make_settings(tmp_path, database_url)


@pytest.fixture
def make_api() -> Iterator[Callable[..., Api]]:
    """Build apps from settings; each is shut down at the end of the test."""
    clients: list[TestClient] = []

    def build(settings: Settings, key: str | None = None) -> Api:
        """``key``: the key of an app already built on the same database (a second app
        finds a key stored and generates none)."""
        app = create_app(settings)
        client = TestClient(app)
        client.__enter__()
        clients.append(client)
        key = key or settings.api_key or app.state.generated_api_key
        assert key
        return Api(client=client, app=app, key=key)

    yield build
    for client in clients:
        client.__exit__(None, None, None)


@pytest.fixture
def api(make_api: Callable[[Settings], Api], settings: Settings) -> Api:
    return make_api(settings)


@pytest.fixture(scope="session")
def classifier(paper: Scenario) -> InertiaClassifier:
    """Euclidean classifier of the paper preset and the good sequence (trains in 0.1 s)."""
    return train(paper, GOOD_SEQUENCE, 10, np.random.default_rng(1), metric="euclidean")
