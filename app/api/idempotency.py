"""The ``Idempotency-Key`` header of the POSTs that store a new row (a job, a scenario).

As Stripe's API and the IETF draft "The Idempotency-Key HTTP Header Field": a client
that sends a POST with a key it made up (a UUID) and loses the answer sends the same
request with the same key again, and is answered what the first one was (the same job,
the same status code), with ``Idempotent-Replayed: true``; the job is made once. The
same key with another request (another body, or another route) is refused, 422 naming
the key; with a request still in progress, 409. A request that failed (a 4xx or a 5xx
of the route) keeps no answer: sent again, it runs again. Keys belong to an API key
(two clients never meet in each other's keys) and are kept ``INERTIA_ID_IDEMPOTENCY_KEY_TTL_S``
(24 h). The table and its races: :mod:`service.store.idempotency`.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Annotated, Any

from fastapi import Depends, Header, HTTPException, Request, status
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from sqlalchemy.orm import Session

from service.store import idempotency as store
from service.store.models import MAX_IDEMPOTENCY_KEY_LENGTH, utcnow
from service.store.session import Database

from ..security import API_KEY_HEADER, hash_key
from .deps import DatabaseDep, SessionDep, SettingsDep, unprocessable

__all__ = [
    "IDEMPOTENCY_KEY_HEADER",
    "IDEMPOTENCY_RESPONSES",
    "LIVE_CLAIM",
    "REPLAYED_HEADER",
    "IdempotencyDep",
    "IdempotentRequest",
    "parse_key",
    "replayable",
    "retry_after_s",
]

IDEMPOTENCY_KEY_HEADER = "Idempotency-Key"
REPLAYED_HEADER = "Idempotent-Replayed"

log = logging.getLogger(__name__)

_WHERE = ("header", IDEMPOTENCY_KEY_HEADER)
# A bare token (Stripe's keys, UUIDs) is visible ASCII; the draft's own form is a
# Structured Field string (RFC 8941 3.3.3): in double quotes, printable ASCII, with
# ``\"`` and ``\\`` the only escapes. Parsed here, for one header of one type, rather than
# with a structured-fields library the project does not otherwise need.
_BARE = re.compile(r"[\x20-\x7e]+")
_QUOTED = re.compile(r'"((?:[\x20\x21\x23-\x5b\x5d-\x7e]|\\["\\])*)"')

#: A claim held for less than this is taken for a request still being answered (a POST
#: that stores a row is answered in well under a second): its 409 asks for the retry in
#: 1 s. One held longer is, most likely, a request whose process died: the 409 gives the
#: wait until its lease ends, when the next request takes the key over.
LIVE_CLAIM = timedelta(seconds=10)


def retry_after_s(claimed_at: datetime | None, now: datetime) -> int:
    """The 409's ``Retry-After`` for a key claimed at ``claimed_at``: 1 s while the claim
    is live (younger than :data:`LIVE_CLAIM`, or not known), else the seconds left on its
    lease (:data:`service.store.idempotency.CLAIM_LEASE`), rounded up, at least 1."""
    if claimed_at is None or now - claimed_at < LIVE_CLAIM:
        return 1
    left = (claimed_at + store.CLAIM_LEASE - now).total_seconds()
    return max(1, math.ceil(left))


#: What the schema says of a route that takes the header.
IDEMPOTENCY_RESPONSES: dict[int | str, dict[str, Any]] = {
    409: {
        "description": "a request with this Idempotency-Key is still in progress",
        "headers": {
            "Retry-After": {
                "description": "seconds to wait before sending the request again: 1 "
                "while the request that holds the key was begun less than 10 s ago, else "
                "what is left of its 2-minute lease (its process died, most likely)",
                "schema": {"type": "integer"},
            }
        },
    },
}

_REPLAYED_DOC = {
    REPLAYED_HEADER: {
        "description": "`true` when this is the stored answer to an earlier request sent "
        f"with the same {IDEMPOTENCY_KEY_HEADER} (nothing was done again); absent otherwise",
        "schema": {"type": "string", "enum": ["true"]},
    }
}


def replayable(
    responses: dict[int | str, dict[str, Any]], *codes: int
) -> dict[int | str, dict[str, Any]]:
    """``responses`` with the replay's header on the answers ``codes`` that a key replays."""
    merged = dict(responses)
    for code in codes:
        entry = dict(merged.get(code, {}))
        entry["headers"] = {**entry.get("headers", {}), **_REPLAYED_DOC}
        merged[code] = entry
    return merged


