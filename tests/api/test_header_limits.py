"""A request head past the limits on its header fields is answered 431, a request target
past the byte limit 414, and the connection closed, with one line logged.

uvicorn's httptools took any number of header fields of any size (10,000 fields, or one
of 16 MB, answered 200), and its h11 refused only a head still incomplete past 16 KiB,
with a 400 (a larger one that came in one read went through). Here with a real uvicorn
server (both of its HTTP implementations: ``app.request_deadlines``' ServerConfig, and
uvicorn's own Config with the protocol class, as the Dockerfile's command runs it) and
raw sockets, and through ``python -m app.serve`` with two API processes.

No timing is asserted: an answer or a close is waited for with a generous bound.
"""

from __future__ import annotations

import json
import logging
import re
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import uvicorn
from pydantic import ValidationError
from service_support import free_port

from app.request_deadlines import H11WithDeadlines, HttpToolsWithDeadlines, ServerConfig
from service.config import get_settings

from .support import add_body_size_route, keyed_app, make_settings, serve_api_only, served_in_thread

KEY = "header-limits-test-key-0123456789"
#: How long a client waits for the answer and the close (s): far past what they take.
WAIT_S = 30.0
PROTOCOLS = {"h11": H11WithDeadlines, "httptools": HttpToolsWithDeadlines}


@pytest.fixture(params=["h11", "httptools"])
def port(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[int]:
    """The app under ServerConfig in a thread, with the default limits (100 fields,
    16 KiB), and a route that answers the size of the body it got; its port."""
    app = keyed_app(tmp_path, KEY)

    add_body_size_route(app)
    port = free_port()
    config = ServerConfig(
        app,
        host="127.0.0.1",
        port=port,
        http=request.param,
        lifespan="off",
        log_level="info",
        request_head_timeout_s=10.0,
        request_body_timeout_s=10.0,
    )
    with served_in_thread(app, config):
        yield port


@pytest.fixture
def http(port: int, request: pytest.FixtureRequest) -> str:
    """Which of uvicorn's HTTP implementations serves ``port``."""
    return str(request.node.callspec.params["port"])


def _head(fields: list[bytes]) -> bytes:
    """A ``GET /health`` head with a Host field and ``fields`` (whole lines, CRLF
    included)."""
    return b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"".join(fields) + b"\r\n"


def _small_fields(count: int) -> list[bytes]:
    return [b"X-Field-%04d: value\r\n" % i for i in range(count)]


def _answer_and_close(sock: socket.socket) -> bytes:
    """All the server sends until it closes the connection (a reset after its answer,
    the client still sending, counts as a close). Fails if it stays open."""
    sock.settimeout(WAIT_S)
    received = b""
    while True:
        try:
            data = sock.recv(65536)
        except ConnectionResetError:
            return received
        except TimeoutError:
            raise AssertionError(f"the server kept the connection open for {WAIT_S} s") from None
        if not data:
            return received
        received += data


def _send(port: int, request: bytes) -> bytes:
    """Send ``request`` at once; what the server answered before it closed."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        try:
            sock.sendall(request)
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed before the whole head was sent
        return _answer_and_close(sock)


def _assert_refused(answer: bytes, status_line: bytes, *limits: str) -> None:
    """``answer`` has ``status_line``, a detail naming one of ``limits``, and says it
    closes."""
    head, _, body = answer.partition(b"\r\n\r\n")
    assert head.startswith(status_line + b"\r\n"), answer[:300]
    assert b"\r\nconnection: close" in head.lower()
    detail = json.loads(body)["detail"]
    assert any(limit in detail for limit in limits), detail


def _assert_431(answer: bytes, *limits: str) -> None:
    _assert_refused(answer, b"HTTP/1.1 431 Request Header Fields Too Large", *limits)


def _assert_414(answer: bytes, *limits: str) -> None:
    _assert_refused(answer, b"HTTP/1.1 414 URI Too Long", *limits)


def _health(port: int) -> None:
    answer = httpx.get(f"http://127.0.0.1:{port}/health", timeout=WAIT_S)
    assert answer.status_code == 200, answer.text


def test_more_header_fields_than_the_limit_is_a_431(port: int) -> None:
    # 101 fields (Host and 100 more), about 2 KB: the count's limit, not the size's.
    answer = _send(port, _head(_small_fields(100)))
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_COUNT=100")
    _health(port)


def test_10000_header_fields_are_a_431(port: int) -> None:
    """About 220 KB: refused for its count or for its size, whichever the server meets
    first (h11 and a first read short of the whole head: the size)."""
    answer = _send(port, _head(_small_fields(10_000)))
    _assert_431(
        answer,
        "INERTIA_ID_REQUEST_HEADER_MAX_COUNT=100",
        "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384",
    )
    _health(port)


def test_a_head_over_16_kib_sent_at_once_is_a_431(port: int) -> None:
    """20 KB in a few fields (under the count), one read on the loopback: h11's own
    limit is only on a head still incomplete."""
    fields = [b"X-Big-%d: %s\r\n" % (i, b"b" * 5000) for i in range(4)]
    answer = _send(port, _head(fields))
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    _health(port)


def test_one_1_mb_header_sent_in_pieces_is_a_431(port: int) -> None:
    """A single field of 1 MB, sent 64 KiB at a time (as fast as the socket takes it):
    refused while it arrives, not once it is whole."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: ")
        try:
            for _ in range(16):
                sock.sendall(b"a" * 65536)
            sock.sendall(b"\r\n\r\n")
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed on the way
        answer = _answer_and_close(sock)
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    _health(port)


