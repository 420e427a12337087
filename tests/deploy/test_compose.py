"""The scale-out shape: docker-compose.yml validates and runs the same code paths."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

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
