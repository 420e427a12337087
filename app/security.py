"""API keys for the write endpoints, and the request body size limit.

Keys are stored as SHA-256 hashes in ``api_keys``; the plaintext exists only in the
client's hands (and, once, in the output of ``inertia-id serve`` when it was generated).
A key set by the environment (``INERTIA_ID_API_KEY``) is the only key accepted.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import secrets
import time
from collections.abc import Callable
from dataclasses import KW_ONLY, InitVar, dataclass

from sqlalchemy import select
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from service.config import Settings
from service.store.models import ApiKey
from service.store.session import Database

from .expiring import Expiring
from .watched_send import WatchedSend

__all__ = [
    "API_KEY_HEADER",
    "SECURITY_HEADERS",
    "AllowedHosts",
    "BodySizeLimit",
    "BodyTooLarge",
    "HeadAsGet",
    "KeyBeforeBody",
    "KeyVerifier",
    "SecurityHeaders",
    "ensure_api_key",
    "hash_key",
    "scope_header",
    "send_detail",
]

API_KEY_HEADER = "X-API-Key"


def hash_key(key: str) -> str:
    return hashlib.sha256(key.encode("utf-8", "surrogateescape")).hexdigest()


def ensure_api_key(db: Database, settings: Settings) -> str | None:
    """Make sure a key exists; return its plaintext only if it was generated now.

    With ``settings.api_key`` set, its hash is stored (once) and nothing is generated.
    Otherwise a key is generated on the first run, when ``api_keys`` is empty.
    """
    with db.session() as session:
        if settings.api_key:
            digest = hash_key(settings.api_key)
            if session.scalar(select(ApiKey.id).where(ApiKey.key_hash == digest)) is None:
                session.add(ApiKey(key_hash=digest))
            return None
        if session.scalar(select(ApiKey.id).limit(1)) is not None:
            return None
        key = secrets.token_urlsafe(32)
        session.add(ApiKey(key_hash=hash_key(key)))
        return key


# Compared and shown as an object: its answers are not part of its value.
@dataclass(eq=False, repr=False)
class KeyVerifier:
    """Checks API keys against the store without holding a connection per request.

    A request's key check used to keep a pooled connection for the whole request; under
    load (20+ clients of ``/identify``) the pool ran dry and every request waited 30 s.
    Here the lookup takes a connection for one query, and its answer is remembered for
    ``ttl_s`` (accepted keys) or ``negative_ttl_s`` (refused keys, so a wrong key sent
    in a loop does not hammer the database either). Keys are only ever added, never
    revoked through the API, so a remembered "accepted" cannot go stale before its TTL
    in any way the service offers.

    :param lookup: ``digest -> accepted?``, one short database query.
    :param clock: monotonic seconds (tests pass their own).
    """

    lookup: InitVar[Callable[[str], bool]]
    _: KW_ONLY
    ttl_s: float = 60.0
    negative_ttl_s: float = 5.0
    size: int = 1024
    clock: InitVar[Callable[[], float]] = time.monotonic

    def __post_init__(self, lookup: Callable[[str], bool], clock: Callable[[], float]) -> None:
        self._lookup = lookup
        self._answers: Expiring[str, bool] = Expiring(self.size, clock=clock)

    @classmethod
    def for_store(cls, db: Database, settings: Settings) -> KeyVerifier:
        if settings.api_key:
            expected = hash_key(settings.api_key)
            return cls(lambda digest: hmac.compare_digest(digest, expected))

        def lookup(digest: str) -> bool:
            with db.session() as session:
                return (
                    session.scalar(select(ApiKey.id).where(ApiKey.key_hash == digest)) is not None
                )

        return cls(lookup)

    def remembered(self, key: str) -> bool | None:
        """The remembered answer for ``key``, or None when it must be looked up (no
        database, no blocking: the API asks this on its event loop first)."""
        return self._answers.get(hash_key(key))

    def __call__(self, key: str) -> bool:
        digest = hash_key(key)
        remembered = self._answers.get(digest)
        if remembered is not None:
            return remembered
        accepted = self._lookup(digest)
        self._answers.put(digest, accepted, ttl_s=self.ttl_s if accepted else self.negative_ttl_s)
        return accepted


class BodyTooLarge(HTTPException):
    """A request body went past the limit while it was being read.

    An HTTPException, so that FastAPI's body parsing passes it on (it turns other
    errors into 400) and its handler answers 413 with the message.
    """

    def __init__(self, limit: int, declared: int | None = None) -> None:
        size = f"of {declared} bytes " if declared is not None else ""
        super().__init__(
            status_code=413,
            detail=f"request body {size}exceeds the limit of {limit} bytes "
            "(INERTIA_ID_MAX_BODY_BYTES); send less data, e.g. fewer telemetry samples",
        )


class BodySizeLimit:
    """Refuse request bodies larger than ``max_bytes`` with 413.

    A declared ``Content-Length`` over the limit is refused before anything is read; a
    body without one (chunked) is counted as it streams in, and reading stops at the
    limit. Pure ASGI, so it sees the body before any route parses it.
    """

    def __init__(self, app: ASGIApp, *, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = _content_length(scope)
        if declared is not None and declared > self.max_bytes:
            await _send_413(send, self.max_bytes, declared)
            return
        received = 0

        async def counting_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLarge(self.max_bytes)
            return message

        watched = WatchedSend(send)
        try:
            await self.app(scope, counting_receive, watched.send)
        except BodyTooLarge:
            if watched.started:
                raise
            await _send_413(send, self.max_bytes, None)


def scope_header(scope: Scope, name: bytes) -> str | None:
    """The first ``name`` header (lower-case) of an ASGI request, as latin-1 text; None
    without one."""
    for key, value in scope.get("headers", []):
        if key == name:
            return str(value.decode("latin-1"))
    return None


async def key_refusal(verify: KeyVerifier, key: str | None) -> str | None:
    """Why ``key`` is refused (the 401's detail, never echoing the key), or None when it
    is accepted. A remembered key is answered on the event loop; only a lookup goes to a
    thread."""
    if not key:
        return f"missing API key: send it in the {API_KEY_HEADER} header"
    accepted = verify.remembered(key)
    if accepted is None:
        accepted = await run_in_threadpool(verify, key)
    return None if accepted else f"invalid API key in the {API_KEY_HEADER} header"


#: The methods that write: every route answering them needs the key.
WRITE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})


class KeyBeforeBody:
    """Refuse a write without an accepted key (401) before its body is read.

    FastAPI reads and parses a route's body before it runs the route's dependencies, so
    a client without a key had its body of up to the size limit parsed, and was told
    what was wrong with it (422), before being refused. Every write route needs the key
    (:func:`app.api.deps.require_api_key` checks it again, with the same message)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in WRITE_METHODS:
            await self.app(scope, receive, send)
            return
        key = scope_header(scope, API_KEY_HEADER.lower().encode())
        problem = await key_refusal(scope["app"].state.verify_key, key)
        if problem is None:
            await self.app(scope, receive, send)
            return
        await send_detail(
            send, 401, problem, headers=[(b"www-authenticate", API_KEY_HEADER.encode())]
        )


async def send_detail(
    send: Send,
    status_code: int,
    detail: str,
    *,
    close: bool = False,
    headers: list[tuple[bytes, bytes]] | None = None,
) -> None:
    """Answer from a middleware, before the app: ``{"detail": detail}`` as JSON, the
    connection closed after it with ``close``."""
    body = json.dumps({"detail": detail}, separators=(",", ":")).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(body)).encode()),
        *(headers or []),
    ]
    if close:
        headers.append((b"connection", b"close"))
    await send({"type": "http.response.start", "status": status_code, "headers": headers})
    await send({"type": "http.response.body", "body": body})