def test_an_unfinished_header_past_the_limit_in_one_read_is_a_431(port: int) -> None:
    """30 KB of one header field, sent at once and not finished: httptools counted a
    head from its second read on (the first, up to 256 KB, held uncounted), so a head
    that came in one read waited, unanswered, for the head deadline (10 s) to close it."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: " + b"a" * 30_000)
        answer = _answer_and_close(sock)
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    _health(port)


def test_a_target_over_16_kib_sent_at_once_is_a_414(port: int) -> None:
    """A 20 KB URL is URI Too Long (RFC 9110 15.5.15), not Request Header Fields Too
    Large: a 431 before. The app, which answers ``/health`` 200 whatever its query, never
    sees it."""
    answer = _send(
        port, b"GET /health?q=" + b"q" * 20_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    )
    _assert_414(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    _health(port)


def test_the_routes_a_long_sequence_url_reaches_document_their_414(port: int) -> None:
    """GET /scenarios/{id}/plan and /response take a sequence in the query string, and
    answer a long one 414 (here 600 steps, 18 KB URL-encoded): /openapi.json left the
    414 out of both, so a client generated from it had no case for the answer."""
    sequence = json.dumps([[4, 4, 4, 0, 0, 0]] * 600, separators=(",", ":"))
    document = httpx.get(f"http://127.0.0.1:{port}/openapi.json", timeout=WAIT_S).json()
    for route in ("plan", "response"):
        target = httpx.URL(f"/scenarios/{'a' * 32}/{route}", params={"sequence": sequence})
        assert len(target.raw_path) > 16_384
        answer = _send(port, b"GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n" % target.raw_path)
        _assert_414(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
        responses = document["paths"]["/scenarios/{scenario_id}/" + route]["get"]["responses"]
        assert "INERTIA_ID_REQUEST_HEADER_MAX_BYTES" in responses["414"]["description"]


def test_a_1_mb_target_sent_in_pieces_is_a_414(port: int) -> None:
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(b"GET /health?q=")
        try:
            for _ in range(16):
                sock.sendall(b"q" * 65536)
            sock.sendall(b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed on the way
        answer = _answer_and_close(sock)
    _assert_414(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    _health(port)


def test_a_target_within_the_limit_and_fields_past_it_are_a_431(port: int) -> None:
    """10 KB of target and 10 KB of a field: the head is too large, not the URL."""
    request = b"GET /health?q=" + b"q" * 10_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n"
    answer = _send(port, request + b"X-Big: " + b"b" * 10_000 + b"\r\n\r\n")
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")


def _response(sock: socket.socket, received: bytes) -> tuple[bytes, bytes]:
    """The next whole response (with a Content-Length) from ``received`` and ``sock``,
    and what was received after it."""
    while b"\r\n\r\n" not in received:
        data = sock.recv(65536)
        assert data, f"the server closed the connection: {received!r}"
        received += data
    head, _, rest = received.partition(b"\r\n\r\n")
    length = next(
        int(line.split(b":", 1)[1])
        for line in head.split(b"\r\n")
        if line.lower().startswith(b"content-length:")
    )
    while len(rest) < length:
        data = sock.recv(65536)
        assert data, f"the server closed the connection: {head!r}"
        rest += data
    return head + b"\r\n\r\n" + rest[:length], rest[length:]


def test_bodies_and_heads_pipelined_in_one_send_are_each_answered(port: int) -> None:
    """A body of known length, a chunked one, and a head close to the limit, sent
    together (the parser is fed heads in pieces and bodies of known length whole): each
    body arrives whole, the head is answered."""
    post = b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: " + KEY.encode()
    sized = post + b"\r\nContent-Length: 300000\r\n\r\n" + b"s" * 300_000
    chunk = b"c" * 30_000
    chunked = post + b"\r\nTransfer-Encoding: chunked\r\n\r\n"
    chunked += b"%x\r\n%s\r\n" % (len(chunk), chunk) * 10 + b"0\r\n\r\n"
    near_limit = _head([*_small_fields(98), b"X-Pad: " + b"p" * 14_250 + b"\r\n"])
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(sized + chunked + near_limit)
        received = b""
        for expected in (b'{"size":300000}', b'{"size":300000}', b'"status"'):
            answer, received = _response(sock, received)
            assert answer.startswith(b"HTTP/1.1 200 OK\r\n"), answer[:300]
            assert expected in answer, answer[-300:]


def test_requests_pipelined_before_a_refused_head_are_answered_first(port: int) -> None:
    """Three requests, then a head past the limit, sent together: the three are answered
    in order, then the refusal, then the connection closes. The refusal used to be
    written at once, ahead of them, and the connection closed under them: a pipelining
    client read the 414 as the answer to its first request (a POST the app did carry
    out) and got none for the others."""
    post = b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: " + KEY.encode()
    sized = post + b"\r\nContent-Length: 5\r\n\r\nhello"
    health = _head([])
    too_long = b"GET /health?q=" + b"q" * 20_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    answer = _send(port, health + sized + health + too_long)
    statuses = re.findall(rb"HTTP/1\.1 (\d{3}) ", answer)
    assert statuses == [b"200", b"200", b"200", b"414"], answer[:600]
    assert b'{"size":5}' in answer
    _assert_414(answer[answer.index(b"HTTP/1.1 414") :], "INERTIA_ID_REQUEST_HEADER_MAX_BYTES")


def _statuses(answer: bytes) -> list[bytes]:
    return re.findall(rb"HTTP/1\.1 (\d{3}) ", answer)


def test_a_long_method_in_one_read_is_refused_before_the_app(port: int, http: str) -> None:
    """h11 takes a method of any length: 100 KB of one, sent at once, reached the app (a
    405) uncounted. llhttp knows only its own methods: a 400 at once."""
    answer = _send(port, b"M" * 100_000 + b" /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    if http == "h11":
        _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    else:
        assert answer.startswith(b"HTTP/1.1 400 Bad Request\r\n"), answer[:300]
    _health(port)


def test_whitespace_around_a_value_counts_towards_the_byte_limit(port: int) -> None:
    """40 KB of spaces before a one-byte value, sent at once: h11 hands the value over
    without them, and the head was answered 200."""
    answer = _send(port, _head([b"X-Spaces:" + b" " * 40_000 + b"v\r\n"]))
    _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")


def test_a_long_method_still_arriving_is_not_a_long_target(port: int, http: str) -> None:
    """30 KB of a method and no space yet: h11's refusal said "the request target (URL) is
    over 16384 bytes" (a 414), of a request that had no target yet."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        try:
            for _ in range(3):
                sock.sendall(b"M" * 10_000)
                time.sleep(0.05)
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed on the way
        answer = _answer_and_close(sock)
    if http == "h11":
        _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384")
    else:
        assert answer.startswith(b"HTTP/1.1 400 Bad Request\r\n"), answer[:300]


