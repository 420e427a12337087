"""Slow clients (slowloris) cannot hold the API's connections.

uvicorn has no timeout on receiving a request: a client that connected and sent nothing,
or its request head or body a byte every few seconds, held its connection for as long as
it liked. The read deadlines of ``app.request_deadlines`` close it. Here with a real
uvicorn server (both of its HTTP implementations) and raw sockets, and through
``python -m app.serve`` as shipped, with one API process and with two.

No timing is asserted: a closed connection is waited for with a generous bound (it never
closed before), and the requests that must go through leave a wide margin.
"""

from __future__ import annotations

import asyncio
import json
import socket
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest
from fastapi import Request
from service_support import free_port

from app.request_deadlines import ServerConfig

from .support import add_body_size_route, keyed_app, serve_api_only, served_in_thread

KEY = "slow-clients-test-key-0123456789"
#: How long a connection the server should close is given to close: far past the
#: deadline (1 s), far short of forever.
CLOSES_WITHIN_S = 20.0
HEAD = b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n"


@dataclass
class Served:
    port: int


def _serve(tmp_path: Path, http: str, head_s: float, body_s: float) -> Iterator[Served]:
    app = keyed_app(tmp_path, KEY)

    async def late_body_size(request: Request) -> dict[str, int]:
        # Takes its body only after the body deadline has passed.
        await asyncio.sleep(body_s + 1.0)
        return {"size": len(await request.body())}

    add_body_size_route(app)
    app.add_api_route("/test/late-body-size", late_body_size, methods=["POST"])
    port = free_port()
    config = ServerConfig(
        app,
        host="127.0.0.1",
        port=port,
        http=http,  # type: ignore[arg-type]
        lifespan="off",
        log_level="info",
        request_head_timeout_s=head_s,
        request_body_timeout_s=body_s,
    )
    with served_in_thread(app, config):
        yield Served(port)


@pytest.fixture(params=["h11", "httptools"])
def server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Served]:
    """The app under uvicorn in a thread, with deadlines of 1 s (head and body)."""
    yield from _serve(tmp_path, request.param, head_s=1.0, body_s=1.0)


@pytest.fixture(params=["h11", "httptools"])
def patient_server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Served]:
    """The same with a body deadline of 2 s, for the bodies that must go through."""
    yield from _serve(tmp_path, request.param, head_s=1.0, body_s=2.0)


def _connect(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=CLOSES_WITHIN_S)
    return sock


def _closed_by_server(sock: socket.socket, trickle: bytes = b"", every_s: float = 0.25) -> bytes:
    """Send ``trickle`` a byte at a time every ``every_s`` until the server closes the
    connection; what it sent before closing. Fails if it is still open after
    :data:`CLOSES_WITHIN_S`."""
    received = b""
    deadline = time.monotonic() + CLOSES_WITHIN_S
    sock.settimeout(every_s)
    position = 0
    while time.monotonic() < deadline:
        try:
            data = sock.recv(65536)
        except TimeoutError:
            if trickle:
                try:
                    sock.sendall(trickle[position % len(trickle) : position % len(trickle) + 1])
                except (BrokenPipeError, ConnectionResetError):
                    return received
                position += 1
            continue
        except ConnectionResetError:
            return received
        if not data:
            return received
        received += data
    raise AssertionError(f"the server kept the connection open for {CLOSES_WITHIN_S} s")


def _response(sock: socket.socket) -> bytes:
    """One whole response (with a Content-Length) read from ``sock``."""
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += sock.recv(65536)
    head, _, body = answer.partition(b"\r\n\r\n")
    length = next(
        int(line.split(b":", 1)[1])
        for line in head.split(b"\r\n")
        if line.lower().startswith(b"content-length:")
    )
    while len(body) < length:
        body += sock.recv(65536)
    return head + b"\r\n\r\n" + body


def _health(port: int) -> None:
    answer = httpx.get(f"http://127.0.0.1:{port}/health", timeout=30)
    assert answer.status_code == 200, answer.text


def test_a_connection_that_sends_nothing_is_closed(server: Served) -> None:
    with _connect(server.port) as sock:
        assert _closed_by_server(sock) == b""
    _health(server.port)


