"""/health (never a 5xx), the OpenAPI document and the interactive docs."""

from __future__ import annotations

import os
import resource
import sqlite3
import subprocess
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import UTC, timedelta
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import delete, text

from inertia_id import Scenario
from service.config import Settings
from service.store.jobs import config_hash
from service.store.models import JobRow, ScenarioRow, WorkerRow, utcnow
from service.store.session import Database

from .support import Api, make_settings, read_only_postgres


def add_worker(
    api: Api,
    name: str,
    seconds_ago: float,
    *,
    warming_for_s: float | None = None,
    without_lock_for_s: float | None = None,
) -> None:
    """A worker row last beaten ``seconds_ago``; ``warming_for_s``: its task process has
    been warming up that long (a replacement importing the core); ``without_lock_for_s``:
    it has not held its incarnation lock for that long."""
    now = utcnow()
    seen = now - timedelta(seconds=seconds_ago)
    warming = None if warming_for_s is None else now - timedelta(seconds=warming_for_s)
    lockless = None if without_lock_for_s is None else now - timedelta(seconds=without_lock_for_s)
    with api.db.session() as session:
        session.add(
            WorkerRow(
                name=name,
                broker_url="filesystem://",
                started_at=seen,
                last_seen_at=seen,
                warming_since=warming,
                lock_missing_since=lockless,
            )
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
        "duplicates_seen": 0,
        "window_s": 3 * api.settings.heartbeat_interval_s,
        "warming": [],
        "without_lock": [],
        "gone": [],
        "warming_limit_s": api.settings.heartbeat_timeout_s,
        "state_unknown_since": None,
        "last_known": [],
        "detail": f"no worker seen in the last {3 * api.settings.heartbeat_interval_s:g} s",
    }


def test_health_counts_recently_seen_workers(api: Api) -> None:
    add_worker(api, "celery@alive", seconds_ago=1.0)
    add_worker(api, "celery@gone", seconds_ago=3600.0)
    health = api.get("/health").json()
    assert health["status"] == "ok"
    assert health["workers"]["names"] == ["celery@alive"]
    assert health["workers"]["count"] == 1


def test_health_leaves_out_a_worker_told_to_stop(api: Api) -> None:
    # SIGTERM: the worker marks its row stopping and takes no job any more; it leaves
    # the list at once, not when its last beat falls out of the window.
    add_worker(api, "celery@alive", seconds_ago=1.0)
    add_worker(api, "celery@stopped", seconds_ago=1.0)
    with api.db.session() as session:
        row = session.get(WorkerRow, "celery@stopped")
        assert row is not None
        row.stopping_since = utcnow()
    health = api.get("/health").json()
    assert health["workers"]["names"] == ["celery@alive"]
    with api.db.session() as session:
        row = session.get(WorkerRow, "celery@alive")
        assert row is not None
        row.stopping_since = utcnow()
    health = api.get("/health").json()
    assert (health["status"], health["workers"]["count"]) == ("degraded", 0)


def test_health_is_ok_while_a_workers_task_process_warms_up(api: Api) -> None:
    # Its task process retired after its jobs (or its memory limit) and the replacement
    # imports the core: the worker beats on and takes the queued jobs once warm. It used
    # to drop out of the list, and /health said "degraded" after every such job.
    add_worker(api, "celery@warming", seconds_ago=1.0, warming_for_s=12.0)
    add_job(api, "queued", seconds_ago=api.settings.queue_stall_s + 60.0, seed=1)
    health = api.get("/health").json()
    assert health["status"] == "ok", health
    workers = health["workers"]
    assert (workers["ok"], workers["names"], workers["detail"]) == (True, ["celery@warming"], None)
    [warming] = workers["warming"]
    assert warming["name"] == "celery@warming"
    assert 12.0 <= warming["warming_s"] < 60.0
    # It takes no job while warming: the queue waits for it, it is not stalled.
    assert health["queue"]["stalled"] is False