def test_a_head_pipelined_after_a_request_counts_from_its_first_byte(port: int) -> None:
    """A request, and the start of an unfinished head, in the first 4 KiB (one piece of the
    parser's feed), then 16,300 bytes more of its field: 20 KB in all. httptools counted
    that head from the next piece on (its share of the first was unknown): 16,300 bytes,
    within the limit and its 64 bytes of framing, held until the head deadline closed the
    connection, unanswered."""
    start = _head([]) + b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: "
    first = start + b"a" * (4096 - len(start))
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(first)
        try:
            sock.sendall(b"a" * 16_300)
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed on the way
        answer = _answer_and_close(sock)
    assert _statuses(answer) == [b"200", b"431"], answer[:600]
    _assert_431(answer[answer.index(b"HTTP/1.1 431") :], "INERTIA_ID_REQUEST_HEADER_MAX_BYTES")


def test_a_head_pipelined_after_a_chunked_body_counts_from_its_first_byte(port: int) -> None:
    """As above, the request before it a POST with a chunked body ending in the piece."""
    post = b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: " + KEY.encode()
    start = post + b"\r\nTransfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n"
    start += b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Big: "
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(start + b"a" * (4096 - len(start)))
        try:
            sock.sendall(b"a" * 16_300)
        except (BrokenPipeError, ConnectionResetError):
            pass  # answered and closed on the way
        answer = _answer_and_close(sock)
    assert _statuses(answer) == [b"200", b"431"], answer[:600]
    assert b'{"size":5}' in answer


