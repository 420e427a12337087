"""Idempotency keys: a POST retried with its key is answered once, from the database.

A client that sent a POST and lost the answer (a timeout, a dropped connection) cannot
tell whether it was done. Sent again with the same ``Idempotency-Key`` header (Stripe's
API; the IETF draft "The Idempotency-Key HTTP Header Field"), it gets the first answer
back instead of a second job. The ``idempotency_keys`` table holds, per client and key,
the request's fingerprint and, once it is answered, the answer:

- :func:`claim` inserts the row in a transaction of its own, committed at once, so the
  primary key settles a race: of identical requests sent together one claims the key,
  the others find it claimed (:data:`IN_PROGRESS`) or answered (:data:`REPLAY`);
- :func:`answer` stores the answer in the caller's transaction (the one that stores
  the new row, where the route allows), so the answer and what it reports commit together;
- :func:`release` lets the key go when the request failed: nothing was made, and the
  same request may be sent again;
- a release the database refused (it turned read-only, or its disk full, after the claim:
  the delete is a write too) is tried again by :class:`PendingReleases`, before the
  process's next request with that key and every second in the background, until the database
  takes it or the lease ends: the key is free as soon as writes are, not 2 minutes on;
- a claim left unanswered past :data:`CLAIM_LEASE` (the API process died mid-request) is
  taken over by the next request with the key; expired rows are deleted by the claims;
- a claim whose process is known to be dead is taken over at once, not at the lease's
  end: its token names the process that made it (:func:`claim_token`), which a process of
  the same host and PID namespace can look up (:func:`claimer_died`). A process killed
  while the database refused writes (its pending releases lost with it), or with a request
  in flight, left its keys to the lease: their retries were 409s for up to 2 minutes.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import secrets
import socket
import threading
import time
import weakref
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from typing import Any, Literal

from sqlalchemy import delete, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from .models import IdempotencyKeyRow, utcnow
from .session import Database

__all__ = [
    "CLAIM_LEASE",
    "IN_PROGRESS",
    "MISMATCH",
    "NEW",
    "REPLAY",
    "Claim",
    "PendingReleases",
    "answer",
    "claim",
    "claim_token",
    "claimer_died",
    "fingerprint",
    "pending_releases",
    "release",
]

log = logging.getLogger(__name__)

#: How long a claim without an answer holds its key. A POST that creates a job or a
#: scenario is answered in well under a second; a claim this old belongs to a request
#: whose process died, and the next request with the key takes it over.
CLAIM_LEASE = timedelta(minutes=2)

NEW: Literal["new"] = "new"
REPLAY: Literal["replay"] = "replay"
IN_PROGRESS: Literal["in_progress"] = "in_progress"
MISMATCH: Literal["mismatch"] = "mismatch"


@dataclass(frozen=True)
class Claim:
    """What :func:`claim` found.

    :param outcome: ``new`` (this request holds the key: run it, then :func:`answer` or
        :func:`release`), ``replay`` (answered before: ``status`` and ``body``),
        ``in_progress`` (another request holds it), ``mismatch`` (the key was used for
        another request: ``route`` is the one it was used on).
    :param token: this request's claim, for :func:`answer` and :func:`release` (``new``).
    :param claimed_at: when the request that holds the key claimed it (``in_progress``;
        its lease ends :data:`CLAIM_LEASE` after), or when this one did (``new``).
    """

    outcome: Literal["new", "replay", "in_progress", "mismatch"]
    token: str | None = None
    route: str | None = None
    status: int | None = None
    body: dict[str, Any] | None = None
    claimed_at: datetime | None = None


def fingerprint(route: str, body: Any) -> str:
    """The request's identity: its route and its body as parsed (the same JSON written
    with other spacing, key order or defaults is the same request)."""
    canonical = json.dumps(
        {"route": route, "body": body}, sort_keys=True, separators=(",", ":"), ensure_ascii=True
    )
    return hashlib.sha256(canonical.encode()).hexdigest()


def _aware(moment: datetime) -> datetime:
    # SQLite hands back naive datetimes (UTC as stored).
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=UTC)


def _read(path: str) -> str | None:
    try:
        with open(path) as opened:
            return opened.read()
    except OSError:
        return None


def _process_start(pid: int) -> str | None:
    """Process ``pid``'s start, in clock ticks after boot (``/proc/<pid>/stat`` field 22),
    or None where it cannot be read (no such process, no /proc)."""
    stat = _read(f"/proc/{pid}/stat")
    fields = stat.rpartition(")")[2].split() if stat else []
    return fields[19] if len(fields) > 19 else None


def _digest(*parts: object) -> str:
    return hashlib.sha256("\0".join(map(str, parts)).encode()).hexdigest()[:8]


def _host() -> str | None:
    """This host's boot, PID namespace and time namespace (8 hex digits), or None where
    /proc cannot tell them: the processes it may look up, and read as this one does. Two
    containers on one kernel share the boot but not the namespace; the host's name
    besides, for hosts whose boot ids could meet.

    The time namespace, as a process in another one reads another start for the same
    process (``/proc/<pid>/stat`` is shifted by the reader's boot-time offset): one
    started with ``unshare --time --boottime`` took a live claim of this host for a dead
    one and ran its request a second time. And None where ``/proc`` is not this PID
    namespace's (``unshare --pid`` without ``--mount-proc``): ``/proc/<pid>`` is then
    another process than ``os.getpid()`` and ``os.kill`` name."""
    boot = _read("/proc/sys/kernel/random/boot_id")
    try:
        namespace = os.readlink("/proc/self/ns/pid")
        seen_as = os.readlink("/proc/self")
    except OSError:
        return None
    if not boot or seen_as != str(os.getpid()):
        return None
    try:
        clock = os.readlink("/proc/self/ns/time")
    except OSError:
        clock = ""  # a kernel without time namespaces (before 5.6): one clock for all
    return _digest(socket.gethostname(), boot.strip(), namespace, clock)


def _incarnation(host: str, pid: int, started: str) -> str:
    return _digest(host, pid, started)


def claim_token() -> str:
    """A new claim's token (32 hex digits, the ``claim`` column's width): the claiming
    process's host (:func:`_host`), pid and incarnation (its pid's start: a pid used
    again is another process), then 8 random hex digits; 32 random ones without /proc."""
    pid = os.getpid()
    host = _host()
    started = _process_start(pid)
    if host is None or started is None:
        return secrets.token_hex(16)
    return f"{host}{pid:08x}{_incarnation(host, pid, started)}{secrets.token_hex(4)}"


def claimer_died(token: str) -> bool:
    """Whether the process that made the claim ``token`` is known to be dead: made on this
    host and PID namespace by a pid that no process holds now, or that another process
    has taken since. False whenever it cannot be told (another host, no /proc, a token
    with no process in it, a process this one may not read): those keep their lease."""
    host = _host()
    if host is None or len(token) != 32 or not token.startswith(host):
        return False
    try:
        pid = int(token[8:16], 16)
    except ValueError:
        return False
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        pass  # alive, another user's: its start is read below where /proc shows it
    except OSError:
        return False
    started = _process_start(pid)
    return started is not None and _incarnation(host, pid, started) != token[16:24]


def claim(
    db: Database,
    *,
    client: str,
    key: str,
    route: str,
    digest: str,
    ttl: timedelta,
    now: datetime | None = None,
) -> Claim:
    """Claim ``key`` for ``client``'s request (``route``, fingerprint ``digest``), or say
    why not. Committed before it returns: a concurrent request sees the claim."""
    now = now or utcnow()
    token = claim_token()
    # Three rounds: the row found may go (released, expired) between the failed insert
    # and the read; the next insert then meets the next request's row or none.
    for _ in range(3):
        try:
            with db.session() as session:
                session.execute(delete(IdempotencyKeyRow).where(IdempotencyKeyRow.expires_at < now))
                session.add(
                    IdempotencyKeyRow(
                        client=client,
                        key=key,
                        route=route,
                        fingerprint=digest,
                        claim=token,
                        claimed_at=now,
                        expires_at=now + ttl,
                    )
                )
            return Claim(NEW, token=token, claimed_at=now)
        except IntegrityError:
            pass
        with db.session() as session:
            row = session.get(IdempotencyKeyRow, (client, key), populate_existing=True)
            if row is None:
                continue
            if _aware(row.expires_at) < now:
                session.delete(row)
                continue
            if row.fingerprint != digest:
                return Claim(MISMATCH, route=row.route)
            if row.answer_status is not None:
                return Claim(REPLAY, status=row.answer_status, body=row.answer_body)
            if _aware(row.claimed_at) > now - CLAIM_LEASE and not claimer_died(row.claim):
                return Claim(IN_PROGRESS, claimed_at=_aware(row.claimed_at))
            taken = session.execute(
                update(IdempotencyKeyRow)
                .where(
                    IdempotencyKeyRow.client == client,
                    IdempotencyKeyRow.key == key,
                    IdempotencyKeyRow.claim == row.claim,
                    IdempotencyKeyRow.answer_status.is_(None),
                )
                .values(claim=token, claimed_at=now)
            )
            if taken.rowcount == 1:  # type: ignore[attr-defined]
                return Claim(NEW, token=token, claimed_at=now)
    return Claim(IN_PROGRESS)


def answer(
    session: Session, *, client: str, key: str, token: str, status: int, body: dict[str, Any]
) -> bool:
    """Store the answer of the request that holds ``key`` in ``session`` (committed with
    the caller's transaction). False when the claim ``token`` no longer holds the key
    (another request took it over: its lease ended, or its process was taken for dead;
    or the key's row is gone): nothing was stored, and the caller, whose work another
    request is doing, must roll its transaction back, or the request is done twice."""
    stored = session.execute(
        update(IdempotencyKeyRow)
        .where(
            IdempotencyKeyRow.client == client,
            IdempotencyKeyRow.key == key,
            IdempotencyKeyRow.claim == token,
        )
        .values(answer_status=status, answer_body=body)
    )
    return bool(stored.rowcount == 1)  # type: ignore[attr-defined]


def release(db: Database, *, client: str, key: str, token: str) -> None:
    """Let ``key`` go: the request that held it failed before it was answered."""
    with db.session() as session:
        session.execute(
            delete(IdempotencyKeyRow).where(
                IdempotencyKeyRow.client == client,
                IdempotencyKeyRow.key == key,
                IdempotencyKeyRow.claim == token,
                IdempotencyKeyRow.answer_status.is_(None),
            )
        )


class PendingReleases:
    """Claims of failed requests that the database refused to let go, let go later.

    A request that claimed its key and then met a database that refuses writes (turned
    read-only, its disk full) fails, and so does its :func:`release`, a delete: the claim
    would hold the key until its lease ends, and a retry sent once the database takes
    writes again would be a 409 for up to 2 minutes. The process that failed knows the
    claim is dead; it tries the release again before each keyed request it serves
    (:meth:`flush`) and every ``interval_s`` in a background thread that ends when none is
    left. A claim whose lease ended is dropped (the next request takes it over anyway).
    A process killed meanwhile leaves its claims to the lease, as before.

    :param db: the database the claims are in.
    :param interval_s: seconds between the background thread's tries.
    """

    def __init__(self, db: Database, *, interval_s: float = 1.0) -> None:
        self._db = db
        self._interval_s = interval_s
        self._lock = threading.Lock()
        # (client, key) -> (token, when the lease ends)
        self._pending: dict[tuple[str, str], tuple[str, datetime]] = {}
        self._thread: threading.Thread | None = None

    def __len__(self) -> int:
        with self._lock:
            return len(self._pending)

    def add(self, *, client: str, key: str, token: str, claimed_at: datetime) -> None:
        """Let ``key``'s claim ``token`` go once the database takes writes."""
        with self._lock:
            self._pending[(client, key)] = (token, _aware(claimed_at) + CLAIM_LEASE)
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(
                    target=self._retry, name="idempotency-releases", daemon=True
                )
                self._thread.start()

    def flush(self, *, only: tuple[str, str] | None = None) -> None:
        """Try the pending releases once (``only``: that ``(client, key)``'s, if pending);
        those the database took, or whose lease ended, are dropped. Never raises: a
        database still refusing keeps them, and the round stops at its first refusal (the
        others would be refused as well: each try is a write, and on PostgreSQL a session
        closed and opened again)."""
        with self._lock:
            if only is None:
                pending = list(self._pending.items())
            else:
                pending = [(only, self._pending[only])] if only in self._pending else []
        now = utcnow()
        for (client, key), (token, lease_end) in pending:
            if lease_end > now:
                try:
                    release(self._db, client=client, key=key, token=token)
                except Exception as exc:  # still refused, or unreachable: try again later
                    log.debug("idempotency key %r not let go yet: %s", key, exc)
                    return
            with self._lock:
                if self._pending.get((client, key), (None,))[0] == token:
                    del self._pending[(client, key)]

    def _retry(self) -> None:
        while True:
            time.sleep(self._interval_s)
            self.flush()
            with self._lock:
                if not self._pending:
                    self._thread = None
                    return


_PENDING: weakref.WeakKeyDictionary[Database, PendingReleases] = weakref.WeakKeyDictionary()
_PENDING_LOCK = threading.Lock()


def pending_releases(db: Database) -> PendingReleases:
    """The releases ``db`` refused in this process (one set per database)."""
    with _PENDING_LOCK:
        found = _PENDING.get(db)
        if found is None:
            found = _PENDING[db] = PendingReleases(db)
        return found
