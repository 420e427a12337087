"""The broker or the database goes away under a running service, and comes back.

Both on private instances (a ``redis-server`` and a PostgreSQL cluster of the test's
own), so stopping them touches nobody else.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from faults import (
    TINY_TRAIN,
    Deployment,
    PostgresCluster,
    RedisServer,
    assert_settled,
    postgres_database,
    random_search,
    wait_for,
)
from sqlalchemy import create_engine, text


@pytest.fixture
def private_redis(tmp_path: Path) -> Iterator[RedisServer]:
    server = RedisServer(tmp_path / "redis").start()
    try:
        yield server
    finally:
        server.stop()


def test_a_job_submitted_while_the_broker_is_down_is_sent_when_it_is_back(
    tmp_path: Path, private_redis: RedisServer
) -> None:
    databases = postgres_database()
    database_url = next(databases)
    deployment = Deployment.on_postgres(tmp_path, database_url, private_redis)
    try:
        serve = deployment.serve(workers=1)
        with serve.client() as client:
            scenario = deployment.scenario(client)
            private_redis.stop()

            # Accepted and stored; it waits, queued and unsent, for the broker.
            job_id = deployment.submit(client, scenario, "train", TINY_TRAIN, seed=41)
            job = deployment.job(job_id)
            assert job.status == "queued" and job.sent_at is None, (job.status, job.sent_at)

            def degraded() -> dict[str, object] | None:
                health = client.get("/health")
                assert health.status_code == 200, health.text
                body = health.json()
                unsent = body["queue"]["unsent"] >= 1
                return body if body["status"] == "degraded" and unsent else None

            health = wait_for(degraded, 120, "/health never reported the unsent job", serve.log)
            assert health["broker"]["ok"] is False  # type: ignore[index]
            assert deployment.job(job_id).status == "queued"

            private_redis.start()
            job = deployment.wait_job(job_id, timeout_s=240)
            assert job.status == "succeeded", (job.status, job.error, serve.log())
            wait_for(
                lambda: client.get("/health").json()["status"] == "ok",
                60,
                "/health did not recover",
                serve.log,
            )
        assert_settled(deployment)
    finally:
        deployment.close()
        for _ in databases:
            pass


def test_a_database_restart_mid_job_ends_the_job_and_the_api_answers_503_meanwhile(
    tmp_path: Path, private_postgres: PostgresCluster, redis_server: RedisServer
) -> None:
    admin = create_engine(private_postgres.url(), isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(text('CREATE DATABASE "inertia"'))
    admin.dispose()
    database_url = private_postgres.url("inertia")
    redis_server.flush()
    deployment = Deployment.on_postgres(tmp_path, database_url, redis_server)
    try:
        serve = deployment.serve(workers=1)
        with serve.client(timeout_s=30) as client:
            scenario = deployment.scenario(client)
            job_id = deployment.submit(client, scenario, "search", random_search(6000), seed=51)
            deployment.wait_job(job_id, ("running",), timeout_s=120)
            deployment.db.dispose()

            private_postgres.stop()
            answers = []
            try:
                for path in ("/jobs", f"/jobs/{job_id}", "/scenarios"):
                    answers.append((path, client.get(path)))
                body = {"type": "train", "scenario_id": scenario, "params": TINY_TRAIN}
                answers.append(("POST /jobs", client.post("/jobs", json=body)))
                health = client.get("/health")
                time.sleep(2)
            finally:
                private_postgres.start()
            # Unavailable, said at once: not a 500, not a hang.
            codes = {path: answer.status_code for path, answer in answers}
            assert set(codes.values()) == {503}, {p: a.text[:200] for p, a in answers}
            assert all(a.headers.get("retry-after") for _, a in answers)
            assert health.status_code == 200 and health.json()["database"]["ok"] is False

            def recovered() -> bool:
                try:
                    return client.get("/jobs").status_code == 200
                except httpx.TransportError:
                    return False

            wait_for(recovered, 60, "the API did not recover from the restart", serve.log)
            job = deployment.wait_job(job_id, timeout_s=240)
            assert job.status == "succeeded" or job.error, (job.status, job.error)
        assert_settled(deployment)
    finally:
        deployment.close()
