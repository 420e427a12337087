"""The service as shipped, under load: /identify, job pick-up and fixed cost, start-up.

Runs the default configuration, ``python -m app.serve`` with one worker and the API key
it GENERATES (read from its banner, as a user would), on both deployments:

- ``sqlite``: the embedded default (SQLite file, filesystem broker), no configuration;
- ``postgres``: PostgreSQL (a fresh database, dropped after) and Redis (``--redis-url``,
  a database number of its own: it is flushed before and after).

For each, and for 1 and 2 API processes (``--api-workers``):

- **start-up**: process spawn to the first 200 from ``/health``, and to ``/health``
  counting the worker;
- **classifiers**, trained through jobs: the default one (no kind: the marginal
  likelihood) and a DTW one (kind clustering, metric dtw);
- **/identify**: ``--clients`` concurrent clients (1, 20, 50) for ``--duration`` s each,
  one simulated 80-sample flight (JSON): requests/s, p50/p95/p99/max latency, errors
  (any non-200; 503s counted apart), the share of correct verdicts, and the CPU the API
  processes and this load generator spent per request. Beside it the computation alone:
  the same classifier (downloaded) and telemetry through ``inertia_id.identify`` in a
  loop in this process, ms per call and the implied requests/s per core. The first
  request to each API process (a cold classifier) is reported apart;
- **jobs** (first API setting only): ``--jobs`` tiny train jobs (nearest-centroid,
  euclidean, 3 realisations) one after another on the idle worker: submit-to-running
  (server stamps ``started_at - created_at``), running-to-done, the end-to-end wall a
  client sees, and the same training timed in-process; the fixed cost per job is the
  end-to-end time less that computation.

    python bench/service_latency.py [--deployments sqlite,postgres] [--duration 10]
        [--clients 1,20,50] [--api-workers 1,2] [--jobs 10] [--json out.json]

- **memory** of the whole process tree (serve, its API processes, the verdict process
  and the fork server it forks them from, the worker and its task process): each
  process's RSS and PSS (``/proc/PID/smaps_rollup``; PSS shares a page among the
  processes that map it, so the tree's PSS is what it takes from the machine), idle after
  start-up, after the classifiers were trained (first API setting) and after the
  /identify load.

The load generator runs on the same machine: its own CPU per request is printed so the
figures can be read against it.
"""

from __future__ import annotations

import asyncio
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from _common import (
    GOOD_SEQUENCE,
    base_parser,
    free_port,
    generated_key,
    int_list,
    positive_int,
    print_header,
    print_table,
    service_env,
    spawn_service,
    stop_service,
)
from _common import write_json as _write_json

ROOT = Path(__file__).resolve().parents[1]
TERMINAL = ("succeeded", "failed", "cancelled")
TINY = {"sequence": GOOD_SEQUENCE, "kind": "nearest-centroid", "metric": "euclidean"}
CLASSIFIERS = {
    "default (marginal likelihood)": {"sequence": GOOD_SEQUENCE},
    "dtw (clustering)": {"sequence": GOOD_SEQUENCE, "kind": "clustering", "metric": "dtw"},
}
TICKS = os.sysconf("SC_CLK_TCK")


def _read(path: str) -> bytes:
    try:
        with open(path, "rb") as fh:
            return fh.read()
    except OSError:
        return b""


def _api_cpu_s(data_dir: Path) -> float:
    """CPU seconds used so far by the live processes of ``data_dir`` that are not
    workers (serve and its API processes)."""
    marker = f"INERTIA_ID_DATA_DIR={data_dir}".encode()
    total = 0
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        if marker not in _read(f"/proc/{entry}/environ").split(b"\0"):
            continue
        if b"celery" in _read(f"/proc/{entry}/cmdline"):
            continue
        fields = _read(f"/proc/{entry}/stat").decode(errors="replace").rpartition(")")[2].split()
        if len(fields) > 12:
            total += int(fields[11]) + int(fields[12])  # utime, stime
    return total / TICKS


