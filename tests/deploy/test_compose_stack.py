"""The docker-compose stack as it ships, run on this machine without Docker.

``docker-compose config`` says what the stack runs; this test runs exactly that: the
``migrate`` service's command, then two of the ``worker`` service's (its ``replicas``)
and the ``api`` service's, with the services' environment. Only what cannot be the same
outside Docker is changed:

- the hostnames ``postgres`` and ``redis`` become 127.0.0.1 (a fresh database on the
  machine's PostgreSQL, as the compose user, and Redis database 13, flushed before and
  after: the machine's other users keep theirs);
- ``/data`` (the shared volume) becomes a temporary folder;
- the API listens on loopback at a free port instead of 0.0.0.0:8000 (a shared machine);
- each container's own hostname is missing: both workers run on this one.

Then, over HTTP with the compose's ``INERTIA_ID_API_KEY``: the paper scenario, the
default classifier trained (the marginal likelihood, which PostgreSQL once refused to
store), telemetry identified, and one worker killed mid-job (``kill -9`` of its whole
process group, as a container dies) while the other finishes the job.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import yaml
from service_support import (
    POSTGRES_ADMIN_URL,
    ROOT,
    TERMINAL,
    GroupProcess,
    clean_env,
    free_port,
    require_service,
    start_in_group,
    wait_for,
)
from sqlalchemy import create_engine, make_url, text

from inertia_id import Scenario, simulate

API_KEY = "compose-" + "k" * 32
REDIS_ADMIN_URL = os.environ.get("INERTIA_ID_TEST_COMPOSE_REDIS_URL", "redis://127.0.0.1:6379/13")
GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4


def _compose_config() -> dict[str, Any]:
    if not shutil.which("docker-compose"):
        require_service("docker-compose", "not installed (apt-get install docker-compose)")
    done = subprocess.run(
        ["docker-compose", "-f", str(ROOT / "docker-compose.yml"), "config"],
        capture_output=True,
        text=True,
        env={**os.environ, "INERTIA_ID_API_KEY": API_KEY},
        cwd=ROOT,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    config = yaml.safe_load(done.stdout)
    assert isinstance(config, dict)
    return config


def _dockerfile_cmd() -> list[str]:
    lines = [ln for ln in (ROOT / "Dockerfile").read_text().splitlines() if ln.startswith("CMD ")]
    return list(json.loads(lines[-1][4:]))


@dataclass
class Container(GroupProcess):
    """One service's command, run as a process group of its own (a container)."""

    def stop(self) -> None:
        """``docker stop``: SIGTERM, a grace period, then SIGKILL."""
        if self.process.poll() is None:
            try:
                os.killpg(self.process.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            try:
                self.process.wait(15)
            except subprocess.TimeoutExpired:
                pass
        self.kill()


def _service_env(environment: dict[str, str], database: str, data_dir: Path) -> dict[str, str]:
    """The compose service's environment with only the hosts (and what they hold) moved."""
    moved = {}
    for name, value in environment.items():
        value = str(value)
        if name == "DATABASE_URL":
            url = make_url(value)
            assert url.host == "postgres", value
            value = url.set(host="127.0.0.1", database=database).render_as_string(
                hide_password=False
            )
        elif name == "BROKER_URL":
            assert value.startswith("redis://redis:6379/"), value
            value = REDIS_ADMIN_URL
        elif value == "/data":
            value = str(data_dir)
        assert "postgres:" not in value and "redis:6379" not in value, (name, value)
        moved[name] = value
    # The image has the project installed with its commands on PATH: so has this venv.
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return clean_env(PATH=path, PYTHONUNBUFFERED="1", **moved)


@pytest.fixture
def compose_database() -> Iterator[str]:
    """A fresh database owned by the compose file's user (created if missing)."""
    admin = create_engine(POSTGRES_ADMIN_URL, isolation_level="AUTOCOMMIT")
    name = f"inertia_id_compose_{uuid.uuid4().hex[:10]}"
    created_role = False
    try:
        with admin.connect() as connection:
            exists = connection.execute(
                text("SELECT 1 FROM pg_roles WHERE rolname = 'inertia'")
            ).first()
            if not exists:
                connection.execute(text("CREATE ROLE inertia LOGIN PASSWORD 'inertia'"))
                created_role = True
            connection.execute(text(f'CREATE DATABASE "{name}" OWNER inertia'))
    except Exception as exc:
        admin.dispose()
        require_service(f"PostgreSQL at {POSTGRES_ADMIN_URL}", exc)
    try:
        yield name
    finally:
        with admin.connect() as connection:
            connection.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
            if created_role:
                owned = connection.execute(
                    text(
                        "SELECT count(*) FROM pg_database d JOIN pg_roles r "
                        "ON d.datdba = r.oid WHERE r.rolname = 'inertia'"
                    )
                ).scalar()
                if not owned:
                    connection.execute(text("DROP ROLE IF EXISTS inertia"))
        admin.dispose()


@pytest.fixture
def compose_redis() -> Iterator[None]:
    import redis

    client = redis.Redis.from_url(REDIS_ADMIN_URL, socket_connect_timeout=2)
    try:
        client.flushdb()
    except Exception as exc:
        client.close()
        require_service(f"Redis at {REDIS_ADMIN_URL}", exc)
    try:
        yield
    finally:
        client.flushdb()
        client.close()


def test_the_compose_stack_trains_the_default_classifier_identifies_and_survives_a_killed_worker(
    tmp_path: Path, compose_database: str, compose_redis: None
) -> None:
    config = _compose_config()
    services = config["services"]
    api, worker = services["api"], services["worker"]
    assert api["command"] == _dockerfile_cmd(), "the api command differs from the image's CMD"
    replicas = int(worker.get("deploy", {}).get("replicas", 1))
    assert replicas == 2, worker.get("deploy")
    assert api["environment"]["INERTIA_ID_API_KEY"] == API_KEY

    data_dir = tmp_path / "data"
    port = free_port()
    command = [str(part) for part in api["command"]]
    assert command[command.index("--host") + 1] == "0.0.0.0"
    assert command[command.index("--port") + 1] == "8000"
    command[command.index("--host") + 1] = "127.0.0.1"
    command[command.index("--port") + 1] = str(port)

    containers: list[Container] = []

    def start(name: str, argv: list[str], environment: dict[str, str]) -> Container:
        log_path = tmp_path / f"{name}.log"
        process = start_in_group(
            argv,
            log_path=log_path,
            cwd=tmp_path,
            env=_service_env(environment, compose_database, data_dir),
        )
        container = Container(name, process, log_path)
        containers.append(container)
        return container

    def logs() -> str:
        return "\n".join(c.log() for c in containers)

    base = f"http://127.0.0.1:{port}"
    try:
        # depends_on: the api and the workers wait for `migrate` to exit 0, and for
        # nothing else of ours: the workers start first here, on the schema it left.
        migrate = services["migrate"]
        for service in (api, worker):
            assert service["depends_on"]["migrate"] == {
                "condition": "service_completed_successfully"
            }, service["depends_on"]
            assert "api" not in service["depends_on"], service["depends_on"]
        migration = start("migrate", [str(p) for p in migrate["command"]], migrate["environment"])
        assert migration.process.wait(120) == 0, migration.log()
        assert "migrated from none (no schema yet) to " in migration.log(), migration.log()
        workers = [
            start(f"worker-{i + 1}", [str(p) for p in worker["command"]], worker["environment"])
            for i in range(replicas)
        ]
        api_container = start("api", command, api["environment"])
        with httpx.Client(base_url=base, headers={"X-API-Key": API_KEY}, timeout=60) as client:

            def all_workers() -> dict[str, Any] | None:
                health = client.get("/health").json()
                return health if health["workers"]["count"] == replicas else None

            health = wait_for(all_workers, 180, f"/health did not count {replicas} workers", logs)
            assert health["status"] == "ok", health
            # A client that never finishes its request head (slowloris): the API's read
            # deadline (10 s by default) closes it while the rest of this test runs.
            slow = socket.create_connection(("127.0.0.1", port), timeout=60)
            slow.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n")

            scenario = client.post("/scenarios", json={"preset": "paper"})
            assert scenario.status_code == 201, scenario.text
            scenario_id = scenario.json()["id"]

            def finish(job_id: str, timeout_s: float = 300) -> dict[str, Any]:
                def done() -> dict[str, Any] | None:
                    job = client.get(f"/jobs/{job_id}").json()
                    return job if job["status"] in TERMINAL else None

                return wait_for(done, timeout_s, f"job {job_id} did not finish", logs)

            # The default classifier: no kind, no metric.
            train = client.post(
                "/jobs",
                json={
                    "type": "train",
                    "scenario_id": scenario_id,
                    "params": {"sequence": GOOD_SEQUENCE, "n_realisations": 20},
                },
            )
            assert train.status_code == 202, train.text
            job = finish(train.json()["id"])
            assert job["status"] == "succeeded", (job["error"], logs())
            classifier = client.get(f"/classifiers/{job['result']['classifier_id']}").json()
            assert classifier["kind"] == "marginal-likelihood"
            assert classifier["metric"] == "marginal-mahalanobis"

            flight = simulate(Scenario.paper(), GOOD_SEQUENCE, 1, np.random.default_rng(7))
            for truth in (1, 3):
                verdict = client.post(
                    "/identify",
                    json={
                        "classifier_id": classifier["id"],
                        "telemetry": {
                            "time_s": flight.time_s.tolist(),
                            "omega_rad_s": flight.omega_measured[truth, 0].tolist(),
                        },
                    },
                )
                assert verdict.status_code == 200, verdict.text
                assert verdict.json()["candidate"] == flight.candidate_names[truth]

            # A worker dies mid-job, container and all; the other one finishes the job.
            search = client.post(
                "/jobs",
                json={
                    "type": "search",
                    "scenario_id": scenario_id,
                    "params": {
                        "method": "random",
                        "sequence_length": 2,
                        "timesteps": 1200,
                        "n_realisations": 5,
                        "metric": "euclidean",
                        "patience_episodes": None,
                    },
                },
            )
            assert search.status_code == 202, search.text
            search_id = search.json()["id"]
            running = wait_for(
                lambda: (j := client.get(f"/jobs/{search_id}").json())["status"] == "running" and j,
                120,
                "the search did not start",
                logs,
            )
            names = {w.name: _node_name(w) for w in workers}
            assert len(set(names.values())) == replicas, names
            victim = next(w for w in workers if names[w.name] == running["worker"])
            victim.kill()
            job = finish(search_id)
            assert job["status"] == "succeeded", (job["error"], logs())
            assert job["worker"] != running["worker"] and job["attempts"] == 2

            jobs = client.get("/jobs").json()["items"]
            assert jobs and all(j["status"] in TERMINAL for j in jobs), jobs
            assert all(j["status"] == "succeeded" or j["error"] for j in jobs), jobs

            # Closed by the server long since (a timeout here: still open).
            with slow:
                assert slow.recv(1) == b"", "the slow client's connection was answered"
            assert "no complete request head within 10 s" in api_container.log(10**6)
    finally:
        for container in containers:
            container.stop()


def _node_name(container: Container) -> str | None:
    """The worker's node name, as its log says when it is ready."""
    found = re.search(r"worker (\S+@\S+): heartbeat and reaper", container.log(10**6))
    return found.group(1) if found else None
