"""API keys on every write endpoint, key storage, and the request size limit."""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from sqlalchemy import select
from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import PlainTextResponse
from starlette.routing import Route

from app.main import create_app
from app.security import AllowedHosts
from service.config import Settings
from service.store.models import ApiKey

from .support import Api, TestClient, make_settings

WRONG_KEY = "not-the-key-0123456789"


def write_routes(api: Api) -> list[tuple[str, str]]:
    """Every documented operation that is not a read."""
    routes = []
    for path, operations in api.get("/openapi.json").json()["paths"].items():
        for method in operations:
            if method.upper() in {"POST", "PUT", "PATCH", "DELETE"}:
                concrete = re.sub(r"\{[^}]+\}", "0123456789abcdef0123456789abcdef", path)
                routes.append((method.upper(), concrete))
    return sorted(routes)


def test_every_write_endpoint_needs_the_key(api: Api) -> None:
    routes = write_routes(api)
    assert ("POST", "/scenarios") in routes
    assert ("DELETE", "/scenarios/0123456789abcdef0123456789abcdef") in routes
    assert ("POST", "/jobs") in routes
    assert ("POST", "/jobs/0123456789abcdef0123456789abcdef/cancel") in routes
    assert ("POST", "/identify") in routes
    for method, path in routes:
        missing = api.client.request(method, path, json={})
        assert missing.status_code == 401, (method, path)
        assert "missing API key" in missing.json()["detail"]
        wrong = api.client.request(method, path, json={}, headers={"X-API-Key": WRONG_KEY})
        assert wrong.status_code == 401, (method, path)
        assert WRONG_KEY not in wrong.text
        assert "invalid API key" in wrong.json()["detail"]


def test_read_endpoints_are_open(api: Api) -> None:
    for path in ("/scenarios", "/jobs", "/classifiers", "/health"):
        assert api.client.get(path).status_code == 200


def test_generated_key_is_stored_hashed_and_kept(
    api: Api, settings: Settings, tmp_path: Path
) -> None:
    with api.db.session() as session:
        hashes = session.scalars(select(ApiKey.key_hash)).all()
    assert hashes == [hashlib.sha256(api.key.encode()).hexdigest()]
    assert len(api.key) >= 40  # token_urlsafe(32): 256 bits
    # A second start on the same database generates nothing; the first key still works.
    again = create_app(settings)
    try:
        assert again.state.generated_api_key is None
    finally:
        again.state.db.dispose()
    assert api.create_scenario()["name"] == "paper"


@pytest.fixture
def env_key_api(
    make_api: Callable[[Settings], Api], tmp_path: Path, database_url: str
) -> Iterator[Api]:
    yield make_api(
        make_settings(tmp_path, database_url, INERTIA_ID_API_KEY="key-from-the-environment")
    )


def test_key_from_the_environment_is_the_accepted_key(env_key_api: Api) -> None:
    api = env_key_api
    assert api.app.state.generated_api_key is None
    assert api.key == "key-from-the-environment"
    with api.db.session() as session:
        hashes = session.scalars(select(ApiKey.key_hash)).all()
    assert hashes == [hashlib.sha256(b"key-from-the-environment").hexdigest()]
    assert api.post("/scenarios", json={"preset": "paper"}).status_code == 201
    refused = api.client.post(
        "/scenarios", json={"preset": "paper"}, headers={"X-API-Key": WRONG_KEY}
    )
    assert refused.status_code == 401


@pytest.fixture
def small_body_api(make_api: Callable[[Settings], Api], tmp_path: Path, database_url: str) -> Api:
    return make_api(make_settings(tmp_path, database_url, INERTIA_ID_MAX_BODY_BYTES=2_000))


def test_oversized_body_is_413(small_body_api: Api) -> None:
    api = small_body_api
    big = {"preset": "paper", "overrides": {"name": "x" * 5_000}}
    response = api.post("/scenarios", json=big)
    assert response.status_code == 413
    detail = response.json()["detail"]
    assert "exceeds the limit of 2000 bytes" in detail
    assert "INERTIA_ID_MAX_BODY_BYTES" in detail
    assert api.get("/scenarios").json()["total"] == 0


def test_oversized_streamed_body_is_413(small_body_api: Api) -> None:
    """Without Content-Length (chunked), the bytes are counted as they arrive."""
    api = small_body_api

    def chunks() -> Iterator[bytes]:
        yield b'{"preset": "paper", "overrides": {"name": "'
        for _ in range(10):
            yield b"y" * 500
        yield b'"}}'

    for path in ("/scenarios", "/identify"):
        response = api.post_raw_json(path, chunks())
        assert response.status_code == 413, (path, response.text)
        assert "exceeds the limit of 2000 bytes" in response.json()["detail"]


