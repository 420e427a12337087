"""The API process's resident memory over thousands of requests: a plateau or growth?

Runs ``python -m app.serve`` as a user does (SQLite, the filesystem broker, one worker, one
API process, the API key it generates, read from its banner; a fresh ``--data-dir``),
trains a classifier through a job (the default kind, the paper preset, the hand-designed
sequence, ``--realisations`` per candidate, as ``inertia-id train -n 20`` does), then
sends ``--requests`` requests, one after another, in rounds of the mix a dashboard and
a client send (the dashboard on two kept-alive connections, with and without the key;
the client and the refusals on a new connection each):

- the dashboard: ``GET /``, its script and style files, ``/health``, ``/vocabulary``,
  ``/auth/check``, the scenario list, presets, one scenario, its baselines and the rate
  response of a sequence (``/scenarios/{id}/response``, 5 realisations), the job list
  (all, and filtered), one job, its result and metrics, the classifier list and one
  classifier;
- a client: ``POST /identify`` with a simulated flight's telemetry (JSON; one of
  ``--flights`` flights, in turn) to the trained classifier, and a new scenario stored
  (with an ``Idempotency-Key``) then deleted;
- refusals: an unknown job and an unknown classifier (a new id each time, 404), a bad
  ``limit`` (422), ``POST /identify`` without the key (401), an unknown path (404), a
  scenario that is not one (422).

Every ``--every`` requests it reads the API process's ``VmRSS`` (``/proc/PID/status``;
with one API process that is serve's own process) and the verdict process's, and prints
them with the change since the first sample, then the highest API RSS of each half of
the run: a warm-up that levels off (a plateau) has the same highest figure in both, growth
a higher one in the second. The API's RSS at the start depends on numba's on-disk cache:
the API's warm-up compiles the kernels when the cache is empty (``NUMBA_CACHE_DIR`` an
empty folder: 402 MiB at the first sample against 324-326 MiB) and loads them from it
otherwise. ``--repo`` runs another checkout's service (the code before a change, say).
The load generator runs on the same machine; a run of 6,000 requests takes about 2
minutes (the training and the start included).

    python bench/api_memory.py [--requests 6000] [--every 250] [--realisations 20]
        [--flights 4] [--repo DIR] [--json out.json]
"""

from __future__ import annotations

import argparse
import itertools
import re
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np
from _common import (
    GOOD_SEQUENCE,
    add_repo,
    base_parser,
    begin,
    free_port,
    generated_key,
    positive_int,
    print_table,
    service_env,
    spawn_service,
    stop_service,
    wait_until_ok,
    write_json,
)

TERMINAL = ("succeeded", "failed", "cancelled")
#: A request the mix sends: its label, and the call that sends it (the answer's status
#: is checked against the expected one, so the mix measures what it says it does).
Request = tuple[str, int, Callable[[], httpx.Response]]


def vm_rss_mib(pid: int) -> float | None:
    """The process's resident memory (``VmRSS``), MiB; None when it is gone."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii", errors="replace") as fh:
            found = re.search(r"^VmRSS:\s+(\d+) kB", fh.read(), re.MULTILINE)
    except OSError:
        return None
    return int(found.group(1)) / 1024 if found else None


def _children(pid: int) -> list[tuple[int, str]]:
    """The processes whose parent is ``pid``, with their command lines."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_bytes().rpartition(b")")[2].split()
            if int(stat[1]) != pid:
                continue
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, IndexError, ValueError, UnicodeDecodeError):
            continue
        found.append((int(entry.name), command))
    return found


def verdict_pid(serve_pid: int) -> int | None:
    """The verdict process: the child of the API process's fork server."""
    for pid, command in _children(serve_pid):
        if "forkserver" in command:
            children = _children(pid)
            if children:
                return children[0][0]
    return None


def _train(client: httpx.Client, scenario: str, args: argparse.Namespace) -> str:
    params = {"sequence": GOOD_SEQUENCE, "n_realisations": args.realisations}
    job = {"type": "train", "scenario_id": scenario, "seed": args.seed, "params": params}
    answer = client.post("/jobs", json=job)
    if answer.status_code != 202:
        raise RuntimeError(f"POST /jobs answered {answer.status_code}: {answer.text}")
    job_id = str(answer.json()["id"])
    deadline = time.perf_counter() + 900
    while time.perf_counter() < deadline:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in TERMINAL:
            if job["status"] != "succeeded":
                raise RuntimeError(f"the training job ended {job['status']}: {job['error']}")
            return job_id
        time.sleep(0.2)
    raise RuntimeError("the training job did not finish in 900 s")


