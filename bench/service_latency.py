"""The service under load: POST /identify latency and throughput, and job pick-up time.

Starts the real service (``python -m app.serve``: uvicorn and one Celery worker, the
embedded default: SQLite and the filesystem broker) in a temporary folder on loopback,
creates the paper scenario, trains a DTW classifier on the hand-designed sequence through
a job, then:

- sends ``POST /identify`` (JSON telemetry of one simulated series, 80 samples) from
  ``--clients`` (20) concurrent clients for ``--duration`` (20) s, and prints the p50 and
  p99 latency, the throughput and the share of correct verdicts;
- submits ``--pickups`` (5) small train jobs one at a time to the idle worker and prints
  the time from ``POST /jobs`` to the job being running (server time stamps
  ``started_at - created_at``, and what a client polling every 10 ms saw).

    python bench/service_latency.py [--clients 20] [--duration 20] [--json out.json]
"""

from __future__ import annotations

import asyncio
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from _common import GOOD_SEQUENCE, base_parser, positive_int, print_header, print_table, write_json

API_KEY = "bench-" + "k" * 32


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _wait_healthy(base: str, timeout_s: float = 120.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            response = httpx.get(f"{base}/health", timeout=2)
            body = response.json()
            if response.status_code == 200 and body.get("status") == "ok":
                return dict(body)
        except (httpx.HTTPError, ValueError):
            pass
        time.sleep(0.5)
    raise RuntimeError(f"the service at {base} did not report a live worker in {timeout_s} s")


def _wait_job(client: httpx.Client, job_id: str, timeout_s: float = 600.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = dict(client.get(f"/jobs/{job_id}").json())
        if job["status"] in ("succeeded", "failed", "cancelled"):
            return job
        time.sleep(0.2)
    raise RuntimeError(f"job {job_id} did not finish in {timeout_s} s")


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q))


async def _load(
    base: str, body: dict[str, Any], expected: str, clients: int, duration_s: float
) -> dict[str, Any]:
    latencies: list[float] = []
    correct = 0
    errors = 0
    stop_at = time.perf_counter() + duration_s

    async def client_loop(client: httpx.AsyncClient) -> None:
        nonlocal correct, errors
        while time.perf_counter() < stop_at:
            start = time.perf_counter()
            response = await client.post("/identify", json=body)
            latencies.append(time.perf_counter() - start)
            if response.status_code != 200:
                errors += 1
            elif response.json().get("candidate") == expected:
                correct += 1

    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx.AsyncClient(
        base_url=base, headers={"X-API-Key": API_KEY}, limits=limits, timeout=30
    ) as client:
        started = time.perf_counter()
        await asyncio.gather(*(client_loop(client) for _ in range(clients)))
        elapsed = time.perf_counter() - started
    return {
        "requests": len(latencies),
        "elapsed_s": elapsed,
        "throughput_rps": len(latencies) / elapsed,
        "p50_ms": 1000 * _percentile(latencies, 50),
        "p99_ms": 1000 * _percentile(latencies, 99),
        "max_ms": 1000 * max(latencies),
        "errors": errors,
        "correct_share": correct / max(len(latencies), 1),
    }


def _pickups(client: httpx.Client, scenario_id: str, count: int, seed: int) -> list[dict[str, Any]]:
    out = []
    for i in range(count):
        body = {
            "type": "train",
            "scenario_id": scenario_id,
            "seed": seed + 1000 + i,
            "params": {"sequence": GOOD_SEQUENCE, "metric": "euclidean", "n_realisations": 5},
        }
        sent = time.perf_counter()
        job = client.post("/jobs", json=body).json()
        seen = None
        while time.perf_counter() - sent < 120:
            state = client.get(f"/jobs/{job['id']}").json()
            if state["status"] != "queued":
                seen = time.perf_counter() - sent
                break
            time.sleep(0.01)
        done = _wait_job(client, job["id"])
        created = datetime.fromisoformat(done["created_at"])
        started = datetime.fromisoformat(done["started_at"])
        out.append({"server_s": (started - created).total_seconds(), "client_seen_s": seen, **done})
    return out


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--clients", type=positive_int, default=20)
    parser.add_argument("--duration", type=positive_int, default=20, help="seconds of load")
    parser.add_argument("--pickups", type=positive_int, default=5)
    args = parser.parse_args()
    print_header("inertia-id service: /identify under load, job pick-up", args)
    from inertia_id import Scenario, simulate

    root = Path(__file__).resolve().parents[1]
    port = _free_port()
    base = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory(prefix="inertia-bench-") as data_dir:
        env = {**os.environ, "INERTIA_ID_API_KEY": API_KEY, "PYTHONUNBUFFERED": "1"}
        log = open(Path(data_dir) / "serve.log", "w")
        service = subprocess.Popen(
            [sys.executable, "-m", "app.serve", "--data-dir", data_dir, "--port", str(port)],
            cwd=root,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            health = _wait_healthy(base)
            print(f"service up at {base}; health: {health.get('status')}", flush=True)
            client = httpx.Client(base_url=base, headers={"X-API-Key": API_KEY}, timeout=30)
            scenario = client.post("/scenarios", json={"preset": "paper"}).json()
            train = client.post(
                "/jobs",
                json={
                    "type": "train",
                    "scenario_id": scenario["id"],
                    "seed": args.seed,
                    "params": {"sequence": GOOD_SEQUENCE, "metric": "dtw", "n_realisations": 20},
                },
            ).json()
            job = _wait_job(client, train["id"])
            if job["status"] != "succeeded":
                raise RuntimeError(f"training job ended {job['status']}: {job['error']}")
            classifier_id = job["result"]["classifier_id"]
            sim = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(args.seed))
            candidate = 3
            body = {
                "classifier_id": classifier_id,
                "telemetry": {
                    "time_s": sim.time_s.tolist(),
                    "omega_rad_s": sim.omega_measured[candidate, 0].tolist(),
                },
            }
            expected = sim.candidate_names[candidate]
            first = client.post("/identify", json=body)
            print(f"warm-up identify: {first.status_code} {first.json().get('candidate')}")
            load = asyncio.run(_load(base, body, expected, args.clients, args.duration))
            print_table(
                [
                    "clients",
                    "requests",
                    "seconds",
                    "throughput req/s",
                    "p50 ms",
                    "p99 ms",
                    "max ms",
                    "errors",
                    "correct",
                ],
                [
                    [
                        args.clients,
                        load["requests"],
                        load["elapsed_s"],
                        load["throughput_rps"],
                        load["p50_ms"],
                        load["p99_ms"],
                        load["max_ms"],
                        load["errors"],
                        f"{100 * load['correct_share']:.1f}%",
                    ]
                ],
                title="POST /identify (DTW classifier, 80-sample telemetry, JSON)",
            )
            pickups = _pickups(client, scenario["id"], args.pickups, args.seed)
            print_table(
                ["job", "server: started - created (s)", "client saw running after (s)"],
                [[p["id"][:8], p["server_s"], p["client_seen_s"]] for p in pickups],
                title="POST /jobs to running, idle worker (filesystem broker)",
            )
            server = [p["server_s"] for p in pickups]
            print(
                f"pick-up: median {np.median(server):.3f} s, max {max(server):.3f} s "
                f"(server time stamps)"
            )
            write_json(
                args.json,
                args,
                {"identify": load, "pickup_s": server, "classifier_id": classifier_id},
            )
        finally:
            os.killpg(service.pid, signal.SIGTERM)
            try:
                service.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(service.pid, signal.SIGKILL)
            log.close()


if __name__ == "__main__":
    main()
