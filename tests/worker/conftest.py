"""Real workers for the worker tests: a ``celery worker`` subprocess on a real broker and
database, jobs written as rows and sent by task name, exactly as the API does.

Every test module runs against both deployments:

- ``filesystem``: the embedded default, a SQLite file and Celery's ``filesystem://`` broker;
- ``redis``: the scale-out shape, PostgreSQL and Redis on this machine (a database created
  for the module and dropped after; Redis database 9, or 9 to 12 by pytest-xdist worker,
  flushed before and after).

Without Redis or PostgreSQL the ``redis`` cases skip, or fail when
``INERTIA_ID_REQUIRE_SERVICES=1`` (CI sets it).
"""

from __future__ import annotations

import itertools
import os
import shutil
import signal
import subprocess
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from celery import Celery
from service_support import (
    ROOT,
    TERMINAL,
    GroupProcess,
    load_job,
    postgres_database,
    require_service,
    start_in_group,
    wait_for_job,
)
from sqlalchemy import select

from inertia_id import Scenario
from service.config import Settings
from service.queue import RUN_JOB_TASK, make_celery, worker_command
from service.store import Database, JobRow, MetricRow, ScenarioRow, WorkerRow, upgrade
from service.store.jobs import config_hash, create_job, mark_sent


def _redis_database() -> int:
    """Redis database 9 for a serial run; under pytest-xdist one of 9 to 12 per worker
    (``gw0`` to ``gw3``), so that two workers' modules never flush each other's
    queues (13 is the compose stack test's)."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    index = int(worker[2:]) if worker[2:].isdigit() else 0
    if index > 3:
        raise RuntimeError(f"at most 4 pytest-xdist workers (-n 4): {worker} has no Redis database")
    return 9 + index


def _redis_url() -> str:
    """``INERTIA_ID_TEST_REDIS_URL``, else a database of this worker's own. The override
    names one database: under more than one pytest-xdist worker each would flush the
    others' queues, so it is refused there."""
    url = os.environ.get("INERTIA_ID_TEST_REDIS_URL")
    if url is None:
        return f"redis://127.0.0.1:6379/{_redis_database()}"
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1") or 1)
    if workers > 1:
        raise RuntimeError(
            f"INERTIA_ID_TEST_REDIS_URL={url} names one Redis database, and the {workers} "
            "pytest-xdist workers would flush each other's queues in it: run in one "
            "process (-n 0) with it, or leave it unset (each worker takes 9 + its index)"
        )
    return url


REDIS_URL = _redis_url()
WORKER_READY_TIMEOUT_S = 60.0


def flush_redis() -> None:
    import redis

    client = redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2)
    try:
        client.flushdb()
    finally:
        client.close()


@dataclass
class WorkerProcess(GroupProcess):
    """A ``celery worker`` subprocess, in its own process group (so that :meth:`kill`
    ends it and its task processes at once, as a machine that died)."""

    #: The incarnations its name's row had before it started.
    earlier: set[str | None] = field(default_factory=set)

    def stop(self, timeout_s: float = 15.0) -> None:
        """Warm shutdown (SIGTERM to the main process, which waits for its task), then
        SIGKILL whatever is left of the group."""
        if self.alive():
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                pass
        self.kill()


@dataclass
class Service:
    """One deployment (database + broker) and the workers started on it."""

    kind: str
    root: Path
    settings: Settings
    db: Database
    celery: Celery
    env: dict[str, str]
    scenario_id: str = ""
    workers: list[WorkerProcess] = field(default_factory=list)

    def start_worker(
        self, *, prefix: str | None = None, warm: bool = True, **env: str
    ) -> WorkerProcess:
        """Start a worker (extra environment in ``env``) and wait until it is ready:
        its monitor has written its ``workers`` row, its task process warm (or only the
        row, its first beat, with ``warm=False``). ``prefix`` names it as an earlier
        worker was (its row then shows the new worker's incarnation)."""
        return self._await_worker(self.spawn_worker(prefix=prefix, **env), warm=warm)

    def spawn_worker(self, *, prefix: str | None = None, **env: str) -> WorkerProcess:
        """Start a worker as :meth:`start_worker` does, without waiting for it: its
        name is ``prefix`` (not yet the row's ``prefix@host``)."""
        prefix = prefix or f"w{len(self.workers) + 1}-{uuid.uuid4().hex[:6]}"
        with self.db.session() as session:
            earlier = set(
                session.scalars(
                    select(WorkerRow.incarnation).where(WorkerRow.name.like(f"{prefix}@%"))
                )
            )
        log_path = self.root / f"{prefix}.log"
        process = start_in_group(
            worker_command(prefix, pool="prefork"),
            log_path=log_path,
            cwd=self.root,
            env={**self.env, **env},
        )
        worker = WorkerProcess(name=prefix, process=process, log_path=log_path)
        worker.earlier = earlier
        self.workers.append(worker)
        return worker

    def _await_worker(self, worker: WorkerProcess, *, warm: bool) -> WorkerProcess:
        prefix, earlier = worker.name, worker.earlier
        deadline = time.monotonic() + WORKER_READY_TIMEOUT_S
        while time.monotonic() < deadline:
            with self.db.session() as session:
                seen = session.scalars(
                    select(WorkerRow.name).where(
                        WorkerRow.name.like(f"{prefix}@%"),
                        WorkerRow.incarnation.is_(None) | WorkerRow.incarnation.not_in(earlier)
                        if earlier
                        else True,
                        # A worker is listed from its first beat, warming up.
                        WorkerRow.warming_since.is_(None) if warm else True,
                    )
                ).first()
            if seen:
                worker.name = seen
                return worker
            if not worker.alive():
                break
            time.sleep(0.1)
        raise AssertionError(f"worker {prefix} did not come up\n{worker.log(4000)}")

    def kill_workers(self) -> None:
        for worker in self.workers:
            worker.kill()

    def logs(self) -> str:
        return "\n".join(w.log(4000) for w in self.workers)

    def submit(self, job_type: str, params: dict[str, Any], *, seed: int = 0) -> str:
        """Store a queued job and send its message, as the API does (a new job even when
        an identical one has finished: a rerun; one still queued or running is returned)."""
        with self.db.session() as session:
            job, _reused = create_job(
                session,
                job_type=job_type,
                scenario_id=self.scenario_id,
                params=params,
                seed=seed,
                rerun=True,
            )
            job_id = job.id
        self.celery.send_task(RUN_JOB_TASK, args=[job_id])
        with self.db.session() as session:
            mark_sent(session, job_id)
        return job_id

    def job(self, job_id: str) -> JobRow:
        return load_job(self.db, job_id)

    def wait_for(
        self, job_id: str, statuses: tuple[str, ...] = TERMINAL, timeout_s: float = 90.0
    ) -> JobRow:
        return wait_for_job(
            self.db,
            job_id,
            statuses=statuses,
            timeout_s=timeout_s,
            logs=self.logs,
            interval_s=0.05,
        )

    def metrics(self, job_id: str) -> list[tuple[str, int, float]]:
        with self.db.session() as session:
            rows = session.execute(
                select(MetricRow.key, MetricRow.step, MetricRow.value)
                .where(MetricRow.job_id == job_id)
                .order_by(MetricRow.key, MetricRow.step, MetricRow.id)
            ).all()
        return [(k, s, v) for k, s, v in rows]


