"""The Alembic migrations build exactly the tables the models describe."""

from __future__ import annotations

import json
from datetime import UTC, datetime

from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from sqlalchemy import create_engine, inspect, text
from sqlalchemy.orm import Session

from service.store.models import Base, JobRow
from service.store.session import downgrade, upgrade


def test_migrating_to_head_gives_the_models_schema(database_url: str) -> None:
    upgrade(database_url)
    engine = create_engine(database_url)
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
            connection.execute(
                text("INSERT INTO scenarios VALUES ('s', 'x', '{}', :t)"), {"t": now}
            )
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

    def columns() -> set[str]:
        with engine.connect() as connection:
            return {column["name"] for column in inspect(connection).get_columns("jobs")}

    try:
        with engine.begin() as connection:
            connection.execute(
                text("INSERT INTO scenarios VALUES ('s', 'x', '{}', :t)"), {"t": now}
            )
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
        assert "attempt_history" not in columns()
        upgrade(url)
        assert "attempt_history" in columns()
        with Session(engine) as session:
            job = session.get(JobRow, "j")
            assert job is not None and job.attempt_history is None
            assert JobOut.model_validate(job).attempt_history == []
        downgrade(url, "0005")
        assert "attempt_history" not in columns()
        assert (count("jobs"), count("metrics"), count("job_tags")) == (1, 1, 1)
    finally:
        engine.dispose()
