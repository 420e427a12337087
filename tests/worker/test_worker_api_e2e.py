"""End to end over HTTP: `inertia-id serve` (API + real worker, embedded default).

Everything a client does goes through the API: create a scenario, train, read the
metrics and the classifier, identify simulated telemetry, run a search, cancel one.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import httpx
import numpy as np
import pytest
from test_worker_serve import _env, _free_port, _wait

from inertia_id import Scenario, simulate

API_KEY = "e2e-" + "x" * 40
GOOD = [[4, 4, 4, 0, 0, 0]] * 4


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[httpx.Client]:
    root = tmp_path_factory.mktemp("e2e")
    port = _free_port()
    log = root / "serve.log"
    with open(log, "wb") as out:
        server = subprocess.Popen(
            [sys.executable, "-m", "app.serve", "--port", str(port), "--data-dir", "data"],
            env=_env(INERTIA_ID_API_KEY=API_KEY),
            cwd=root,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    base = f"http://127.0.0.1:{port}"
    client = httpx.Client(base_url=base, headers={"X-API-Key": API_KEY}, timeout=30)
    try:

        def healthy() -> bool:
            try:
                return bool(client.get("/health").json()["status"] == "ok")
            except httpx.TransportError:  # not listening yet
                return False

        _wait(
            healthy,
            120,
            "the service did not become healthy",
            log,
        )
        client.log = log  # type: ignore[attr-defined]
        yield client
    finally:
        client.close()
        server.send_signal(signal.SIGTERM)
        try:
            server.wait(40)
        except subprocess.TimeoutExpired:
            server.kill()


def _finish(client: httpx.Client, job_id: str, timeout_s: float = 180) -> dict[str, Any]:
    def done() -> dict[str, Any] | None:
        job = client.get(f"/jobs/{job_id}").json()
        return job if job["status"] in ("succeeded", "failed", "cancelled") else None

    return dict(_wait(done, timeout_s, f"job {job_id} did not finish", client.log))  # type: ignore[attr-defined]


def test_train_metrics_classifier_and_identify_over_http(service: httpx.Client) -> None:
    scenario = service.post("/scenarios", json={"preset": "paper"})
    assert scenario.status_code == 201, scenario.text
    scenario_id = scenario.json()["id"]
    submitted = service.post(
        "/jobs",
        json={
            "type": "train",
            "scenario_id": scenario_id,
            "seed": 1,
            "params": {"sequence": GOOD, "metric": "euclidean", "n_realisations": 10},
        },
    )
    assert submitted.status_code == 202, submitted.text
    job = _finish(service, submitted.json()["id"])
    assert job["status"] == "succeeded", job["error"]
    assert job["progress"] == 1.0
    metrics = service.get(f"/jobs/{job['id']}/metrics", params={"key": "f1"}).json()
    (f1,) = metrics["series"]
    assert f1["key"] == "f1" and f1["values"] == [pytest.approx(job["result"]["f1"])]
    assert f1["values"][0] == pytest.approx(1.0)
    classifier_id = job["result"]["classifier_id"]
    classifier = service.get(f"/classifiers/{classifier_id}").json()
    assert classifier["sequence"] == GOOD and classifier["metric"] == "euclidean"

    sim = simulate(Scenario.paper(), GOOD, 1, np.random.default_rng(7))
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
    again = service.post(
        "/jobs",
        json={
            "type": "train",
            "scenario_id": scenario_id,
            "seed": 1,
            "params": {"sequence": GOOD, "metric": "euclidean", "n_realisations": 10},
        },
    )
    assert again.status_code == 200 and again.json()["id"] == job["id"]


def test_search_runs_and_a_running_search_can_be_cancelled(service: httpx.Client) -> None:
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
    job = _finish(service, small["id"])
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
    _wait(
        lambda: service.get(f"/jobs/{long['id']}").json()["status"] == "running",
        60,
        "the long search did not start",
        service.log,  # type: ignore[attr-defined]
    )
    asked = time.monotonic()
    assert service.post(f"/jobs/{long['id']}/cancel").status_code == 200
    job = _finish(service, long["id"], 60)
    assert job["status"] == "cancelled"
    assert time.monotonic() - asked < 30
