"""The Alembic migrations build exactly the tables the models describe."""

from __future__ import annotations

import json
import re
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import Engine, create_engine, event, inspect, text
from sqlalchemy.orm import Session

from service.store.models import Base, JobRow
from service.store.session import downgrade, upgrade


def _scenario_s(connection: Any, now: datetime) -> None:
    """Scenario 's', as the jobs inserted by hand below name it."""
    connection.execute(text("INSERT INTO scenarios VALUES ('s', 'x', '{}', :t)"), {"t": now})


def _job_columns(engine: Engine) -> set[str]:
    with engine.connect() as connection:
        return {column["name"] for column in inspect(connection).get_columns("jobs")}


def test_migrating_to_head_gives_the_models_schema(empty_database_url: str) -> None:
    upgrade(empty_database_url)
    engine = create_engine(empty_database_url)
    try:
        with engine.connect() as connection:
            context = MigrationContext.configure(connection, opts={"compare_type": True})
            differences = compare_metadata(context, Base.metadata)
    finally:
        engine.dispose()
    assert differences == []


def test_stored_curve_rates_are_renamed_for_what_they_hold(empty_database_url: str) -> None:
    """Metrics stored as best_final_rate_rad_s meant NSGA-II's settled residual and the
    other searches' end-of-command rate: 0005 names each for what it held, and nothing
    else moves; the downgrade gives the old code back its names."""
    url = empty_database_url
    upgrade(url, "0004")
    now = datetime.now(UTC)
    engine = create_engine(url)
    jobs = {"pareto": "nsga2", "learner": "ppo", "cem": "cem", "fit": None}
    metric = text("INSERT INTO metrics (job_id, key, step, value) VALUES (:j, :k, :s, 0.5)")
    try:
        with engine.begin() as connection:
            _scenario_s(connection, now)
            for job_id, method in jobs.items():
                connection.execute(
                    text(
                        "INSERT INTO jobs (id, type, status, scenario_id, params, seed, "
                        "config_hash, progress, cancel_requested, attempts, created_at) VALUES "
                        "(:id, :type, 'succeeded', 's', :params, 0, :id, 1.0, false, 1, :t)"
                    ),
                    {
                        "id": job_id,
                        "type": "search" if method else "train",
                        "params": json.dumps({} if method is None else {"method": method}),
                        "t": now,
                    },
                )
                for step, key in enumerate(["best_final_rate_rad_s", "best_f1"]):
                    connection.execute(metric, {"j": job_id, "k": key, "s": step})
            # A job recorded by today's code keeps its names.
            connection.execute(metric, {"j": "learner", "k": "best_residual_rate_rad_s", "s": 9})

        def keys() -> dict[str, list[str]]:
            with engine.connect() as connection:
                rows = connection.execute(
                    text("SELECT job_id, key FROM metrics ORDER BY job_id, step")
                ).all()
            found: dict[str, list[str]] = {}
            for job_id, key in rows:
                found.setdefault(job_id, []).append(key)
            return found

        before = keys()
        upgrade(url)
        assert keys() == {
            "pareto": ["best_residual_rate_rad_s", "best_f1"],
            "learner": ["best_end_rate_rad_s", "best_f1", "best_residual_rate_rad_s"],
            "cem": ["best_end_rate_rad_s", "best_f1"],
            "fit": ["best_end_rate_rad_s", "best_f1"],
        }
        downgrade(url, "0004")
        assert keys() == before
    finally:
        engine.dispose()


def test_attempt_history_comes_and_goes_keeping_every_job_its_metrics_and_tags(
    empty_database_url: str,
) -> None:
    """0006 adds ``jobs.attempt_history``: a job stored before has none kept (NULL, shown
    as an empty list); the downgrade removes the column and nothing else. A batch that
    copied the jobs table on SQLite had deleted every metric and tag with it (their ON
    DELETE CASCADE, foreign keys on)."""
    from app.schemas import JobOut

    url = empty_database_url
    upgrade(url, "0005")
    now = datetime.now(UTC)
    engine = create_engine(url)

    def count(table: str) -> int:
        with engine.connect() as connection:
            return int(connection.execute(text(f"SELECT count(*) FROM {table}")).scalar_one())

    try:
        with engine.begin() as connection:
            _scenario_s(connection, now)
            connection.execute(
                text(
                    "INSERT INTO jobs (id, type, status, scenario_id, params, seed, "
                    "config_hash, progress, cancel_requested, attempts, handbacks, superseded, "
                    "created_at) VALUES "
                    "('j', 'train', 'succeeded', 's', '{}', 0, 'h', 1.0, false, 2, 0, false, :t)"
                ),
                {"t": now},
            )
            connection.execute(
                text("INSERT INTO metrics (job_id, key, step, value) VALUES ('j', 'f1', 0, 1)")
            )
            connection.execute(text("INSERT INTO job_tags (job_id, tag) VALUES ('j', 'audit')"))
        assert "attempt_history" not in _job_columns(engine)
        upgrade(url)
        assert "attempt_history" in _job_columns(engine)
        with Session(engine) as session:
            job = session.get(JobRow, "j")
            assert job is not None and job.attempt_history is None
            assert JobOut.model_validate(job).attempt_history == []
        downgrade(url, "0005")
        assert "attempt_history" not in _job_columns(engine)
        assert (count("jobs"), count("metrics"), count("job_tags")) == (1, 1, 1)
    finally:
        engine.dispose()