def test_health_is_degraded_when_a_warm_up_takes_too_long(api: Api) -> None:
    limit = min(api.settings.heartbeat_timeout_s, api.settings.worker_start_timeout_s)
    add_worker(api, "celery@ready", seconds_ago=1.0)
    add_worker(api, "celery@stuck", seconds_ago=1.0, warming_for_s=limit + 30.0)
    health = api.get("/health").json()
    assert health["status"] == "degraded"
    workers = health["workers"]
    assert workers["ok"] is False and workers["warming_limit_s"] == limit
    assert workers["names"] == ["celery@ready", "celery@stuck"]
    assert [w["name"] for w in workers["warming"]] == ["celery@stuck"]
    assert "worker celery@stuck has been warming up for" in workers["detail"]
    assert f"(over {limit:g} s)" in workers["detail"]


def test_health_is_degraded_when_no_live_worker_holds_its_incarnation_lock(api: Api) -> None:
    # Such a worker leaves every job sent to it queued (a same-name twin could take its
    # run): before, /health said "ok" while the queue waited for it.
    add_worker(api, "celery@lockless", seconds_ago=1.0, without_lock_for_s=20.0)
    health = api.get("/health").json()
    assert health["status"] == "degraded", health
    workers = health["workers"]
    assert (workers["ok"], workers["names"]) == (False, ["celery@lockless"])
    [lockless] = workers["without_lock"]
    assert lockless["name"] == "celery@lockless" and 20.0 <= lockless["without_lock_s"] < 60.0
    assert "worker celery@lockless has not held its incarnation lock for" in workers["detail"]
    # A worker that holds its lock takes the jobs: listed, yet "ok".
    add_worker(api, "celery@locked", seconds_ago=1.0)
    health = api.get("/health").json()
    assert health["status"] == "ok", health
    assert [w["name"] for w in health["workers"]["without_lock"]] == ["celery@lockless"]
    assert health["workers"]["detail"] is None


def test_a_warming_worker_that_stopped_beating_is_gone(api: Api) -> None:
    add_worker(api, "celery@dead", seconds_ago=3600.0, warming_for_s=3600.0)
    health = api.get("/health").json()
    assert health["status"] == "degraded"
    assert (health["workers"]["names"], health["workers"]["warming"]) == ([], [])


def test_a_worker_whose_process_is_gone_is_listed_gone_not_warming(api: Api) -> None:
    """Killed (kill -9) as it warmed up: its row, which it can no longer beat, still
    says warming within the silence window, but its incarnation lock went with it."""
    from worker.incarnation import Life

    live = Life(api.settings.resolved_database_url, "live-incarnation")
    assert live.hold()
    try:
        add_worker(api, "celery@killed", seconds_ago=2.0, warming_for_s=20.0)
        add_worker(api, "celery@live", seconds_ago=2.0, warming_for_s=5.0)
        with api.db.session() as session:
            session.get_one(WorkerRow, "celery@killed").incarnation = "dead-incarnation"
            session.get_one(WorkerRow, "celery@live").incarnation = live.incarnation
        health = api.get("/health").json()
        workers = health["workers"]
        # Before: both listed, the dead one warming 20 s, until its row fell out of the
        # silence window.
        assert (workers["names"], [w["name"] for w in workers["warming"]]) == (
            ["celery@live"],
            ["celery@live"],
        ), workers
        assert [w["name"] for w in workers["gone"]] == ["celery@killed"], workers
        assert 2.0 <= workers["gone"][0]["silent_s"] < 2.0 + 30.0
        assert health["status"] == "ok", health
    finally:
        live.release()
    # The only worker gone: no live worker, and the detail says which is gone.
    health = api.get("/health").json()
    assert health["status"] == "degraded"
    assert "worker celery@live's process is gone" in health["workers"]["detail"], health


