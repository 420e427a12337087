"""What the tests that run the service for real share: a free port, a clean environment,
polling with the logs on failure, a fresh PostgreSQL database, process groups, a job row,
and ``python -m app.serve`` started and stopped.

The worker, fault, deploy and browser suites each used to carry their own copy of these.
They import this module as ``service_support``: ``tests/`` has no ``__init__.py``, so
pytest puts it on ``sys.path`` when it loads ``tests/conftest.py``, before any test.

Timing is never asserted here: the deadlines are "it did not happen at all" guards.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn, TypeVar

import httpx
import pytest
from sqlalchemy import create_engine, event, make_url, text
from sqlalchemy.engine import Engine

from service.store import Database, JobRow, upgrade

ROOT = Path(__file__).resolve().parents[1]
TERMINAL = ("succeeded", "failed", "cancelled")
POSTGRES_ADMIN_URL = os.environ.get(
    "INERTIA_ID_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
)

T = TypeVar("T")


def skip_or_fail(message: str) -> NoReturn:
    """Skip, or fail when the environment says the services must be there (CI sets
    ``INERTIA_ID_REQUIRE_SERVICES=1``)."""
    if os.environ.get("INERTIA_ID_REQUIRE_SERVICES") == "1":
        pytest.fail(message)
    pytest.skip(message)


def require_service(what: str, error: BaseException | str) -> NoReturn:
    """:func:`skip_or_fail` for a service that is missing or does not answer."""
    detail = f"{type(error).__name__}: {error}" if isinstance(error, BaseException) else error
    skip_or_fail(f"{what} is not available: {detail}")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def clean_env(**extra: str) -> dict[str, str]:
    """This process's environment without any inertia-id setting (so that the machine's
    configuration never leaks into a service under test), this checkout first on
    ``PYTHONPATH``, plus ``extra``."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith("INERTIA_ID_") and k not in ("DATABASE_URL", "BROKER_URL")
    }
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**env, **extra}


def tail(path: Path, chars: int = 6000) -> str:
    """The end of a log file ("" while there is none)."""
    try:
        return path.read_text(errors="replace")[-chars:]
    except OSError:
        return ""