def _content_length(scope: Scope) -> int | None:
    text = scope_header(scope, b"content-length")
    try:
        return None if text is None else int(text)
    except ValueError:
        return None


async def _send_413(send: Send, limit: int, declared: int | None) -> None:
    await send_detail(send, 413, BodyTooLarge(limit, declared).detail, close=True)


def host_name(header: str) -> str:
    """The host of a ``Host`` header, lower-cased, without its port."""
    header = header.strip().lower()
    if header.startswith("["):
        end = header.find("]")
        return header[: end + 1] if end > 0 else header
    name, _, _port = header.partition(":") if header.count(":") == 1 else (header, "", "")
    return name


class AllowedHosts:
    """Refuse requests whose ``Host`` header names a host the service does not answer to.

    A service bound to loopback is still reachable from a browser through DNS
    rebinding (a hostile page whose name resolves to 127.0.0.1); checking the Host
    header closes that. 400 with the value and the setting that allows it.

    :param hosts: accepted host names; ``"*"`` accepts any.
    """

    def __init__(self, app: ASGIApp, *, hosts: list[str]) -> None:
        self.app = app
        self.hosts = {h.lower() for h in hosts}
        self.any = "*" in self.hosts

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if self.any or scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        header = scope_header(scope, b"host") or ""
        if host_name(header) in self.hosts:
            await self.app(scope, receive, send)
            return
        detail = (
            f"Host header {header[:100]!r} is not a name this service answers to "
            f"({', '.join(sorted(self.hosts))}); set INERTIA_ID_ALLOWED_HOSTS to add one"
        )
        await send_detail(send, 400, detail)


#: Sent with every answer. The dashboard keeps the API key in the browser's storage, so
#: no other site may frame it (a clickjacking page could make a user press "Submit"),
#: and no answer is to be sniffed into another content type. ``frame-ancestors`` is the
#: only directive set: a full policy would have to allow Swagger UI's inline script.
SECURITY_HEADERS: tuple[tuple[bytes, bytes], ...] = (
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"content-security-policy", b"frame-ancestors 'none'"),
    (b"referrer-policy", b"no-referrer"),
)


class SecurityHeaders:
    """Adds :data:`SECURITY_HEADERS` to every HTTP response start (a header the app set
    itself is kept)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                present = {name.lower() for name, _ in headers}
                headers += [(k, v) for k, v in SECURITY_HEADERS if k not in present]
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)


class HeadAsGet:
    """Answer ``HEAD`` as ``GET`` without the body (RFC 9110 §9.3.2): FastAPI routes a
    GET route's HEAD to 405, and uptime monitors and ``curl -I`` ask with HEAD. The
    headers, ``Content-Length`` included, are the GET's."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "HEAD":
            await self.app(scope, receive, send)
            return

        async def without_body(message: Message) -> None:
            if message["type"] == "http.response.body":
                message = {**message, "body": b""}
            await send(message)

        await self.app({**scope, "method": "GET", _ASKED_WITH: "HEAD"}, receive, without_body)


# The method a request was sent with, where :class:`HeadAsGet` changed it.
_ASKED_WITH = "inertia_id.asked_with"


def asked_with(scope: Scope) -> str:
    """The method the client sent (``HEAD`` for a HEAD answered as GET)."""
    return str(scope.get(_ASKED_WITH, scope["method"]))