def test_small_body_passes_the_limit(small_body_api: Api) -> None:
    assert small_body_api.create_scenario(name="fits")["name"] == "fits"


def test_every_answer_forbids_framing_and_sniffing(small_body_api: Api) -> None:
    """The dashboard keeps the key in the browser: no other site may frame it (a review
    found no such header on / or /static), refusals included."""
    answers = [
        small_body_api.client.get("/"),
        small_body_api.client.get("/static/js/app.js"),
        small_body_api.client.get("/health"),
        small_body_api.client.get("/jobs/nope"),
        small_body_api.client.post("/scenarios", content=b"x" * 5000),  # 413
        small_body_api.client.get("/health", headers={"Host": "evil.example"}),  # 400
    ]
    assert [a.status_code for a in answers] == [200, 200, 200, 404, 413, 400]
    for answer in answers:
        assert answer.headers["x-frame-options"] == "DENY"
        assert answer.headers["content-security-policy"] == "frame-ancestors 'none'"
        assert answer.headers["x-content-type-options"] == "nosniff"


def test_head_is_answered_as_get_without_the_body(api: Api) -> None:
    """Uptime monitors and ``curl -I`` ask with HEAD; it was a 405 on every route."""
    for path in ("/health", "/", "/jobs", "/static/js/app.js"):
        got, head = api.client.get(path), api.client.head(path)
        assert head.status_code == got.status_code == 200, path
        assert head.content == b""
        assert head.headers["content-length"] == got.headers["content-length"], path
        assert head.headers["content-type"] == got.headers["content-type"], path
    # A HEAD writes nothing: a write route is not a GET route.
    assert api.client.head("/identify").status_code == 405


def test_a_write_without_the_key_is_refused_before_its_body_is_read(api: Api) -> None:
    """A client without a key had its body parsed and was told what was wrong with it (a
    422 naming the JSON error) before being refused."""
    headers = {"Content-Type": "application/json"}
    for path, body in (("/jobs", b"{not json"), ("/scenarios", b'{"preset": "nope"}')):
        bare = api.client.post(path, content=body, headers=headers)
        wrong = api.client.post(path, content=body, headers={**headers, "X-API-Key": "no"})
        assert (bare.status_code, wrong.status_code) == (401, 401), (bare.text, wrong.text)
        assert bare.json() == {"detail": "missing API key: send it in the X-API-Key header"}
        assert wrong.json() == {"detail": "invalid API key in the X-API-Key header"}
        assert bare.headers["www-authenticate"] == "X-API-Key"
        # With the key, the body is judged as before.
        assert (
            api.client.post(path, content=body, headers={**headers, **api.auth}).status_code == 422
        )
    assert api.client.patch("/jobs/nope", json={"name": "x"}).status_code == 401
    assert api.client.delete("/scenarios/nope").status_code == 401


async def _ok(_request: Request) -> PlainTextResponse:
    return PlainTextResponse("ok")


@pytest.mark.parametrize("host", ["127.0.0.1", "0.0.0.0"])
def test_allowed_hosts_add_to_the_loopback_names(host: str) -> None:
    """The 400 says "set INERTIA_ID_ALLOWED_HOSTS to add one", but the setting replaced
    the loopback names: a deployment that named only its public host refused its own
    healthcheck (``Host: 127.0.0.1``). Now the names are added to them."""
    settings = Settings(INERTIA_ID_HOST=host, INERTIA_ID_ALLOWED_HOSTS="Inertia.Example.org")
    assert set(settings.resolved_allowed_hosts) == {
        "127.0.0.1",
        "localhost",
        "::1",
        "[::1]",
        "inertia.example.org",
    }
    app = Starlette(routes=[Route("/", _ok)])
    client = TestClient(AllowedHosts(app, hosts=settings.resolved_allowed_hosts))
    for name in ("127.0.0.1:8000", "localhost", "[::1]:8000", "inertia.example.org"):
        assert client.get("/", headers={"Host": name}).status_code == 200, name
    refused = client.get("/", headers={"Host": "evil.example"})
    assert refused.status_code == 400
    assert "'evil.example'" in refused.json()["detail"]
    assert "INERTIA_ID_ALLOWED_HOSTS" in refused.json()["detail"]
    # "*" still accepts any; unset still means the loopback names (or any, bound to all).
    assert Settings(INERTIA_ID_ALLOWED_HOSTS="api,*").resolved_allowed_hosts == ["*"]
    unset = Settings(INERTIA_ID_HOST=host, INERTIA_ID_ALLOWED_HOSTS="")
    assert unset.resolved_allowed_hosts == (
        ["*"] if host == "0.0.0.0" else ["127.0.0.1", "localhost", "::1", "[::1]"]
    )
