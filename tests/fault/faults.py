"""The service as it ships, and the faults done to it.

- :class:`Serve`: one ``python -m app.serve`` process (the shipped command: the API and
  its worker subprocesses), on a data dir of its deployment, driven over HTTP with the
  key it generated and printed in its banner;
- :class:`RedisServer`, :class:`PostgresCluster`: private brokers and database clusters
  on free ports in a temporary folder, for the tests that stop and restart them (the
  machine's shared services are never touched);
- :func:`processes_of`: every live process of a data dir, found through ``/proc`` (the
  ``INERTIA_ID_DATA_DIR`` that serve hands its workers), to show none is left behind;
- :func:`assert_settled`: the end of every test: every job terminal, failures with a
  reason, no row lost.

Timing is never asserted: deadlines here are "it did not happen at all" guards.
"""

from __future__ import annotations

import asyncio
import glob
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Coroutine, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import httpx
from service_support import (
    POSTGRES_ADMIN_URL,
    TERMINAL,
    clean_env,
    free_port,
    load_job,
    require_service,
    start_in_group,
    wait_for,
    wait_for_job,
)
from service_support import postgres_database as shared_postgres_database
from sqlalchemy import select

from service.store import Database, JobRow, MetricRow, ScenarioRow

GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4

#: Short beats, so that dead workers and lost messages are noticed in seconds (the
#: production defaults are minutes). The silence that marks a worker dead is three
#: intervals: long enough that a busy two-core machine does not fake one.
FAST_TIMINGS = {
    "INERTIA_ID_HEARTBEAT_INTERVAL_S": "1",
    "INERTIA_ID_HEARTBEAT_TIMEOUT_S": "30",
    "INERTIA_ID_RESEND_AFTER_S": "3",
    "INERTIA_ID_UNSENT_GRACE_S": "2",
}

#: A tiny train job (well under a second of work).
TINY_TRAIN: dict[str, Any] = {
    "sequence": GOOD_SEQUENCE,
    "kind": "nearest-centroid",
    "metric": "euclidean",
    "n_realisations": 3,
}


def random_search(timesteps: int, time_limit_s: float | None = None) -> dict[str, Any]:
    """A random search: about 1.2-2 ms of work a step with the compiled simulator on
    the 2-core machine (6,000 steps: about 8 s; 3 ms with numpy's RK4, when 1,200 steps
    were enough to be caught running), stopped within a second by a cancel or a
    hand-back, or by ``time_limit_s`` (counted from each claim), which then ends it
    "succeeded" (stopped: time_limit) with a re-score of a second or so."""
    limit = {} if time_limit_s is None else {"time_limit_s": time_limit_s}
    return {
        **limit,
        "method": "random",
        "sequence_length": 2,
        "timesteps": timesteps,
        "n_realisations": 5,
        "metric": "euclidean",
        "sakoe_chiba_radius": 2,
        "fuel_weight": 0.0,
        "patience_episodes": None,
    }


T = TypeVar("T")


