"""A request still in flight when uvicorn's shutdown grace runs out.

uvicorn cancels the request's task at the end of its grace (``timeout_graceful_shutdown``,
5 s under ``inertia-id serve``): a slow upload half sent at SIGTERM. Before, the
cancellation came out of the app as an exception: uvicorn logged "Exception in ASGI
application" with a traceback and answered "500 Internal Server Error", as for a bug. Now
the client is told 503 (the service is stopping; Connection: close, Retry-After) and
nothing is logged but uvicorn's own line about the tasks it cancelled. Both of uvicorn's
HTTP implementations, with a real server in a thread and a raw socket.
"""

from __future__ import annotations

import logging
import socket
import threading
from pathlib import Path

import pytest
from service_support import free_port

from app.request_deadlines import ServerConfig

from .support import add_body_size_route, keyed_app, served_in_thread

KEY = "shutdown-cut-test-key-0123456789"


@pytest.mark.parametrize("http", ["h11", "httptools"])
def test_a_request_cut_off_by_the_shutdown_grace_is_a_503_not_a_logged_500(
    tmp_path: Path, http: str, caplog: pytest.LogCaptureFixture
) -> None:
    app = keyed_app(tmp_path, KEY)
    entered = threading.Event()
    add_body_size_route(app, entered)
    port = free_port()
    config = ServerConfig(
        app,
        host="127.0.0.1",
        port=port,
        http=http,  # type: ignore[arg-type]
        lifespan="off",
        log_level="info",
        # uvicorn's loggers left to propagate to the root logger, where caplog reads them
        # (its own configuration stops them at "uvicorn").
        log_config=None,
        timeout_graceful_shutdown=0.5,
        # The body deadline far past the grace: the grace, not the deadline, cuts it.
        request_head_timeout_s=60.0,
        request_body_timeout_s=60.0,
    )
    caplog.set_level(logging.INFO)
    with served_in_thread(app, config) as running:
        with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
            sock.sendall(
                b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                b"X-API-Key: " + KEY.encode() + b"\r\n"
                b"Content-Type: application/octet-stream\r\nContent-Length: 100\r\n\r\n" + b"x" * 10
            )
            assert entered.wait(30), "the request did not reach the app"
            running.server.should_exit = True
            received = b""
            while True:
                data = sock.recv(65536)
                if not data:
                    break
                received += data
        running.thread.join(30)
        assert not running.thread.is_alive(), "uvicorn did not stop"
    status_line = received.split(b"\r\n", 1)[0]
    assert status_line == b"HTTP/1.1 503 Service Unavailable", received
    head = received.split(b"\r\n\r\n", 1)[0].lower()
    assert b"connection: close" in head and b"retry-after:" in head, received
    messages = [r.getMessage() for r in caplog.records]
    assert not any("Exception in ASGI application" in m for m in messages), messages
    assert not any(r.exc_info for r in caplog.records), messages
    # The access log is read (uvicorn's loggers reach caplog): the 503, no 500.
    assert any('POST /test/body-size HTTP/1.1" 503' in m for m in messages), messages
    assert not any('" 500' in m for m in messages), messages
