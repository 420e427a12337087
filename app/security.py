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

from sqlalchemy import select
from sqlalchemy.orm import Session
from starlette.exceptions import HTTPException
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from .config import Settings
from .db.models import ApiKey
from .db.session import Database

__all__ = [
    "API_KEY_HEADER",
    "BodySizeLimit",
    "BodyTooLarge",
    "ensure_api_key",
    "hash_key",
    "is_valid_key",
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


def is_valid_key(session: Session, settings: Settings, key: str) -> bool:
    """Whether ``key`` is accepted: the environment's key if set, else any stored key."""
    digest = hash_key(key)
    if settings.api_key:
        return hmac.compare_digest(digest, hash_key(settings.api_key))
    # Comparing hashes: the lookup's timing says nothing useful about the key.
    return session.scalar(select(ApiKey.id).where(ApiKey.key_hash == digest)) is not None


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
        started = False

        async def counting_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    raise BodyTooLarge(self.max_bytes)
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, counting_receive, tracking_send)
        except BodyTooLarge:
            if started:
                raise
            await _send_413(send, self.max_bytes, None)


def _content_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", []):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None


async def _send_413(send: Send, limit: int, declared: int | None) -> None:
    body = json.dumps(
        {"detail": BodyTooLarge(limit, declared).detail}, separators=(",", ":")
    ).encode()
    await send(
        {
            "type": "http.response.start",
            "status": 413,
            "headers": [
                (b"content-type", b"application/json"),
                (b"content-length", str(len(body)).encode()),
                (b"connection", b"close"),
            ],
        }
    )
    await send({"type": "http.response.body", "body": body})