def test_a_head_at_the_limit_pipelined_after_a_sized_body_is_answered(port: int) -> None:
    """A POST with a body of known length and, sent with it, a head of exactly the byte
    limit: the head is answered. httptools charged the head the part of the body in the
    parser's first 4 KiB piece (counted from the POST head's blank line), and a body of
    3,965 bytes put it past the limit and its 64 bytes of framing: a 431."""
    post = b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: " + KEY.encode()
    at_limit = _head([b"X-Pad: " + b"p" * 16_351 + b"\r\n"])
    # The target, Host and X-Pad as HeadLimits counts them: 16 KiB exactly.
    assert len(b"/health") + (4 + 9 + 4) + (5 + 16_351 + 4) == 16_384
    head = post + b"\r\nContent-Length: %d\r\n\r\n"
    # The body's size that leaves the head open past 4 pieces of 4 KiB after the first.
    size = 4 * 4096 + 4 + 4096 - len(head % 1000) - len(at_limit)
    assert 0 < size < 4096 - len(head % 1000)
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(head % size + b"b" * size + at_limit)
        received = b""
        for expected in (b'{"size":%d}' % size, b'"status"'):
            answer, received = _response(sock, received)
            assert answer.startswith(b"HTTP/1.1 200 OK\r\n"), answer[:300]
            assert expected in answer, answer[-300:]


#: A request for a protocol this server does not speak (RFC 9110 7.8).
_UPGRADE = b"Connection: upgrade\r\nUpgrade: example/1\r\n"


def test_a_request_pipelined_after_an_upgrade_not_made_is_answered(port: int) -> None:
    """The upgrade is not made, so the connection stays HTTP/1.1 and the next request,
    sent with it, is answered: uvicorn's httptools dropped the rest of the read (its
    parser stops where the other protocol would begin), and the client waited for an
    answer until the head deadline closed the connection."""
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        sock.sendall(_head([_UPGRADE]) + _head([]))
        first, received = _response(sock, b"")
        second, received = _response(sock, received)
        assert first.startswith(b"HTTP/1.1 200 OK\r\n"), first[:300]
        assert second.startswith(b"HTTP/1.1 200 OK\r\n"), second[:300]
        sock.sendall(_head([]))  # and the connection goes on
        third, _ = _response(sock, received)
        assert third.startswith(b"HTTP/1.1 200 OK\r\n"), third[:300]


def test_an_upgrade_request_with_a_body_is_refused_on_httptools(port: int, http: str) -> None:
    """llhttp takes what follows the head of such a request as the other protocol's, its
    body too: the app was handed the POST without its body (``{"size":0}``), and the
    rest of the read was dropped. Now a 400 naming the upgrade, and the connection
    closed. h11 reads the body, and goes on in HTTP/1.1."""
    post = b"POST /test/body-size HTTP/1.1\r\nHost: 127.0.0.1\r\nX-API-Key: " + KEY.encode()
    request = post + b"\r\n" + _UPGRADE + b"Content-Length: 5\r\n\r\nhello"
    answer = _send(port, request + _head([]) + _head([b"Connection: close\r\n"]))
    if http == "h11":
        assert _statuses(answer) == [b"200", b"200", b"200"], answer[:600]
        assert b'{"size":5}' in answer
    else:
        _assert_refused(answer, b"HTTP/1.1 400 Bad Request", "Upgrade: example/1")


