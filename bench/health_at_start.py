"""What ``/health`` says, second by second, while a worker starts.

``--shape serve``: ``python -m app.serve`` as the README runs it (the API and one worker,
SQLite and the filesystem broker, a fresh data dir), ``/health`` polled from the moment
it is started. ``--shape worker``: the scale-out shape, the API under uvicorn as the
compose file runs it, then, once it answers, one ``celery -A worker.celery_app worker
--concurrency=1`` as the compose file and README start one (``--store sqlite``: a SQLite
file and the filesystem broker; ``--store postgresql``: a fresh database on
``--postgres`` and Redis at ``--redis``), ``/health`` polled from the worker's start.
``--restart`` (worker shape) names the worker (``-n``), and once it is warm kills its main
process (``kill -9``) and starts it again under the same name, polled from the kill;
with ``--new-name`` both go unnamed, as the compose file starts them, so the restart gets
a name of its own (``celery-<token>@host``; serve's restarts do too).
``--busy N`` keeps N processes spinning on the CPU meanwhile, as a loaded machine.
``--repo`` runs another checkout (the code before a change) by the same procedure.

Prints the runs of equal answers (status, workers listed, warm-ups under way and their
age, workers whose process is gone) in seconds since the start polled.

Run: python bench/health_at_start.py [--shape serve|worker] [--store sqlite|postgresql]
     [--restart [--new-name]] [--seconds 40] [--busy 0] [--repo PATH]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
from _common import (
    add_repo,
    base_parser,
    begin,
    free_port,
    print_table,
    scratch_postgres,
    service_env,
    spawn_service,
    state_runs,
    stop_service,
    write_json,
)

State = tuple[str, str, str, str]


def _state(health: dict[str, Any] | None) -> State:
    if health is None:
        return "no answer", "-", "-", "-"
    workers = health["workers"]
    warming = ", ".join(f"{w['name']} {w['warming_s']:.0f} s" for w in workers["warming"])
    # "gone" exists only in the code after the change: before, a dead worker was
    # listed as it last beat until its row left the window.
    gone = ", ".join(w["name"] for w in workers.get("gone") or [])
    return health["status"], ", ".join(workers["names"]) or "-", warming or "-", gone or "-"


def _busy() -> None:
    while True:
        pass


def _poll(client: httpx.Client, began: float, until: float, interval: float) -> list[Any]:
    samples: list[tuple[float, State]] = []
    while True:
        now = time.perf_counter()
        try:
            health: dict[str, Any] | None = client.get("/health").json()
        except httpx.TransportError:
            health = None
        samples.append((now - began, _state(health)))
        if now - began >= until:
            return samples
        time.sleep(max(0.0, interval - (time.perf_counter() - now)))


def _warm(client: httpx.Client) -> bool:
    workers = client.get("/health").json()["workers"]
    return bool(workers["names"]) and not workers["warming"]


@contextmanager
def _store(args: argparse.Namespace, root: Path) -> Iterator[dict[str, str]]:
    """DATABASE_URL and BROKER_URL of a fresh store, dropped after."""
    if args.store == "sqlite":
        yield {"DATABASE_URL": f"sqlite:///{root / 'data' / 'inertia-id.db'}"}
        return
    with scratch_postgres(args.postgres) as url:
        yield {"DATABASE_URL": url, "BROKER_URL": args.redis}


def _serve(args: argparse.Namespace, root: Path, env: dict[str, str]) -> list[Any]:
    port = free_port()
    argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
    began = time.perf_counter()
    process = spawn_service(argv, log_path=root / "serve.log", cwd=root, env=env)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
            return _poll(client, began, args.seconds, args.interval)
    finally:
        stop_service(process)


def _worker(args: argparse.Namespace, root: Path, env: dict[str, str]) -> list[Any]:
    port = free_port()
    api_argv = [
        sys.executable, "-m", "uvicorn", "app.main:create_app", "--factory",
        "--host", "127.0.0.1", "--port", str(port),
    ]  # fmt: skip
    worker_argv = [
        sys.executable, "-m", "celery", "-A", "worker.celery_app", "worker",
        "--concurrency=1", "--loglevel=INFO",
    ]  # fmt: skip
    if args.restart and not args.new_name:
        worker_argv += ["-n", f"bench-{uuid.uuid4().hex[:6]}@%h"]
    api = spawn_service(api_argv, log_path=root / "api.log", cwd=root, env=env)
    workers: list[subprocess.Popen[bytes]] = []
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
            deadline = time.perf_counter() + 120
            while True:
                try:
                    client.get("/health").raise_for_status()
                    break
                except httpx.TransportError:
                    if time.perf_counter() > deadline or api.poll() is not None:
                        raise RuntimeError((root / "api.log").read_text()) from None
                    time.sleep(0.2)
            began = time.perf_counter()
            workers.append(
                spawn_service(worker_argv, log_path=root / "worker1.log", cwd=root, env=env)
            )
            if not args.restart:
                return _poll(client, began, args.seconds, args.interval)
            while not _warm(client):
                if time.perf_counter() - began > 300:
                    raise RuntimeError((root / "worker1.log").read_text())
                time.sleep(0.2)
            # The main process alone, as the kernel's OOM killer or kill -9 of its pid:
            # its task process follows it (PR_SET_PDEATHSIG).
            os.kill(workers[0].pid, signal.SIGKILL)
            workers[0].wait(10)
            began = time.perf_counter()
            workers.append(
                spawn_service(worker_argv, log_path=root / "worker2.log", cwd=root, env=env)
            )
            return _poll(client, began, args.seconds, args.interval)
    finally:
        for worker in workers:
            stop_service(worker)
        stop_service(api)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--shape", choices=["serve", "worker"], default="serve")
    parser.add_argument("--store", choices=["sqlite", "postgresql"], default="sqlite")
    parser.add_argument("--restart", action="store_true", help="kill -9 and start again")
    parser.add_argument(
        "--new-name",
        action="store_true",
        help="with --restart, no -n: the restart gets a name of its own, as compose's do",
    )
    parser.add_argument("--seconds", type=float, default=40.0, help="s polled")
    parser.add_argument("--interval", type=float, default=0.5, help="s between two polls")
    parser.add_argument(
        "--postgres", default="postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
    )
    parser.add_argument(
        "--redis", default=os.environ.get("INERTIA_ID_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")
    )
    parser.add_argument(
        "--busy", type=int, default=0, help="processes spinning on the CPU meanwhile (load)"
    )
    add_repo(parser)
    args = begin(parser, "/health while a worker starts")
    if args.shape == "serve" and (args.restart or args.store != "sqlite"):
        parser.error("--restart and --store postgresql are for --shape worker")
    if args.new_name and not args.restart:
        parser.error("--new-name goes with --restart")
    hogs = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.busy)]
    for hog in hogs:
        hog.start()
    try:
        with tempfile.TemporaryDirectory() as folder:
            root = Path(folder)
            (root / "data").mkdir()
            env = service_env(Path(args.repo).resolve())
            if args.shape == "serve":
                samples = _serve(args, root, env)
            else:
                with _store(args, root) as urls:
                    env.update(urls, INERTIA_ID_DATA_DIR=str(root / "data"))
                    env["INERTIA_ID_API_KEY"] = "bench-" + uuid.uuid4().hex
                    samples = _worker(args, root, env)
    finally:
        for hog in hogs:
            hog.kill()
    rows = state_runs(samples)
    print_table(["from s", "to s", "status", "workers", "warming", "gone"], rows)
    write_json(args.json, args, {"samples": samples})


if __name__ == "__main__":
    main()
