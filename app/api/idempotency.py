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
import string
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Annotated, Any, NoReturn

from fastapi import Depends, Header, HTTPException, Request, status
from fastapi.responses import JSONResponse
from pydantic import BaseModel
from sqlalchemy.orm import Session

from service.store import idempotency as store
from service.store.models import MAX_IDEMPOTENCY_KEY_LENGTH, utcnow
from service.store.session import Database

from ..security import API_KEY_HEADER, hash_key
from .deps import DatabaseDep, SessionDep, SettingsDep, quoted, unprocessable

__all__ = [
    "IDEMPOTENCY_KEY_HEADER",
    "IDEMPOTENCY_RESPONSES",
    "LIVE_CLAIM",
    "REPLAYED_HEADER",
    "RETRY_AFTER_MAX",
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
# The draft's field is a Structured Field String (RFC 8941 3.3.3): in double quotes,
# printable ASCII, ``\"`` and ``\\`` the only escapes. A bare key (Stripe's, a UUID) is
# taken too, as the characters of an sf-token (RFC 8941 3.3.4: tchar, ":" and "/"), a
# leading digit allowed (a UUID's), and base64's trailing "=" padding: anything else
# there (a quote, a backslash, a space, "=" before the end, ";", ",") is what a
# structured field would read as something other than one key.
# Parsed here, for one header of one type, as RFC 8941 4.2 parses an Item (its
# algorithms, with messages that say where it broke), rather than with a
# structured-fields library the project does not otherwise need.
_TOKEN_PUNCTUATION = "!#$%&'*+-.^_`|~:/"
_TOKEN_CHARS = frozenset(string.ascii_letters + string.digits + _TOKEN_PUNCTUATION)
_PRINTABLE = re.compile(r"[\x20-\x7e]*")
_NAMED = {" ": "a space", ",": "a comma", '"': "a double quote", "\\": "a backslash"}
_SF_STRING_RULE = '(RFC 8941: "..." of printable ASCII, \\" and \\\\ its only escapes)'

#: A claim held for less than this is taken for a request still being answered (a POST
#: that stores a row is answered in well under a second): its 409 asks for the retry in
#: 1 s. One held longer is waiting on something (SQLite's write lock waits up to 30 s, a
#: PostgreSQL lock as long as it must) or its process died, which the 409 cannot tell.
LIVE_CLAIM = timedelta(seconds=10)

#: The most a 409 asks a client to wait while the claim may still be live: a request
#: that ends is retried within this of its end, and a dead process's claim costs a client
#: that obeys 26 requests over the lease's 2 minutes, 16 of them past LIVE_CLAIM (11
#: before). Before,
#: past LIVE_CLAIM the 409 gave the lease's rest (up to 110 s), also to a live request
#: held up 12 s, whose key was free at second 13.
RETRY_AFTER_MAX = timedelta(seconds=10)

#: Past LIVE_CLAIM the wait is the claim's age over this, so a client's retries back off
#: as the claim ages (each about a fifth of the time waited so far: at most 20 % more than
#: the request's own time), up to RETRY_AFTER_MAX.
RETRY_AFTER_AGE_DIVISOR = 5


def retry_after_s(claimed_at: datetime | None, now: datetime) -> int:
    """The 409's ``Retry-After`` for a key claimed at ``claimed_at``: 1 s while the claim
    is live (younger than :data:`LIVE_CLAIM`, or not known); past that, a fifth of its age
    (:data:`RETRY_AFTER_AGE_DIVISOR`), at most :data:`RETRY_AFTER_MAX` and never past its
    lease's end (:data:`service.store.idempotency.CLAIM_LEASE`, when the next request takes
    the key over); rounded up, at least 1."""
    if claimed_at is None or now - claimed_at < LIVE_CLAIM:
        return 1
    age = now - claimed_at
    wait = min(age / RETRY_AFTER_AGE_DIVISOR, RETRY_AFTER_MAX, claimed_at + store.CLAIM_LEASE - now)
    return max(1, math.ceil(wait.total_seconds()))


#: What the schema says of a route that takes the header.
IDEMPOTENCY_RESPONSES: dict[int | str, dict[str, Any]] = {
    409: {
        "description": "a request with this Idempotency-Key is still in progress (or took "
        "the key over from this one, which then kept nothing): send it again after "
        "Retry-After",
        "headers": {
            "Retry-After": {
                "description": "seconds to wait before sending the request again: 1 "
                "while the request that holds the key was begun less than 10 s ago, else "
                "a fifth of the time it has held the key, at most 10 s and at most what is "
                "left of its 2-minute lease (after which a dead process's key is taken over)",
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


def _refuse(raw: str, why: str) -> NoReturn:
    unprocessable(_WHERE, f"{IDEMPOTENCY_KEY_HEADER} {quoted(raw)} {why}")


def _sf_string(raw: str, value: str) -> str:
    """The key of ``value``, an sf-string (RFC 8941 4.2.5), and nothing after it but
    spaces; else a 422 saying where it broke."""
    key: list[str] = []
    at = 1
    while at < len(value):
        char = value[at]
        if char == "\\":
            escaped = value[at + 1 : at + 2]
            if escaped not in ('"', "\\"):
                _refuse(
                    raw,
                    f"is not a Structured Field string: the escape {value[at : at + 2]!r} at "
                    f"character {at + 1} {_SF_STRING_RULE}",
                )
            key.append(escaped)
            at += 2
        elif char == '"':
            rest = value[at + 1 :].lstrip(" ")
            if rest.startswith(","):
                _refuse(raw, "is a list (a comma after the quoted key): send one key")
            if rest.startswith(";"):
                _refuse(
                    raw,
                    "has parameters (';' after the quoted key), which this header does not "
                    "take: send the quoted key alone",
                )
            if rest:
                _refuse(
                    raw,
                    f"is not a Structured Field string: {rest[:40]!r} follows its closing "
                    "quote (send the quoted key alone)",
                )
            return "".join(key)
        else:
            key.append(char)
            at += 1
    _refuse(raw, f"is not a Structured Field string: its quote is never closed {_SF_STRING_RULE}")


def _bare_key(raw: str, value: str) -> str:
    """``value``, a bare key: the characters of an sf-token (RFC 8941 3.3.4), a leading
    digit allowed (a UUID's); else a 422 naming the first other character."""
    for at, char in enumerate(value):
        if char in _TOKEN_CHARS:
            continue
        if char == "=" and at > 0 and value[at:] == "=" * (len(value) - at):
            # base64 padding (a random key from a client's base64 encoder): taken, as it
            # was before the RFC 8941 parser; RFC 8941 has no "=" in a token, but at the
            # end of a bare value it cannot start a parameter or a dictionary member.
            return value
        if char == ",":
            _refuse(
                raw,
                f"is a list (a comma at character {at + 1}, outside a quoted string): send one key",
            )
        _refuse(
            raw,
            f"has {_NAMED.get(char, repr(char))} at character {at + 1}, which a bare key "
            f"may not hold (an sf-token: letters, digits and {_TOKEN_PUNCTUATION}): send "
            'such a key as a quoted string, "...", with \\" and \\\\ for its quotes and '
            "backslashes",
        )
    return value


def parse_key(raw: str) -> str:
    """The key an ``Idempotency-Key`` header holds: the draft's sf-string (``"..."``) or
    a bare sf-token (a UUID), of 1 to 255 printable ASCII characters; else a 422 that
    quotes the value and says what in it is refused.

    A value that opens with a double quote is an sf-string and is parsed as one: a quote
    left open, an escape other than ``\\"`` and ``\\\\``, or anything after the closing
    quote is refused, not kept as a bare key that merely begins with a quote. A bare key
    holds token characters only: a quote, a space, a ``,`` (a list: which key the client
    retries with is not known) or a ``;`` would make a structured field something else."""
    # RFC 8941 4.2: spaces around the value are not part of it (HTTP strips them first).
    value = raw.strip(" ")
    if not value:
        _refuse_empty(raw, "is empty" if not raw else "holds only spaces")
    if not _PRINTABLE.fullmatch(value):
        _refuse_characters(raw)
    key = _sf_string(raw, value) if value.startswith('"') else _bare_key(raw, value)
    if not key.strip(" "):
        _refuse_empty(raw, "is an empty quoted string" if not key else "quotes only spaces")
    if len(key) > MAX_IDEMPOTENCY_KEY_LENGTH:
        unprocessable(
            _WHERE,
            f"{IDEMPOTENCY_KEY_HEADER} must be at most {MAX_IDEMPOTENCY_KEY_LENGTH} "
            f"characters, got {len(key)}: {key[:40]!r}...",
        )
    return key


def _refuse_empty(raw: str, why: str) -> NoReturn:
    # Said as it is: "must be 1 to 255 printable ASCII characters" left a client that
    # sent an empty key (an unset variable) to look for a character it did not send.
    unprocessable(
        _WHERE,
        f"{IDEMPOTENCY_KEY_HEADER} {why} (got {quoted(raw)}): send a key of 1 to "
        f"{MAX_IDEMPOTENCY_KEY_LENGTH} printable ASCII characters (a UUID, say), or no "
        f"{IDEMPOTENCY_KEY_HEADER} header",
    )


def _refuse_characters(raw: str) -> NoReturn:
    unprocessable(
        _WHERE,
        f"{IDEMPOTENCY_KEY_HEADER} must be 1 to {MAX_IDEMPOTENCY_KEY_LENGTH} printable "
        f"ASCII characters (a UUID, say), got {quoted(raw)}",
    )


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
    answered: bool = False

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
                lease_left = (found.claimed_at + store.CLAIM_LEASE - now).total_seconds()
                detail = (
                    f"a request with {IDEMPOTENCY_KEY_HEADER} {self.key!r} has held it "
                    f"for {held:.0f} s without an answer (still waiting, or its process "
                    f"died); send it again in {wait} s: the key is free when that request "
                    f"ends, or in {math.ceil(lease_left)} s at the latest, when its lease ends"
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
        """Keep this answer for the key, in ``session``'s transaction.

        :raises HTTPException: 409 when another request took the key over before this one
            stored its first answer (this one outlived its lease, or its process was taken
            for dead): the route's work is rolled back, as that request does it. Before,
            the answer was dropped and the work committed: the request was done twice."""
        if self.token is None:
            return
        held = store.answer(
            session,
            client=self.client,
            key=self.key,
            token=self.token,
            status=status_code,
            body=body.model_dump(mode="json"),
        )
        if held:
            self.answered = True
            return
        if self.answered:
            # Its first answer is committed with its work (a job's, before the broker's
            # send): the key's row went since (past its TTL), not to another request.
            log.warning(
                "%s %r: its row went before its answer was updated",
                IDEMPOTENCY_KEY_HEADER,
                self.key,
            )
            return
        self.token = None  # nothing of this request's is left to let go
        raise HTTPException(
            status.HTTP_409_CONFLICT,
            detail=f"a later request with {IDEMPOTENCY_KEY_HEADER} {self.key!r} took the "
            "key over while this one was being answered (this one held it past its "
            f"{store.CLAIM_LEASE.total_seconds():.0f} s lease, or its process was taken "
            "for dead): nothing was kept of this one; send it again for that request's "
            "answer",
            headers={"Retry-After": "1"},
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
            "printable ASCII characters, in double quotes as the draft's RFC 8941 string, "
            'with \\" and \\\\ escapes, or bare of token characters only: letters, digits '
            "and !#$%&'*+-.^_`|~:/): sent again with the same request, within "
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
            + ", ".join(quoted(value) for value in sent[:4]),
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