def wait_for(
    predicate: Callable[[], T | None],
    timeout_s: float,
    what: str,
    logs: Callable[[], str],
    *,
    interval_s: float = 0.2,
) -> T:
    """Poll ``predicate`` until it returns something truthy; fail with ``what`` and the
    logs after ``timeout_s``. A connection refused or cut counts as "not yet": the
    service is starting or restarting."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            value = predicate()
        except (httpx.TransportError, OSError):
            value = None
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} within {timeout_s:g} s\n{logs()}")
        time.sleep(interval_s)


def postgres_database(
    admin_url: str = POSTGRES_ADMIN_URL,
    *,
    prefix: str = "inertia_id_test",
    template: str | None = None,
) -> Iterator[str]:
    """The URL of a fresh database on the server at ``admin_url`` (named ``prefix`` and
    a random suffix, so a leftover says which suite made it); dropped when the
    generator is exhausted or closed. ``template``: a database to copy (one of
    :func:`migrated_postgres_template`'s), instead of an empty one."""
    admin = create_engine(admin_url, isolation_level="AUTOCOMMIT")
    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    copy_of = f' TEMPLATE "{template}"' if template else ""
    try:
        with admin.connect() as connection:
            connection.execute(text(f'CREATE DATABASE "{name}"{copy_of}'))
    except Exception as exc:
        admin.dispose()
        require_service(f"PostgreSQL at {admin_url}", exc)
    try:
        yield admin.url.set(database=name).render_as_string(hide_password=False)
    finally:
        try:
            with admin.connect() as connection:
                connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        finally:
            admin.dispose()


@contextmanager
def migrated_postgres_template(admin_url: str = POSTGRES_ADMIN_URL) -> Iterator[str]:
    """The name of a database migrated to head, for :func:`postgres_database` to copy.

    Migrating a new database took about 0.4 s (under load), once per test of the worker
    suite's ``store``; PostgreSQL copies a template in about 0.07 s. The migrations still
    run, once a session, here: a broken one fails every test that copies the result.
    Nothing stays connected to it (``CREATE DATABASE ... TEMPLATE`` needs that)."""
    databases = postgres_database(admin_url, prefix="inertia_id_template")
    url = next(databases)
    upgrade(url)
    try:
        yield make_url(url).database or ""
    finally:
        databases.close()


def migrated_sqlite_template(folder: Path) -> Path:
    """A SQLite file in ``folder`` migrated to head, for tests to copy as their fresh
    database (about 0.4 s a migration under load, once per test of the API suite; a
    copy takes milliseconds and the app's own ``upgrade`` then finds it at head). The
    engine is disposed, so its WAL is checkpointed and the file alone is the database."""
    path = folder / "migrated.db"
    upgrade(f"sqlite:///{path}")
    assert not path.with_name(path.name + "-wal").exists(), "the template's WAL was left"
    return path


def load_job(db: Database, job_id: str) -> JobRow:
    """The job's row as it is now, detached from its session."""
    with db.session() as session:
        job = session.get(JobRow, job_id)
        assert job is not None, f"job {job_id} is gone"
        session.expunge(job)
        return job


def wait_for_job(
    db: Database,
    job_id: str,
    *,
    statuses: tuple[str, ...] = TERMINAL,
    timeout_s: float,
    logs: Callable[[], str],
    interval_s: float = 0.2,
) -> JobRow:
    """The job's row once its status is one of ``statuses``."""

    def reached() -> JobRow | None:
        job = load_job(db, job_id)
        return job if job.status in statuses else None

    def why() -> str:
        job = load_job(db, job_id)
        return f"(now {job.status!r}, error={job.error!r})\n{logs()}"

    return wait_for(
        reached, timeout_s, f"job {job_id} did not reach {statuses}", why, interval_s=interval_s
    )


def start_in_group(
    argv: list[str],
    *,
    log_path: Path,
    cwd: Path | None = None,
    env: dict[str, str] | None = None,
    append: bool = False,
) -> subprocess.Popen[bytes]:
    """Start ``argv`` in a process group of its own (so that it can be killed whole, as
    a machine or a container dies), its output and errors to ``log_path`` (added to the
    end with ``append``: a restarted server keeps its earlier log)."""
    with open(log_path, "ab" if append else "wb") as log:
        return subprocess.Popen(
            argv,
            cwd=cwd,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


@dataclass
class GroupProcess:
    """A subprocess started with ``start_new_session=True`` (a process group of its own,
    as a container or a machine is), and its log file."""

    name: str
    process: subprocess.Popen[bytes]
    log_path: Path

    def log(self, chars: int = 5000) -> str:
        return f"--- {self.name} log ({self.log_path}) ---\n{tail(self.log_path, chars)}"

    def alive(self) -> bool:
        return self.process.poll() is None

    def kill(self) -> None:
        """SIGKILL the whole group at once: a machine or a container that died."""
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait(10)


@dataclass
class ServeProcess:
    """A running ``python -m app.serve`` and a client that carries its API key."""

    base_url: str
    client: httpx.Client
    log_path: Path

    def logs(self) -> str:
        return f"--- serve log ({self.log_path}) ---\n{tail(self.log_path)}"


@contextmanager
def serve_app(
    root: Path, *, api_key: str, ready_timeout_s: float = 120.0
) -> Iterator[ServeProcess]:
    """``python -m app.serve`` as a user runs it (the API and one worker, the embedded
    default, data in ``root/data``) on a free port, once ``/health`` says ok and its
    worker is warm (listed, not warming); SIGTERM at the end (SIGKILL when that is
    ignored for 40 s)."""
    port = free_port()
    log_path = root / "serve.log"
    with open(log_path, "wb") as out:
        server = subprocess.Popen(
            [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
            env=clean_env(INERTIA_ID_API_KEY=api_key),
            cwd=root,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    base_url = f"http://127.0.0.1:{port}"
    client = httpx.Client(base_url=base_url, headers={"X-API-Key": api_key}, timeout=30)
    running = ServeProcess(base_url, client, log_path)
    try:
        wait_for(
            lambda: (
                (health := client.get("/health").json())["status"] == "ok"
                and not health["workers"]["warming"]
            ),
            ready_timeout_s,
            "the service did not become healthy",
            running.logs,
        )
        yield running
    finally:
        client.close()
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(40)
        except subprocess.TimeoutExpired:
            server.kill()


@contextmanager
def writes_refused_while(refusing: threading.Event) -> Iterator[None]:
    """Inside, every connection handed out is read-only while ``refusing`` is set: SQLite's
    ``query_only`` (SQLITE_READONLY, as a read-only file), PostgreSQL's read-only
    transactions (SQLSTATE 25006, as a hot standby): the database answers and refuses
    writes, as a full disk's does. ``refusing`` is cleared on the way out."""

    def read_only_while_refusing(dbapi_connection: Any, _record: Any, _proxy: Any) -> None:
        if isinstance(dbapi_connection, sqlite3.Connection):
            dbapi_connection.execute(f"PRAGMA query_only = {int(refusing.is_set())}")
        else:
            mode = "READ ONLY" if refusing.is_set() else "READ WRITE"
            dbapi_connection.execute(f"SET SESSION CHARACTERISTICS AS TRANSACTION {mode}")
            dbapi_connection.commit()

    event.listen(Engine, "checkout", read_only_while_refusing)
    try:
        yield
    finally:
        event.remove(Engine, "checkout", read_only_while_refusing)
        refusing.clear()


class SilentableProxy:
    """A TCP relay to the PostgreSQL server that can fall silent (:meth:`silence`): it
    then passes nothing on, either way, while the kernel still acknowledges what is
    sent, as for a server whose answers are lost on the way (a SIGSTOPped proxy does
    the same). Closed, it ends its connections, so the server ends their sessions."""

    def __init__(self, host: str, port: int) -> None:
        self.target = (host, port)
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.1)
        self.port = self.listener.getsockname()[1]
        self.silent = threading.Event()
        self.closing = threading.Event()
        self.sockets: list[socket.socket] = []
        self.clients: list[socket.socket] = []
        self.guard = threading.Lock()
        self.threads = [threading.Thread(target=self._accept, daemon=True)]
        self.threads[0].start()

    def silence(self) -> None:
        self.silent.set()

    def speak_again(self, *, forget: bool = False) -> None:
        """Pass bytes on again; with ``forget``, first drop the connections from its
        clients without a word to the server (their goodbyes lost in the silence): the
        server's sessions live on, as after a long outage."""
        if forget:
            with self.guard:
                clients, self.clients = self.clients, []
            for client in clients:
                client.close()
        self.silent.clear()

    def _accept(self) -> None:
        while not self.closing.is_set():
            try:
                client, _ = self.listener.accept()
            except TimeoutError:
                continue
            server = socket.create_connection(self.target)
            with self.guard:
                self.sockets += [client, server]
                self.clients.append(client)
            for source, sink in ((client, server), (server, client)):
                thread = threading.Thread(target=self._relay, args=(source, sink), daemon=True)
                self.threads.append(thread)
                thread.start()

    def _relay(self, source: socket.socket, sink: socket.socket) -> None:
        with contextlib.suppress(OSError, ValueError):
            while not self.closing.is_set():
                # Asked after select: what arrives once silent is left unread.
                if not select.select([source], [], [], 0.1)[0] or self.silent.is_set():
                    time.sleep(0.05)
                    continue
                data = source.recv(65536)
                if not data:
                    sink.shutdown(socket.SHUT_WR)
                    return
                sink.sendall(data)

    def close(self) -> None:
        self.closing.set()
        for thread in self.threads:
            thread.join(5.0)
        for sock in [*self.sockets, self.listener]:
            sock.close()


def classifier_row(scenario_id: str, model: Any) -> Any:
    """A trained classifier's ``classifiers`` row, as a train job stores it."""
    import json

    import numpy as np

    from service.store import ClassifierRow

    document = model.to_json()
    return ClassifierRow(
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


def job_clock(monkeypatch: pytest.MonkeyPatch, after_claim: float) -> list[float]:
    """Every job run from now on (``worker.runner.execute_job``) reads a clock of its own
    that says 0 at its claim and ``now[0]`` at every reading after it: ``after_claim``
    until the test moves it (``now`` is returned). So a job's time limit, at least 1 s
    (``TIME_LIMIT_MIN_S``), runs out where the test says, with no sleep and on a machine
    of any speed; a limit of 1e-9 s did that before the floor."""
    import worker.runner
    from worker.context import JobContext

    now = [after_claim]

    def context(*args: Any, **kwargs: Any) -> JobContext:
        readings = iter([0.0])
        return JobContext(*args, clock=lambda: next(readings, now[0]), **kwargs)

    monkeypatch.setattr(worker.runner, "JobContext", context)
    return now