def _list_or_bad_string(raw: str) -> str | None:
    """Why ``raw`` is neither a bare key nor one sf-string, or None when it is one of them.

    A value that opens with a double quote is the draft's sf-string and is parsed as one:
    a quote left open, an escape other than ``\\"`` and ``\\\\``, or anything after the
    closing quote is refused, not kept as a bare key that merely begins with a quote. A
    comma outside quotes makes the field a list (two keys joined by a proxy, or
    ``a, b`` typed as one): which of them the client retries with is not known."""
    if not raw.startswith('"'):
        if "," in raw:
            return "is a list (a comma outside a quoted string): send one key"
        return None
    closed = _QUOTED.match(raw)
    if closed is not None and closed.end() == len(raw):
        return None
    if closed is not None and raw[closed.end() :].lstrip(" ").startswith(","):
        return "is a list (a comma outside a quoted string): send one key"
    return (
        "starts with a double quote but is not a Structured Field string (RFC 8941: one "
        'closing quote, nothing after it, printable ASCII, \\" and \\\\ the only escapes)'
    )


def parse_key(raw: str) -> str:
    """The key an ``Idempotency-Key`` header holds: a bare token or a quoted string of
    1 to 255 printable ASCII characters; else a 422 that quotes the value."""
    why = _list_or_bad_string(raw) if _BARE.fullmatch(raw) else None
    if why is not None:
        unprocessable(_WHERE, f"{IDEMPOTENCY_KEY_HEADER} {raw[:80]!r} {why}")
    quoted = _QUOTED.fullmatch(raw)
    key = re.sub(r"\\(.)", r"\1", quoted.group(1)) if quoted else raw
    if not (quoted or _BARE.fullmatch(raw)) or not key.strip():
        unprocessable(
            _WHERE,
            f"{IDEMPOTENCY_KEY_HEADER} must be 1 to {MAX_IDEMPOTENCY_KEY_LENGTH} printable "
            f"ASCII characters (a UUID, say), got {raw[:80]!r}",
        )
    if len(key) > MAX_IDEMPOTENCY_KEY_LENGTH:
        unprocessable(
            _WHERE,
            f"{IDEMPOTENCY_KEY_HEADER} must be at most {MAX_IDEMPOTENCY_KEY_LENGTH} "
            f"characters, got {len(key)}: {key[:40]!r}...",
        )
    return key


@dataclass
class IdempotentRequest:
    """One request's key: :meth:`begin` before the work, :meth:`answer` with its answer."""

    db: Database
    client: str
    key: str
    route: str
    ttl: timedelta
    token: str | None = None
    claimed_at: datetime | None = None

    def begin(self, body: BaseModel) -> JSONResponse | None:
        """Claim the key for this request (None: go on), or the first answer to replay.

        :raises HTTPException: 409 while another request holds the key.
        :raises RequestValidationError: 422, the key was used for another request.
        """
        digest = store.fingerprint(self.route, body.model_dump(mode="json"))
        pending = store.pending_releases(self.db)
        if len(pending):
            # This key, if this process could not let it go (the database refused writes),
            # is let go first: this is its retry, which must run, not meet the dead claim.
            # Only this one: the others' are left to their own retries and the background
            # thread (each try is a write: a request paid one per dead claim).
            pending.flush(only=(self.client, self.key))
        found = store.claim(
            self.db, client=self.client, key=self.key, route=self.route, digest=digest, ttl=self.ttl
        )
        if found.outcome == store.NEW:
            self.token = found.token
            self.claimed_at = found.claimed_at
            return None
        if found.outcome == store.REPLAY:
            assert found.status is not None
            return JSONResponse(
                found.body, status_code=found.status, headers={REPLAYED_HEADER: "true"}
            )
        if found.outcome == store.IN_PROGRESS:
            now = utcnow()
            wait = retry_after_s(found.claimed_at, now)
            if found.claimed_at is None or now - found.claimed_at < LIVE_CLAIM:
                detail = (
                    f"a request with {IDEMPOTENCY_KEY_HEADER} {self.key!r} is still in "
                    "progress; send it again once that one is answered"
                )
            else:
                held = (now - found.claimed_at).total_seconds()
                detail = (
                    f"a request with {IDEMPOTENCY_KEY_HEADER} {self.key!r} has held it "
                    f"for {held:.0f} s without an answer (its process may have died); "
                    f"the key is free in {wait} s, when the request sent again runs"
                )
            raise HTTPException(
                status.HTTP_409_CONFLICT, detail=detail, headers={"Retry-After": str(wait)}
            )
        unprocessable(
            _WHERE,
            f"{IDEMPOTENCY_KEY_HEADER} {self.key!r} was used for another request "
            f"({found.route} with another body); a new request needs a new key",
        )

    def answer(self, session: Session, status_code: int, body: BaseModel) -> None:
        """Keep this answer for the key, in ``session``'s transaction."""
        if self.token is None:
            return
        store.answer(
            session,
            client=self.client,
            key=self.key,
            token=self.token,
            status=status_code,
            body=body.model_dump(mode="json"),
        )

    def release(self) -> None:
        """Let the key go: this request failed before it was answered. A release the
        database refuses (it turned read-only after the claim) is left to
        :class:`service.store.idempotency.PendingReleases`, never raised over the
        request's own error."""
        if self.token is None:
            return
        token, self.token = self.token, None
        try:
            store.release(self.db, client=self.client, key=self.key, token=token)
        except Exception as exc:
            log.warning(
                "%s %r not let go (%s): tried again until the database takes it",
                IDEMPOTENCY_KEY_HEADER,
                self.key,
                exc,
            )
            store.pending_releases(self.db).add(
                client=self.client,
                key=self.key,
                token=token,
                claimed_at=self.claimed_at or utcnow(),
            )