@pytest.fixture(scope="module", params=["filesystem", "redis"])
def deployment(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Service]:
    """A migrated database with the paper scenario, and a broker; no worker yet."""
    kind = request.param
    root = tmp_path_factory.mktemp(f"worker-{kind}")
    databases: Iterator[str] | None = None
    if kind == "filesystem":
        database_url = f"sqlite:///{root / 'data' / 'inertia-id.db'}"
        broker_url = "filesystem://"
    else:
        try:
            flush_redis()
        except Exception as exc:
            require_service(f"Redis at {REDIS_URL}", exc)
        databases = postgres_database(prefix="inertia_id_worker")
        database_url = next(databases)
        broker_url = REDIS_URL
    env = {
        **os.environ,
        "INERTIA_ID_DATA_DIR": str(root / "data"),
        "DATABASE_URL": database_url,
        "BROKER_URL": broker_url,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])),
    }
    settings = Settings(
        INERTIA_ID_DATA_DIR=root / "data", DATABASE_URL=database_url, BROKER_URL=broker_url
    )
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    upgrade(settings.resolved_database_url)
    db = Database(settings.resolved_database_url)
    service = Service(kind, root, settings, db, make_celery(settings), env)
    with db.session() as session:
        row = ScenarioRow(name="paper", document=Scenario.paper().model_dump(mode="json"))
        session.add(row)
        session.flush()
        service.scenario_id = row.id
    try:
        yield service
    finally:
        service.kill_workers()
        db.dispose()
        if kind == "redis":
            flush_redis()
        if databases is not None:
            for _ in databases:
                pass


@pytest.fixture(scope="module")
def service(deployment: Service) -> Service:
    """The deployment with one worker running."""
    deployment.start_worker()
    return deployment


_SEEDS = itertools.count(10_000)


@dataclass
class Store:
    """A migrated database (with the paper scenario) and settings on a filesystem broker
    in a temporary folder, for tests that run worker code in-process."""

    settings: Settings
    db: Database
    scenario_id: str

    def add_job(
        self, job_type: str = "train", params: dict[str, Any] | None = None, **values: Any
    ) -> str:
        """A job row as given; each its own configuration (a seed of its own unless given),
        as identical reusable jobs cannot both exist."""
        params = {} if params is None else params
        values.setdefault("seed", next(_SEEDS))
        with self.db.session() as session:
            job = JobRow(
                type=job_type,
                scenario_id=self.scenario_id,
                params=params,
                config_hash=config_hash(job_type, self.scenario_id, params, values["seed"]),
                **values,
            )
            session.add(job)
            session.flush()
            return job.id

    def job(self, job_id: str) -> JobRow:
        return load_job(self.db, job_id)


@pytest.fixture(params=["sqlite", "postgresql"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Store]:
    # A copy of the session's database at head (a migration per test cost about 0.4 s
    # under load): the file copied on SQLite, the template on PostgreSQL.
    databases: Iterator[str] | None = None
    (tmp_path / "data").mkdir(parents=True, exist_ok=True)
    if request.param == "sqlite":
        path = tmp_path / "data" / "inertia-id.db"
        shutil.copyfile(request.getfixturevalue("migrated_sqlite"), path)
        database_url = f"sqlite:///{path}"
    else:
        databases = postgres_database(
            prefix="inertia_id_worker", template=request.getfixturevalue("migrated_postgres")
        )
        database_url = next(databases)
    settings = Settings(
        INERTIA_ID_DATA_DIR=tmp_path / "data", DATABASE_URL=database_url, BROKER_URL="filesystem://"
    )
    db = Database(database_url)
    with db.session() as session:
        row = ScenarioRow(name="paper", document=Scenario.paper().model_dump(mode="json"))
        session.add(row)
        session.flush()
        scenario_id = row.id
    try:
        yield Store(settings, db, scenario_id)
    finally:
        db.dispose()
        if databases is not None:
            for _ in databases:
                pass