def _tree_memory(data_dir: Path) -> dict[str, Any]:
    """RSS and PSS (MiB) of each live process of ``data_dir`` (serve and everything it
    started), with its parent and command line, and the tree's totals."""
    marker = f"INERTIA_ID_DATA_DIR={data_dir}".encode()
    processes = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or marker not in _read(f"/proc/{entry}/environ").split(b"\0"):
            continue
        rollup = _read(f"/proc/{entry}/smaps_rollup").decode(errors="replace")
        kib = dict(re.findall(r"^(Rss|Pss):\s+(\d+) kB", rollup, re.MULTILINE))
        if not kib:
            continue  # gone meanwhile
        status = _read(f"/proc/{entry}/status").decode(errors="replace")
        ppid = re.search(r"^PPid:\s+(\d+)", status, re.MULTILINE)
        command = _read(f"/proc/{entry}/cmdline").replace(b"\0", b" ").decode(errors="replace")
        processes.append(
            {
                "pid": int(entry),
                "ppid": int(ppid.group(1)) if ppid else None,
                "command": command.strip()[:80],
                "rss_mib": int(kib["Rss"]) / 1024,
                "pss_mib": int(kib["Pss"]) / 1024,
            }
        )
    processes.sort(key=lambda p: p["pid"])
    roles: dict[int, str] = {}
    for p in processes:  # a parent's pid is below its children's (no wrap-around here)
        p["role"] = roles[p["pid"]] = _role(p["command"], roles.get(p["ppid"]))
    return {
        "processes": processes,
        "rss_mib": sum(p["rss_mib"] for p in processes),
        "pss_mib": sum(p["pss_mib"] for p in processes),
    }


def _role(command: str, parent: str | None) -> str:
    """What a process of the tree is, from its command line and its parent's role."""
    if "app.serve" in command:
        return "serve"  # with one API process, the API process too
    if "celery" in command:
        return "worker task process" if parent == "worker (main)" else "worker (main)"
    if "resource_tracker" in command:
        return "resource tracker"
    if "multiprocessing.spawn" in command:
        return "API process"
    if "forkserver" in command:
        return "verdict process" if parent == "fork server" else "fork server"
    return command[:40]


def _own_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


# --------------------------------------------------------------------------- deployments


@dataclass
class Backend:
    name: str
    env: dict[str, str]
    cleanup: list[Callable[[], None]] = field(default_factory=list)


@contextmanager
def _backend(name: str, data_dir: Path, args: Any) -> Iterator[Backend]:
    env = service_env(ROOT)
    env["INERTIA_ID_DATA_DIR"] = str(data_dir)
    if name == "sqlite":
        yield Backend(name, env)
        return
    import redis
    from sqlalchemy import create_engine, text

    admin = create_engine(args.postgres_url, isolation_level="AUTOCOMMIT")
    database = f"inertia_id_bench_{uuid.uuid4().hex[:10]}"
    with admin.connect() as connection:
        connection.execute(text(f'CREATE DATABASE "{database}"'))
    broker = redis.Redis.from_url(args.redis_url)
    broker.flushdb()
    env["DATABASE_URL"] = admin.url.set(database=database).render_as_string(hide_password=False)
    env["BROKER_URL"] = args.redis_url
    try:
        yield Backend(name, env)
    finally:
        broker.flushdb()
        broker.close()
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{database}" WITH (FORCE)'))
        admin.dispose()


@dataclass
class Service:
    process: subprocess.Popen[bytes]
    base: str
    key: str
    start_to_health_s: float
    start_to_worker_s: float
    log_path: Path


def _start(backend: Backend, data_dir: Path, api_workers: int, key: str | None) -> Service:
    port = free_port()
    log_path = data_dir.parent / f"serve-{api_workers}.log"
    argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", str(data_dir)]
    argv += ["--workers", "1", "--api-workers", str(api_workers), "--log-level", "warning"]
    base = f"http://127.0.0.1:{port}"
    spawned = time.perf_counter()
    process = spawn_service(argv, log_path=log_path, cwd=data_dir.parent, env=backend.env)
    first = worker = None
    deadline = spawned + 300
    with httpx.Client(timeout=5) as client:
        while time.perf_counter() < deadline and worker is None:
            if process.poll() is not None:
                raise RuntimeError(f"serve exited:\n{log_path.read_text(errors='replace')}")
            try:
                health = client.get(f"{base}/health")
            except httpx.TransportError:
                time.sleep(0.02)
                continue
            now = time.perf_counter()
            if health.status_code == 200:
                first = first if first is not None else now - spawned
                workers = health.json()["workers"]
                # Listed from its first beat, warming: seen once warm, as before.
                if workers["count"] >= 1 and not workers.get("warming"):
                    worker = now - spawned
            time.sleep(0.02)
    if first is None or worker is None:
        raise RuntimeError(f"serve did not come up:\n{log_path.read_text(errors='replace')}")
    key = generated_key(log_path) or key
    if not key:
        raise RuntimeError("serve printed no generated API key")
    return Service(process, base, key, first, worker, log_path)