def _idempotent_request(
    request: Request,
    database: DatabaseDep,
    session: SessionDep,
    settings: SettingsDep,
    key: Annotated[
        str | None,
        Header(
            alias=IDEMPOTENCY_KEY_HEADER,
            description="A key the client makes up for this request (a UUID; 1 to 255 "
            "printable ASCII characters): sent again with the same request, within "
            "INERTIA_ID_IDEMPOTENCY_KEY_TTL_S (24 h), it is answered as the first time, "
            "with Idempotent-Replayed: true, and nothing is made twice",
            # Documented only: checked by parse_key, whose 422 quotes the value (a bare
            # token, or the draft's quoted string: up to 2 + 2 x 255 characters).
            json_schema_extra={
                "minLength": 1,
                "maxLength": 2 + 2 * MAX_IDEMPOTENCY_KEY_LENGTH,
                "pattern": "^[\\x20-\\x7e]+$",
            },
        ),
    ] = None,
) -> Iterator[IdempotentRequest | None]:
    if key is None:
        yield None
        return
    sent = request.headers.getlist(IDEMPOTENCY_KEY_HEADER)
    if len(sent) > 1:
        # Two lines are two keys (the draft's field is one Item; joined, "a, b" is not
        # one): the request's own key is not known, so neither is taken.
        unprocessable(
            _WHERE,
            f"send one {IDEMPOTENCY_KEY_HEADER} header, got {len(sent)}: "
            + ", ".join(repr(value[:80]) for value in sent[:4]),
        )
    route = request.scope.get("route")
    handle = IdempotentRequest(
        db=database,
        # The route's API key check ran first: the header is there, and accepted.
        client=hash_key(request.headers.get(API_KEY_HEADER, "")),
        key=parse_key(key),
        route=f"{request.method} {getattr(route, 'path', request.url.path)}",
        ttl=timedelta(seconds=settings.idempotency_key_ttl_s),
    )
    try:
        yield handle
        # The route's work and its answer are committed here, not after this exit (the
        # request's session, the same one, is closed after): when that commit fails,
        # nothing was stored, and the key must go too, or its retry is a 409 until the
        # lease ends.
        session.commit()
    except BaseException:
        # Nothing was made (the route's transaction is rolled back, here first: on
        # SQLite it may hold the write lock the release needs): a retry runs again.
        # (A job already stored keeps its answer: release leaves an answered key.)
        session.rollback()
        handle.release()
        raise


# scope="function": the key is let go, or its answer kept, before the answer is sent.
IdempotencyDep = Annotated[IdempotentRequest | None, Depends(_idempotent_request, scope="function")]
