"""What ``/health`` says while a worker starts: its first task process imports the core
(seconds; tens of seconds on a loaded machine) before the worker can take a job.

The worker is listed from its first beat, as warming (the warm-up's age since the worker
started), until its task process is warm. Before, it was listed only once warm: an
operator who started a worker saw no worker at all ("degraded") for the whole warm-up.
A worker killed whole and started again under its name is the new process from that
process's first beat: before, the dead one's row (warming, when it was killed warming)
stayed listed as it was for the silence window, while its restart warmed up unlisted.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from datetime import timedelta
from typing import TYPE_CHECKING, Any

import pytest
from service_support import ROOT, wait_for
from test_worker_replacement import REPLACED_JOB_TIMEOUT_S

import worker.monitor
from app.api.health import health
from service.config import Settings
from service.store import WorkerRow
from service.store.incarnations import lock_held
from service.store.jobs import beat_worker, start_worker
from service.store.models import utcnow
from service.store.session import Database
from worker.incarnation import Life
from worker.monitor import WorkerMonitor

if TYPE_CHECKING:
    from conftest import Service, Store

WORKER = "w1@host"


def _warming(report: Any) -> dict[str, float]:
    return {w.name: w.warming_s for w in report.workers.warming}


def test_a_starting_worker_is_listed_as_warming_from_its_first_beat(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    cold = True
    monkeypatch.setattr(worker.monitor, "warm", lambda: not cold)
    monkeypatch.setattr(worker.monitor, "cold_since", lambda: None)  # none started yet
    url = store.settings.resolved_database_url
    # The worker process started (worker_init) 4 s before its first beat.
    monkeypatch.setattr(worker.monitor, "_started_at", time.time() - 4.0, raising=False)
    monitor = WorkerMonitor(WORKER, store.settings, Life(url, "first"))
    try:
        monitor.tick()
        report = health(store.settings, store.db, monitor.celery)
        # Before: no worker listed, "degraded" ("no worker seen in the last 15 s").
        assert report.workers.names == [WORKER], report.workers
        assert report.status == "ok", report
        # Dated from the worker's start, not from its first beat.
        assert 4.0 <= _warming(report)[WORKER] < 4.0 + 30.0, report.workers.warming
        cold = False
        monitor.tick()
        report = health(store.settings, store.db, monitor.celery)
        assert (report.status, report.workers.names, report.workers.warming) == (
            "ok",
            [WORKER],
            [],
        )
    finally:
        monitor.stop()


def _slow_beating_monitor(
    store: Store, monkeypatch: pytest.MonkeyPatch, is_warm: Callable[[], bool]
) -> WorkerMonitor:
    """A monitor whose interval (600 s) is far beyond a test's waits, its task
    processes warm when ``is_warm`` says: only an early beat comes within them."""
    monkeypatch.setattr(worker.monitor, "warm", is_warm)
    monkeypatch.setattr(worker.monitor, "cold_since", lambda: None)
    settings = store.settings.model_copy(
        update={"heartbeat_interval_s": 600.0, "heartbeat_timeout_s": 1800.0}
    )
    return WorkerMonitor(WORKER, settings, Life(settings.resolved_database_url, "first"))


def test_a_worker_beats_as_soon_as_its_task_process_is_warm_not_an_interval_later(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The warm-up ended between two beats showed in /health only at the next one, up
    to a whole interval (5 s) later; every start that waits for a warm worker waited
    with it. Now the monitor beats once as soon as a task process is warm."""
    cold = True
    monitor = _slow_beating_monitor(store, monkeypatch, lambda: not cold)
    settings = monitor.settings
    beats: list[bool] = []
    store_beat = monitor._store_beat

    def counted() -> None:
        store_beat()
        beats.append(not cold)  # whether that beat found a warm task process

    monkeypatch.setattr(monitor, "_store_beat", counted)

    def warming() -> list[str] | None:
        report = health(settings, store.db, monitor.celery)
        return [w.name for w in report.workers.warming] if report.workers.names else None

    try:
        monitor.start()
        first = wait_for(warming, 10.0, "no first beat stored", lambda: f"beats {beats}")
        assert first == [WORKER]
        time.sleep(0.5)  # cold: no beat but the first
        assert beats == [False]
        cold = False
        wait_for(
            lambda: warming() == [],
            10.0,
            "the warm worker still listed as warming",
            lambda: f"beats {beats}",
        )
        time.sleep(0.5)  # warm: one early beat, then the interval again
        assert beats == [False, True]
    finally:
        monitor.stop()