# --------------------------------------------------------------------------- jobs


def _wait_job(client: httpx.Client, job_id: str, timeout_s: float = 900.0) -> dict[str, Any]:
    deadline = time.perf_counter() + timeout_s
    while time.perf_counter() < deadline:
        job = dict(client.get(f"/jobs/{job_id}").json())
        if job["status"] in TERMINAL:
            return job
        time.sleep(0.01)
    raise RuntimeError(f"job {job_id} did not finish in {timeout_s} s")


def _submit(client: httpx.Client, scenario: str, params: dict[str, Any], seed: int) -> str:
    answer = client.post(
        "/jobs", json={"type": "train", "scenario_id": scenario, "seed": seed, "params": params}
    )
    if answer.status_code != 202:
        raise RuntimeError(f"POST /jobs answered {answer.status_code}: {answer.text}")
    return str(answer.json()["id"])


def _stamp(text: str) -> datetime:
    return datetime.fromisoformat(text)


def _tiny_compute_s(repeats: int) -> list[float]:
    """The tiny job's training, as the worker's handler does it, timed in-process."""
    from inertia_id import Scenario
    from inertia_id.classifiers.registry import train_classifier

    scenario = Scenario.paper()
    times = []
    for seed in range(repeats + 1):
        start = time.perf_counter()
        model = train_classifier(
            scenario,
            GOOD_SEQUENCE,
            3,
            np.random.default_rng(seed),
            kind="nearest-centroid",
            metric="euclidean",
        )
        model.to_json()
        times.append(time.perf_counter() - start)
    return times[1:]  # the first pays one-off imports and caches


_SEEDS = iter(range(5000, 10**9))


def _jobs(client: httpx.Client, scenario: str, count: int) -> list[dict[str, float]]:
    out = []
    for _ in range(count):
        sent = time.perf_counter()
        job_id = _submit(client, scenario, {**TINY, "n_realisations": 3}, seed=next(_SEEDS))
        job = _wait_job(client, job_id)
        wall = time.perf_counter() - sent
        if job["status"] != "succeeded":
            raise RuntimeError(f"tiny job ended {job['status']}: {job['error']}")
        created, started = _stamp(job["created_at"]), _stamp(job["started_at"])
        finished = _stamp(job["finished_at"])
        out.append(
            {
                "pickup_s": (started - created).total_seconds(),
                "run_s": (finished - started).total_seconds(),
                "server_total_s": (finished - created).total_seconds(),
                "client_wall_s": wall,
            }
        )
    return out


# --------------------------------------------------------------------------- identify


def _body(classifier: str, seed: int) -> tuple[dict[str, Any], str]:
    from inertia_id import Scenario, simulate

    flight = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(seed))
    candidate = 3
    telemetry = {
        "time_s": flight.time_s.tolist(),
        "omega_rad_s": flight.omega_measured[candidate, 0].tolist(),
    }
    return {"classifier_id": classifier, "telemetry": telemetry}, flight.candidate_names[candidate]


