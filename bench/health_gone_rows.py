"""How long ``/health`` takes with many rows of gone workers in the ``workers`` table.

Each worker killed (``kill -9``, its machine lost) leaves its row, beaten within the
silence window, whose incarnation lock is free: ``/health`` tells it gone by its lock.
This fills a fresh store (``--store sqlite``: a file in a temporary folder;
``--store postgresql``: a fresh database on ``--postgres``, dropped after) with one live
worker (its lock held) and ``--gone`` rows of gone workers (beaten 2 s ago, their locks
free; on SQLite each with the lock file a killed worker leaves), then times
``--requests`` calls of ``/health`` in process (FastAPI's TestClient, the filesystem
broker) and prints the median and the 90th percentile per count.

Run: python bench/health_gone_rows.py [--store sqlite|postgresql] [--gone 0,50,500]
     [--requests 30]
(``PYTHONPATH`` picks the code measured: a checkout of the code before a change.)
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import timedelta
from pathlib import Path

from _common import (
    base_parser,
    begin,
    positive_int,
    print_table,
    scratch_postgres,
    write_json,
)
from sqlalchemy import update


def _counts(value: str) -> list[int]:
    """argparse type: row counts separated by commas, 0 or more each."""
    try:
        counts = [int(part) for part in value.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected counts separated by commas, got {value!r}"
        ) from None
    if not counts or min(counts) < 0:
        raise argparse.ArgumentTypeError(f"expected counts of 0 or more, got {value!r}")
    return counts


@contextmanager
def _database(args: argparse.Namespace, root: Path) -> Iterator[str]:
    """The URL of a fresh, migrated database, dropped after."""
    from service.store import upgrade

    if args.store == "sqlite":
        url = f"sqlite:///{root / 'inertia-id.db'}"
        upgrade(url)
        yield url
        return
    with scratch_postgres(args.postgres) as url:
        upgrade(url)
        yield url


def _fill(url: str, gone: int) -> None:
    """``gone`` rows of gone workers, beaten 2 s ago, their locks free (on SQLite the
    files a killed worker leaves behind)."""
    from service.store.incarnations import lock_file
    from service.store.models import WorkerRow, utcnow
    from service.store.session import Database

    database = Database(url)
    seen = utcnow() - timedelta(seconds=2.0)
    with database.session() as session:
        session.query(WorkerRow).filter(WorkerRow.name != "celery@live").delete()
        for index in range(gone):
            incarnation = uuid.uuid4().hex
            session.add(
                WorkerRow(
                    name=f"celery@gone-{index}",
                    broker_url="filesystem://",
                    started_at=seen,
                    last_seen_at=seen,
                    incarnation=incarnation,
                )
            )
            path = lock_file(url, incarnation)
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.touch()
    database.dispose()


def _measure(args: argparse.Namespace, root: Path, url: str, gone: int) -> list[float]:
    from fastapi.testclient import TestClient

    from app.main import create_app
    from service.config import Settings
    from service.store.models import WorkerRow, utcnow
    from service.store.session import Database

    _fill(url, gone)
    settings = Settings(
        INERTIA_ID_DATA_DIR=root,
        DATABASE_URL=url,
        BROKER_URL="filesystem://",
        INERTIA_ID_API_KEY=None,
        INERTIA_ID_VERDICT_PROCESS="lazy",
        INERTIA_ID_ALLOWED_HOSTS="testserver,127.0.0.1,localhost",
    )
    times: list[float] = []
    with TestClient(create_app(settings)) as client:
        database = Database(url)
        for _ in range(args.requests):
            # The live worker beats; the gone rows stay within the silence window,
            # their last beats 2 s old.
            with database.session() as session:
                now = utcnow()
                session.execute(update(WorkerRow).values(last_seen_at=now - timedelta(seconds=2.0)))
                session.get_one(WorkerRow, "celery@live").last_seen_at = now
            began = time.perf_counter()
            health = client.get("/health").json()
            times.append(time.perf_counter() - began)
            assert len(health["workers"]["gone"]) == gone, health["workers"]
            assert health["workers"]["names"] == ["celery@live"], health["workers"]
        database.dispose()
    return times


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--store", choices=("sqlite", "postgresql"), default="sqlite")
    parser.add_argument(
        "--postgres",
        default="postgresql+psycopg://postgres@127.0.0.1:5432/postgres",
        help="PostgreSQL server (its maintenance database) for --store postgresql",
    )
    parser.add_argument("--gone", type=_counts, default=[0, 50, 500], help="gone rows")
    parser.add_argument("--requests", type=positive_int, default=30, help="/health calls each")
    args = begin(parser, "/health with the rows of gone workers")

    from service.store.models import WorkerRow, utcnow
    from service.store.session import Database
    from worker.incarnation import Life

    rows = []
    with tempfile.TemporaryDirectory() as folder, _database(args, Path(folder)) as url:
        live = Life(url, uuid.uuid4().hex)
        assert live.hold()
        database = Database(url)
        with database.session() as session:
            now = utcnow()
            session.add(
                WorkerRow(
                    name="celery@live",
                    broker_url="filesystem://",
                    started_at=now,
                    last_seen_at=now,
                    incarnation=live.incarnation,
                )
            )
        database.dispose()
        try:
            for gone in args.gone:
                times = _measure(args, Path(folder), url, gone)
                rows.append(
                    [
                        gone,
                        statistics.median(times),
                        statistics.quantiles(times, n=10)[-1] if len(times) > 1 else times[0],
                        max(times),
                    ]
                )
        finally:
            live.release()
    print_table(["gone rows", "median s", "p90 s", "max s"], rows)
    write_json(args.json, args, {"store": args.store, "rows": rows})


if __name__ == "__main__":
    main()