def test_health_reads_the_locks_of_many_gone_workers_at_a_cost_that_does_not_grow(
    api: Api,
) -> None:
    """Each killed worker leaves a row its lock tells gone. Before: on PostgreSQL each
    row was probed in its own savepoint (a try-lock and an unlock), 4 statements a row:
    /health took 0.10 s with 50 such rows and 1.06 s with 500. Now the statements are
    as many with 30 gone rows as with 1."""
    from sqlalchemy import event

    def statements_of_health(gone: int) -> int:
        with api.db.session() as session:
            session.execute(delete(WorkerRow))
        for index in range(gone):
            add_worker(api, f"celery@killed-{index}", seconds_ago=2.0)
            with api.db.session() as session:
                session.get_one(WorkerRow, f"celery@killed-{index}").incarnation = f"dead-{index}"
        executed: list[str] = []

        def count(*args: object) -> None:
            executed.append(str(args[2]))

        engine = api.app.state.db.engine
        event.listen(engine, "before_cursor_execute", count)
        try:
            workers = api.get("/health").json()["workers"]
        finally:
            event.remove(engine, "before_cursor_execute", count)
        assert len(workers["gone"]) == gone, workers
        return len(executed)

    assert statements_of_health(30) == statements_of_health(1)


def add_job(api: Api, status: str, seconds_ago: float, seed: int) -> None:
    """A job of ``status``, created and sent ``seconds_ago``."""
    at = utcnow() - timedelta(seconds=seconds_ago)
    params = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean"}
    with api.db.session() as session:
        scenario = ScenarioRow(name="paper", document=Scenario.paper().model_dump(mode="json"))
        session.add(scenario)
        session.flush()
        session.add(
            JobRow(
                type="train",
                scenario_id=scenario.id,
                params=params,
                config_hash=config_hash("train", scenario.id, params, seed),
                seed=seed,
                status=status,
                created_at=at,
                sent_at=at,
            )
        )


def test_health_is_degraded_when_a_job_waits_long_while_a_worker_is_idle(api: Api) -> None:
    # The worker beats, yet the job it could take has waited past the threshold: its
    # task process cannot start, or its consumer is stuck.
    add_worker(api, "celery@stuck", seconds_ago=1.0)
    waited_s = api.settings.queue_stall_s + 60.0
    add_job(api, "queued", seconds_ago=waited_s, seed=1)
    health = api.get("/health").json()
    assert health["status"] == "degraded"
    assert health["workers"]["ok"] is True
    queue = health["queue"]
    assert queue["ok"] is False and queue["stalled"] is True
    assert queue["oldest_queued_s"] >= waited_s
    assert "1 live worker(s) had no job" in queue["detail"]


def test_health_is_ok_when_a_job_waits_long_for_busy_workers(api: Api) -> None:
    # Every live worker runs a job: a long queue is a busy service, not a broken one.
    add_worker(api, "celery@busy", seconds_ago=1.0)
    add_job(api, "running", seconds_ago=600.0, seed=1)
    add_job(api, "queued", seconds_ago=api.settings.queue_stall_s + 60.0, seed=2)
    health = api.get("/health").json()
    assert health["status"] == "ok", health
    assert health["queue"]["stalled"] is False and health["queue"]["detail"] is None


def test_a_worker_without_its_lock_is_not_an_idle_worker_of_a_stalled_queue(api: Api) -> None:
    # It claims no job until it takes its lock again: listed (workers.without_lock), yet
    # not a worker that beats but takes nothing for no known reason. Before, it counted
    # idle: a busy locked worker's queue was "stalled", and /health "degraded".
    add_worker(api, "celery@busy", seconds_ago=1.0)
    add_worker(api, "celery@lockless", seconds_ago=1.0, without_lock_for_s=300.0)
    add_job(api, "running", seconds_ago=600.0, seed=1)
    add_job(api, "queued", seconds_ago=api.settings.queue_stall_s + 60.0, seed=2)
    health = api.get("/health").json()
    assert health["status"] == "ok", health
    assert health["queue"]["stalled"] is False and health["queue"]["detail"] is None
    # Alone, it is the fault /health names: the workers' detail, not a stalled queue.
    with api.db.session() as session:
        session.get_one(WorkerRow, "celery@busy").lock_missing_since = utcnow()
    health = api.get("/health").json()
    assert health["status"] == "degraded" and health["queue"]["stalled"] is False
    assert "has not held its incarnation lock" in health["workers"]["detail"]