def _computation(client: httpx.Client, body: dict[str, Any], seconds: float) -> dict[str, float]:
    """ms per ``identify`` call in this process, the same classifier and telemetry."""
    from inertia_id import identify
    from inertia_id.classifiers.registry import classifier_from_json

    document = client.get(f"/classifiers/{body['classifier_id']}/download")
    document.raise_for_status()
    start = time.perf_counter()
    model = classifier_from_json(document.content)
    load_s = time.perf_counter() - start
    start = time.perf_counter()
    identify(model, body["telemetry"])  # the first call may compile (numba)
    first_s = time.perf_counter() - start
    calls = 0
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        identify(model, body["telemetry"])
        calls += 1
    per_call = (time.perf_counter() - start) / calls
    return {
        "load_ms": 1000 * load_s,
        "first_call_ms": 1000 * first_s,
        "ms_per_call": 1000 * per_call,
        "bound_rps_per_core": 1 / per_call,
    }


class _Connection:
    """One keep-alive HTTP/1.1 connection that sends a prepared request and reads the
    answer: a load generator that costs the machine far less CPU than an HTTP library
    (httpx spent 3 ms of client CPU a request here, on the 2 cores the server also uses)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.reader, self.writer = reader, writer

    @classmethod
    async def open(cls, host: str, port: int) -> _Connection:
        reader, writer = await asyncio.open_connection(host, port)
        return cls(reader, writer)

    async def send(self, request: bytes) -> tuple[int, bytes]:
        self.writer.write(request)
        head = await self.reader.readuntil(b"\r\n\r\n")
        status = int(head.split(b" ", 2)[1])
        length = 0
        for line in head.split(b"\r\n")[1:]:
            name, _, value = line.partition(b":")
            if name.strip().lower() == b"content-length":
                length = int(value)
        return status, await self.reader.readexactly(length)

    async def close(self) -> None:
        self.writer.close()
        await self.writer.wait_closed()


def _request(base: str, key: str, body: dict[str, Any]) -> tuple[str, int, bytes]:
    host, port = base.removeprefix("http://").rsplit(":", 1)
    payload = json.dumps(body).encode()
    head = (
        f"POST /identify HTTP/1.1\r\nHost: {host}:{port}\r\nX-API-Key: {key}\r\n"
        f"Content-Type: application/json\r\nContent-Length: {len(payload)}\r\n\r\n"
    ).encode()
    return host, int(port), head + payload


async def _load(
    base: str,
    key: str,
    body: dict[str, Any],
    expected: str,
    clients: int,
    seconds: float,
    rate_per_client: float | None = None,
) -> dict[str, Any]:
    """``clients`` connections sending ``/identify`` for ``seconds``.

    Closed loop (``rate_per_client`` None): each sends its next request when the last is
    answered, so the service runs flat out and latency is mostly queueing (Little's law:
    clients / throughput). Open loop: each sends at a fixed rate (requests a second,
    scheduled, not waiting for the last answer's time), the way independent ground
    stations would; latency is then the service's own.
    """
    host, port, request = _request(base, key, body)
    latencies: list[float] = []
    codes: dict[int, int] = {}
    correct = 0
    connections = [await _Connection.open(host, port) for _ in range(clients)]
    stop_at = time.perf_counter() + seconds

    async def one(index: int, connection: _Connection) -> None:
        nonlocal correct
        next_at = time.perf_counter() + (
            index / clients / rate_per_client if rate_per_client else 0
        )
        while True:
            if rate_per_client:
                await asyncio.sleep(max(0.0, next_at - time.perf_counter()))
                started = next_at
                next_at += 1.0 / rate_per_client
            else:
                started = time.perf_counter()
            if started >= stop_at:
                return
            try:
                status, answer = await connection.send(request)
            except (OSError, asyncio.IncompleteReadError):
                status, answer = 0, b""
            latencies.append(time.perf_counter() - started)
            codes[status] = codes.get(status, 0) + 1
            if status == 200 and json.loads(answer).get("candidate") == expected:
                correct += 1

    started = time.perf_counter()
    await asyncio.gather(*(one(i, c) for i, c in enumerate(connections)))
    elapsed = time.perf_counter() - started
    for connection in connections:
        await connection.close()
    values = np.asarray(latencies) * 1000
    return {
        "clients": clients,
        "rate_per_client": rate_per_client,
        "requests": len(latencies),
        "seconds": elapsed,
        "rps": len(latencies) / elapsed,
        "p50_ms": float(np.percentile(values, 50)),
        "p95_ms": float(np.percentile(values, 95)),
        "p99_ms": float(np.percentile(values, 99)),
        "max_ms": float(values.max()),
        "errors": sum(n for code, n in codes.items() if code != 200),
        "refused_503": codes.get(503, 0),
        "codes": {str(k): v for k, v in sorted(codes.items())},
        "correct_share": correct / max(1, len(latencies)),
    }


async def _cold(
    base: str, key: str, body: dict[str, Any], requests: int
) -> list[tuple[int, float]]:
    """(status, seconds) of the first requests after start, two at a time, each on a
    connection of its own so that every API process gets some: a cold classifier (and,
    for DTW, a numba compile) per process."""
    out: list[tuple[int, float]] = []

    async def one() -> None:
        async with httpx.AsyncClient(
            base_url=base, headers={"X-API-Key": key}, timeout=120
        ) as client:
            start = time.perf_counter()
            answer = await client.post("/identify", json=body)
            out.append((answer.status_code, time.perf_counter() - start))

    for _ in range(0, requests, 2):
        await asyncio.gather(one(), one())
    return out


# --------------------------------------------------------------------------- main


def _run_deployment(name: str, args: Any) -> dict[str, Any]:
    figures: dict[str, Any] = {
        "deployment": name,
        "startups": [],
        "identify": [],
        "jobs": None,
        "memory": [],
    }
    with tempfile.TemporaryDirectory(prefix="inertia-bench-") as tmp:
        data_dir = Path(tmp) / "data"
        with _backend(name, data_dir, args) as backend:
            key: str | None = None
            ids: dict[str, str] = {}
            scenario = ""
            for api_workers in args.api_workers:
                service = _start(backend, data_dir, api_workers, key)
                key = service.key
                figures["startups"].append(
                    {
                        "api_workers": api_workers,
                        "first_health_s": service.start_to_health_s,
                        "worker_seen_s": service.start_to_worker_s,
                    }
                )
                print(
                    f"[{name}] serve up ({api_workers} API processes): /health after "
                    f"{service.start_to_health_s:.2f} s, worker after "
                    f"{service.start_to_worker_s:.2f} s",
                    flush=True,
                )

                def memory(when: str, api_workers: int = api_workers) -> None:
                    tree = _tree_memory(data_dir)
                    figures["memory"].append({"api_workers": api_workers, "when": when, **tree})
                    print(
                        f"[{name}] memory {when} ({api_workers} API processes): "
                        f"{len(tree['processes'])} processes, PSS {tree['pss_mib']:.0f} MiB, "
                        f"RSS {tree['rss_mib']:.0f} MiB",
                        flush=True,
                    )

                memory("idle after start-up")
                try:
                    client = httpx.Client(base_url=service.base, headers={"X-API-Key": key})
                    client.timeout = httpx.Timeout(60)
                    if not ids:
                        created = client.post("/scenarios", json={"preset": "paper"})
                        created.raise_for_status()
                        scenario = created.json()["id"]
                        figures["jobs"] = _jobs_figures(client, scenario, args)
                        for label, params in CLASSIFIERS.items():
                            started = time.perf_counter()
                            job = _wait_job(client, _submit(client, scenario, params, args.seed))
                            if job["status"] != "succeeded":
                                raise RuntimeError(f"{label}: {job['status']}: {job['error']}")
                            ids[label] = job["result"]["classifier_id"]
                            print(
                                f"[{name}] trained {label} in "
                                f"{time.perf_counter() - started:.1f} s",
                                flush=True,
                            )
                        memory("after training the classifiers")
                    for label, classifier in ids.items():
                        body, expected = _body(classifier, args.seed)
                        cold = asyncio.run(_cold(service.base, key, body, 6 * api_workers))
                        computation = _computation(client, body, args.compute_seconds)
                        closed_rps: dict[int, float] = {}
                        runs = [(c, None) for c in args.clients] + [
                            (c, "open") for c in args.clients if c > 1
                        ]
                        for clients, mode in runs:
                            rate = None
                            if mode == "open":
                                # An offered load the service can carry: a share of what
                                # it did flat out with as many clients.
                                rate = args.open_share * closed_rps[clients] / clients
                            before_api, before_own = _api_cpu_s(data_dir), _own_cpu_s()
                            load = asyncio.run(
                                _load(
                                    service.base,
                                    key,
                                    body,
                                    expected,
                                    clients,
                                    args.duration,
                                    rate_per_client=rate,
                                )
                            )
                            load["mode"] = mode or "closed"
                            if mode is None:
                                closed_rps[clients] = load["rps"]
                            requests = max(1, load["requests"])
                            load["api_cpu_ms_per_request"] = (
                                1000 * (_api_cpu_s(data_dir) - before_api) / requests
                            )
                            load["client_cpu_ms_per_request"] = (
                                1000 * (_own_cpu_s() - before_own) / requests
                            )
                            figures["identify"].append(
                                {
                                    "classifier": label,
                                    "api_workers": api_workers,
                                    "cold_first": [
                                        {"status": code, "ms": 1000 * t} for code, t in cold
                                    ],
                                    "computation": computation,
                                    **load,
                                }
                            )
                            print(
                                f"[{name}] {label}, {api_workers} API, {clients} clients "
                                f"({load['mode']}): "
                                f"{load['rps']:.1f} req/s, p99 {load['p99_ms']:.1f} ms, "
                                f"{load['errors']} errors",
                                flush=True,
                            )
                    memory("after the /identify load")
                    client.close()
                finally:
                    stop_service(service.process)
    return figures


def _jobs_figures(client: httpx.Client, scenario: str, args: Any) -> dict[str, Any]:
    # One job first: the worker's first job may pay one-off costs (caches, compiles).
    first = _jobs(client, scenario, 1)[0]
    runs = _jobs(client, scenario, args.jobs)
    compute = float(np.median(_tiny_compute_s(5)))
    med = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
    return {
        "first_job": first,
        "runs": runs,
        "median": med,
        "compute_in_process_s": compute,
        "fixed_cost_s": med["client_wall_s"] - compute,
        "fixed_cost_server_s": med["server_total_s"] - compute,
    }


def _print_memory(results: list[dict[str, Any]]) -> None:
    rows = []
    for figures in results:
        for snapshot in figures.get("memory", []):
            for p in snapshot["processes"]:
                rows.append(
                    [
                        figures["deployment"],
                        snapshot["api_workers"],
                        snapshot["when"],
                        p["pid"],
                        p["ppid"],
                        p["role"],
                        p["rss_mib"],
                        p["pss_mib"],
                    ]
                )
            rows.append(
                [
                    figures["deployment"],
                    snapshot["api_workers"],
                    snapshot["when"],
                    "all",
                    "",
                    f"{len(snapshot['processes'])} processes",
                    snapshot["rss_mib"],
                    snapshot["pss_mib"],
                ]
            )
    print_table(
        ["deployment", "API processes", "when", "pid", "parent", "process", "RSS MiB", "PSS MiB"],
        rows,
        title="Memory of the process tree (PSS: shared pages split among the processes)",
    )


def _print(results: list[dict[str, Any]]) -> None:
    _print_memory(results)
    rows = []
    for figures in results:
        for s in figures["startups"]:
            rows.append(
                [figures["deployment"], s["api_workers"], s["first_health_s"], s["worker_seen_s"]]
            )
    print_table(
        ["deployment", "API processes", "spawn to /health 200 (s)", "to worker seen (s)"],
        rows,
        title="Start-up: python -m app.serve --workers 1",
    )
    rows = []
    for figures in results:
        for r in figures["identify"]:
            rows.append(
                [
                    figures["deployment"],
                    r["classifier"],
                    r["api_workers"],
                    r["clients"],
                    r.get("mode", "closed")
                    + ("" if not r.get("rate_per_client") else f" {r['rate_per_client']:.1f}/s"),
                    r["requests"],
                    r["rps"],
                    r["p50_ms"],
                    r["p95_ms"],
                    r["p99_ms"],
                    r["max_ms"],
                    r["errors"],
                    f"{100 * r['correct_share']:.0f}%",
                    r["computation"]["ms_per_call"],
                    r["computation"]["bound_rps_per_core"],
                    r["api_cpu_ms_per_request"],
                    r["client_cpu_ms_per_request"],
                ]
            )
    print_table(
        [
            "deployment",
            "classifier",
            "API",
            "clients",
            "load",
            "requests",
            "req/s",
            "p50 ms",
            "p95 ms",
            "p99 ms",
            "max ms",
            "errors",
            "correct",
            "compute ms",
            "bound req/s/core",
            "API CPU ms/req",
            "client CPU ms/req",
        ],
        rows,
        title="POST /identify (generated key, 80-sample JSON telemetry); compute = "
        "inertia_id.identify in-process; closed: each client sends when answered (flat out); "
        "open: each client at a fixed rate (a share of the closed-loop throughput)",
    )
    rows = []
    for figures in results:
        for r in figures["identify"]:
            if (
                r["clients"] == min(x["clients"] for x in figures["identify"])
                and r.get("mode", "closed") == "closed"
            ):
                rows.append(
                    [
                        figures["deployment"],
                        r["classifier"],
                        r["api_workers"],
                        max(c["ms"] for c in r["cold_first"]),
                        sum(c["status"] != 200 for c in r["cold_first"]),
                        r["computation"]["load_ms"],
                        r["computation"]["first_call_ms"],
                    ]
                )
    print_table(
        [
            "deployment",
            "classifier",
            "API",
            "first requests: max ms",
            "not 200",
            "in-process load ms",
            "in-process first call ms",
        ],
        rows,
        title="Cold classifier: the first requests after start (two at a time, new "
        "connections), and the same document loaded and first called in-process",
    )
    rows = []
    for figures in results:
        jobs = figures["jobs"]
        if jobs is None:
            continue
        med = jobs["median"]
        rows.append(
            [
                figures["deployment"],
                len(jobs["runs"]),
                jobs["first_job"]["pickup_s"],
                med["pickup_s"],
                max(r["pickup_s"] for r in jobs["runs"]),
                med["run_s"],
                med["client_wall_s"],
                jobs["compute_in_process_s"],
                jobs["fixed_cost_s"],
            ]
        )
    print_table(
        [
            "deployment",
            "jobs",
            "first job pick-up s",
            "pick-up s (median)",
            "pick-up s (max)",
            "running to done s",
            "submit to succeeded s",
            "compute in-process s",
            "fixed cost per job s",
        ],
        rows,
        title="Tiny train jobs (nearest-centroid, euclidean, 3 realisations), one at a time on "
        "an idle worker; pick-up = started_at - created_at",
    )


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--deployments",
        default="sqlite,postgres",
        help="comma-separated: sqlite (embedded default), postgres (PostgreSQL + Redis)",
    )
    parser.add_argument("--clients", type=int_list, default=[1, 20, 50])
    parser.add_argument("--api-workers", type=int_list, default=[1, 2])
    parser.add_argument("--duration", type=positive_int, default=10, help="seconds per load")
    parser.add_argument(
        "--open-share",
        type=float,
        default=0.5,
        help="open-loop offered load as a share of the closed-loop throughput (default 0.5)",
    )
    parser.add_argument(
        "--compute-seconds", type=float, default=2.0, help="seconds of in-process identify"
    )
    parser.add_argument("--jobs", type=positive_int, default=10, help="tiny jobs to time")
    parser.add_argument(
        "--postgres-url",
        default=os.environ.get(
            "INERTIA_ID_BENCH_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres"
        ),
        help="an admin connection: a database is created there and dropped after",
    )
    parser.add_argument(
        "--redis-url",
        default=os.environ.get("INERTIA_ID_BENCH_REDIS_URL", "redis://127.0.0.1:6379/14"),
        help="a Redis database for the broker: FLUSHED before and after",
    )
    args = parser.parse_args()
    deployments = [d.strip() for d in args.deployments.split(",") if d.strip()]
    unknown = sorted(set(deployments) - {"sqlite", "postgres"})
    if unknown:
        parser.error(f"--deployments: unknown {unknown}; known: sqlite, postgres")
    print_header("inertia-id service: start-up, /identify under load, job pick-up", args)
    results = [_run_deployment(name, args) for name in deployments]
    print()
    _print(results)
    _write_json(args.json, args, {"deployments": results})


if __name__ == "__main__":
    main()
