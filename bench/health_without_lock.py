"""How long ``/health`` takes to say that its one worker lost its incarnation lock, and
to say "ok" again once the worker takes it back.

Starts ``python -m app.serve`` as the README runs it (the API and one worker, SQLite and
the filesystem broker, a fresh data dir), waits for "ok", then ``--rounds`` times: keeps
the lock from the worker as an operator's mistake would (``<database>.incarnations``
removed and a file put in its place), polls ``/health`` every ``--interval`` s until it
is "degraded" with the worker in ``workers.without_lock``, removes the file and polls
until "ok". Prints each round's two delays, s from the change on disk. The worker finds
the lock lost at its next beat (``INERTIA_ID_HEARTBEAT_INTERVAL_S``, 5 s), so both are
expected within one interval. ``--repo`` runs another checkout (the code before a
change): there ``/health`` never says it, and the round ends after ``--give-up`` s.

Run: python bench/health_without_lock.py [--rounds 3] [--interval 0.1] [--repo PATH]
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
from _common import (
    add_repo,
    base_parser,
    begin,
    free_port,
    positive_int,
    print_table,
    service_env,
    spawn_service,
    stop_service,
    wait_until_ok,
    write_json,
)


def _lockless(health: dict[str, Any]) -> bool:
    workers = health["workers"]
    return health["status"] == "degraded" and bool(workers.get("without_lock"))


def _until(
    client: httpx.Client, seen: Callable[[dict[str, Any]], bool], interval: float, limit: float
) -> tuple[float | None, list[str]]:
    """Seconds until /health answers as ``seen`` says (None past ``limit``), and the
    statuses it said meanwhile, in order, repeats left out."""
    began = time.perf_counter()
    statuses: list[str] = []
    while time.perf_counter() - began < limit:
        health = client.get("/health").json()
        if not statuses or statuses[-1] != health["status"]:
            statuses.append(health["status"])
        if seen(health):
            return time.perf_counter() - began, statuses
        time.sleep(interval)
    return None, statuses


def _keep_lock_away(folder: Path) -> None:
    # The worker may make the folder again between the removal and the file (its beat).
    while True:
        shutil.rmtree(folder, ignore_errors=True)
        try:
            folder.touch(exist_ok=False)
        except FileExistsError:
            continue
        return


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=positive_int, default=3, help="lock kept away, given back")
    parser.add_argument("--interval", type=float, default=0.1, help="s between two polls")
    parser.add_argument("--give-up", type=float, default=30.0, help="s before a round gives up")
    add_repo(parser)
    args = begin(parser, "/health while the worker lacks its incarnation lock")
    rounds: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        env = service_env(Path(args.repo).resolve())
        port = free_port()
        log_path = root / "serve.log"
        argv = [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"]
        process = spawn_service(argv, log_path=log_path, cwd=root, env=env)
        folder = root / "data" / "inertia-id.db.incarnations"
        try:
            with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as client:
                wait_until_ok(client, process, log_path)
                for _ in range(args.rounds):
                    _keep_lock_away(folder)
                    shown, said = _until(client, _lockless, args.interval, args.give_up)
                    folder.unlink()
                    back, _ = _until(
                        client, lambda h: h["status"] == "ok", args.interval, args.give_up
                    )
                    rounds.append({"shown_s": shown, "ok_again_s": back, "said": said})
        finally:
            stop_service(process)
    print_table(
        ["round", "degraded, worker listed, after s", "/health said", "ok again after s"],
        [
            [
                n,
                "never" if r["shown_s"] is None else f"{r['shown_s']:.1f}",
                " then ".join(r["said"]),
                "never" if r["ok_again_s"] is None else f"{r['ok_again_s']:.1f}",
            ]
            for n, r in enumerate(rounds, 1)
        ],
    )
    write_json(args.json, args, {"rounds": rounds})


if __name__ == "__main__":
    main()