def test_health_is_ok_while_a_fresh_job_waits_for_an_idle_worker(api: Api) -> None:
    add_worker(api, "celery@idle", seconds_ago=1.0)
    add_job(api, "queued", seconds_ago=1.0, seed=1)
    health = api.get("/health").json()
    assert health["status"] == "ok", health
    assert health["queue"]["queued"] == 1 and health["queue"]["stalled"] is False


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
    assert health["database"] == {
        "ok": False,
        "takes_writes": None,
        "detail": "postgresql unreachable",
    }
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


def test_health_is_degraded_naming_the_disk_when_the_data_dir_takes_no_writes(api: Api) -> None:
    # A full disk, stood in for by a file-size limit of 1 KiB on this process (no root
    # needed): a write past it fails (EFBIG; Python ignores SIGXFSZ), as one on a full disk
    # fails (ENOSPC). Before, /health said "ok", "filesystem broker folder writable" and
    # "sqlite reachable" on a full tmpfs where every POST was a 503 and every beat failed:
    # os.access reads the mode bits, and root passes them.
    add_worker(api, "celery@alive", seconds_ago=0.0)
    assert api.get("/health").json()["status"] == "ok"
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (1024, hard))
    try:
        response = api.get("/health")
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "degraded"
    assert health["broker"] == {
        "ok": False,
        "detail": "filesystem broker folder (broker/ in the data dir) takes no writes: "
        "File too large",
    }
    if api.db.engine.dialect.name == "sqlite":
        assert health["database"] == {
            "ok": False,
            "takes_writes": False,
            "detail": "sqlite reachable, but the folder of its file takes no writes: "
            "File too large; workers' heartbeats and results cannot be stored until it "
            "takes writes",
        }
    else:
        assert health["database"]["ok"] is True
    # The database is still read: its workers are listed, not "the database is unreachable".
    assert health["workers"]["names"] == ["celery@alive"]
    assert health["queue"]["ok"] is True
    # Nothing is left behind, and with room again the service is "ok".
    assert not list(api.settings.broker_dir.rglob(".health-probe-*"))
    assert api.get("/health").json()["status"] == "ok"


def test_health_is_degraded_naming_a_read_only_postgresql(api: Api) -> None:
    # Before: "ok" and "postgresql reachable" while every write was a 500.
    if api.db.engine.dialect.name != "postgresql":
        pytest.skip("a PostgreSQL database set read-only")
    add_worker(api, "celery@alive", seconds_ago=0.0)
    assert api.get("/health").json()["status"] == "ok"
    with read_only_postgres(api):
        health = api.get("/health").json()
    assert health["status"] == "degraded"
    assert health["database"] == {
        "ok": False,
        "takes_writes": False,
        "detail": "postgresql reachable, but it takes no writes: its transactions are "
        "read-only (transaction_read_only is on); workers' heartbeats and results cannot be "
        "stored until it takes writes",
    }
    # Still read: the workers are listed.
    assert health["workers"]["names"] == ["celery@alive"]
    assert api.get("/health").json()["status"] == "ok"


@contextmanager
def immutable(*paths: Path) -> Iterator[None]:
    """``paths`` made unwritable, their folder not: immutable (``chattr +i``) where this
    process may set that (root, whom mode bits do not stop), else mode 0444."""
    as_root = os.geteuid() == 0
    if as_root:
        done = subprocess.run(["chattr", "+i", *map(str, paths)], capture_output=True, text=True)
        if done.returncode != 0:
            pytest.skip(f"chattr +i is refused here: {done.stderr.strip()}")
    else:
        for path in paths:
            path.chmod(0o444)
    try:
        yield
    finally:
        if as_root:
            subprocess.run(["chattr", "-i", *map(str, paths)], check=True)
        else:
            for path in paths:
                path.chmod(0o644)