class _Records(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append(f"{record.levelname} {record.getMessage()}")


@pytest.fixture
def uvicorn_log(port: int) -> Iterator[list[str]]:
    """The lines uvicorn's error log gets (our refusals go there too), from the server of
    ``port`` on (its config sets up uvicorn's logging, removing any handler before)."""
    records = _Records()
    log = logging.getLogger("uvicorn.error")
    log.addHandler(records)
    try:
        yield records.lines
    finally:
        log.removeHandler(records)


@pytest.mark.parametrize(
    ("request_bytes", "status", "limit"),
    [
        (_head(_small_fields(100)), 431, "INERTIA_ID_REQUEST_HEADER_MAX_COUNT=100"),
        (
            _head([b"X-Big: " + b"b" * 20_000 + b"\r\n"]),
            431,
            "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384",
        ),
        (
            b"GET /?q=" + b"q" * 20_000 + b" HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n",
            414,
            "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=16384",
        ),
    ],
    ids=["fields", "bytes", "target"],
)
def test_a_refused_head_logs_one_line_naming_its_status_and_limit(
    port: int, uvicorn_log: list[str], request_bytes: bytes, status: int, limit: str
) -> None:
    """Not uvicorn's "Invalid HTTP request received." besides, which says nothing of the
    limit (it was logged for each refused head before)."""
    answer = _send(port, request_bytes)  # logged before the close the client waits for
    assert answer.startswith(b"HTTP/1.1 %d " % status), answer[:300]
    assert len(uvicorn_log) == 1, uvicorn_log
    assert f"answered {status} to 127.0.0.1:" in uvicorn_log[0], uvicorn_log
    assert limit in uvicorn_log[0], uvicorn_log


def test_a_malformed_request_keeps_uvicorns_400_and_warning(
    port: int, uvicorn_log: list[str]
) -> None:
    answer = _send(port, b"GET /health HTTP/1.1\r\nHost 127.0.0.1\r\n\r\n")  # no colon
    assert answer.startswith(b"HTTP/1.1 400 Bad Request\r\n"), answer[:300]
    assert uvicorn_log == ["WARNING Invalid HTTP request received."]
    _health(port)


def test_a_head_at_the_limits_goes_through_and_keeps_its_connection(port: int) -> None:
    """100 fields (Host and 99 more) and close to 16 KiB: answered, and the connection
    stays open for the next request."""
    fields = [*_small_fields(98), b"X-Pad: " + b"p" * 14_250 + b"\r\n"]
    request = _head(fields)
    assert 16_300 < len(request) <= 16_384
    with socket.create_connection(("127.0.0.1", port), timeout=WAIT_S) as sock:
        for _ in range(2):
            sock.sendall(request)
            answer = b""
            while b'"status"' not in answer:
                data = sock.recv(65536)
                assert data, f"the server closed the connection: {answer!r}"
                answer += data
            assert answer.startswith(b"HTTP/1.1 200 OK\r\n"), answer[:300]


@pytest.mark.parametrize("http", ["h11", "httptools"])
def test_uvicorns_own_config_takes_the_limits_from_the_settings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, http: str
) -> None:
    """The Dockerfile's command (``uvicorn --http app.request_deadlines:...``) has no
    ServerConfig: the limits are the settings', INERTIA_ID_REQUEST_HEADER_MAX_COUNT here."""
    monkeypatch.setenv("INERTIA_ID_REQUEST_HEADER_MAX_COUNT", "10")
    get_settings.cache_clear()
    try:
        app = keyed_app(tmp_path, KEY)
        port = free_port()
        config = uvicorn.Config(
            app,
            host="127.0.0.1",
            port=port,
            http=PROTOCOLS[http],
            lifespan="off",
            log_level="info",
        )
        with served_in_thread(app, config):
            _health(port)  # Host and a few of httpx's own: under 10
            answer = _send(port, _head(_small_fields(10)))
            _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_COUNT=10")
    finally:
        monkeypatch.delenv("INERTIA_ID_REQUEST_HEADER_MAX_COUNT")
        get_settings.cache_clear()


@pytest.mark.parametrize(
    ("variable", "value"),
    [("INERTIA_ID_REQUEST_HEADER_MAX_COUNT", 0), ("INERTIA_ID_REQUEST_HEADER_MAX_BYTES", 1023)],
)
def test_a_limit_below_its_bound_is_refused(tmp_path: Path, variable: str, value: int) -> None:
    with pytest.raises(ValidationError, match=variable):
        make_settings(tmp_path, "sqlite://", **{variable: value})


def test_serve_with_two_api_processes_answers_431(tmp_path: Path) -> None:
    """``python -m app.serve`` as shipped (no workers needed here) with
    ``INERTIA_ID_REQUEST_HEADER_MAX_BYTES=2048``: the limit reaches each API process."""
    env = {"INERTIA_ID_REQUEST_HEADER_MAX_BYTES": "2048", "INERTIA_ID_VERDICT_PROCESS": "off"}
    with serve_api_only(tmp_path, 2, **env) as (port, log):
        for _ in range(4):  # to whichever API process accepts each
            answer = _send(port, _head([b"X-Big: " + b"b" * 3000 + b"\r\n"]))
            _assert_431(answer, "INERTIA_ID_REQUEST_HEADER_MAX_BYTES=2048")
        _health(port)
        assert "answered 431 to 127.0.0.1:" in log.read_text()
