"""How many bytes, and how long, a page of ``GET /jobs`` takes, with and without results.

A throwaway SQLite store (the service's own app, through its test client) gets one real
run of each kind of job a team keeps (small PPO, CEM and NSGA-II searches on the paper
preset, a training, a sweep of that classifier), run in-process by the worker's own
``execute_job``. The store is then filled to ``--jobs`` finished jobs by submitting the
same parameters under other seeds and finishing each with its kind's real result (through
the store's ``claim`` and ``finish``, which write the summary as a worker does): the list
is timed on real results, without running hundreds of searches. Each page is read
best-of-``--repeats``: its body in bytes and its time in ms, at the default page size and
at ``--limit`` (200), with ``include=result`` beside when the service takes it.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

from _common import GOOD_SEQUENCE, base_parser, begin, positive_int, print_table, write_json

# Small real runs: seconds each, results shaped as a team's (curve, best, fresh draws,
# baselines; a front for NSGA-II; points and confusions for the sweep).
_SEARCHES: dict[str, dict[str, Any]] = {
    "search ppo": {"method": "ppo", "sequence_length": 4, "timesteps": 256, "ppo": {"n_steps": 64}},
    "search cem": {"method": "cem", "sequence_length": 8, "timesteps": 512},
    "search nsga2": {
        "method": "nsga2",
        "sequence_length": 4,
        "nsga2": {"population": 16, "generations": 3, "polish_iterations": 0},
    },
}
_TRAIN: dict[str, Any] = {"sequence": GOOD_SEQUENCE, "metric": "euclidean"}
_SWEEP: dict[str, Any] = {"n_test": 100, "ceiling_realisations": 200}


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=positive_int, default=200, help="finished jobs stored")
    parser.add_argument("--limit", type=positive_int, default=200, help="the large page size")
    parser.add_argument("--repeats", type=positive_int, default=5, help="reads per page, best kept")
    parser.add_argument(
        "--store",
        metavar="DIR",
        type=Path,
        default=None,
        help="keep the store (jobs.db) in this new folder, e.g. to serve the dashboard on it",
    )
    args = begin(parser, "GET /jobs: bytes and time of a page")
    if args.store is not None:
        if args.store.exists():
            parser.error(f"--store {str(args.store)!r} exists; name a new folder")
        args.store.mkdir(parents=True)
        figures = _measure(args.store, args)
    else:
        with tempfile.TemporaryDirectory(prefix="job-list-size-") as folder:
            figures = _measure(Path(folder), args)
    write_json(args.json, args, figures)


def _measure(folder: Path, args: argparse.Namespace) -> dict[str, Any]:
    from app.main import create_app
    from service.config import Settings
    from worker.runner import execute_job

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Starlette's nudge towards httpx2
        from fastapi.testclient import TestClient

    settings = Settings(
        INERTIA_ID_DATA_DIR=folder,
        DATABASE_URL=f"sqlite:///{folder / 'jobs.db'}",
        BROKER_URL="filesystem://",
        INERTIA_ID_API_KEY="bench-key-job-list-size",
        INERTIA_ID_MAX_PAGE_SIZE=max(args.limit, 50),
        INERTIA_ID_ALLOWED_HOSTS="testserver",
    )
    app = create_app(settings)
    with TestClient(app) as client:
        client.headers["X-API-Key"] = "bench-key-job-list-size"
        created = client.post("/scenarios", json={"preset": "paper"})
        created.raise_for_status()
        scenario_id = created.json()["id"]

        def run(job_type: str, params: dict[str, Any], seed: int) -> dict[str, Any]:
            answer = client.post(
                "/jobs",
                json={"type": job_type, "scenario_id": scenario_id, "params": params, "seed": seed},
            )
            answer.raise_for_status()
            job_id = answer.json()["id"]
            status = execute_job(job_id, settings=settings, worker_name="bench")
            job: dict[str, Any] = client.get(f"/jobs/{job_id}").json()
            if status != "succeeded":
                raise SystemExit(f"the {job_type} job {status}: {job['error']}")
            return job

        kinds: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {}
        rows = []
        for label, params in _SEARCHES.items():
            start = time.perf_counter()
            job = run("search", params, args.seed)
            kinds[label] = ("search", params, job["result"])
            rows.append([label, time.perf_counter() - start, _size(job["result"])])
        start = time.perf_counter()
        trained = run("train", _TRAIN, args.seed)
        kinds["train"] = ("train", _TRAIN, trained["result"])
        rows.append(["train", time.perf_counter() - start, _size(trained["result"])])
        sweep_params = {**_SWEEP, "classifier_id": trained["result"]["classifier_id"]}
        start = time.perf_counter()
        swept = run("sweep", sweep_params, args.seed)
        kinds["sweep"] = ("sweep", sweep_params, swept["result"])
        rows.append(["sweep", time.perf_counter() - start, _size(swept["result"])])
        print_table(["real run", "s", "result bytes"], rows, "One real run of each kind")

        _fill(client, app, scenario_id, list(kinds.values()), args.jobs - len(kinds), args.seed)
        pages = [("default page", {}), (f"limit={args.limit}", {"limit": args.limit})]
        takes_include = client.get("/jobs", params={"include": "result"}).status_code == 200
        if takes_include:
            pages.append(
                (f"limit={args.limit}, include=result", {"limit": args.limit, "include": "result"})
            )
        measured = []
        for label, query in pages:
            best_s, body = _read(client, query, args.repeats)
            measured.append(
                {
                    "page": label,
                    "jobs": len(json.loads(body)["items"]),
                    "bytes": len(body),
                    "ms": best_s * 1e3,
                }
            )
        _, full = _read(client, dict(pages[-1][1]), 1)
        items = json.loads(full)["items"]
        fields = [
            [
                name,
                max(_size(i.get(name)) for i in items),
                sum(_size(i.get(name)) for i in items) / len(items),
            ]
            for name in ("params", "summary", "result")
        ]
        print_table(
            ["field", "max bytes", "mean bytes"], fields, f"A job's fields ({pages[-1][0]})"
        )
        print_table(
            ["GET /jobs", "jobs", "bytes", "ms (best)"],
            [[m["page"], m["jobs"], m["bytes"], m["ms"]] for m in measured],
            f"{args.jobs} finished jobs in SQLite (include=result "
            f"{'taken' if takes_include else 'not taken: the list sends results'})",
        )
    return {"real_runs": rows, "fields": fields, "pages": measured}


def _fill(
    client: Any,
    app: Any,
    scenario_id: str,
    kinds: list[tuple[str, dict[str, Any], dict[str, Any]]],
    count: int,
    seed: int,
) -> None:
    """``count`` more finished jobs, in turn of each kind, each with its kind's real result."""
    from service.store.jobs import claim, finish

    for i in range(max(count, 0)):
        job_type, params, result = kinds[i % len(kinds)]
        answer = client.post(
            "/jobs",
            json={
                "type": job_type,
                "scenario_id": scenario_id,
                "params": params,
                "seed": seed + 1 + i,
                "name": f"{job_type} run {i}",
                "tags": ["bench", job_type],
            },
        )
        answer.raise_for_status()
        job_id = answer.json()["id"]
        with app.state.db.session() as session:
            claim(session, job_id, "bench")
        with app.state.db.session() as session:
            finish(session, job_id, "succeeded", result=result)


def _read(client: Any, query: dict[str, Any], repeats: int) -> tuple[float, bytes]:
    best = float("inf")
    body = b""
    for _ in range(repeats):
        start = time.perf_counter()
        answer = client.get("/jobs", params=query)
        best = min(best, time.perf_counter() - start)
        answer.raise_for_status()
        body = answer.content
    return best, body


def _size(value: Any) -> int:
    return len(json.dumps(value, separators=(",", ":")))


if __name__ == "__main__":
    main()