def test_jobs_stopped_by_their_time_limit_say_so_once_migrated(empty_database_url: str) -> None:
    """0012 adds ``jobs.stopped``, filled for the jobs stored before: "time_limit" for
    those failed naming the limit (by the worker's words, the heartbeat's end included)
    and for those that succeeded with what they had (their result's ``stopped``); NULL
    for every other (another failure, a cancelled search, one stopped by its budget). The
    downgrade removes the column and nothing else."""
    from app.schemas import JobOut

    url = empty_database_url
    upgrade(url, "0011")
    now = datetime.now(UTC)
    engine = create_engine(url)
    limit = "JobTimeLimitExceeded: the job exceeded its time limit of 30 s"
    jobs: dict[str, tuple[str, str, str | None, dict[str, Any] | None, str | None]] = {
        "train-limit": ("train", "failed", limit, None, "time_limit"),
        "sweep-none": (
            "sweep",
            "failed",
            f"{limit} before the first sweep point",
            None,
            "time_limit",
        ),
        "beat-ended": (
            "search",
            "failed",
            "the job exceeded its time limit of 30 s (still running 640 s after it; ended)",
            None,
            "time_limit",
        ),
        "search-limit": ("search", "succeeded", None, {"stopped": "time_limit"}, "time_limit"),
        "sweep-limit": (
            "sweep",
            "succeeded",
            None,
            {"points": [], "stopped": "time_limit"},
            "time_limit",
        ),
        "search-budget": ("search", "succeeded", None, {"stopped": "budget"}, None),
        "search-cancelled": ("search", "cancelled", None, {"stopped": "cancelled"}, None),
        "train-done": ("train", "succeeded", None, {"f1": 1.0}, None),
        "other-failure": ("train", "failed", "InputError: the time limit of 30 s", None, None),
        "queued": ("train", "queued", None, None, None),
    }

    try:
        with engine.begin() as connection:
            _scenario_s(connection, now)
            for job_id, (job_type, status, error, result, _stopped) in jobs.items():
                connection.execute(
                    text(
                        "INSERT INTO jobs (id, type, status, scenario_id, params, seed, "
                        "config_hash, progress, cancel_requested, attempts, handbacks, "
                        "superseded, created_at, error, result) VALUES (:id, :type, :status, "
                        "'s', '{}', 0, :id, 1.0, false, 1, 0, false, :t, :error, :result)"
                    ),
                    {
                        "id": job_id,
                        "type": job_type,
                        "status": status,
                        "t": now,
                        "error": error,
                        "result": None if result is None else json.dumps(result),
                    },
                )
        assert "stopped" not in _job_columns(engine)
        upgrade(url)
        with Session(engine) as session:
            found = {
                job_id: JobOut.model_validate(session.get(JobRow, job_id)).stopped
                for job_id in jobs
            }
        assert found == {job_id: job[-1] for job_id, job in jobs.items()}
        downgrade(url, "0011")
        assert "stopped" not in _job_columns(engine)
        with engine.connect() as connection:
            assert int(connection.execute(text("SELECT count(*) FROM jobs")).scalar_one()) == len(
                jobs
            )
    finally:
        engine.dispose()


def _tables(engine: Engine) -> dict[str, tuple[set[str], list[dict[str, Any]]]]:
    """Each table but Alembic's: its columns, and its rows as column -> value (sorted)."""
    with engine.connect() as connection:
        schema = inspect(connection)
        found = {}
        for name in schema.get_table_names():
            if name == "alembic_version":
                continue
            rows = connection.execute(text(f"SELECT * FROM {name}")).mappings().all()
            columns = {column["name"] for column in schema.get_columns(name)}
            found[name] = (columns, sorted((dict(row) for row in rows), key=repr))
    return found


def _kept(
    before: dict[str, tuple[set[str], list[dict[str, Any]]]],
    after: dict[str, tuple[set[str], list[dict[str, Any]]]],
) -> dict[str, list[dict[str, Any]]]:
    """``before``'s rows of the tables ``after`` has, cut to the columns ``after`` has:
    what a migration between the two must have kept."""
    return {
        name: sorted(
            (
                {k: v for k, v in row.items() if k in columns}
                for row in before.get(name, ((), []))[1]
            ),
            key=repr,
        )
        for name, (columns, _rows) in after.items()
    }