def _flights(classifier: str, count: int, seed: int) -> list[dict[str, Any]]:
    """``count`` bodies for ``POST /identify``: one simulated flight each, the candidates
    in turn."""
    from inertia_id import Scenario, simulate

    flight = simulate(Scenario.paper(), GOOD_SEQUENCE, count, np.random.default_rng(seed))
    n_candidates = flight.omega_measured.shape[0]
    return [
        {
            "classifier_id": classifier,
            "telemetry": {
                "time_s": flight.time_s.tolist(),
                "omega_rad_s": flight.omega_measured[n % n_candidates, n].tolist(),
            },
        }
        for n in range(count)
    ]


def _mix(
    dashboard: httpx.Client,
    script: httpx.Client,
    anonymous: httpx.Client,
    ids: dict[str, str],
    bodies: list[dict[str, Any]],
) -> Iterator[Request]:
    """The requests of one round, endlessly: the dashboard's (``dashboard``, one kept-alive
    connection with the key; ``anonymous``, one without), a client script's and the
    refusals (``script``: a new connection each, with the key)."""
    scenario, job, classifier = ids["scenario"], ids["job"], ids["classifier"]
    sequence = "[[4,4,4,0,0,0],[4,4,4,0,0,0]]"
    stored: list[str] = []

    def store_scenario() -> httpx.Response:
        answer = script.post(
            "/scenarios",
            json={"preset": "paper", "overrides": {"name": "memory probe"}},
            headers={"Idempotency-Key": str(uuid.uuid4())},
        )
        if answer.status_code == 201:
            stored.append(answer.json()["id"])
        return answer

    def delete_scenario() -> httpx.Response:
        return script.delete(f"/scenarios/{stored.pop()}")

    def one_round(round_: int, body: dict[str, Any]) -> list[Request]:
        return [
            ("GET /", 200, lambda: anonymous.get("/")),
            ("GET /static/js/app.js", 200, lambda: anonymous.get("/static/js/app.js")),
            ("GET /static/js/api.js", 200, lambda: anonymous.get("/static/js/api.js")),
            ("GET /static/css/style.css", 200, lambda: anonymous.get("/static/css/style.css")),
            ("GET /health", 200, lambda: anonymous.get("/health")),
            ("GET /vocabulary", 200, lambda: anonymous.get("/vocabulary")),
            ("GET /auth/check", 204, lambda: dashboard.get("/auth/check")),
            ("GET /scenarios", 200, lambda: dashboard.get("/scenarios")),
            ("GET /scenarios/presets", 200, lambda: dashboard.get("/scenarios/presets")),
            ("GET /scenarios/{id}", 200, lambda: dashboard.get(f"/scenarios/{scenario}")),
            ("GET baselines", 200, lambda: dashboard.get(f"/scenarios/{scenario}/baselines")),
            (
                "GET response",
                200,
                lambda: dashboard.get(
                    f"/scenarios/{scenario}/response",
                    params={"sequence": sequence, "n_realisations": 5},
                ),
            ),
            ("GET /jobs", 200, lambda: dashboard.get("/jobs")),
            ("GET /jobs?status=", 200, lambda: dashboard.get("/jobs?status=succeeded&limit=10")),
            ("GET /jobs/{id}", 200, lambda: dashboard.get(f"/jobs/{job}")),
            ("GET /jobs/{id}/result", 200, lambda: dashboard.get(f"/jobs/{job}/result")),
            ("GET /jobs/{id}/metrics", 200, lambda: dashboard.get(f"/jobs/{job}/metrics")),
            ("GET /classifiers", 200, lambda: dashboard.get("/classifiers")),
            ("GET /classifiers/{id}", 200, lambda: dashboard.get(f"/classifiers/{classifier}")),
            ("POST /identify", 200, lambda: script.post("/identify", json=body)),
            ("POST /scenarios", 201, store_scenario),
            ("DELETE /scenarios/{id}", 204, delete_scenario),
            ("404 job", 404, lambda: script.get(f"/jobs/{uuid.uuid4()}")),
            (
                "404 classifier",
                404,
                lambda: script.post("/identify", json={**body, "classifier_id": str(uuid.uuid4())}),
            ),
            ("422 limit", 422, lambda: script.get("/jobs?limit=many")),
            ("401 identify", 401, lambda: anonymous.post("/identify", json=body)),
            ("404 path", 404, lambda: script.get(f"/no-such-page/{round_}")),
            ("422 scenario", 422, lambda: script.post("/scenarios", json={"preset": "moon"})),
        ]

    for round_ in itertools.count():
        yield from one_round(round_, bodies[round_ % len(bodies)])


