"""A defect in one request does not break the client's next one on the same connection.

Starlette's ``ServerErrorMiddleware`` sent our 500 and raised the exception again; uvicorn
then closed the keep-alive connection without ``Connection: close``, and the client's
next request on it failed ("connection reset"). Here with a real uvicorn server (both of
its HTTP implementations) and one ``httpx.Client``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import uvicorn
from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from service_support import free_port
from starlette.background import BackgroundTask
from starlette.types import ASGIApp, Receive, Scope, Send

from .support import keyed_app, served_in_thread

KEY = "keep-alive-test-key-0123456789"


def _boom() -> None:
    raise RuntimeError("a defect of the route: list index out of range")


class _OuterBoom:
    """A middleware outside the app's own that fails on one path (a defect in a
    middleware: the one path left to Starlette's ServerErrorMiddleware)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["path"] == "/test/outer-boom":
            raise RuntimeError("a defect of a middleware")
        await self.app(scope, receive, send)


def _app(tmp_path: Path) -> FastAPI:
    app = keyed_app(tmp_path, KEY)

    # Test-only routes, added to the app as built.
    async def boom() -> None:
        _boom()

    def boom_in_a_thread() -> None:
        _boom()

    async def peer(request: Request) -> dict[str, int]:
        assert request.client is not None
        return {"port": request.client.port}

    async def fails_after_answering() -> JSONResponse:
        return JSONResponse({"ok": True}, background=BackgroundTask(_boom))

    app.add_api_route("/test/boom", boom)
    app.add_api_route("/test/boom-sync", boom_in_a_thread)
    app.add_api_route("/test/peer", peer)
    app.add_api_route("/test/background", fails_after_answering)
    app.add_middleware(_OuterBoom)
    return app


@pytest.fixture(params=["h11", "httptools"])
def server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """The app served by uvicorn in a thread; its base URL."""
    app = _app(tmp_path)
    port = free_port()
    config = uvicorn.Config(
        app, host="127.0.0.1", port=port, http=request.param, lifespan="off", log_level="info"
    )
    with served_in_thread(app, config):
        yield f"http://127.0.0.1:{port}"


def _port(client: httpx.Client) -> int:
    response = client.get("/test/peer")
    assert response.status_code == 200
    port: int = response.json()["port"]
    return port


@pytest.mark.parametrize("path", ["/test/boom", "/test/boom-sync"])
def test_a_500_leaves_the_connection_open_for_the_next_request(
    server: str, path: str, caplog: pytest.LogCaptureFixture
) -> None:
    with httpx.Client(base_url=server, headers={"X-API-Key": KEY}, timeout=10) as client:
        connection = _port(client)
        with caplog.at_level(logging.INFO):
            response = client.get(path, headers={"X-Request-ID": "keep-alive-0001"})
            assert response.status_code == 500
            # The body as it always was: the request id, no internals.
            assert response.json() == {
                "detail": "internal error: a defect of the service, not of the request "
                "(request id keep-alive-0001; the server's log has the details)"
            }
            assert response.headers["X-Request-ID"] == "keep-alive-0001"
            assert response.headers.get("connection", "").lower() != "close"
            # The next request on the same connection.
            health = client.get("/health")
            assert health.status_code == 200, health.text
            assert _port(client) == connection, "the server closed the connection"

    # Logged once, with the reason and the traceback, under the request's id.
    logged = [r for r in caplog.records if "keep-alive-0001" in r.getMessage()]
    assert len(logged) == 1, [r.getMessage() for r in logged]
    assert logged[0].levelno == logging.ERROR
    assert f"(GET {path}) failed: RuntimeError" in logged[0].getMessage()
    assert logged[0].exc_info is not None
    assert "list index out of range" in str(logged[0].exc_info[1])
    assert not [r for r in caplog.records if "Exception in ASGI application" in r.getMessage()]


def test_a_defect_after_the_answer_is_logged_and_the_connection_kept(
    server: str, caplog: pytest.LogCaptureFixture
) -> None:
    with httpx.Client(base_url=server, timeout=10) as client:
        connection = _port(client)
        with caplog.at_level(logging.INFO):
            response = client.get("/test/background", headers={"X-Request-ID": "background-01"})
            assert response.status_code == 200 and response.json() == {"ok": True}
            assert client.get("/health").status_code == 200
            assert _port(client) == connection
    logged = [r for r in caplog.records if "background-01" in r.getMessage()]
    assert len(logged) == 1 and logged[0].exc_info is not None
    assert "after its answer was sent" in logged[0].getMessage()


def test_a_defect_outside_the_apps_middleware_says_it_closes_the_connection(
    server: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The one path where the server still closes the connection says so in the 500
    (``Connection: close``): the client opens a new one for its next request."""
    with httpx.Client(base_url=server, timeout=10) as client:
        connection = _port(client)
        with caplog.at_level(logging.INFO):
            response = client.get("/test/outer-boom")
            assert response.status_code == 500
            assert response.headers["connection"].lower() == "close"
            assert "defect of the service" in response.json()["detail"]
            assert client.get("/health").status_code == 200
            assert _port(client) != connection
    assert [r for r in caplog.records if "/test/outer-boom) failed" in r.getMessage()]


def test_the_callers_faults_keep_their_answers(server: str) -> None:
    """A 422 and a 404 are not defects: unchanged, on the same connection."""
    with httpx.Client(base_url=server, headers={"X-API-Key": KEY}, timeout=10) as client:
        connection = _port(client)
        refused = client.post("/scenarios", json={"preset": "no-such-preset"})
        assert refused.status_code == 422, refused.text
        assert refused.json()["detail"][0]["loc"]
        assert client.get("/jobs/does-not-exist").status_code == 404
        assert _port(client) == connection
