"""How many jobs identical reruns sent at once through the API make.

Runs ``python -m app.serve`` as shipped (its generated key; ``--workers 0`` by default,
so that no worker runs the jobs while they are counted; ``--database-url`` for
PostgreSQL, the scale-out path: an empty database of your own), stores the paper
scenario, submits one small search and then, for each of ``--rounds``, sends
``--clients`` identical submissions at once, each on its own connection, with ``"rerun":
true`` and, with ``--rerun-of``, ``"rerun_of"``: the id of the job that stood before the
round (what the dashboard's Run it again button sends). Before each round the job that
stands is marked succeeded in the database, as a worker would have finished it (with
``--workers 0`` none runs): a round reruns a finished job, as twenty dashboards clicking
Run it again on a result do (a rerun of a job still queued or running is handed that
job). Each round prints how many new jobs (202) and reused answers (200) it got, and
how many jobs of the configuration exist then. One new job a round is what a user who
double-clicked, or a retrying script, meant.

With ``--idempotency-key`` every submission of a round carries one ``Idempotency-Key``
(a new one each round), and the round's rerun is sent once more after the burst, as a
client whose answer was lost retries it; the scenario is stored the same way first,
``--clients`` identical POSTs /scenarios at once with one key. Printed: the scenarios
made, and each round's new jobs, replays (``Idempotent-Replayed: true``) and 409s (the
first still in progress). Without the header a retry was a new job and each POST a new
scenario.

    python bench/concurrent_reruns.py [--clients 10] [--rounds 3] [--rerun-of]
        [--idempotency-key]
        [--database-url postgresql+psycopg://postgres@127.0.0.1:5432/NAME] [--repo DIR]
"""

from __future__ import annotations

import secrets
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import sqlalchemy
from _common import (
    add_repo,
    base_parser,
    begin,
    free_port,
    generated_key,
    positive_int,
    service_env,
    spawn_service,
    stop_service,
    write_json,
)