def _drive(
    requests: Iterator[Request],
    serve_pid: int,
    args: argparse.Namespace,
) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Send ``--requests`` requests, sampling the RSS every ``--every``."""
    samples: list[dict[str, Any]] = []
    unexpected: dict[str, int] = {}
    began = time.perf_counter()

    def sample(sent: int) -> None:
        verdict = verdict_pid(serve_pid)
        samples.append(
            {
                "requests": sent,
                "seconds": time.perf_counter() - began,
                "api_rss_mib": vm_rss_mib(serve_pid),
                "verdict_rss_mib": vm_rss_mib(verdict) if verdict else None,
            }
        )

    sample(0)
    for sent in range(1, args.requests + 1):
        label, expected, send = next(requests)
        answer = send()
        if answer.status_code != expected:
            key = f"{label}: {answer.status_code} (expected {expected})"
            unexpected[key] = unexpected.get(key, 0) + 1
        if sent % args.every == 0 or sent == args.requests:
            sample(sent)
    return samples, unexpected


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--requests", type=positive_int, default=6000, help="requests sent in all")
    parser.add_argument(
        "--every", type=positive_int, default=250, help="requests between two RSS samples"
    )
    parser.add_argument(
        "--realisations", type=positive_int, default=20, help="the classifier's, per candidate"
    )
    parser.add_argument(
        "--flights", type=positive_int, default=4, help="telemetry bodies sent in turn"
    )
    add_repo(parser)
    args = begin(parser, "The API process's resident memory over a request mix")
    with tempfile.TemporaryDirectory(prefix="inertia-bench-") as folder:
        root = Path(folder)
        port = free_port()
        log_path = root / "serve.log"
        argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
        argv += ["--workers", "1"]
        env = service_env(Path(args.repo).resolve())
        process = spawn_service(argv, log_path=log_path, cwd=root, env=env)
        try:
            base = f"http://127.0.0.1:{port}"
            one_shot = httpx.Limits(max_keepalive_connections=0)
            with (
                httpx.Client(base_url=base, timeout=60) as dashboard,
                httpx.Client(base_url=base, timeout=60, limits=one_shot) as script,
                httpx.Client(base_url=base, timeout=60) as anonymous,
            ):
                wait_until_ok(anonymous, process, log_path)
                key = generated_key(log_path) or ""
                dashboard.headers["X-API-Key"] = script.headers["X-API-Key"] = key
                created = dashboard.post("/scenarios", json={"preset": "paper"})
                created.raise_for_status()
                scenario = created.json()["id"]
                started = time.perf_counter()
                job = _train(dashboard, scenario, args)
                classifier = dashboard.get(f"/jobs/{job}").json()["result"]["classifier_id"]
                print(f"classifier trained in {time.perf_counter() - started:.1f} s", flush=True)
                ids = {"scenario": scenario, "job": job, "classifier": classifier}
                bodies = _flights(classifier, args.flights, args.seed)
                requests = _mix(dashboard, script, anonymous, ids, bodies)
                samples, unexpected = _drive(requests, process.pid, args)
        finally:
            stop_service(process)
    _print(samples, unexpected, args)
    write_json(args.json, args, {"samples": samples, "unexpected": unexpected})


def _print(
    samples: list[dict[str, Any]], unexpected: dict[str, int], args: argparse.Namespace
) -> None:
    first = samples[0]["api_rss_mib"]
    rows = [
        [
            s["requests"],
            f"{s['seconds']:.1f}",
            s["api_rss_mib"],
            s["api_rss_mib"] - first,
            s["verdict_rss_mib"],
        ]
        for s in samples
    ]
    print_table(["requests", "s", "API RSS MiB", "since start", "verdict RSS MiB"], rows)
    # RSS moves up and down by a few MiB as the allocator takes and returns memory: a
    # plateau has the same highest figure in both halves, growth a higher one each time.
    middle = args.requests // 2
    first_half = [s["api_rss_mib"] for s in samples if 0 < s["requests"] <= middle]
    second_half = [s for s in samples if s["requests"] > middle]
    if first_half and len(second_half) >= 2:
        slope = np.polyfit(
            [s["requests"] for s in second_half], [s["api_rss_mib"] for s in second_half], 1
        )[0]
        print(
            f"highest API RSS up to {middle:,} requests {max(first_half):.1f} MiB, "
            f"after {max(s['api_rss_mib'] for s in second_half):.1f} MiB; least-squares "
            f"slope after {slope * 1000:+.2f} MiB per 1,000 requests"
        )
    if unexpected:
        print_table(["unexpected answer", "count"], sorted(unexpected.items()))
    else:
        print("every answer had the expected status")


if __name__ == "__main__":
    main()
