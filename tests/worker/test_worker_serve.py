"""``inertia-id serve``: API and workers from one command, stopped together."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
import urllib.request
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from service_support import (
    SilentableProxy,
    classifier_row,
    clean_env,
    free_port,
    tail,
    wait_for,
)
from sqlalchemy import make_url, select

from inertia_id import Scenario
from service.config import Settings
from service.queue import RUN_JOB_TASK, make_celery
from service.store import Database, JobRow, ScenarioRow, WorkerRow
from service.store.jobs import config_hash
from service.store.models import utcnow
from service.store.refusals import database_label

if TYPE_CHECKING:
    from conftest import Store


def test_serve_help_lists_its_options_from_both_entry_points() -> None:
    for command in (
        [sys.executable, "-m", "app.serve", "--help"],
        [sys.executable, "-m", "inertia_id.cli", "serve", "--help"],
    ):
        done = subprocess.run(command, capture_output=True, text=True, env=clean_env(), timeout=60)
        assert done.returncode == 0, done.stderr
        for option in ("--host", "--port", "--data-dir", "--workers"):
            assert option in done.stdout
        assert "127.0.0.1" in done.stdout
        # Each option that takes its default from a variable names it: with
        # INERTIA_ID_HOST=0.0.0.0 set, the help said "default 127.0.0.1" while serve
        # bound every address.
        help_text = " ".join(done.stdout.split())
        for variable in (
            "INERTIA_ID_HOST",
            "INERTIA_ID_PORT",
            "INERTIA_ID_DATA_DIR",
            "INERTIA_ID_API_WORKERS",
        ):
            assert variable in help_text


def test_serve_refuses_a_negative_worker_count() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "app.serve", "--workers", "-1"],
        capture_output=True,
        text=True,
        env=clean_env(),
        timeout=60,
    )
    assert done.returncode == 2 and "--workers must be >= 0, got -1" in done.stderr


def test_serve_refuses_a_bad_setting_in_one_line_naming_it(tmp_path: Path) -> None:
    """A setting from the environment that is no value of its type or range ended serve
    with a pydantic traceback; it is one line per setting, and nothing is created."""
    env = {
        **clean_env(),
        "INERTIA_ID_REQUEST_HEAD_TIMEOUT_S": "abc",
        "INERTIA_ID_QUEUE_STALL_S": "0",
    }
    with socket.socket() as probe:  # a port free now: the port check comes first
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    done = subprocess.run(
        [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=60,
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[0].startswith("inertia-id serve: INERTIA_ID_REQUEST_HEAD_TIMEOUT_S='abc': ")
    assert lines[1].startswith("inertia-id serve: INERTIA_ID_QUEUE_STALL_S='0': ")
    assert len(lines) == 2 and not (tmp_path / "data").exists()


def test_serve_refuses_a_bad_port_or_api_workers_setting_in_one_line(tmp_path: Path) -> None:
    """INERTIA_ID_PORT=x (or INERTIA_ID_API_WORKERS=two) ended serve with a traceback from
    building its parser, --port given or not; it is one line naming the variable and its
    value, exit 1, nothing created. A --port given wins over the variable."""
    env = {**clean_env(), "INERTIA_ID_PORT": "x", "INERTIA_ID_API_WORKERS": "two"}
    command = [sys.executable, "-m", "app.serve", "--data-dir", "data"]
    done = subprocess.run(
        command, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=60
    )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines[0].startswith("inertia-id serve: INERTIA_ID_PORT='x': ")
    assert lines[1].startswith("inertia-id serve: INERTIA_ID_API_WORKERS='two': ")
    assert len(lines) == 2 and not (tmp_path / "data").exists()
    # --port given: the variable is not read; the other one still is.
    done = subprocess.run(
        [*command, "--port", "1"], capture_output=True, text=True, env=env, cwd=tmp_path, timeout=60
    )
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        "inertia-id serve: INERTIA_ID_API_WORKERS='two': "
    )


def test_serve_on_a_busy_port_says_so_before_starting_anything(tmp_path: Path) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = subprocess.run(
            [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
            capture_output=True,
            text=True,
            env=clean_env(),
            cwd=tmp_path,
            timeout=60,
        )
    assert done.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port}: Address already in use" in done.stderr
    assert not (tmp_path / "data").exists()


def _get(url: str) -> Any:
    with urllib.request.urlopen(url, timeout=5) as response:
        return json.loads(response.read())


def test_serve_runs_the_api_and_a_worker_that_does_jobs_then_stops_both(
    tmp_path: Path, short_tmpdir: Path
) -> None:
    """serve as it ships (one API process, one worker, the verdict process eager): its
    worker does a job written as the API writes it, and SIGTERM, sent with a request in
    flight, ends serve with 128 + 15 having stopped everything it started. One start
    checks what four did:

    - The fork server and verdict process of the API, the resource tracker and the
      workers' processes are all gone by the time serve has exited. Before, the fork
      server (ppid 1) outlived serve by over a second at each of 12 stops (it tears down
      its preloaded imports once serve's end of its pipe closes).
    - Nothing of serve's is left in ``TMPDIR``. Before, each stop left an empty
      ``pymp-*`` folder of the worker's (billiard's pool makes it; serve kills the worker
      once its job is handed back, so the worker's exit never removed it).
    - The workers are told to stop at once, and wind down while uvicorn waits for the
      requests in flight (an upload left half sent, which holds it for its whole grace);
      serve waits for them once the API has stopped. Before, they were told only after
      the API had stopped: under /identify load serve took the grace and then the
      workers' wind-down, one after the other. Asserted as the order of the log's lines."""
    data_dir = tmp_path / "data"
    port = free_port()
    log = tmp_path / "serve.log"
    temp = short_tmpdir
    slow: socket.socket | None = None
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", str(data_dir)],
            env=clean_env(TMPDIR=str(temp)),
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    try:
        base = f"http://127.0.0.1:{port}"
        health = wait_for(
            lambda: (h := _get(f"{base}/health"))["workers"]["count"] == 1 and h,
            90,
            "the API did not report one live worker",
            lambda: tail(log),
        )
        assert health["status"] == "ok" and re.fullmatch(
            r"worker1-[0-9a-f]{6}@.+", health["workers"]["names"][0]
        )
        banner = log.read_text()
        assert f"URL:       {base}" in banner and f"{base}/docs" in banner
        assert re.search(r"API key:   \S{20,}", banner), banner
        worker_pid = int(re.search(r"worker1 started \(pid (\d+),", banner).group(1))  # type: ignore[union-attr]
        key = re.search(r"API key:   (\S{20,})", banner).group(1)  # type: ignore[union-attr]

        # Warm: the verdict process forked from the fork server (it listens in the API's
        # temp folder; eager is the default, so a default that changed fails this wait),
        # the worker's task process warm (the pool made its shared memory, in the
        # worker's temp folder, before it forked the process).
        tree = wait_for(
            lambda: (
                log.read_text().count("Application startup complete") == 1
                and _verdict_processes_up(server.pid, 1)
                and not _get(f"{base}/health")["workers"]["warming"]
                and (found := _descendants(server.pid))
                and any("celery" in c for c in found.values())
                and found
            ),
            120,
            "serve's verdict process did not start, or its worker did not warm up",
            lambda: tail(log),
        )
        made = _left_in(temp)

        # A job written the way the API writes it is run by serve's worker.
        settings = Settings(INERTIA_ID_DATA_DIR=data_dir)
        db = Database(settings.resolved_database_url)
        params = {"sequence": [[4, 4, 4, 0, 0, 0]] * 4, "metric": "euclidean", "n_realisations": 3}
        with db.session() as session:
            scenario = ScenarioRow(name="paper", document=Scenario.paper().model_dump(mode="json"))
            session.add(scenario)
            session.flush()
            job = JobRow(
                type="train",
                scenario_id=scenario.id,
                params=params,
                config_hash=config_hash("train", scenario.id, params, 0),
            )
            session.add(job)
            session.flush()
            job_id = job.id
        make_celery(settings).send_task(RUN_JOB_TASK, args=[job_id])

        def finished() -> str | None:
            with db.session() as session:
                status = session.get(JobRow, job_id).status  # type: ignore[union-attr]
            return status if status in ("succeeded", "failed", "cancelled") else None

        assert wait_for(finished, 90, "the job did not finish", lambda: tail(log)) == "succeeded"
        db.dispose()
        # Nothing of the service lands in the working directory.
        assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "serve.log"]
        slow = _hold_a_request_in_flight(port, key)
    finally:
        try:
            _stop_serve(server)
        finally:
            if slow is not None:
                slow.close()
    _assert_workers_told_before_the_api_stopped(log, 1)
    # SIGTERM ends serve through its cleanup, with the conventional 128 + 15.
    assert server.returncode == 128 + signal.SIGTERM, tail(log)
    text = log.read_text()
    assert "workers stopped" in text
    assert not _alive(worker_pid), f"worker pid {worker_pid} still alive after serve stopped"
    left = {pid: command for pid, command in tree.items() if _alive(pid)}
    for pid in left:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    assert not left, f"left behind by serve: {left}\n{tail(log)}"
    assert "shutdown complete: no process of this service is left" in text
    assert made, "serve made no temp folder: the test saw nothing to clean up"
    left_files = _left_in(temp)
    assert not left_files, (
        f"left in TMPDIR by serve (made while it ran: {made}): {left_files}\n{tail(log)}"
    )


def test_the_socket_shared_by_several_api_processes_accepts_connections_without_nagle() -> None:
    # uvicorn's own listening socket has protocol 0, so asyncio left TCP_NODELAY off the
    # connections it accepted: each response then waited ~40 ms for a delayed ACK.
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    import uvicorn

    from app.serve import tcp_socket

    config = uvicorn.Config("app.main:create_app", factory=True, host="127.0.0.1", port=0)
    listening = tcp_socket(config.bind_socket())
    assert listening.proto == socket.IPPROTO_TCP
    # As an API process receives it (multiprocessing rebuilds it with the same protocol).
    shared = socket.socket(
        listening.family, listening.type, listening.proto, fileno=os.dup(listening.fileno())
    )
    listening.close()

    async def nodelay_of_an_accepted_connection() -> int:
        seen: asyncio.Future[int] = asyncio.get_running_loop().create_future()

        class Probe(asyncio.Protocol):
            def connection_made(self, transport: asyncio.BaseTransport) -> None:
                sock = transport.get_extra_info("socket")
                seen.set_result(sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY))

        server = await asyncio.get_running_loop().create_server(Probe, sock=shared)
        _reader, writer = await asyncio.open_connection(*shared.getsockname()[:2])
        try:
            return await asyncio.wait_for(seen, 10)
        finally:
            writer.close()
            server.close()

    # On a thread of its own: Playwright (tests/browser) keeps the main thread's loop.
    with ThreadPoolExecutor(1) as pool:
        nodelay = pool.submit(asyncio.run, nodelay_of_an_accepted_connection()).result()
    assert nodelay != 0


def test_serve_lists_a_worker_it_started_as_warming_before_its_first_beat(
    store: Store, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A worker's main process imports Celery for seconds before its first beat. Before,
    /health said "no worker seen" meanwhile, 4 s after serve's API first answered. Now
    serve records each worker it starts as warming, keeps its row seen while the process
    lives and has not beaten, and removes it once the process is gone."""
    from app.api.health import health
    from app.serve import WorkerPool

    # A worker that never gets to its first beat.
    monkeypatch.setattr(
        WorkerPool,
        "command",
        lambda _self, _index: [sys.executable, "-c", "import time; time.sleep(60)"],
    )
    pool = WorkerPool(1, tmp_path / "logs", settings=store.settings)
    celery = make_celery(store.settings)
    pool.start()
    name = pool.node_name(1)

    def seen_at() -> datetime:
        with store.db.session() as session:
            return session.get_one(WorkerRow, name).last_seen_at

    def age_row() -> None:
        with store.db.session() as session:
            session.get_one(WorkerRow, name).last_seen_at = utcnow() - timedelta(seconds=60)

    try:
        report = health(store.settings, store.db, celery)
        assert (report.status, report.workers.names) == ("ok", [name]), report.workers
        assert [w.name for w in report.workers.warming] == [name], report.workers
        age_row()
        old = seen_at()
        wait_for(lambda: seen_at() != old, 10.0, "the starting worker's row was not kept", str)
        process = pool.processes[1]
        process.kill()
        process.wait(10)

        def row_gone() -> bool:
            with store.db.session() as session:
                return session.get(WorkerRow, name) is None

        # Ended before its first beat: its row is removed (the supervisor looks every
        # second), not left "warming" until its silence window ends.
        wait_for(row_gone, 10.0, "the dead worker's row was kept", str)
        report = health(store.settings, store.db, celery)
        assert (report.status, report.workers.names) == ("degraded", []), report.workers
    finally:
        pool.stop(grace_s=1.0)


def test_a_worker_stopped_before_its_first_beat_at_serve_s_stop_is_no_error(
    store: Store, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """serve stopped (SIGTERM, Ctrl-C) while a worker still imports: the worker ends at
    serve's request before its first beat. That was logged at ERROR as a crash ("worker1
    (pid ...) exited with status -15 before its first beat"); now it is an INFO line
    saying it was stopped, and its announced row is still removed."""
    from app.serve import WorkerPool

    monkeypatch.setattr(
        WorkerPool,
        "command",
        lambda _self, _index: [sys.executable, "-c", "import time; time.sleep(60)"],
    )
    pool = WorkerPool(1, tmp_path / "logs", settings=store.settings)
    pool.start()
    name = pool.node_name(1)
    with caplog.at_level(logging.INFO, logger="inertia_id.serve"):
        pool.request_stop()
        pool.stop(grace_s=5.0)
    records = [r for r in caplog.records if r.name == "inertia_id.serve"]
    assert [r.getMessage() for r in records if r.levelno >= logging.WARNING] == []
    assert any("stopped before its first beat" in r.getMessage() for r in records), [
        r.getMessage() for r in records
    ]
    with store.db.session() as session:
        assert session.get(WorkerRow, name) is None


def test_serve_lists_no_worker_whose_process_crashes_before_its_first_beat(
    store: Store, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A worker that crashes while importing (a bad setting, a broken install) never
    beats. Its announced row said "warming" until its silence window ended, and each of
    serve's restarts (a name of its own each) announced another: /health stayed "ok"
    with up to 3 warming workers for as long as serve ran (90 s seen) while none lived.
    Now the row of a process that ended unbeaten is removed, and its restarts are not
    announced: /health says no worker is seen from the first crash on."""
    import app.serve
    from app.api.health import health
    from app.serve import WorkerPool

    monkeypatch.setattr(app.serve, "RESTART_DELAY_S", 0.5)
    monkeypatch.setattr(
        WorkerPool,
        "command",
        lambda _self, _index: [sys.executable, "-c", "raise SystemExit(3)"],
    )

    def rows() -> list[str]:
        with store.db.session() as session:
            return list(session.scalars(select(WorkerRow.name)))

    spawns: list[str] = []
    #: The rows right after each start: the first is announced, its restarts not.
    listed: list[list[str]] = []
    spawn = WorkerPool._spawn

    def counted_spawn(self: WorkerPool, index: int) -> None:
        spawn(self, index)
        spawns.append(self.node_name(index))
        listed.append(rows())

    monkeypatch.setattr(WorkerPool, "_spawn", counted_spawn)
    pool = WorkerPool(1, tmp_path / "logs", settings=store.settings)
    celery = make_celery(store.settings)
    pool.start()

    try:
        # Restarted three times: each under a name of its own.
        wait_for(lambda: len(spawns) >= 4, 30.0, "the worker was not restarted", str)
        assert len(set(spawns)) == len(spawns)
        assert listed[0] == [spawns[0]]
        assert listed[1:] == [[]] * (len(listed) - 1)
        time.sleep(1.5)  # the supervisor looks every second
        assert rows() == []
        report = health(store.settings, store.db, celery)
        assert (report.status, report.workers.names) == ("degraded", []), report.workers
        assert "no worker seen" in (report.workers.detail or "")
    finally:
        pool.stop(grace_s=1.0)


def _descendants(root: int) -> dict[int, str]:
    """``root``'s descendants by pid (their command lines), read from ``/proc``."""
    from app.serve import child_processes

    found: dict[int, str] = {}
    frontier = [root]
    while frontier:
        for pid, (_state, command) in child_processes(frontier.pop()).items():
            found[pid] = command
            frontier.append(pid)
    return found


def _holders(path: Path) -> dict[int, str]:
    """The processes with a descriptor open on ``path`` (their command lines)."""
    found = {}
    for fds in Path("/proc").glob("[0-9]*/fd"):
        with contextlib.suppress(OSError):
            if any(os.readlink(fd) == str(path) for fd in fds.iterdir()):
                command = (fds.parent / "cmdline").read_bytes().replace(b"\0", b" ")
                found[int(fds.parent.name)] = command.decode(errors="replace")
    return found


def _alive(pid: int) -> bool:
    """Whether ``pid`` is a process that has not ended (a zombie has)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rpartition(b")")[2].split()[0] != b"Z"
    except OSError:
        return False


def test_a_second_stop_signal_while_serve_stops_does_not_cut_its_shutdown_short(
    tmp_path: Path,
) -> None:
    """A second SIGTERM (or Ctrl-C) while serve is stopping its workers is logged and
    the shutdown goes on. Before, it raised out of the cleanup: serve exited at once with
    its worker (ppid 1) and fork server still running, and no "workers stopped" line.

    Stopped by Ctrl-C (SIGINT) here, then SIGTERM: the Ctrl-C stop leaves no process
    behind either (SIGTERM's is checked in
    test_serve_runs_the_api_and_a_worker_that_does_jobs_then_stops_both). One start for
    what four did (both signals, first and second, with a stop of each): with one API
    process both first signals take uvicorn's one handler (``Server.handle_exit``, which
    calls ``pool.request_stop``), and once uvicorn returns, each is raised again into
    serve's ``main`` (SIGTERM as SystemExit(143), SIGINT as KeyboardInterrupt) and both
    run the same ``finally``, where both second signals take ``_already_stopping``."""
    port = free_port()
    log = tmp_path / "serve.log"
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
            env=clean_env(),
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    try:
        tree = wait_for(
            lambda: (
                (found := _descendants(server.pid))
                and any("celery" in c for c in found.values())
                and "Uvicorn running" in log.read_text()
                and found
            ),
            120,
            "serve did not start its API and worker",
            lambda: tail(log),
        )
        # Warm first: its worker has beaten, and the verdict process is forked (the fork
        # server has preloaded). The grace runs from the first signal, and the API's stop
        # waits for a verdict process still warming: under a loaded CI that ate the whole
        # grace, and the worker was killed before the second signal could be sent.
        wait_for(
            lambda: (
                (h := _get(f"http://127.0.0.1:{port}/health"))["workers"]["count"] == 1
                and not h["workers"]["warming"]
                and sum("forkserver" in c for c in _descendants(server.pid).values()) >= 2
            ),
            120,
            "serve's worker did not beat, or its verdict process did not start",
            lambda: tail(log),
        )
        tree = _descendants(server.pid)
        # A worker that does not stop (frozen): serve waits its grace for it, the window
        # the second signal must land in. The workers are told to stop at the first
        # signal now, and an idle one was gone before this test could send a second.
        for pid, command in tree.items():
            if "celery" in command:
                os.kill(pid, signal.SIGSTOP)
        server.send_signal(signal.SIGINT)
        wait_for(
            lambda: "stopping workers" in log.read_text(),
            60,
            "serve did not start stopping its workers",
            lambda: tail(log),
        )
        server.send_signal(signal.SIGTERM)
        server.wait(60)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    left = {pid: command for pid, command in tree.items() if _alive(pid)}
    for pid in left:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    text = log.read_text()
    assert not left, f"left behind by serve: {left}\n{tail(log)}"
    assert "workers stopped" in text and "shutdown complete" in text, tail(log)
    assert "SIGTERM while stopping" in text, tail(log)
    # Ctrl-C ends serve with 0, through the same cleanup; the second signal changes nothing.
    assert server.returncode == 0, tail(log)


def _left_in(folder: Path) -> list[str]:
    return sorted(str(path.relative_to(folder)) for path in folder.rglob("*"))


def _stop_serve(server: subprocess.Popen[bytes], stop_signal: int = signal.SIGTERM) -> None:
    """Stop serve as an operator does (SIGTERM, or ``stop_signal``: SIGINT for Ctrl-C);
    killed (and the test failed) past 60 s."""
    server.send_signal(stop_signal)
    try:
        server.wait(60)
    except subprocess.TimeoutExpired:
        server.kill()
        server.wait()
        raise


@pytest.fixture
def short_tmpdir() -> Iterator[Path]:
    """A TMPDIR for serve short enough that the fork server's socket fits in the folder
    serve makes there (``pymp-*/listener-*``, AF_UNIX's 107 bytes): ``tmp_path`` is not,
    once pytest's run counter has three digits (``/tmp/pytest-of-root/pytest-127/popen-gw1/
    test_serve_leaves_nothing_in_t1/tmp``: 108 bytes with the socket), and serve then makes
    its folder in ``/tmp`` instead, where these tests do not look."""
    folder = Path(tempfile.mkdtemp(prefix="iid-", dir="/tmp"))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _verdict_processes_up(root: int, api_workers: int) -> bool:
    """Each API process's fork server has forked its verdict process (eager)."""
    found = _descendants(root).values()
    return sum("multiprocessing.forkserver" in c for c in found) >= 2 * api_workers


def test_serve_with_several_api_processes_stops_in_order_and_leaves_nothing(
    tmp_path: Path, short_tmpdir: Path
) -> None:
    """serve with ``--api-workers 2`` and a worker, stopped by SIGTERM with a request in
    flight. One start checks what two did:

    - At SIGTERM the workers are told to stop at once, and wind down while uvicorn waits
      for the requests in flight (an upload left half sent, which holds it for its whole
      grace); serve waits for them once the API has stopped. Before, they were told only
      after the API had stopped: under /identify load serve took the grace and then the
      workers' wind-down, one after the other. Asserted as the order of the log's lines
      (with one API process, in
      test_serve_runs_the_api_and_a_worker_that_does_jobs_then_stops_both).
    - Nothing of serve's is left in ``TMPDIR``. Before, each stop left one
      ``pymp-*/listener-*`` of each API process (killed by the SIGTERM uvicorn raises
      again after its graceful stop, it never removed it). The worker's folder is told
      apart by its name (``inertia-id-worker1-*``).
    """
    port = free_port()
    log = tmp_path / "serve.log"
    temp = short_tmpdir
    key = "serve-stop-" + "k" * 24
    argv = [*_SERVE, "--port", str(port), "--data-dir", "data"]
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [*argv, "--workers", "1", "--api-workers", "2"],
            env=clean_env(
                TMPDIR=str(temp), INERTIA_ID_VERDICT_PROCESS="eager", INERTIA_ID_API_KEY=key
            ),
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    slow: socket.socket | None = None
    try:
        worker_log = tmp_path / "data" / "logs" / "worker1.log"
        # Warm: each verdict process forked (its API process's fork server listens in
        # the API's temp folder), the worker beating.
        wait_for(
            lambda: (
                log.read_text().count("Application startup complete") == 2
                and _verdict_processes_up(server.pid, 2)
                and worker_log.exists()
                and "heartbeat and reaper" in worker_log.read_text(errors="replace")
            ),
            120,
            "serve's verdict processes or its worker did not start",
            lambda: tail(log) + tail(worker_log),
        )
        made = _left_in(temp)
        slow = _hold_a_request_in_flight(port, key)
    finally:
        try:
            _stop_serve(server)
        finally:
            if slow is not None:
                slow.close()
    _assert_workers_told_before_the_api_stopped(log, 2)
    # SIGTERM ends serve with 128 + 15 whatever --api-workers is. Before, with
    # --api-workers 2 it ended with 0 (uvicorn's supervisor took the signal and
    # returned), with 1 with 143.
    assert server.returncode == 128 + signal.SIGTERM, tail(log)
    assert "shutdown complete" in log.read_text(), tail(log)
    assert any(name.startswith("pymp-") for name in made), (
        f"the API processes made no temp folder: the test saw nothing to clean up: {made}"
    )
    left = _left_in(temp)
    assert not left, f"left in TMPDIR by serve (made while it ran: {made}): {left}\n{tail(log)}"


def test_a_worker_takes_the_temp_folder_serve_made_and_removes_it_at_a_normal_exit(
    tmp_path: Path,
) -> None:
    """A worker's main process started by serve keeps multiprocessing's temp files (its
    pool's shared memory) in the folder serve made for it, which serve removes once it
    has killed the worker; a worker that exits by itself (serve killed, the worker told
    to stop by the kernel) removes it as multiprocessing removes its own. Without the
    folder named, multiprocessing makes its own, as before."""
    given = tmp_path / "given"
    given.mkdir()
    script = textwrap.dedent(
        """
        import os, sys
        import billiard
        from multiprocessing import util
        from worker.process import TEMP_DIR_ENV, use_launcher_temp_dir

        named = os.environ.get(TEMP_DIR_ENV)
        taken = use_launcher_temp_dir()
        assert taken == (named is not None), (taken, named)
        assert TEMP_DIR_ENV not in os.environ  # not for the processes it starts
        billiard.get_context().Value("i")  # what the pool makes: a file in the folder
        folder = util.get_temp_dir()
        assert (folder == named) if taken else folder.startswith(sys.argv[1]), folder
        assert os.path.isdir(folder)
        """
    )
    for env in ({"INERTIA_ID_WORKER_TEMP_DIR": str(given)}, {}):
        done = subprocess.run(
            [sys.executable, "-c", script, str(tmp_path / "pymp-")],
            env=clean_env(TMPDIR=str(tmp_path), **env),
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert (done.returncode, done.stderr) == (0, ""), done.stderr
        assert list(tmp_path.iterdir()) == [], env


def _store_classifier(database_url: str, scenario_id: str, model: Any) -> str:
    """Store a trained classifier as a train job would; its id."""
    db = Database(database_url)
    try:
        with db.session() as session:
            row = classifier_row(scenario_id, model)
            session.add(row)
            session.flush()
            return str(row.id)
    finally:
        db.dispose()


@pytest.mark.parametrize(
    ("api_workers", "stop_signal", "code"),
    # Ctrl-C with two API processes: the supervisor's handle_int and handle_term both
    # only set should_exit, then stop each API process alike (SIGTERM, uvicorn's
    # Multiprocess.terminate_all); only serve's exit status tells them apart.
    [("1", signal.SIGTERM, 128 + signal.SIGTERM), ("2", signal.SIGINT, 0)],
)
def test_serve_identifies_with_a_tmpdir_too_long_for_a_socket_and_leaves_nothing(
    tmp_path: Path, api_workers: str, stop_signal: int, code: int, euclidean_classifier: Any
) -> None:
    """With a TMPDIR of 100 characters the fork server's socket
    (``$TMPDIR/pymp-*/listener-*``) passes AF_UNIX's 107 bytes: no verdict process could
    start (``OSError: AF_UNIX path too long``) and every ``/identify`` was a 500. Each API
    process now says so and puts multiprocessing's temp folder in /tmp, removed at its
    stop as the one in TMPDIR would have been.

    Stopped by SIGTERM with one API process and by Ctrl-C with two, which ends serve with
    0 whatever --api-workers is, as SIGTERM ends it with 128 + 15 (checked with two in
    test_serve_with_several_api_processes_stops_in_order_and_leaves_nothing).
    """
    import numpy as np
    from scenario_support import GOOD_SEQUENCE

    from inertia_id import simulate

    temp = tmp_path / "t"
    temp = Path(str(temp) + "t" * (100 - len(str(temp))))
    temp.mkdir()
    assert len(str(temp)) == 100
    port = free_port()
    log = tmp_path / "serve.log"
    key = "serve-long-tmpdir-" + "k" * 24
    argv = [*_SERVE, "--port", str(port), "--data-dir", "data", "--workers", "0"]
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [*argv, "--api-workers", api_workers],
            env=clean_env(TMPDIR=str(temp), INERTIA_ID_API_KEY=key),
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    base = f"http://127.0.0.1:{port}"
    try:
        wait_for(
            lambda: (
                "AF_UNIX path too long" in log.read_text()
                or (
                    log.read_text().count("Application startup complete") == int(api_workers)
                    and _verdict_processes_up(server.pid, int(api_workers))
                )
            ),
            120,
            "serve's verdict processes did not start",
            lambda: tail(log),
        )
        assert "AF_UNIX path too long" not in log.read_text(), tail(log)
        headers = {"X-API-Key": key, "Content-Type": "application/json"}
        request = urllib.request.Request(
            f"{base}/scenarios", data=b'{"preset": "paper"}', headers=headers
        )
        with urllib.request.urlopen(request, timeout=30) as response:
            scenario_id = json.loads(response.read())["id"]
        database_url = Settings(INERTIA_ID_DATA_DIR=tmp_path / "data").resolved_database_url
        classifier_id = _store_classifier(database_url, scenario_id, euclidean_classifier)
        flight = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(7))
        body = {
            "classifier_id": classifier_id,
            "telemetry": {
                "time_s": flight.time_s.tolist(),
                "omega_rad_s": flight.omega_measured[3, 0].tolist(),
            },
        }
        request = urllib.request.Request(
            f"{base}/identify", data=json.dumps(body).encode(), headers=headers
        )
        with urllib.request.urlopen(request, timeout=60) as response:
            assert response.status == 200
            assert json.loads(response.read())["status"] == "identified"
    finally:
        _stop_serve(server, stop_signal)
    assert server.returncode == code, tail(log)
    assert "shutdown complete" in log.read_text(), tail(log)
    said = re.findall(r"TMPDIR is too long .* its temp folder is (\S+) instead", log.read_text())
    assert len(said) == int(api_workers), tail(log)
    assert all(len(folder) < 30 and not os.path.exists(folder) for folder in said), said
    assert _left_in(temp) == [], tail(log)


def _hold_a_request_in_flight(port: int, key: str) -> socket.socket:
    """An upload left half sent: it holds the API's stop for its whole grace."""
    body = b'{"preset": "paper"}'
    slow = socket.create_connection(("127.0.0.1", port), timeout=60)
    slow.sendall(
        f"POST /scenarios HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: {key}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(body)}\r\n\r\n".encode()
        + body[:5]
    )
    time.sleep(0.5)  # its head read: a request in flight
    return slow


def _assert_workers_told_before_the_api_stopped(log: Path, api_workers: int) -> None:
    """serve's log says the workers were told to stop before the API had stopped, and
    that they had stopped after it."""
    lines = log.read_text().splitlines()

    def first(*markers: str) -> int:
        found = [i for i, line in enumerate(lines) if any(m in line for m in markers)]
        assert found, f"none of {markers} in serve's log:\n{tail(log)}"
        return found[0]

    # The first word to the workers: its own line now, "stopping workers" before.
    told = first("told 1 worker(s) to stop", "stopping workers")
    # One process: uvicorn's own line; several: their supervisor's, after every child's.
    stopped = "Finished server process" if api_workers == 1 else "Stopping parent process"
    api_stopped = first(stopped)
    assert told < api_stopped < first("workers stopped"), "\n".join(lines[told - 5 :])


def test_the_orphan_reaper_leaves_multiprocessing_s_own_children_to_it() -> None:
    """serve's supervisor reaps the orphans it adopted, not the processes that
    multiprocessing started and waits for itself (uvicorn's API processes with
    --api-workers 2). Before, it reaped an API process that had exited: uvicorn then saw
    no exit code (a startup failure not told from a crash) and sent SIGKILL to its pid
    after the health-check timeout, a pid the kernel may have given to another process."""
    import multiprocessing

    from app.serve import child_processes, reap_orphans

    process = multiprocessing.get_context("spawn").Process(target=sys.exit, args=(3,))
    process.start()
    try:
        wait_for(
            lambda: child_processes().get(process.pid or 0, ("",))[0] == "Z",
            60,
            "the child did not exit",
            lambda: "",
        )
        # Only the multiprocessing child is offered: the test process's other children
        # (other tests' ended subprocesses) are kept, as serve keeps its Popen's.
        others = set(child_processes()) - {process.pid}
        assert reap_orphans(others) == 0
        assert child_processes().get(process.pid or 0, ("",))[0] == "Z"
    finally:
        process.join(10)
    assert process.exitcode == 3


def test_the_api_processes_stop_when_serve_is_killed(tmp_path: Path, short_tmpdir: Path) -> None:
    """``kill -9`` of serve with --api-workers 2: the kernel tells its API processes to
    stop (PR_SET_PDEATHSIG), as it tells its workers. Before, both served on (ppid 1) for
    ever, holding serve's port: a new serve on it said "cannot listen". They stop as at
    serve's SIGTERM, and leave nothing in TMPDIR (before, each left its temp folder)."""
    port = free_port()
    log = tmp_path / "serve.log"
    temp = short_tmpdir
    command = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [*command, "--workers", "0", "--api-workers", "2"],
            env=clean_env(TMPDIR=str(temp)),
            cwd=tmp_path,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    api: list[int] = []
    try:
        api = wait_for(
            lambda: (
                len(found := [p for p, c in _descendants(server.pid).items() if "spawn_main" in c])
                == 2
                and log.read_text().count("Application startup complete") == 2
                and _verdict_processes_up(server.pid, 2)
                and found
            ),
            120,
            "serve did not start its two API processes and their verdict processes",
            lambda: tail(log),
        )
        server.kill()
        server.wait(10)
        gone = wait_for(
            lambda: not any(_alive(pid) for pid in api),
            30,
            "the API processes outlived serve",
            lambda: tail(log),
        )
        assert gone
        assert _left_in(temp) == [], tail(log)
    finally:
        if server.poll() is None:
            server.kill()
        for pid in api:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


def _folders_open_in(pid: int, folder: Path) -> set[str]:
    """The names of the folders in ``folder`` that process ``pid`` has open."""
    found = set()
    with contextlib.suppress(OSError):
        for fd in os.listdir(f"/proc/{pid}/fd"):
            with contextlib.suppress(OSError):
                target = Path(os.readlink(f"/proc/{pid}/fd/{fd}"))
                if target.parent == folder:
                    found.add(target.name)
    return found


def test_serve_removes_the_temp_folders_of_a_killed_serve_and_keeps_a_live_one_s(
    tmp_path: Path, short_tmpdir: Path
) -> None:
    """``kill -9`` of serve left its own temp folder in TMPDIR for good (``pymp-*``, the
    fork server's socket in it; a killed process runs no exit), and its worker's where
    the worker was killed with it (a supervisor that kills the whole group). The next
    serve removes them at its start, and keeps the folders of processes still running:
    another serve's beside, and the killed serve's worker while it lives (handing its
    job back)."""
    temp = short_tmpdir
    servers: list[subprocess.Popen[bytes]] = []

    def start(name: str, *options: str, **env: str) -> Path:
        log = tmp_path / f"{name}.log"
        with open(log, "wb") as out:
            servers.append(
                subprocess.Popen(
                    [*_SERVE, "--port", str(free_port()), "--data-dir", name, *options],
                    env=clean_env(TMPDIR=str(temp), **env),
                    cwd=tmp_path,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                )
            )
        return log

    def logs() -> str:
        return "\n".join(tail(log, 3000) for log in sorted(tmp_path.glob("*.log")))

    # The one killed: its worker started, its verdict process forked (the fork server
    # listens in its temp folder). Beside it one that lives on, as cheap as can be.
    killed_log = start("killed", "--workers", "1", INERTIA_ID_VERDICT_PROCESS="eager")
    live_log = start("live", "--workers", "0", INERTIA_ID_VERDICT_PROCESS="lazy")
    killed, live = servers
    worker = 0
    try:
        worker = wait_for(
            lambda: (
                _verdict_processes_up(killed.pid, 1)
                and "Application startup complete" in live_log.read_text()
                and (started := re.search(r"worker1 started \(pid (\d+),", killed_log.read_text()))
                and int(started.group(1))
            ),
            120,
            "the serve to kill did not start its worker and verdict process, or the other "
            "did not start",
            logs,
        )
        made = {path.name for path in temp.iterdir()}
        lives = _folders_open_in(live.pid, temp)
        (worker_folder,) = (name for name in made - lives if name.startswith("inertia-id-worker"))
        serve_folders = made - lives - {worker_folder}
        assert serve_folders, f"the serve to kill made no temp folder of its own: {made}"
        os.kill(worker, signal.SIGSTOP)  # not done handing its job back yet
        killed.kill()
        killed.wait(10)

        later_log = start("later", "--workers", "0", INERTIA_ID_VERDICT_PROCESS="off")
        wait_for(
            lambda: "Application startup complete" in later_log.read_text(),
            120,
            "the later serve did not start",
            logs,
        )
        now = {path.name for path in temp.iterdir()}
        assert not serve_folders & now, f"left by the killed serve: {serve_folders & now}"
        assert worker_folder in now, "the folder of the killed serve's live worker was removed"
        assert lives <= now, f"the live serve's folders were removed: {lives - now}"

        # The worker killed too (the whole group): its folder is no one's now, once its
        # task processes, which hold the folder's lock as forks of the worker, have ended
        # as well (they die a moment after the worker; in CI the folder was still held).
        group = [worker, *_descendants(worker)]
        os.killpg(worker, signal.SIGKILL)
        wait_for(
            lambda: not any(map(_alive, group)), 10, "the worker's group outlived SIGKILL", logs
        )
        from app.temp_folders import remove_stale

        # Until every process holding its lock has ended: once in CI and once in 12 runs
        # here, the folder was still held just after the worker's group was seen dead
        # (which process held it is not known: a holder that stays 10 s fails this and
        # is named by its command line).
        removed: list[str] = []
        wait_for(
            lambda: removed.extend(remove_stale([str(temp)])) or removed,
            10,
            "the dead worker's folder was not removed",
            lambda: f"{logs()}\nheld by: {_holders(temp / worker_folder)}",
        )
        assert removed == [str(temp / worker_folder)]
    finally:
        if worker:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(worker, signal.SIGKILL)
        for server in servers:
            if server.poll() is None:
                _stop_serve(server)
    assert _left_in(temp) == [], logs()


def test_only_unheld_temp_folders_serve_marked_as_its_user_s_are_stale(tmp_path: Path) -> None:
    """What a serve's start removes: the folders it makes for itself and its workers
    (their names, the file that marks them), of its user, that no process holds locked.
    A held one (a live process's), another user's, and one without the file (a
    ``pymp-*`` of any Python program, a worker folder of a serve from before these
    locks, which may be live) are kept."""
    from app.temp_folders import MARKER, SERVE_PREFIX, make_locked, remove_stale, worker_prefix

    base = str(tmp_path)
    held = make_locked(SERVE_PREFIX, base, owner="serve")
    dead = [make_locked(p, base, owner="test") for p in (SERVE_PREFIX, worker_prefix(12))]
    for folder in dead:
        os.close(folder.fd)  # as at its process's end
    assert (Path(held.path) / MARKER).read_text().startswith("serve: ")
    unmarked = [tmp_path / "pymp-abcd1234", tmp_path / "inertia-id-worker1-abcd1234"]
    for folder in unmarked:
        folder.mkdir()
    (tmp_path / "pymp-abcd5678").write_text("a file, not a folder")
    kept = {held.path, *map(str, unmarked)}
    if os.geteuid() == 0:  # another user's, unheld: root can make one
        theirs = make_locked(SERVE_PREFIX, base, owner="theirs")
        os.close(theirs.fd)
        os.chown(theirs.path, 65534, 65534)
        kept.add(theirs.path)
    try:
        removed = remove_stale([base, str(tmp_path / "missing")])
        assert sorted(removed) == sorted(folder.path for folder in dead)
        assert {str(path) for path in tmp_path.iterdir() if path.is_dir()} == kept
    finally:
        held.remove()


_SERVE = [sys.executable, "-m", "app.serve"]


def test_serve_as_subreaper_reaps_an_orphan_that_ended_and_stops_one_that_lives(
    tmp_path: Path,
) -> None:
    """serve adopts its descendants' orphans (a killed worker's task process, say): one
    that has ended is reaped while serve runs (else a zombie until serve ends), and one
    still there at the end is stopped. Run in a process of its own, as serve is."""
    script = tmp_path / "subreaper.py"
    script.write_text(
        textwrap.dedent(
            """
            import os, subprocess, sys, time
            from app.serve import become_subreaper, child_processes, reap_orphans, stop_children

            assert become_subreaper()
            # Each middle process starts a grandchild and exits: the grandchild is orphaned.
            for seconds in ("0.2", "600"):
                subprocess.run([sys.executable, "-c",
                    "import subprocess, sys; subprocess.Popen([sys.executable, '-c', "
                    f"'import time; time.sleep({seconds})'])"], check=True)
            time.sleep(2)
            before = {pid: state for pid, (state, _) in child_processes().items()}
            reaped = reap_orphans(set())
            after = child_processes()
            lines = stop_children(grace_s=2)
            print(sorted(before.values()), reaped, len(after), len(lines), len(child_processes()))
            """
        )
    )
    out = subprocess.run(
        [sys.executable, str(script)], env=clean_env(), capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    # Two adopted (one ended: a zombie, one sleeping), one reaped, one left and stopped.
    assert out.stdout.split("]")[1].split() == ["1", "1", "1", "0"], out.stdout
    assert out.stdout.startswith("['S', 'Z']"), out.stdout


@pytest.mark.parametrize(
    ("url", "said"),
    [
        # No URL at all: SQLAlchemy's ArgumentError traceback from the first connection.
        ("secret-and-no-url", "DATABASE_URL is no database URL "),
        # A kind with no driver here: a "No module named 'MySQLdb'" traceback.
        ("mysql://user:secret@127.0.0.1/inertia", "no driver for the database "),
    ],
)
def test_serve_and_the_worker_refuse_an_unusable_database_url_in_one_line(
    tmp_path: Path, url: str, said: str
) -> None:
    """``serve`` ended in a traceback, nothing said before it; the worker's start (``celery
    -A worker.celery_app``, which imports it) went on, logging the traceback at each
    beat. Now each is one line, exit status 1, the password not shown, nothing created."""
    env = clean_env(DATABASE_URL=url)
    with socket.socket() as probe:  # a port free now: the port check comes first
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    starts = {
        "serve": [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
        "worker": [sys.executable, "-c", "import worker.celery_app"],
        "api": [sys.executable, "-c", "from app.main import create_app; create_app()"],
    }
    for program, command in starts.items():
        done = subprocess.run(
            command, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120
        )
        assert done.returncode == 1, (program, done.stderr)
        assert "Traceback" not in done.stderr, (program, done.stderr)
        lines = done.stderr.strip().splitlines()
        assert lines == [lines[0]] and lines[0].startswith(f"inertia-id {program}: {said}"), (
            program,
            done.stderr,
        )
        assert "secret" not in done.stderr
    assert not (tmp_path / "data").exists()


def _proxy(database_url: str) -> SilentableProxy:
    url = make_url(database_url)
    return SilentableProxy(url.host or "127.0.0.1", url.port or 5432)


def _through(proxy: SilentableProxy, database_url: str) -> str:
    url = make_url(database_url)
    return url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_serve_and_the_api_give_up_a_start_on_a_silent_database_in_one_line(
    store: Store, tmp_path: Path
) -> None:
    """The database's address takes the connection but nothing answers (a proxy frozen,
    or in front of a server that is away). Before, ``serve`` and the API's start (its
    migration) waited for ever, printing nothing (still waiting 30 s on, measured). Now
    their connects give up after 5 s (libpq's connect_timeout) and each says, in one
    line, which database did not answer and what for; nothing is created."""
    proxy = _proxy(store.settings.resolved_database_url)
    proxy.silence()
    through = _through(proxy, store.settings.resolved_database_url)
    starts = {
        "serve": [sys.executable, "-m", "app.serve", "--port", str(free_port()), "--workers", "0"],
        "api": [sys.executable, "-c", "from app.main import create_app; create_app()"],
    }
    try:
        for program, command in starts.items():
            env = clean_env(DATABASE_URL=through, INERTIA_ID_DATA_DIR=str(tmp_path / program))
            try:
                done = subprocess.run(
                    command, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=90
                )
            except subprocess.TimeoutExpired:
                pytest.fail(f"{program} still waited 90 s on a silent database")
            assert done.returncode == 1, (program, done.stderr)
            lines = done.stderr.strip().splitlines()
            assert len(lines) == 1, (program, done.stderr)
            assert lines[0].startswith(
                f"inertia-id {program}: cannot reach the database {database_label(through)} "
                "to migrate it: "
            ), (program, done.stderr)
    finally:
        proxy.close()


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_migrate_gives_up_on_a_silent_database_in_one_line(store: Store, tmp_path: Path) -> None:
    """``inertia-id migrate`` (and its ``--check``) behind a proxy that takes the connection
    and never answers: it waited for ever, printing nothing; now its connect gives up
    after DATABASE_SILENT_S and it says, in one line, which database it could not reach."""
    proxy = _proxy(store.settings.resolved_database_url)
    proxy.silence()
    through = _through(proxy, store.settings.resolved_database_url)
    env = clean_env(DATABASE_URL=through, INERTIA_ID_DATA_DIR=str(tmp_path / "data"))
    try:
        for extra in ([], ["--check"]):
            command = [sys.executable, "-m", "service.store.migrate", *extra]
            try:
                done = subprocess.run(
                    command, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=60
                )
            except subprocess.TimeoutExpired:
                pytest.fail(f"migrate {extra} still waited 60 s on a silent database")
            assert done.returncode == 4, (extra, done.stdout, done.stderr)
            lines = done.stderr.strip().splitlines()
            assert len(lines) == 1, (extra, done.stderr)
            assert lines[0].startswith(
                f"inertia-id migrate: cannot reach the database {database_label(through)}: "
            ), (extra, done.stderr)
    finally:
        proxy.close()


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_serve_s_own_statements_give_up_on_a_database_that_does_not_answer(
    store: Store, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """serve's worker rows (announced as each worker starts, removed as it ends) go out on
    a pooled connection, and its stop's hand-back check on a new one. Behind a proxy
    frozen meanwhile, each waited for ever (still waiting 30 s on, measured), and with
    them serve's stop. Now a statement unanswered DATABASE_ANSWER_S (2 s here) after it
    was sent is cut, a connect gives up after DATABASE_SILENT_S (2 s here), and each
    failure is one warning naming the database, as serve's housekeeping fails."""
    import app.serve
    from app.serve import WorkerPool, _handed_back

    monkeypatch.setattr(app.serve, "DATABASE_SILENT_S", 2.0, raising=False)
    monkeypatch.setattr(app.serve, "DATABASE_ANSWER_S", 2.0, raising=False)
    proxy = _proxy(store.settings.resolved_database_url)
    settings = store.settings.model_copy(
        update={"database_url": _through(proxy, store.settings.resolved_database_url)}
    )
    pool = WorkerPool(0, tmp_path / "logs", settings=settings)
    pool.names[1] = "worker1-silent"
    try:
        pool._announce(1)  # a pooled connection, open through the proxy
        with store.db.session() as session:
            assert session.get(WorkerRow, pool.node_name(1)) is not None
        proxy.silence()
        outcome: list[Any] = []

        def housekeeping() -> None:
            pool._announce(1)
            with contextlib.suppress(Exception):
                _handed_back(settings)([pool.node_name(1)])
                outcome.append("the hand-back check answered")
            outcome.append("done")

        with caplog.at_level(logging.WARNING, logger="inertia_id.serve"):
            thread = threading.Thread(target=housekeeping, daemon=True)
            thread.start()
            thread.join(60.0)
        if thread.is_alive():
            pytest.fail("serve's housekeeping still waited 60 s on a silent database")
        assert outcome == ["done"]
        said = [r.getMessage() for r in caplog.records if r.name == "inertia_id.serve"]
        assert len(said) == 1 and said[0].startswith(
            f"could not record worker1 as starting: the database "
            f"{database_label(settings.resolved_database_url)} did not answer ("
        ), said
    finally:
        proxy.close()
        pool.stop(grace_s=0.0)


@pytest.mark.parametrize("store", ["postgresql"], indirect=True)
def test_serve_tells_its_workers_to_stop_while_its_database_does_not_answer(
    store: Store, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The starting workers' rows are kept each second; behind a frozen proxy that
    statement waits until it is cut (DATABASE_ANSWER_S, 20 s here). It ran on the
    supervisor's thread, which tells the workers to stop at serve's signal: they were
    told only once it had given up. Now it runs on a thread of its own, and the workers
    are told at once."""
    import app.serve
    from app.serve import WorkerPool

    monkeypatch.setattr(app.serve, "DATABASE_ANSWER_S", 20.0, raising=False)
    monkeypatch.setattr(
        WorkerPool,
        "command",
        lambda _self, _index: [sys.executable, "-c", "import time; time.sleep(120)"],
    )
    proxy = _proxy(store.settings.resolved_database_url)
    settings = store.settings.model_copy(
        update={"database_url": _through(proxy, store.settings.resolved_database_url)}
    )
    pool = WorkerPool(1, tmp_path / "logs", settings=settings)
    try:
        pool.start()  # announced as starting, through the proxy
        proxy.silence()
        time.sleep(2.5)  # a look at the starting workers' rows is under way, unanswered
        pool.request_stop()
        try:
            pool.processes[1].wait(10.0)
        except subprocess.TimeoutExpired:
            pytest.fail("the worker was not told to stop within 10 s of serve's signal")
        assert pool.processes[1].returncode == -signal.SIGTERM
    finally:
        proxy.close()
        pool.stop(grace_s=0.0)