def test_health_is_degraded_naming_a_sqlite_file_that_takes_no_writes(api: Api) -> None:
    # Before: "ok", "sqlite reachable" with the database file and its WAL immutable and
    # their folder writable, while every write was a 503 and every beat failed, until the
    # workers' beats went stale.
    if api.db.engine.dialect.name != "sqlite":
        pytest.skip("a SQLite file made read-only")
    add_worker(api, "celery@alive", seconds_ago=0.0)
    assert api.get("/health").json()["status"] == "ok"
    path = Path(str(api.db.engine.url.database))
    files = [p for p in (path, path.with_name(path.name + "-wal")) if p.exists()]
    with immutable(*files):
        health = api.get("/health").json()
        assert api.post("/scenarios", json={"preset": "paper"}).status_code == 503
    assert health["status"] == "degraded"
    assert health["database"] == {
        "ok": False,
        "takes_writes": False,
        "detail": "sqlite reachable, but its file takes no writes: attempt to write a "
        "readonly database; workers' heartbeats and results cannot be stored until it "
        "takes writes",
    }
    assert health["workers"]["names"] == ["celery@alive"]
    assert api.get("/health").json()["status"] == "ok"
    assert api.post("/scenarios", json={"preset": "paper"}).status_code == 201


def test_health_takes_a_sqlite_writer_holding_the_lock_for_a_database_that_takes_writes(
    api: Api,
) -> None:
    # The file probe begins a write: behind a long writer it is refused at once
    # (SQLITE_BUSY, no busy timeout), which means writes are taken, not "takes no writes".
    if api.db.engine.dialect.name != "sqlite":
        pytest.skip("SQLite's write lock")
    add_worker(api, "celery@alive", seconds_ago=0.0)
    writer = sqlite3.connect(str(api.db.engine.url.database), isolation_level=None)
    try:
        writer.execute("BEGIN IMMEDIATE")
        writer.execute("UPDATE workers SET broker_url = broker_url")
        health = api.get("/health").json()
    finally:
        writer.execute("ROLLBACK")
        writer.close()
    assert health["database"] == {"ok": True, "takes_writes": True, "detail": "sqlite reachable"}
    assert health["status"] == "ok"


