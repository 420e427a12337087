"""End to end over HTTP: `inertia-id serve` (API + real worker, embedded default).

Everything a client does goes through the API: create a scenario, train, read the
metrics and the classifier, identify simulated telemetry, run a search, cancel one.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE
from service_support import TERMINAL, ServeProcess, serve_app, wait_for

from inertia_id import Scenario, simulate

API_KEY = "e2e-" + "x" * 40


@pytest.fixture(scope="module")
def serve(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServeProcess]:
    with serve_app(tmp_path_factory.mktemp("e2e"), api_key=API_KEY) as running:
        yield running


@pytest.fixture(scope="module")
def service(serve: ServeProcess) -> httpx.Client:
    return serve.client


def _finish(serve: ServeProcess, job_id: str, timeout_s: float = 180) -> dict[str, Any]:
    def done() -> dict[str, Any] | None:
        job = serve.client.get(f"/jobs/{job_id}").json()
        return job if job["status"] in TERMINAL else None

    return dict(wait_for(done, timeout_s, f"job {job_id} did not finish", serve.logs))


def test_train_metrics_classifier_and_identify_over_http(
    serve: ServeProcess, service: httpx.Client
) -> None:
    scenario = service.post("/scenarios", json={"preset": "paper"})
    assert scenario.status_code == 201, scenario.text
    scenario_id = scenario.json()["id"]
    train = {
        "type": "train",
        "scenario_id": scenario_id,
        "seed": 1,
        "params": {"sequence": GOOD_SEQUENCE, "metric": "euclidean", "n_realisations": 10},
    }
    submitted = service.post("/jobs", json=train)
    assert submitted.status_code == 202, submitted.text
    job = _finish(serve, submitted.json()["id"])
    assert job["status"] == "succeeded", job["error"]
    assert job["progress"] == 1.0
    metrics = service.get(f"/jobs/{job['id']}/metrics", params={"key": "f1"}).json()
    (f1,) = metrics["series"]
    assert f1["key"] == "f1" and f1["values"] == [pytest.approx(job["result"]["f1"])]
    assert f1["values"][0] == pytest.approx(1.0)
    classifier_id = job["result"]["classifier_id"]
    classifier = service.get(f"/classifiers/{classifier_id}").json()
    assert classifier["sequence"] == GOOD_SEQUENCE and classifier["metric"] == "euclidean"

    sim = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(7))
    for candidate in (0, 3):
        verdict = service.post(
            "/identify",
            json={
                "classifier_id": classifier_id,
                "telemetry": {
                    "time_s": sim.time_s.tolist(),
                    "omega_rad_s": sim.omega_measured[candidate, 0].tolist(),
                },
            },
        )
        assert verdict.status_code == 200, verdict.text
        assert verdict.json()["candidate"] == sim.candidate_names[candidate]
        assert verdict.json()["matches_none"] is False

    # The same submission again is the same job, not a duplicate.
    again = service.post("/jobs", json=train)
    assert again.status_code == 200 and again.json()["id"] == job["id"]


def test_search_runs_and_a_running_search_can_be_cancelled(
    serve: ServeProcess, service: httpx.Client
) -> None:
    scenario_id = service.post("/scenarios", json={"preset": "paper"}).json()["id"]
    small = service.post(
        "/jobs",
        json={
            "type": "search",
            "scenario_id": scenario_id,
            "params": {
                "method": "random",
                "sequence_length": 2,
                "timesteps": 40,
                "n_realisations": 5,
            },
        },
    ).json()
    job = _finish(serve, small["id"])
    assert job["status"] == "succeeded", job["error"]
    assert len(job["result"]["best"]["sequence"]) == 2
    curve = service.get(f"/jobs/{job['id']}/metrics", params={"key": "mean_episode_reward"})
    (series,) = curve.json()["series"]
    assert series["steps"] and series["steps"][-1] == job["result"]["timesteps"]

    long = service.post(
        "/jobs",
        json={
            "type": "search",
            "scenario_id": scenario_id,
            "params": {"method": "random", "timesteps": 400_000, "n_realisations": 5},
        },
    ).json()
    wait_for(
        lambda: service.get(f"/jobs/{long['id']}").json()["status"] == "running",
        60,
        "the long search did not start",
        serve.logs,
    )
    asked = time.monotonic()
    assert service.post(f"/jobs/{long['id']}/cancel").status_code == 200
    job = _finish(serve, long["id"], 60)
    assert job["status"] == "cancelled"
    assert time.monotonic() - asked < 30