def test_a_request_head_sent_a_byte_at_a_time_is_closed(server: Served) -> None:
    with _connect(server.port) as sock:
        sock.sendall(HEAD + b"X-Slow: ")
        assert _closed_by_server(sock, trickle=b"a") == b""
    _health(server.port)


def test_a_slow_head_after_a_response_on_a_kept_alive_connection_is_closed(
    server: Served,
) -> None:
    with _connect(server.port) as sock:
        sock.sendall(HEAD + b"\r\n")
        assert _response(sock).startswith(b"HTTP/1.1 200 ")
        # The next request's head, a byte every quarter second: the keep-alive timeout
        # (5 s) is cancelled by each byte, the head deadline is not.
        sock.sendall(b"GET /health HTTP/1.1\r\n")
        assert _closed_by_server(sock, trickle=b"x") == b""
    _health(server.port)


def test_a_request_body_sent_a_byte_at_a_time_is_closed(
    server: Served, caplog: pytest.LogCaptureFixture
) -> None:
    with _connect(server.port) as sock:
        sock.sendall(
            b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: "
            + KEY.encode()
            + b"\r\nContent-Type: application/octet-stream\r\nContent-Length: 100000\r\n\r\n"
        )
        assert _closed_by_server(sock, trickle=b"a") == b""
    _health(server.port)
    # A client cut off is not a defect of the service.
    assert not [r for r in caplog.records if "defect" in r.getMessage()]


def test_a_slow_but_steady_body_goes_through(patient_server: Served) -> None:
    """A body that brings 4 KiB every 0.25 s for longer than the deadline (2 s) is read
    whole: the deadline is on each stretch of the body, not on the whole."""
    chunk = b"b" * 4096
    chunks = 12  # 3 s at 0.25 s a chunk

    def steady() -> Iterator[bytes]:
        for _ in range(chunks):
            time.sleep(0.25)
            yield chunk

    headers = {"X-API-Key": KEY, "Content-Length": str(chunks * len(chunk))}
    with httpx.Client(base_url=f"http://127.0.0.1:{patient_server.port}", timeout=60) as client:
        answer = client.post("/test/body-size", content=steady(), headers=headers)
    assert answer.status_code == 200, answer.text
    assert answer.json() == {"size": chunks * len(chunk)}


def test_a_body_the_app_takes_after_the_deadline_goes_through(server: Served) -> None:
    """1 MB sent at once to a route that reads it only after the body deadline (1 s):
    uvicorn stops reading past 64 KiB until the app takes it, the client cannot send
    meanwhile, and it is not the slow one."""
    big = b"c" * 1_000_000
    with httpx.Client(base_url=f"http://127.0.0.1:{server.port}", timeout=60) as client:
        answer = client.post("/test/late-body-size", content=big, headers={"X-API-Key": KEY})
    assert answer.status_code == 200, answer.text
    assert answer.json() == {"size": len(big)}


# ------------------------------------------------------------- python -m app.serve


@pytest.mark.parametrize("api_workers", [1, 2])
def test_serve_closes_slow_heads_with_one_api_process_and_with_two(
    tmp_path: Path, api_workers: int
) -> None:
    """``python -m app.serve`` as shipped (no workers needed here), with
    ``INERTIA_ID_REQUEST_HEAD_TIMEOUT_S=1``: slow heads are closed whichever API process
    accepted them, and a normal request still works."""
    env = {"INERTIA_ID_REQUEST_HEAD_TIMEOUT_S": "1", "INERTIA_ID_VERDICT_PROCESS": "off"}
    with serve_api_only(tmp_path, api_workers, **env) as (port, log):
        base = f"http://127.0.0.1:{port}"
        # Several, to whichever API process accepts each.
        slow = [_connect(port) for _ in range(8)]
        try:
            for sock in slow:
                sock.sendall(HEAD + b"X-Slow: ")
            for sock in slow:
                assert _closed_by_server(sock, trickle=b"a") == b""
        finally:
            for sock in slow:
                sock.close()
        answer = httpx.get(f"{base}/health", timeout=30)
        assert answer.status_code == 200 and "status" in json.loads(answer.text)
        assert "no complete request head within 1 s" in log.read_text()