def run_async(coroutine: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run`` on a thread of its own: the browser tests' Playwright keeps an
    event loop running on the main thread for the whole session."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coroutine).result()


def service_env(data_dir: Path, **extra: str) -> dict[str, str]:
    """This process's environment without any inertia-id setting, on ``data_dir``, plus
    ``extra``."""
    return clean_env(PYTHONUNBUFFERED="1", INERTIA_ID_DATA_DIR=str(data_dir), **extra)


# --------------------------------------------------------------------------- processes


def _read(path: str) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError:
        return b""


def processes_of(data_dir: Path) -> dict[int, str]:
    """Live processes (pid -> command line) whose environment names ``data_dir``: serve,
    its API processes, its workers and their task processes. Zombies have no
    environment and are not counted."""
    marker = f"INERTIA_ID_DATA_DIR={data_dir}".encode()
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == os.getpid():
            continue
        if marker in _read(f"/proc/{entry}/environ").split(b"\0"):
            found[int(entry)] = _read(f"/proc/{entry}/cmdline").replace(b"\0", b" ").decode()
    return found


def children_of(pid: int) -> list[int]:
    """Live direct children of ``pid``."""
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        stat = _read(f"/proc/{entry}/stat").decode(errors="replace")
        # "pid (comm) state ppid ...": comm may hold spaces and parentheses.
        fields = stat.rpartition(")")[2].split()
        if len(fields) >= 2 and fields[1] == str(pid) and fields[0] != "Z":
            out.append(int(entry))
    return out


def alive(pid: int) -> bool:
    stat = _read(f"/proc/{pid}/stat").decode(errors="replace")
    fields = stat.rpartition(")")[2].split()
    return bool(fields) and fields[0] not in ("Z", "X")


def kill_all(pids: Iterable[int]) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


# --------------------------------------------------------------------------- serve

_KEY = re.compile(r"^API key:   (\S+)\n\s+\(generated now", re.MULTILINE)
_WORKER = re.compile(r"worker(\d+) started \(pid (\d+), name (\S+)\)")


@dataclass
class Serve:
    """One ``python -m app.serve`` and what its banner and log say."""

    process: subprocess.Popen[bytes]
    log_path: Path
    port: int
    data_dir: Path
    workers: int
    key: str = ""

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def log(self, chars: int = 6000) -> str:
        text = _read(str(self.log_path)).decode(errors="replace")
        parts = [f"--- serve log {self.log_path} ---\n{text[-chars:]}"]
        for path in sorted((self.data_dir / "logs").glob("worker*.log")):
            worker_log = _read(str(path)).decode(errors="replace")
            parts.append(f"--- {path.name} ---\n{worker_log[-3000:]}")
        return "\n".join(parts)

    def generated_key(self) -> str | None:
        found = _KEY.search(_read(str(self.log_path)).decode(errors="replace"))
        return found.group(1) if found else None

    def worker_pids(self) -> dict[str, int]:
        """Worker name (``worker1-3fa2c1``) -> pid, as logged; the latest start of each."""
        text = _read(str(self.log_path)).decode(errors="replace")
        by_index: dict[str, tuple[str, int]] = {}
        for index, pid, name in _WORKER.findall(text):
            by_index[index] = (name, int(pid))
        return {name: pid for name, pid in by_index.values()}

    def client(self, timeout_s: float = 30.0) -> httpx.Client:
        return httpx.Client(base_url=self.base, headers={"X-API-Key": self.key}, timeout=timeout_s)

    def running(self) -> bool:
        return self.process.poll() is None

    def kill(self) -> None:
        """``kill -9`` of serve alone: its workers are left to notice."""
        try:
            self.process.send_signal(signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait(10)

    def terminate(self, timeout_s: float = 60.0) -> int:
        """SIGTERM (a graceful restart, ``docker stop``); the exit status."""
        self.process.send_signal(signal.SIGTERM)
        try:
            return self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(
                f"serve ignored SIGTERM for {timeout_s:g} s\n{self.log()}"
            ) from None


# --------------------------------------------------------------------------- backends


def postgres_database(admin_url: str = POSTGRES_ADMIN_URL) -> Iterator[str]:
    """A fresh database on the server at ``admin_url``; dropped when exhausted."""
    return shared_postgres_database(admin_url, prefix="inertia_id_fault")


class RedisServer:
    """A private ``redis-server`` (no persistence) on a free port, for tests that stop
    and restart the broker."""

    def __init__(self, root: Path, port: int | None = None) -> None:
        binary = shutil.which("redis-server")
        if binary is None:
            require_service("redis-server", "not installed (apt-get install redis-server)")
        self.binary = str(binary)
        self.root = root
        self.port = port or free_port()
        self.process: subprocess.Popen[bytes] | None = None
        root.mkdir(parents=True, exist_ok=True)

    def url(self, db: int = 0) -> str:
        return f"redis://127.0.0.1:{self.port}/{db}"

    def start(self) -> RedisServer:
        self.process = start_in_group(
            [
                self.binary,
                "--port",
                str(self.port),
                "--bind",
                "127.0.0.1",
                "--save",
                "",
                "--appendonly",
                "no",
                "--dir",
                str(self.root),
            ],
            log_path=self.root / "redis.log",
            append=True,
        )
        import redis

        client = redis.Redis.from_url(self.url(), socket_connect_timeout=1)

        def answers() -> bool:
            if self.process is not None and self.process.poll() is not None:
                raise AssertionError(f"redis-server exited\n{self.log()}")
            try:
                return bool(client.ping())
            except redis.RedisError:
                return False

        try:
            wait_for(answers, 30, "redis-server did not answer", self.log)
        except AssertionError:
            self.stop()
            raise
        finally:
            client.close()
        return self

    def log(self) -> str:
        return _read(str(self.root / "redis.log")).decode(errors="replace")[-3000:]

    def flush(self) -> None:
        import redis

        client = redis.Redis.from_url(self.url(), socket_connect_timeout=2)
        try:
            client.flushall()
        finally:
            client.close()

    def stop(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait(10)
        self.process = None


def _postgres_bin() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: p.split("/")[4])
    return Path(found[-1]).parent if found else None


class PostgresCluster:
    """A private PostgreSQL cluster (initdb) on a free port, owned by the ``postgres``
    user, for the test that restarts the database under the service."""

    def __init__(self) -> None:
        bindir = _postgres_bin()
        if bindir is None:
            require_service("PostgreSQL server binaries", "no /usr/lib/postgresql/*/bin/initdb")
        self.bindir = bindir
        # Not under pytest's tmp_path: the postgres user must be able to reach the folder.
        self.dir = Path(tempfile.mkdtemp(prefix="inertia-id-pg-"))
        self.data = self.dir / "data"
        self.port = free_port()

    def _as_postgres(self, *command: str) -> subprocess.CompletedProcess[str]:
        prefix = ["runuser", "-u", "postgres", "--"] if os.geteuid() == 0 else []
        return subprocess.run(
            [*prefix, *command], capture_output=True, text=True, timeout=120, cwd=self.dir
        )

    def url(self, database: str = "postgres") -> str:
        return f"postgresql+psycopg://postgres@127.0.0.1:{self.port}/{database}"

    def init(self) -> PostgresCluster:
        if os.geteuid() == 0:
            shutil.chown(self.dir, "postgres", "postgres")
        done = self._as_postgres(
            str(self.bindir / "initdb"), "-D", str(self.data), "-U", "postgres", "-A", "trust"
        )
        if done.returncode != 0:
            require_service("a private PostgreSQL cluster (initdb)", done.stderr[-2000:])
        return self

    def start(self) -> None:
        options = (
            f"-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1 -c fsync=off "
            "-c full_page_writes=off"
        )
        done = self._as_postgres(
            str(self.bindir / "pg_ctl"),
            "-D",
            str(self.data),
            "-o",
            options,
            "-l",
            str(self.dir / "postgres.log"),
            "-w",
            "start",
        )
        assert done.returncode == 0, f"pg_ctl start failed: {done.stderr}\n{self.log()}"

    def stop(self) -> None:
        self._as_postgres(
            str(self.bindir / "pg_ctl"), "-D", str(self.data), "-m", "fast", "-w", "stop"
        )

    def log(self) -> str:
        return _read(str(self.dir / "postgres.log")).decode(errors="replace")[-3000:]

    def remove(self) -> None:
        self._as_postgres(
            str(self.bindir / "pg_ctl"), "-D", str(self.data), "-m", "immediate", "-w", "stop"
        )
        shutil.rmtree(self.dir, ignore_errors=True)


# --------------------------------------------------------------------------- deployment


@dataclass
class Deployment:
    """A data dir on a database and a broker, and the serve processes run on it.

    :param kind: ``sqlite`` (the embedded default: SQLite and the filesystem broker, no
        ``DATABASE_URL``/``BROKER_URL``) or ``postgres`` (PostgreSQL and Redis).
    """

    kind: str
    root: Path
    database_url: str
    env: dict[str, str]
    redis: RedisServer | None = None
    key: str = ""
    serves: list[Serve] = field(default_factory=list)
    jobs: set[str] = field(default_factory=set)
    _db: Database | None = None

    @classmethod
    def on_postgres(cls, root: Path, database_url: str, redis: RedisServer) -> Deployment:
        """The ``postgres`` shape on ``root``: the database at ``database_url``, Redis
        database 0 of ``redis`` as the broker, with the fast timings."""
        env = service_env(
            (root / "data").resolve(),
            DATABASE_URL=database_url,
            BROKER_URL=redis.url(0),
            **FAST_TIMINGS,
        )
        return cls("postgres", root, database_url, env, redis=redis)

    @property
    def data_dir(self) -> Path:
        return (self.root / "data").resolve()

    def wait_gone(self, timeout_s: float, what: str) -> None:
        """Wait until no process of the data dir is left (serve, its API and verdict
        processes, its workers and their task processes)."""
        wait_for(
            lambda: not processes_of(self.data_dir),
            timeout_s,
            what,
            lambda: f"{processes_of(self.data_dir)}\n{self.logs()}",
        )

    @property
    def db(self) -> Database:
        if self._db is None:
            self._db = Database(self.database_url)
        return self._db

    def logs(self) -> str:
        return "\n".join(s.log() for s in self.serves[-2:])

    def serve(
        self,
        *,
        workers: int = 1,
        api_workers: int = 1,
        ready_timeout_s: float = 120.0,
        **extra_env: str,
    ) -> Serve:
        """Start ``python -m app.serve`` and wait until its API answers and all its
        workers have reported in."""
        port = free_port()
        log_path = self.root / f"serve-{len(self.serves) + 1}.log"
        process = start_in_group(
            [
                sys.executable,
                "-m",
                "app.serve",
                "--port",
                str(port),
                "--data-dir",
                str(self.data_dir),
                "--workers",
                str(workers),
                "--api-workers",
                str(api_workers),
            ],
            log_path=log_path,
            cwd=self.root,
            env={**self.env, **extra_env},
        )
        serve = Serve(process, log_path, port, self.data_dir, workers)
        self.serves.append(serve)

        def ready() -> bool:
            if not serve.running():
                raise AssertionError(f"serve exited with {process.returncode}\n{serve.log()}")
            names = set(serve.worker_pids())
            if len(names) < workers:
                return False
            health = httpx.get(f"{serve.base}/health", timeout=10).json()
            # Listed from their first beat; up once warm.
            warming = {w["name"] for w in health["workers"]["warming"]}
            seen = {n.partition("@")[0] for n in health["workers"]["names"] if n not in warming}
            return names <= seen

        wait_for(ready, ready_timeout_s, "serve did not come up with its workers", serve.log)
        generated = serve.generated_key()
        if generated:
            self.key = generated
        assert self.key, f"serve printed no generated API key\n{serve.log()}"
        serve.key = self.key
        return serve

    # ---- jobs

    def scenario(self, client: httpx.Client) -> str:
        created = client.post("/scenarios", json={"preset": "paper"})
        assert created.status_code == 201, created.text
        return str(created.json()["id"])

    def submit(
        self,
        client: httpx.Client,
        scenario_id: str,
        job_type: str,
        params: dict[str, Any],
        *,
        seed: int = 0,
    ) -> str:
        answer = client.post(
            "/jobs",
            json={"type": job_type, "scenario_id": scenario_id, "seed": seed, "params": params},
        )
        assert answer.status_code == 202, answer.text
        job_id = str(answer.json()["id"])
        self.jobs.add(job_id)
        return job_id

    def job(self, job_id: str) -> JobRow:
        return load_job(self.db, job_id)

    def wait_job(
        self, job_id: str, statuses: tuple[str, ...] = TERMINAL, timeout_s: float = 180.0
    ) -> JobRow:
        return wait_for_job(self.db, job_id, statuses=statuses, timeout_s=timeout_s, logs=self.logs)

    def metrics(self, job_id: str) -> list[tuple[str, int]]:
        with self.db.session() as session:
            rows = session.execute(
                select(MetricRow.key, MetricRow.step)
                .where(MetricRow.job_id == job_id)
                .order_by(MetricRow.key, MetricRow.step, MetricRow.id)
            ).all()
        return [(k, s) for k, s in rows]

    def close(self) -> None:
        for serve in self.serves:
            if serve.running():
                serve.kill()
        kill_all(processes_of(self.data_dir))
        if self._db is not None:
            self._db.dispose()


def assert_settled(deployment: Deployment, *, also: Iterable[str] = ()) -> list[JobRow]:
    """Every job terminal (none queued or running), each failure or cancel with its
    reason, and every job the test submitted still there."""
    with deployment.db.session() as session:
        rows = list(session.scalars(select(JobRow)).all())
        for row in rows:
            session.expunge(row)
        scenarios = set(session.scalars(select(ScenarioRow.id)).all())
    by_id = {row.id: row for row in rows}
    missing = (deployment.jobs | set(also)) - set(by_id)
    assert not missing, f"job rows lost: {sorted(missing)}"
    stuck = [(r.id, r.type, r.status, r.error) for r in rows if r.status not in TERMINAL]
    assert not stuck, f"jobs not finished: {stuck}\n{deployment.logs()}"
    silent = [(r.id, r.status) for r in rows if r.status != "succeeded" and not r.error]
    assert not silent, f"jobs ended without a reason: {silent}"
    orphans = [r.id for r in rows if r.scenario_id not in scenarios]
    assert not orphans, f"jobs of a missing scenario: {orphans}"
    return rows