@contextmanager
def writes_refused(api: Api) -> Iterator[None]:
    """The test's database answering but refusing writes: a PostgreSQL one read-only, a
    SQLite one on a full disk (a 1 KiB file-size limit on this process, see above)."""
    if api.db.engine.dialect.name == "postgresql":
        with read_only_postgres(api):
            yield
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (1024, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


def test_health_says_the_workers_state_is_unknown_while_the_database_refuses_writes(
    api: Api,
) -> None:
    # The workers' beats are refused as every write is: their last one stored falls out
    # of the window, and /health said "no worker seen in the last 3 s" while they beat on
    # and one held a finished run's result for the database to take (under `inertia-id
    # serve` on a full tmpfs; a celery worker on a read-only PostgreSQL).
    add_worker(api, "celery@held", seconds_ago=40.0)
    add_worker(api, "celery@beside", seconds_ago=41.0)
    add_worker(api, "celery@long-gone", seconds_ago=3600.0)
    add_job(api, "running", seconds_ago=60.0, seed=1)
    with api.db.session() as session:
        last_beat = session.get_one(WorkerRow, "celery@held").last_seen_at
    with writes_refused(api):
        response = api.get("/health")
    assert response.status_code == 200
    health = response.json()
    assert health["status"] == "degraded"
    assert "no worker seen" not in health["workers"]["detail"], health["workers"]
    database = health["database"]
    assert database["ok"] is False and database["takes_writes"] is False
    assert database["detail"].endswith(
        "; workers' heartbeats and results cannot be stored until it takes writes"
    )
    workers = health["workers"]
    assert workers["ok"] is False and workers["names"] == []
    assert workers["last_known"] == ["celery@beside", "celery@held"]
    stamp = last_beat.replace(tzinfo=UTC) if last_beat.tzinfo is None else last_beat
    assert workers["state_unknown_since"] == stamp.isoformat().replace("+00:00", "Z")
    detail = workers["detail"]
    second = stamp.astimezone(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    assert detail.startswith(
        f"the workers' state is unknown since {second}"
        " (their last beat stored): the database refuses writes, their heartbeats included; "
        "live then: celery@beside, celery@held; 1 job(s) running as last stored: a run that "
        "finished since keeps its result and stores it once the database takes writes"
    ), detail
    # Writes taken again, and no beat since: no worker seen, as before.
    health = api.get("/health").json()
    assert health["database"] == {
        "ok": True,
        "takes_writes": True,
        "detail": health["database"]["detail"],
    }
    assert health["workers"]["state_unknown_since"] is None
    assert health["workers"]["last_known"] == []
    assert health["workers"]["detail"].startswith("no worker seen in the last")


def test_health_does_not_call_a_postgresql_read_only_after_its_setting_is_reset(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A session keeps the default_transaction_read_only it started with: the API's pooled
    # connection opened during a read-only spell read "on" after the reset, and /health
    # said "takes no writes" while the workers stored their beats again (a celery worker
    # and the API on a scratch database: "degraded ... read-only" 10 s after the reset).
    if api.db.engine.dialect.name != "postgresql":
        pytest.skip("a PostgreSQL session's read-only default")
    add_worker(api, "celery@alive", seconds_ago=0.0)
    with read_only_postgres(api) as reset:
        assert api.get("/health").json()["database"]["ok"] is False
        reset()
        # The pool still holds the session opened read-only; what the probe's own session
        # read answers for a second (app.api.health._FRESH_FOR_S), a second passed.
        from app.api import health as module

        later = _clock_now() + module._FRESH_FOR_S
        monkeypatch.setattr(module, "_clock", lambda: later)
        health = api.get("/health").json()
    assert health["database"]["detail"] == "postgresql reachable", health
    assert health["database"] == {
        "ok": True,
        "takes_writes": True,
        "detail": "postgresql reachable",
    }
    assert health["status"] == "ok"


def _clock_now() -> float:
    from app.api import health

    return health._clock()


def _backend_pids(database: Database, count: int) -> set[int]:
    """The PostgreSQL sessions behind ``count`` connections taken from the pool at once."""
    held = [database.engine.connect() for _ in range(count)]
    try:
        return {c.execute(text("SELECT pg_backend_pid()")).scalar_one() for c in held}
    finally:
        for connection in held:
            connection.close()


def test_health_keeps_the_pools_sessions_while_postgresql_is_read_only(api: Api) -> None:
    # While the database is read-only its pooled sessions read "on" as they should: each
    # /health closed every idle one of the API's pool (the next request to take one opened
    # a new session), so every poll during the spell cost the other requests their
    # connections (20 pollers: 1,990 sessions opened in 15 s, 775 while it took writes).
    if api.db.engine.dialect.name != "postgresql":
        pytest.skip("a PostgreSQL session's read-only default")
    with read_only_postgres(api):
        # Three sessions opened read-only, idle in the pool as after three requests.
        before = _backend_pids(api.db, 3)
        for _ in range(3):
            database = api.get("/health").json()["database"]
            assert database["takes_writes"] is False, database
            assert "read-only" in database["detail"], database
        after = _backend_pids(api.db, 3)
    assert after == before


def test_polls_at_once_on_a_read_only_postgresql_share_the_probes_new_session(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The pooled session's "read-only" is checked on a session opened for the probe,
    # outside the pool: each poll opened its own (20 pollers: up to 20 sessions beyond
    # the pool's). Within a second (the clock held still here) they share one.
    if api.db.engine.dialect.name != "postgresql":
        pytest.skip("a PostgreSQL session's read-only default")
    from app.api import health

    monkeypatch.setattr(health, "_clock", lambda: 1000.0, raising=False)
    dialect = api.db.engine.dialect
    opened: list[int] = []
    connect = dialect.connect

    def counted(*args: Any, **kwargs: Any) -> Any:
        opened.append(1)
        return connect(*args, **kwargs)

    with read_only_postgres(api):
        _backend_pids(api.db, 3)  # the pool's sessions, opened read-only
        monkeypatch.setattr(dialect, "connect", counted)
        try:
            for _ in range(3):
                assert api.get("/health").json()["database"]["takes_writes"] is False
        finally:
            monkeypatch.undo()
    assert len(opened) == 1
