"""Faults a running service must absorb without a restart, on one ``serve`` per deployment:
lost and never-sent messages, identical submissions racing, a scenario deleted while
jobs are submitted for it, and ``/identify`` at 50 concurrent clients (and past
capacity)."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import httpx
import numpy as np
import pytest
from faults import (
    GOOD_SEQUENCE,
    TINY_TRAIN,
    Deployment,
    Serve,
    assert_settled,
    random_search,
    run_async,
)
from sqlalchemy import func, select

from inertia_id import Scenario, simulate
from service.store import JobRow
from service.store.jobs import config_hash

#: Codes a write may answer while the scenario it names is being deleted.
SUBMIT_CODES = {200, 202, 404, 409}
DELETE_CODES = {204, 404, 409}


@dataclass
class Running:
    deployment: Deployment
    serve: Serve
    client: httpx.Client
    scenario: str


@pytest.fixture(scope="module")
def running(module_deployment: Deployment) -> Iterator[Running]:
    serve = module_deployment.serve(workers=1)
    with serve.client() as client:
        yield Running(module_deployment, serve, client, module_deployment.scenario(client))


def test_lost_and_never_sent_messages_are_sent_again(running: Running) -> None:
    deployment, client = running.deployment, running.client
    # The only worker busy: the next job's message waits in the broker, and is lost there.
    busy = deployment.submit(client, running.scenario, "search", random_search(7500), seed=11)
    deployment.wait_job(busy, ("running",), timeout_s=120)
    lost = deployment.submit(client, running.scenario, "train", TINY_TRAIN, seed=12)
    assert deployment.job(lost).sent_at is not None
    if deployment.redis is None:
        messages = list((deployment.data_dir / "broker" / "queue").glob("*.msg"))
        assert messages, "the message of the queued job is not in the broker folder"
        for message in messages:
            message.unlink()
    else:
        import redis

        broker = redis.Redis.from_url(deployment.redis.url(0))
        try:
            assert broker.llen("celery") >= 1, "the message of the queued job is not in Redis"
            broker.delete("celery")
        finally:
            broker.close()
    # A job committed by an API that died before sending it: a row and no message.
    params = {**TINY_TRAIN, "n_realisations": 4}
    with deployment.db.session() as session:
        row = JobRow(
            type="train",
            scenario_id=running.scenario,
            params=params,
            seed=13,
            config_hash=config_hash("train", running.scenario, params, 13),
        )
        session.add(row)
        session.flush()
        unsent = row.id
    deployment.jobs.add(unsent)
    assert deployment.job(unsent).sent_at is None

    for job_id in (busy, lost, unsent):
        job = deployment.wait_job(job_id, timeout_s=180)
        assert job.status == "succeeded", (job_id, job.status, job.error, deployment.logs())
    assert deployment.job(unsent).sent_at is not None
    assert_settled(deployment)


def _fire(count: int, send: Any) -> list[httpx.Response]:
    """``send(i, client)`` from ``count`` threads at once, each with its own connection."""
    barrier = threading.Barrier(count)

    def one(index: int) -> httpx.Response:
        with httpx.Client(
            base_url=running_base[0], headers={"X-API-Key": running_key[0]}, timeout=60
        ) as client:
            barrier.wait()
            return send(index, client)  # type: ignore[no-any-return]

    with ThreadPoolExecutor(count) as pool:
        return list(pool.map(one, range(count)))


running_base: list[str] = [""]
running_key: list[str] = [""]


@pytest.fixture
def fire(running: Running) -> Any:
    running_base[0], running_key[0] = running.serve.base, running.serve.key
    return _fire


def test_identical_submissions_racing_make_one_job(running: Running, fire: Any) -> None:
    deployment = running.deployment
    params = {**TINY_TRAIN, "n_realisations": 5}
    body = {"type": "train", "scenario_id": running.scenario, "seed": 21, "params": params}
    answers = fire(10, lambda _i, client: client.post("/jobs", json=body))
    codes = sorted(a.status_code for a in answers)
    assert codes == [200] * 9 + [202], [(a.status_code, a.text[:200]) for a in answers]
    ids = {a.json()["id"] for a in answers}
    assert len(ids) == 1
    deployment.jobs |= ids
    job_id = next(iter(ids))
    with deployment.db.session() as session:
        # The service hashes its normalised parameters (every default filled in), so the
        # stored job's own hash is the one to count, not one recomputed from the request.
        digest = session.scalar(select(JobRow.config_hash).where(JobRow.id == job_id))
        count = session.scalar(
            select(func.count()).select_from(JobRow).where(JobRow.config_hash == digest)
        )
    assert digest is not None
    assert count == 1
    deployment.wait_job(job_id, timeout_s=120)
    assert_settled(deployment)


def test_deleting_a_scenario_while_jobs_are_submitted_for_it(running: Running, fire: Any) -> None:
    deployment, client = running.deployment, running.client
    seen: list[tuple[str, int, str]] = []
    for round_ in range(3):
        scenario = deployment.scenario(client)

        def act(index: int, c: httpx.Client, scenario: str = scenario, round_: int = round_) -> Any:
            if index % 3 == 0:
                return c.delete(f"/scenarios/{scenario}")
            body = {
                "type": "train",
                "scenario_id": scenario,
                "seed": 100 * round_ + index,
                "params": TINY_TRAIN,
            }
            return c.post("/jobs", json=body)

        for answer in fire(9, act):
            kind = answer.request.method
            seen.append((kind, answer.status_code, answer.text[:300]))
            if kind == "POST" and answer.status_code in (200, 202):
                deployment.jobs.add(answer.json()["id"])
    bad = [s for s in seen if s[1] not in (SUBMIT_CODES if s[0] == "POST" else DELETE_CODES)]
    assert not bad, bad
    for job_id in deployment.jobs:
        deployment.wait_job(job_id, timeout_s=180)
    assert_settled(deployment)


# --------------------------------------------------------------------------- identify


def _telemetry(seed: int) -> list[tuple[dict[str, Any], str]]:
    """One simulated flight of each candidate, as /identify bodies (without the id)."""
    scenario = Scenario.paper()
    flight = simulate(scenario, GOOD_SEQUENCE, 1, np.random.default_rng(seed))
    return [
        (
            {
                "time_s": flight.time_s.tolist(),
                "omega_rad_s": flight.omega_measured[k, 0].tolist(),
            },
            name,
        )
        for k, name in enumerate(flight.candidate_names)
    ]


async def _identify_load(
    base: str, key: str, classifier: str, clients: int, per_client: int
) -> list[tuple[int, str | None, str | None, str]]:
    """(status, candidate, Retry-After, expected) of every request."""
    flights = _telemetry(2024)
    out: list[tuple[int, str | None, str | None, str]] = []
    limits = httpx.Limits(max_connections=clients, max_keepalive_connections=clients)
    async with httpx.AsyncClient(
        base_url=base, headers={"X-API-Key": key}, limits=limits, timeout=60
    ) as client:
        start = asyncio.Event()

        async def one_client(index: int) -> None:
            await start.wait()
            for i in range(per_client):
                telemetry, expected = flights[(index + i) % len(flights)]
                answer = await client.post(
                    "/identify", json={"classifier_id": classifier, "telemetry": telemetry}
                )
                candidate = answer.json().get("candidate") if answer.status_code == 200 else None
                out.append(
                    (answer.status_code, candidate, answer.headers.get("retry-after"), expected)
                )

        tasks = [asyncio.create_task(one_client(i)) for i in range(clients)]
        await asyncio.sleep(0.1)
        start.set()
        await asyncio.gather(*tasks)
    return out


@pytest.fixture(scope="module")
def classifier(running: Running) -> str:
    params = {**TINY_TRAIN, "n_realisations": 5}
    job_id = running.deployment.submit(running.client, running.scenario, "train", params, seed=31)
    job = running.deployment.wait_job(job_id, timeout_s=120)
    assert job.status == "succeeded", job.error
    return str((job.result or {})["classifier_id"])


def test_identify_at_50_clients_answers_every_request_and_the_api_stays_responsive(
    running: Running, classifier: str
) -> None:
    side: list[tuple[str, int]] = []
    done = threading.Event()

    def others() -> None:
        # /health and the job list while identify is loaded: they must keep answering.
        with httpx.Client(base_url=running.serve.base, timeout=30) as client:
            while not done.is_set():
                side.append(("/health", client.get("/health").status_code))
                side.append(("/jobs", client.get("/jobs").status_code))
                time.sleep(0.1)

    thread = threading.Thread(target=others)
    thread.start()
    try:
        answers = run_async(
            _identify_load(running.serve.base, running.serve.key, classifier, 50, 4)
        )
    finally:
        done.set()
        thread.join(60)
    assert len(answers) == 200
    failed = [a for a in answers if a[0] != 200]
    assert not failed, failed[:5]
    wrong = [a for a in answers if a[1] != a[3]]
    assert not wrong, wrong[:5]
    assert side and all(code == 200 for _, code in side), side
    assert {path for path, _ in side} == {"/health", "/jobs"}
    assert_settled(running.deployment)


def test_identify_past_capacity_answers_503_with_retry_after(
    running: Running, classifier: str
) -> None:
    # A second API on the same data, with room for one computation and two waiting.
    small = running.deployment.serve(
        workers=0, INERTIA_ID_COMPUTE_QUEUE="2", INERTIA_ID_COMPUTE_THREADS="1"
    )
    try:
        answers = run_async(_identify_load(small.base, small.key, classifier, 50, 4))
    finally:
        small.terminate()
    codes = {a[0] for a in answers}
    assert codes <= {200, 503}, sorted(codes)
    refused = [a for a in answers if a[0] == 503]
    assert refused, "50 clients never overflowed a queue of 2"
    assert all(a[2] is not None and int(a[2]) >= 1 for a in refused), refused[:5]
    wrong = [a for a in answers if a[0] == 200 and a[1] != a[3]]
    assert not wrong, wrong[:5]
    assert_settled(running.deployment)