def _at_once(count: int, send: Any) -> list[Any]:
    """``send()`` on ``count`` threads released together: answers or exceptions."""
    barrier = threading.Barrier(count)
    answers: list[Any] = [None] * count

    def run(index: int) -> None:
        barrier.wait()
        try:
            answers[index] = send()
        except Exception as exc:
            answers[index] = exc

    threads = [threading.Thread(target=run, args=(i,)) for i in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    return answers


def _keyed(headers: dict[str, str], args: Any, what: str) -> dict[str, str]:
    """``headers`` with a new ``Idempotency-Key`` when the bench sends one."""
    if not args.idempotency_key:
        return headers
    return {**headers, "Idempotency-Key": f"{what}-{secrets.token_hex(8)}"}


def _burst(base: str, path: str, body: dict[str, Any], headers: dict[str, str], n: int) -> Any:
    def send() -> httpx.Response:
        with httpx.Client(base_url=base, headers=headers, timeout=60) as own:
            return own.post(path, json=body)

    return _at_once(n, send)


def _status(answer: Any) -> int | None:
    return answer.status_code if isinstance(answer, httpx.Response) else None


def _replays(answers: list[Any]) -> int:
    return sum(
        isinstance(a, httpx.Response) and a.headers.get("Idempotent-Replayed") == "true"
        for a in answers
    )


def _finish(database_url: str, job_id: str) -> None:
    """Mark the job succeeded, as its worker would (plain SQL: the schema of any checkout)."""
    engine = sqlalchemy.create_engine(database_url)
    try:
        with engine.begin() as connection:
            connection.execute(
                sqlalchemy.text(
                    "UPDATE jobs SET status = 'succeeded', progress = 1.0, "
                    "finished_at = CURRENT_TIMESTAMP WHERE id = :id"
                ),
                {"id": job_id},
            )
    finally:
        engine.dispose()


def _rounds(
    base: str, key: str, database_url: str, args: Any
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    headers = {"X-API-Key": key}
    with httpx.Client(base_url=base, headers=headers, timeout=60) as client:
        stored = _burst(
            base, "/scenarios", {"preset": "paper"}, _keyed(headers, args, "scenario"), args.clients
        )
        made = {a.json()["id"] for a in stored if isinstance(a, httpx.Response) and a.is_success}
        if not made:
            raise RuntimeError(f"POST /scenarios stored nothing: {stored}")
        scenarios = {
            "sent": args.clients,
            "made": client.get("/scenarios", params={"limit": 200}).json()["total"],
            "replayed": _replays(stored),
            "conflicts": sum(_status(a) == 409 for a in stored),
        }
        scenario = sorted(made)[0]
        body: dict[str, Any] = {
            "type": "search",
            "scenario_id": scenario,
            "seed": args.seed,
            "params": {"method": "random", "sequence_length": 4, "timesteps": 64},
        }
        first = client.post("/jobs", json=body)
        if first.status_code not in (200, 202):
            raise RuntimeError(f"POST /jobs answered {first.status_code}: {first.text}")
        standing, digest = first.json()["id"], first.json()["config_hash"]
        rounds = []
        for _ in range(args.rounds):
            if args.workers == 0:
                _finish(database_url, standing)
            rerun = {**body, "rerun": True}
            if args.rerun_of:
                rerun["rerun_of"] = standing
            sent = _keyed(headers, args, "rerun")
            answers = _burst(base, "/jobs", rerun, sent, args.clients)
            if args.idempotency_key:
                # The retry of a client whose answer was lost, once the burst is answered.
                answers.append(client.post("/jobs", json=rerun, headers=sent))
            codes = [a.status_code for a in answers if isinstance(a, httpx.Response)]
            listed = client.get("/jobs", params={"scenario_id": scenario, "limit": 200}).json()
            replayed = _replays(answers)
            rounds.append(
                {
                    "new": codes.count(202) - _replays([a for a in answers if _status(a) == 202]),
                    "reused": codes.count(200),
                    "replayed": replayed,
                    "other": sorted(c for c in codes if c not in (200, 202)),
                    "errors": [repr(a) for a in answers if not isinstance(a, httpx.Response)],
                    "jobs_in_all": sum(j["config_hash"] == digest for j in listed["items"]),
                }
            )
            # A plain submission is handed the job that stands now.
            standing = client.post("/jobs", json=body).json()["id"]
    return scenarios, rounds


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--clients", type=positive_int, default=10, help="reruns sent at once")
    parser.add_argument("--rounds", type=positive_int, default=3)
    parser.add_argument("--rerun-of", action="store_true", help="send rerun_of too")
    parser.add_argument(
        "--idempotency-key",
        action="store_true",
        help="one Idempotency-Key a round (and for the scenario), and a retry after each burst",
    )
    parser.add_argument("--workers", type=int, default=0, help="serve --workers")
    parser.add_argument("--database-url", default=None, help="default: serve's SQLite file")
    add_repo(parser)
    args = begin(parser, "Identical reruns sent at once: jobs made")
    with tempfile.TemporaryDirectory(prefix="concurrent-reruns-") as folder:
        root = Path(folder)
        env = service_env(Path(args.repo).resolve())
        database_url = f"sqlite:///{root / 'data' / 'inertia-id.db'}"
        if args.database_url:
            env["DATABASE_URL"] = database_url = args.database_url
        port = free_port()
        log_path = root / "serve.log"
        argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
        argv += ["--workers", str(args.workers), "--log-level", "warning"]
        process = spawn_service(argv, log_path=log_path, cwd=root, env=env)
        base = f"http://127.0.0.1:{port}"
        try:
            deadline = time.monotonic() + 300
            while True:
                try:
                    if httpx.get(f"{base}/health", timeout=5).status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                if time.monotonic() > deadline or process.poll() is not None:
                    raise RuntimeError(log_path.read_text(errors="replace"))
                time.sleep(0.2)
            key = generated_key(log_path)
            if key is None:
                raise RuntimeError("serve generated no API key: give it an empty database")
            scenarios, rounds = _rounds(base, key, database_url, args)
        finally:
            stop_service(process)
    keyed = " with one Idempotency-Key" if args.idempotency_key else ""
    print(
        f"scenario: {scenarios['sent']} identical POSTs /scenarios at once{keyed} -> "
        f"{scenarios['made']} scenarios stored ({scenarios['replayed']} replays, "
        f"{scenarios['conflicts']} 409 in progress)"
    )
    sent = f"{args.clients} reruns at once{keyed}" + (" and 1 retry" if keyed else "")
    for n, result in enumerate(rounds, 1):
        print(
            f"round {n}: {sent} -> {result['new']} new jobs (202), "
            f"{result['reused']} reused (200), {result['replayed']} replays, "
            f"other {result['other']}, errors {len(result['errors'])}; "
            f"{result['jobs_in_all']} jobs of the configuration in all"
        )
    write_json(args.json, args, {"scenarios": scenarios, "rounds": rounds})


if __name__ == "__main__":
    main()