def test_a_beat_that_fails_before_it_looks_at_the_task_processes_comes_early_once(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The early beat is asked for once a beat that found no warm task process. Before,
    a beat that failed before it looked (here the lock's check) left the question's
    answer yes, and with a task process warm the monitor beat (database, reaper,
    re-sender) at every poll, 0.2 s, instead of every interval (found by a review)."""
    cold = True
    monitor = _slow_beating_monitor(store, monkeypatch, lambda: not cold)
    ticks: list[float] = []
    tick = monitor.tick

    def counted() -> None:
        ticks.append(time.monotonic())
        tick()

    def keep() -> bool:
        raise RuntimeError("lock check failed")

    monkeypatch.setattr(monitor, "tick", counted)
    try:
        monitor.start()
        wait_for(lambda: ticks, 10.0, "no first beat", lambda: "")
        time.sleep(0.3)  # the first beat, cold, stored
        monkeypatch.setattr(monitor.life, "keep", keep)
        cold = False
        time.sleep(2.0)
    finally:
        monitor.stop()
    assert len(ticks) == 2, f"{len(ticks)} beats in about 2 s with a 600 s interval"


def test_a_worker_process_knows_when_it_was_started() -> None:
    """The first warm-up's date: the process's start, before its imports (seconds)."""
    before = time.time()
    printed = subprocess.run(
        [sys.executable, "-c", "import worker.monitor as m; print(m._process_started_at())"],
        capture_output=True,
        text=True,
        check=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    ).stdout
    after = time.time()
    # /proc's uptime is to 10 ms, a process's start to a clock tick.
    assert before - 0.1 <= float(printed) <= after, (before, printed, after)


def test_a_restart_under_its_name_replaces_the_dead_ones_warming_row_at_its_first_beat(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(worker.monitor, "warm", lambda: False)  # the restart warms up
    monkeypatch.setattr(worker.monitor, "cold_since", lambda: None)
    url = store.settings.resolved_database_url
    dead_since = utcnow() - timedelta(seconds=40)
    with store.db.session() as session:
        # The dead process's last beat: it was warming up (a replacement, for 40 s)
        # when it was killed (kill -9), a moment ago.
        start_worker(session, WORKER, "filesystem://", "dead")
        beat_worker(session, WORKER, "filesystem://", warming_since=dead_since, incarnation="dead")
    monkeypatch.setattr(worker.monitor, "_started_at", time.time(), raising=False)
    restart = WorkerMonitor(WORKER, store.settings, Life(url, "restart"))
    try:
        restart.tick()
        with store.db.session() as session:
            row = session.get_one(WorkerRow, WORKER)
            assert row.incarnation == "restart"  # before: "dead", until the restart was warm
        report = health(store.settings, store.db, restart.celery)
        # The restart's own warm-up, seconds old; before, the dead one's, 40 s old.
        assert report.workers.names == [WORKER], report.workers
        assert _warming(report)[WORKER] < 30.0, report.workers.warming
    finally:
        restart.stop()


def _killed(monitor: WorkerMonitor) -> None:
    """As ``kill -9`` of the worker's main process leaves it: its lock let go by the
    operating system (its file left behind), its row as its last beat wrote it."""
    monitor._ticker.stop()
    monitor.life._let_go()
    monitor.db.dispose()
    # A PostgreSQL server ends the lock's session a moment after its client is gone
    # (on SQLite the lock is let go of at once, its file left behind).
    url = monitor.settings.resolved_database_url
    if not url.startswith("postgresql"):
        return
    probe = Database(url)

    def free() -> bool:
        with probe.session() as session:
            return lock_held(session, url, monitor.life.incarnation) is not True

    try:
        wait_for(free, 10.0, "the killed worker's lock was never let go of", lambda: "")
    finally:
        probe.dispose()


@pytest.mark.parametrize("same_name", [True, False], ids=["same-name", "new-name"])
def test_a_killed_worker_is_listed_gone_not_warming_beside_its_restart(
    store: Store, monkeypatch: pytest.MonkeyPatch, same_name: bool
) -> None:
    """Killed while warming up and started again: under its name (``-n w1@host``), or
    under a new one (serve's worker1-<token>, compose's celery-<token>@host), before the
    restart's first beat and after it."""
    cold_since = [time.time() - 40.0]  # a replacement warming up for 40 s
    monkeypatch.setattr(worker.monitor, "warm", lambda: False)
    monkeypatch.setattr(worker.monitor, "cold_since", lambda: cold_since[0])
    url = store.settings.resolved_database_url
    dead = WorkerMonitor(WORKER, store.settings, Life(url, "dead"))
    dead.life.hold()
    dead._booting_since = None  # it had been warm: this is a replacement's warm-up
    dead.tick()
    report = health(store.settings, store.db, dead.celery)
    assert _warming(report) == {WORKER: pytest.approx(40.0, abs=30.0)}, report.workers
    _killed(dead)
    restarted = WORKER if same_name else "w1-4f1a2b@host"
    restart = WorkerMonitor(restarted, store.settings, Life(url, "restart"))
    try:
        restart.life.hold()
        # Before the restart's first beat: the dead one is gone, not warming (before,
        # listed warming 40 s, and live, until its row fell out of the 15 s window).
        report = health(store.settings, store.db, restart.celery)
        assert (report.workers.names, report.workers.warming) == ([], []), report.workers
        assert [w.name for w in report.workers.gone] == [WORKER], report.workers
        assert report.status == "degraded"
        assert f"worker {WORKER}'s process is gone" in (report.workers.detail or "")
        cold_since[0] = time.time()
        restart.tick()
        report = health(store.settings, store.db, restart.celery)
        assert report.workers.names == [restarted], report.workers
        assert list(_warming(report)) == [restarted], report.workers
        assert [w.name for w in report.workers.gone] == ([] if same_name else [WORKER])
        assert report.status == "ok", report
    finally:
        restart.stop()


def test_a_live_twin_takes_back_the_row_a_killed_twin_named(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(worker.monitor, "warm", lambda: True)
    url = store.settings.resolved_database_url
    first = WorkerMonitor(WORKER, store.settings, Life(url, "first"))
    twin = WorkerMonitor(WORKER, store.settings, Life(url, "twin"))
    try:
        for monitor in (first, twin):
            monitor.life.hold()
            monitor.tick()  # the twin, started last, is named by the row
        _killed(twin)
        first.tick()  # the live one's beat: the row names it, and it is listed
        report = health(store.settings, store.db, first.celery)
        assert (report.status, report.workers.names, report.workers.gone) == (
            "ok",
            [WORKER],
            [],
        ), report.workers
    finally:
        first.stop()


def test_two_live_twins_leave_their_shared_row_to_one_of_them(
    store: Store, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Two live processes started under one name by mistake, one warm and one warming.
    Before: each beat wrote its own state and incarnation on the row they share, so
    /health said warming, then warm, then warming, at every beat. Now the row stays the
    twin's that beat it last, the other keeps it seen and says why in its log, and the
    row is the other's once the first has gone."""
    url = store.settings.resolved_database_url
    beating = ["first"]  # the process whose beat runs: "first" is warm, "twin" warming
    monkeypatch.setattr(worker.monitor, "warm", lambda: beating[0] == "first")
    monkeypatch.setattr(worker.monitor, "cold_since", lambda: time.time() - 3.0)
    first = WorkerMonitor(WORKER, store.settings, Life(url, "first"))
    twin = WorkerMonitor(WORKER, store.settings, Life(url, "twin"))
    try:
        for beating[0], monitor in (("first", first), ("twin", twin)):
            monitor.life.hold()
            monitor.tick()  # the twin, started last, is named by the row
        states = []
        for _ in range(3):
            for beating[0], monitor in (("first", first), ("twin", twin)):
                monitor.tick()
                with store.db.session() as session:
                    row = session.get_one(WorkerRow, WORKER)
                    states.append((row.incarnation, row.warming_since is not None))
        assert set(states) == {("twin", True)}, states
        assert "another live process beats under this name (incarnation twin)" in caplog.text
        # /health lists the name once, with the twin's state, and says that a second
        # process beats under it (before: nothing did; the first's state was unseen).
        report = health(store.settings, store.db, first.celery)
        assert (report.workers.names, report.workers.duplicates_seen) == ([WORKER], 1)
        assert "give each worker its own name" in (report.workers.detail or "")
        _killed(twin)
        beating[0] = "first"
        first.tick()  # the twin's lock is free: the row is this one's again
        report = health(store.settings, store.db, first.celery)
        assert (report.status, report.workers.names, report.workers.warming) == (
            "ok",
            [WORKER],
            [],
        ), report.workers
        assert (report.workers.duplicates_seen, report.workers.detail) == (0, None)
    finally:
        first.stop()


def _settings(deployment: Service) -> Settings:
    return Settings(
        INERTIA_ID_DATA_DIR=deployment.settings.data_dir,
        DATABASE_URL=deployment.settings.database_url,
        BROKER_URL=deployment.settings.broker_url,
        # A warm-up on a loaded machine (38 s measured) stays within the warming limit.
        INERTIA_ID_HEARTBEAT_TIMEOUT_S=300,
    )


def test_health_lists_a_real_worker_warming_while_it_starts(deployment: Service) -> None:
    """A ``celery worker`` as the compose file and README start one: from its first beat
    until its task process is warm, /health lists it as warming and says "ok"."""
    settings = _settings(deployment)
    started = deployment.spawn_worker()
    seen: list[tuple[str, list[str], list[str]]] = []

    def warm() -> bool:
        report = health(settings, deployment.db, deployment.celery)
        names = [n for n in report.workers.names if n.startswith(f"{started.name}@")]
        warming = [w.name for w in report.workers.warming if w.name in names]
        if names:
            seen.append((report.status, names, warming))
        return bool(names) and not warming

    try:
        wait_for(warm, REPLACED_JOB_TIMEOUT_S, "the worker never became warm", started.log)
        # Its first beat comes while its task process imports the core (seconds).
        assert seen[0][2] == seen[0][1], seen[:3]  # before: first listed once warm
        assert all(status == "ok" for status, _, _ in seen), seen
    finally:
        started.stop()