def _rows(
    tables: dict[str, tuple[set[str], list[dict[str, Any]]]],
) -> dict[str, list[dict[str, Any]]]:
    return {name: rows for name, (_columns, rows) in tables.items()}


def _revisions() -> list[str]:
    """Every revision, base first (from the scripts, so a new migration is walked too)."""
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    from service.store.session import MIGRATIONS

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    walked = ScriptDirectory.from_config(config).walk_revisions()
    return [script.revision for script in reversed(list(walked))]


@contextmanager
def _tables_copied(url: str) -> Iterator[set[str]]:
    """The tables that the statements run inside the block copy into a new one (an
    Alembic batch on SQLite: create ``_alembic_tmp_<table>``, copy, drop the old, rename)."""
    copied: set[str] = set()
    copy = re.compile(r"CREATE TABLE \"?_alembic_tmp_(\w+)")

    def record(_conn: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        copied.update(copy.findall(statement))

    event.listen(Engine, "before_cursor_execute", record)
    try:
        yield copied
    finally:
        event.remove(Engine, "before_cursor_execute", record)


def _seed_at_0001(engine: Engine) -> None:
    """Rows in every table of 0001: three jobs with three metrics each, a classifier of
    the first, a worker and an API key."""
    now = datetime(2026, 11, 22, 12, tzinfo=UTC)
    with engine.begin() as connection:
        connection.execute(
            text("INSERT INTO scenarios VALUES ('s', 'paper', '{\"x\": 1}', :t)"), {"t": now}
        )
        for index, state in enumerate(["succeeded", "running", "queued"]):
            connection.execute(
                text(
                    "INSERT INTO jobs (id, type, status, scenario_id, params, seed, "
                    "config_hash, progress, cancel_requested, attempts, created_at) VALUES "
                    "(:id, 'train', :state, 's', '{}', :i, :id, 0.5, false, :i, :t)"
                ),
                {"id": f"job{index}", "state": state, "i": index, "t": now},
            )
            for step in range(3):
                connection.execute(
                    text(
                        "INSERT INTO metrics (job_id, key, step, value) VALUES (:j, 'f1', :s, :v)"
                    ),
                    {"j": f"job{index}", "s": step, "v": 0.25 * step},
                )
        connection.execute(
            text(
                "INSERT INTO classifiers (id, job_id, scenario_id, metric, f1, accuracy, "
                "sequence, candidate_names, confusion, document, sha256, created_at) VALUES "
                "('c', 'job0', 's', 'euclidean', 1.0, 1.0, '[[4, 0]]', '[\"a\"]', '[[1]]', "
                "'{}', :sha, :t)"
            ),
            {"sha": "0" * 64, "t": now},
        )
        connection.execute(
            text("INSERT INTO workers VALUES ('w1@host', 'filesystem://', :t, :t)"), {"t": now}
        )
        connection.execute(
            text("INSERT INTO api_keys (key_hash, created_at) VALUES (:h, :t)"),
            {"h": "0" * 64, "t": now},
        )


def test_each_step_down_to_base_and_back_keeps_every_row_the_schema_still_holds(
    empty_database_url: str,
) -> None:
    """Every table holds rows at head (jobs with a name, summary, tags, metrics, an
    attempt history and a classifier); each downgrade to base keeps every row, and every
    value, of the tables and columns its schema still has, and so does each upgrade back
    from 0001 (seeded with a row in every table). 0004's downgrade dropped the jobs' name
    and summary with a batch that copied ``jobs`` on SQLite: the old table's drop deleted
    every metric (ON DELETE CASCADE, foreign keys on) and unlinked every classifier from
    its job (ON DELETE SET NULL). No step copies a table but 0003's, which changes the
    classifier columns' types (SQLite alters no type in place; no foreign key points at
    ``classifiers``); 0002's downgrade copied ``classifiers`` to drop its kind."""
    from service.store import (
        ApiKey,
        ClassifierRow,
        Database,
        IdempotencyKeyRow,
        JobTagRow,
        MetricRow,
        ScenarioRow,
        WorkerRow,
    )

    url = empty_database_url
    upgrade(url)
    db = Database(url)
    try:
        with db.session() as session:
            session.add(ScenarioRow(id="s", name="paper", document={"x": 1}))
            session.add(WorkerRow(name="w1@host", broker_url="filesystem://"))
            session.add(ApiKey(key_hash="0" * 64))
            session.add(
                IdempotencyKeyRow(
                    client="0" * 64,
                    key="retry-1",
                    route="POST /jobs",
                    fingerprint="f" * 64,
                    claim="c" * 32,
                    expires_at=datetime(2030, 1, 1, tzinfo=UTC),
                    answer_status=202,
                    answer_body={"id": "job0"},
                )
            )
            session.flush()
            for index, status in enumerate(["succeeded", "running", "queued"]):
                job_id = f"job{index}"
                session.add(
                    JobRow(
                        id=job_id,
                        type="train",
                        status=status,
                        scenario_id="s",
                        params={"n_realisations": index},
                        seed=index,
                        config_hash=f"h{index}",
                        attempts=index,
                        name=f"run {index}",
                        summary={"f1": 0.5},
                        attempt_history=[{"attempt": 1, "cause": "worker lost"}],
                        stopped="time_limit" if status == "succeeded" else None,
                        tag_rows=[JobTagRow(tag="audit"), JobTagRow(tag=f"t{index}")],
                    )
                )
                session.flush()
                session.add_all(
                    MetricRow(job_id=job_id, key="f1", step=step, value=0.25 * step)
                    for step in range(3)
                )
            session.add(
                ClassifierRow(
                    id="c",
                    job_id="job0",
                    scenario_id="s",
                    metric="euclidean",
                    f1=1.0,
                    accuracy=1.0,
                    sequence=[[4, 0]],
                    candidate_names=["a"],
                    confusion=[[1]],
                    document="{}",
                    sha256="0" * 64,
                )
            )
    finally:
        db.dispose()

    revisions = _revisions()
    assert revisions[0] == "0001" and len(revisions) >= 7, revisions
    copies: dict[str, set[str]] = {}
    engine = create_engine(url)
    try:
        at_head = _rows(_tables(engine))
        assert all(at_head.values()), {name for name, rows in at_head.items() if not rows}
        # Down: undo each revision from head's, ending with 0001's (to base).
        for undone, target in zip(revisions[::-1], [*revisions[-2::-1], "base"], strict=True):
            before = _tables(engine)
            with _tables_copied(url) as copied:
                downgrade(url, target)
            copies[f"{undone} down"] = copied
            after = _tables(engine)
            assert _rows(after) == _kept(before, after), f"rows lost going down to {target}"
            if target == "0001":
                assert len(_rows(after)["metrics"]) == 9
                assert [row["job_id"] for row in _rows(after)["classifiers"]] == ["job0"]
        assert _tables(engine) == {}  # base: no table of ours
        upgrade(url, "0001")
        _seed_at_0001(engine)
        at_0001 = _rows(_tables(engine))
        assert all(at_0001.values()), {name for name, rows in at_0001.items() if not rows}
        # Up: apply each revision after 0001's, to head.
        for target in revisions[1:]:
            before = _tables(engine)
            with _tables_copied(url) as copied:
                upgrade(url, target)
            copies[f"{target} up"] = copied
            after = _tables(engine)
            assert _kept(after, before) == _rows(before), f"rows lost going up to {target}"
            if target == "0002":
                assert [row["kind"] for row in _rows(after)["classifiers"]] == ["clustering"]
        assert {name: len(rows) for name, rows in _rows(_tables(engine)).items()} == {
            **{name: len(rows) for name, rows in at_0001.items()},
            "job_tags": 0,  # none at 0001: the table came with 0004
            "idempotency_keys": 0,  # the table came with 0010
        }
    finally:
        engine.dispose()
    sqlite = url.startswith("sqlite")
    copied_tables = {step: tables for step, tables in copies.items() if tables}
    assert copied_tables == (
        {"0003 down": {"classifiers"}, "0003 up": {"classifiers"}} if sqlite else {}
    )


def test_a_downgrade_on_an_sqlite_too_old_to_drop_a_column_says_so_and_keeps_the_rows(
    tmp_path: Any, monkeypatch: Any
) -> None:
    """The downgrades drop columns in place (SQLite 3.35 and newer); an older SQLite
    failed with its own "near DROP: syntax error". Told by name now, the step undone."""
    from service.store import Database, WorkerRow

    url = f"sqlite:///{tmp_path / 'old.db'}"
    upgrade(url)
    db = Database(url)
    try:
        with db.session() as session:
            session.add(WorkerRow(name="w1@host", broker_url="filesystem://"))
    finally:
        db.dispose()
    monkeypatch.setattr(sqlite3, "sqlite_version_info", (3, 34, 1))
    monkeypatch.setattr(sqlite3, "sqlite_version", "3.34.1")
    with pytest.raises(
        RuntimeError, match=r"needs SQLite 3\.35\.0 or newer; this Python's SQLite is 3\.34\.1"
    ):
        downgrade(url, "0008")
    engine = create_engine(url)
    try:
        with engine.connect() as connection:
            columns = {c["name"] for c in inspect(connection).get_columns("workers")}
            assert "lock_missing_since" in columns
            assert connection.execute(text("SELECT name FROM workers")).scalars().all() == [
                "w1@host"
            ]
    finally:
        engine.dispose()
    monkeypatch.undo()
    downgrade(url, "0008")
