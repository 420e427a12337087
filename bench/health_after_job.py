"""What ``/health`` says while a worker's task process is replaced after a routine job.

Starts ``python -m app.serve`` as the README runs it (the API and one worker, SQLite and
the filesystem broker, a fresh data dir) with ``INERTIA_ID_WORKER_MAX_JOBS`` (default 1:
the task process retires after every job, as it does after its 100th job or after a job
that left it above ``INERTIA_ID_WORKER_MAX_MEMORY_MB``), submits ``--jobs`` tiny
trainings with the key it printed, each as the one before ends (so from the second on a
job waits for the replacement task process to warm up), and polls ``/health`` every
``--interval`` s until ``--after`` s past the last one's end. ``--busy N`` keeps N
processes spinning on the CPU meanwhile, as a loaded machine. Prints the jobs (when
submitted, started, finished: the wait of the second is the replacement's warm-up) and
the runs of equal answers (status, workers listed, warm-ups under way and their age), in
seconds since the first submission. ``--repo`` runs another checkout (the code before a
change) by the same procedure.

Run: python bench/health_after_job.py [--jobs 2] [--after 40] [--busy 0] [--repo PATH]
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
from _common import (
    add_repo,
    base_parser,
    begin,
    free_port,
    generated_key,
    positive_int,
    print_table,
    service_env,
    spawn_service,
    state_runs,
    stop_service,
    wait_until_ok,
    write_json,
)

TINY_TRAIN: dict[str, Any] = {
    "sequence": [[4, 4, 4, 0, 0, 0]] * 4,
    "kind": "nearest-centroid",
    "metric": "euclidean",
    "n_realisations": 3,
}
TERMINAL = {"succeeded", "failed", "cancelled"}


def _state(health: dict[str, Any]) -> tuple[str, int, str]:
    workers = health["workers"]
    # "warming" exists only in the code after the change; before, a warming worker
    # was simply not listed.
    warming = ", ".join(f"{w['warming_s']:.0f} s" for w in workers.get("warming") or [])
    return health["status"], int(workers["count"]), warming or "-"


def _busy() -> None:
    while True:
        pass


def _watch(
    client: httpx.Client, scenario_id: str, args: argparse.Namespace
) -> tuple[list[tuple[float, tuple[str, int, str]]], list[dict[str, Any]]]:
    """Submit the jobs, each as the one before ends, and poll /health until ``--after``
    s past the last one's end. The samples and the jobs' events, in s since the start."""
    began = time.perf_counter()
    samples: list[tuple[float, tuple[str, int, str]]] = []
    jobs: list[dict[str, Any]] = []

    def submit(n: int) -> None:
        response = client.post(
            "/jobs",
            json={
                "type": "train",
                "scenario_id": scenario_id,
                "seed": args.seed + n,
                "params": TINY_TRAIN,
            },
        )
        response.raise_for_status()
        jobs.append({"id": response.json()["id"], "submitted_s": time.perf_counter() - began})

    submit(0)
    while True:
        now = time.perf_counter()
        job = jobs[-1]
        status = client.get(f"/jobs/{job['id']}").json()["status"]
        if status != "queued" and "started_s" not in job:
            job["started_s"] = now - began
        if status in TERMINAL and "finished_s" not in job:
            job["finished_s"] = now - began
            job["status"] = status
            if len(jobs) < args.jobs:
                submit(len(jobs))
                continue
        samples.append((now - began, _state(client.get("/health").json())))
        if "finished_s" in jobs[-1] and now - began - jobs[-1]["finished_s"] >= args.after:
            return samples, jobs
        if now - began > 900:
            raise RuntimeError("the jobs did not finish in 900 s")
        time.sleep(max(0.0, args.interval - (time.perf_counter() - now)))


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=positive_int, default=2, help="jobs, one after another")
    parser.add_argument("--after", type=float, default=40.0, help="s watched after the last")
    parser.add_argument("--interval", type=float, default=0.5, help="s between two polls")
    parser.add_argument(
        "--max-jobs", type=positive_int, default=1, help="INERTIA_ID_WORKER_MAX_JOBS"
    )
    parser.add_argument(
        "--busy", type=int, default=0, help="processes spinning on the CPU meanwhile (load)"
    )
    add_repo(parser)
    args = begin(parser, "/health after a job whose task process retires")
    hogs = [multiprocessing.Process(target=_busy, daemon=True) for _ in range(args.busy)]
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        env = service_env(Path(args.repo).resolve())
        env["INERTIA_ID_WORKER_MAX_JOBS"] = str(args.max_jobs)
        port = free_port()
        log_path = root / "serve.log"
        argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
        process = spawn_service(argv, log_path=log_path, cwd=root, env=env)
        try:
            base = f"http://127.0.0.1:{port}"
            with httpx.Client(base_url=base, timeout=30) as client:
                wait_until_ok(client, process, log_path)
                client.headers["X-API-Key"] = generated_key(log_path) or ""
                created = client.post("/scenarios", json={"preset": "paper"})
                created.raise_for_status()
                for hog in hogs:
                    hog.start()
                samples, jobs = _watch(client, created.json()["id"], args)
        finally:
            for hog in hogs:
                hog.kill()
            stop_service(process)
    first_end = jobs[0]["finished_s"]
    after = [(at, state) for at, state in samples if at >= first_end]
    not_ok = [at for at, (status, _c, _w) in after if status != "ok"]
    print_table(
        ["job", "submitted s", "started s", "finished s", "waited s", "status"],
        [
            [
                n,
                f"{job['submitted_s']:.1f}",
                f"{job['started_s']:.1f}",
                f"{job['finished_s']:.1f}",
                f"{job['started_s'] - job['submitted_s']:.1f}",
                job["status"],
            ]
            for n, job in enumerate(jobs, 1)
        ],
    )
    print()
    rows = state_runs(samples)
    print_table(["from s", "to s", "status", "workers", "warming"], rows)
    print(
        f"\nafter the first job ended: {len(not_ok)} of {len(after)} polls not ok "
        f"({len(not_ok) * args.interval:.1f} s at {args.interval:g} s a poll)"
    )
    write_json(
        args.json,
        args,
        {"jobs": jobs, "samples": samples, "not_ok_polls": len(not_ok), "polls": len(after)},
    )


if __name__ == "__main__":
    main()
