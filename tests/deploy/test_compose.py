"""The scale-out shape: docker-compose.yml validates and runs the same code paths."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml
from psycopg.pq import Conninfo
from sqlalchemy import create_engine
from sqlalchemy.engine import make_url

from service.config import Settings

ROOT = Path(__file__).resolve().parents[2]


def _compose() -> list[str]:
    if shutil.which("docker-compose"):
        return ["docker-compose"]
    if os.environ.get("INERTIA_ID_REQUIRE_SERVICES") == "1":
        pytest.fail("docker-compose is not installed (apt-get install docker-compose)")
    pytest.skip("docker-compose is not installed")


def _config(env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*_compose(), "-f", str(ROOT / "docker-compose.yml"), "config"],
        capture_output=True,
        text=True,
        env={**os.environ, **env},
        cwd=ROOT,
        timeout=60,
    )


def test_compose_file_validates_with_the_scale_out_services() -> None:
    done = _config({"INERTIA_ID_API_KEY": "k" * 32})
    assert done.returncode == 0, done.stderr
    for service in ("api:", "worker:", "postgres:", "redis:"):
        assert service in done.stdout
    assert "postgresql+psycopg://" in done.stdout and "redis://redis:6379/0" in done.stdout
    assert "127.0.0.1:8000" in done.stdout or "host_ip: 127.0.0.1" in done.stdout


def test_compose_migrates_once_before_the_api_and_the_workers_start() -> None:
    """Before, the API migrated as it started and the workers waited for it to answer;
    a one-shot ``migrate`` service (``inertia-id migrate``) now runs first, once the
    database is healthy, and the others start once it exited 0."""
    done = _config({"INERTIA_ID_API_KEY": "k" * 32})
    assert done.returncode == 0, done.stderr
    services = yaml.safe_load(done.stdout)["services"]
    migrate = services["migrate"]
    assert migrate["command"] == ["inertia-id", "migrate"]
    assert migrate["depends_on"]["postgres"] == {"condition": "service_healthy"}
    assert migrate.get("restart", "no") == "no"
    assert migrate["environment"]["DATABASE_URL"] == services["api"]["environment"]["DATABASE_URL"]
    for name in ("api", "worker"):
        depends_on = services[name]["depends_on"]
        assert depends_on["migrate"] == {"condition": "service_completed_successfully"}, name


def test_compose_refuses_to_start_without_an_api_key() -> None:
    env = {k: v for k, v in os.environ.items() if k != "INERTIA_ID_API_KEY"}
    done = subprocess.run(
        [*_compose(), "-f", str(ROOT / "docker-compose.yml"), "config"],
        capture_output=True,
        text=True,
        env=env,
        cwd=ROOT,
        timeout=60,
    )
    assert done.returncode != 0
    assert "INERTIA_ID_API_KEY" in done.stderr


def _api_settings(env: dict[str, str]) -> Settings:
    """The settings the compose's api container reads from its environment."""
    done = _config({"INERTIA_ID_API_KEY": "k" * 32, **env})
    assert done.returncode == 0, done.stderr
    environment = yaml.safe_load(done.stdout)["services"]["api"]["environment"]
    return Settings.model_validate({k: "" if v is None else v for k, v in environment.items()})


def test_compose_passes_the_allowed_hosts_to_the_api() -> None:
    """A TLS proxy in front that forwards the public Host (Caddy's and Traefik's
    default) or names the service (``api:8000``) was refused 400 on every request: the
    compose file gave no way to set INERTIA_ID_ALLOWED_HOSTS short of editing it. The
    loopback names stay: the healthcheck asks 127.0.0.1, and without it the api never
    turns healthy and no worker starts."""
    given = _api_settings({"INERTIA_ID_ALLOWED_HOSTS": "inertia.example.org,api"})
    hosts = given.resolved_allowed_hosts
    assert {"inertia.example.org", "api", "127.0.0.1", "localhost"} <= set(hosts), hosts
    assert "*" not in hosts
    # Unset: the loopback names, as before (the port is published on loopback only).
    unset = {k: v for k, v in os.environ.items() if k != "INERTIA_ID_ALLOWED_HOSTS"}
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(os, "environ", unset)
        hosts = _api_settings({}).resolved_allowed_hosts
    assert set(hosts) == {"127.0.0.1", "localhost", "::1", "[::1]"}, hosts


def test_a_postgres_password_with_url_characters_reaches_the_service_as_it_is(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The password was pasted into DATABASE_URL unescaped: ``p@ss`` made the host
    ``ss@postgres``, and a ``%`` or ``/`` broke the URL too. The URL now holds none and
    the password goes as PGPASSWORD, which libpq (under psycopg) reads when the URL
    has none."""
    password = "p@ss%25w/rd:1#x?y"
    done = _config({"INERTIA_ID_API_KEY": "k" * 32, "POSTGRES_PASSWORD": password})
    assert done.returncode == 0, done.stderr
    services = yaml.safe_load(done.stdout)["services"]
    assert services["postgres"]["environment"]["POSTGRES_PASSWORD"] == password
    for name in ("api", "worker"):
        environment = services[name]["environment"]
        settings = Settings.model_validate(environment)
        url = make_url(settings.resolved_database_url)
        assert (url.drivername, url.host, url.port) == ("postgresql+psycopg", "postgres", 5432)
        assert (url.username, url.database, url.password) == ("inertia", "inertia", None)
        # What psycopg is given: no password, so libpq takes PGPASSWORD, unescaped.
        _args, given = create_engine(url).dialect.create_connect_args(url)
        assert "password" not in given, given
        monkeypatch.setenv("PGPASSWORD", environment["PGPASSWORD"])
        defaults = {option.keyword: option.val for option in Conninfo.get_defaults()}
        assert defaults[b"password"] == password.encode(), name
