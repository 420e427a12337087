"""Whether a worker incarnation's lock is held: the probe the workers and ``/health``
share (see :mod:`worker.incarnation` for the lock itself, which each worker process holds
for as long as it lives).

Here, not in ``worker``: the API reads the same locks to tell a live worker from the
row a dead one left (``app`` and ``worker`` never import each other).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import logging
import os
from collections.abc import Iterable
from pathlib import Path

from sqlalchemy import text
from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import Session

__all__ = ["LockUnreadable", "lock_file", "lock_held", "lock_key", "locks_held"]

logger = logging.getLogger(__name__)


class LockUnreadable(Exception):
    """A lock whose state cannot be told: ``where`` (its folder, or the PostgreSQL
    server) and the error, as ``__cause__``."""

    def __init__(self, where: str, error: BaseException) -> None:
        super().__init__(f"cannot read the incarnation locks {where}: {error}")
        self.where = where
        self.error = error


def lock_key(incarnation: str) -> int:
    """A PostgreSQL advisory lock key (signed 64 bits) for ``incarnation``."""
    return int.from_bytes(hashlib.sha256(incarnation.encode()).digest()[:8], "big", signed=True)


def lock_file(database_url: str, incarnation: str) -> Path | None:
    """The lock file of ``incarnation`` beside a SQLite database file; None elsewhere."""
    folder = _lock_folder(database_url)
    return None if folder is None else folder / f"{incarnation}.lock"


def _lock_folder(database_url: str) -> Path | None:
    """The folder of the lock files beside a SQLite database file; None elsewhere."""
    url = make_url(database_url)
    if not url.drivername.startswith("sqlite") or url.database in (None, "", ":memory:"):
        return None
    database = Path(url.database or "")
    return database.with_name(f"{database.name}.incarnations")


def lock_held(session: Session, database_url: str, incarnation: str) -> bool | None:
    """Whether ``incarnation``'s lock is held now; None where a database has no locks (an
    in-memory SQLite). Raises :class:`LockUnreadable` where it cannot be told: a lock
    file that cannot be read (``<database>.incarnations`` is a file, or unreadable), or
    a PostgreSQL probe that fails (the server restarting, the session ended, a
    statement error).

    On PostgreSQL asked through ``session``'s connection (another session than the
    holder's, also in the holder's own process). A free lock file is removed: a dead
    incarnation's, which nobody will hold again.
    """
    if session.get_bind().dialect.name == "postgresql":
        key = lock_key(incarnation)
        try:
            # In a savepoint: a statement that fails leaves the caller's transaction
            # usable (else every later statement of the caller's session failed too).
            with session.begin_nested():
                free = session.execute(
                    text("SELECT pg_try_advisory_lock(:key)"), {"key": key}
                ).scalar()
        except Exception as exc:
            if isinstance(exc, DBAPIError) and exc.connection_invalidated:
                # The server ended the session, and the transaction with it: rolled
                # back here too, so the caller's session connects afresh at its next
                # statement instead of failing at each until its end.
                session.rollback()
            raise LockUnreadable("on the PostgreSQL server", exc) from exc
        if free:
            _release_probe(session, key, incarnation)
        return not free
    path = lock_file(database_url, incarnation)
    if path is None:
        return None
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return False  # released at a clean exit, or never taken: not running
    except OSError as exc:
        raise LockUnreadable(f"in {path.parent}", exc) from exc
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
            return True
        raise LockUnreadable(f"in {path.parent}", exc) from exc
    else:
        with contextlib.suppress(OSError):
            path.unlink()  # a dead incarnation's file: nobody will hold it again
        return False
    finally:
        os.close(fd)


def locks_held(
    session: Session, database_url: str, incarnations: Iterable[str]
) -> dict[str, bool | None]:
    """Whether each of ``incarnations``' locks is held now, as :func:`lock_held` says of
    one (None where a database has no locks; :class:`LockUnreadable` where it cannot be
    told), at a cost that does not grow with the rows on PostgreSQL: ``/health`` probed
    each row of a gone worker with its own savepoint, try-lock and unlock, 0.10 s for 50
    rows and 1.06 s for 500 (``bench/health_gone_rows.py --store postgresql``).

    On PostgreSQL one read of ``pg_locks``, which lists the advisory locks every session
    of this database holds, takes none (no probe can keep a live worker's lock from it).
    On SQLite the lock folder is listed once and only the files in it are tried (those
    of live workers, and of killed ones until a probe removes them)."""
    wanted = list(dict.fromkeys(incarnations))
    if not wanted:
        return {}
    if session.get_bind().dialect.name == "postgresql":
        try:
            with session.begin_nested():
                # A bigint key is listed in two unsigned 32-bit halves (objsubid 1).
                halves = session.execute(
                    text(
                        "SELECT classid::bigint, objid::bigint FROM pg_locks"
                        " WHERE locktype = 'advisory' AND objsubid = 1 AND granted"
                        " AND database = (SELECT oid FROM pg_database"
                        " WHERE datname = current_database())"
                    )
                ).all()
        except Exception as exc:
            if isinstance(exc, DBAPIError) and exc.connection_invalidated:
                session.rollback()  # as in lock_held
            raise LockUnreadable("on the PostgreSQL server", exc) from exc
        held = {
            int.from_bytes(((high << 32) | low).to_bytes(8, "big"), "big", signed=True)
            for high, low in halves
        }
        return {incarnation: lock_key(incarnation) in held for incarnation in wanted}
    folder = _lock_folder(database_url)
    if folder is None:
        return dict.fromkeys(wanted)
    try:
        present = set(os.listdir(folder))
    except FileNotFoundError:
        present = set()  # no worker has taken a lock here yet
    except OSError as exc:
        raise LockUnreadable(f"in {folder}", exc) from exc
    return {
        incarnation: f"{incarnation}.lock" in present
        and lock_held(session, database_url, incarnation)
        for incarnation in wanted
    }


def _release_probe(session: Session, key: int, incarnation: str) -> None:
    """Let go of ``incarnation``'s lock, which a probe in ``session`` just took (found
    free). Should the unlock fail, or find no lock to release, the probe's session is
    ended (its connection closed, not put back in the pool; the caller's transaction
    rolled back): a session advisory lock outlives the rollback of a savepoint or a
    transaction, so the pooled connection went on holding the other incarnation's lock,
    which that process, alive after all, could then never take again (nor any later
    probe find free: it is re-entrant)."""
    try:
        with session.begin_nested():
            released = session.execute(
                text("SELECT pg_advisory_unlock(:key)"), {"key": key}
            ).scalar()
    except Exception as exc:
        if isinstance(exc, DBAPIError) and exc.connection_invalidated:
            session.rollback()  # the session ended: the lock went with it
            return
        released, reason = False, f"{type(exc).__name__}: {exc}".splitlines()[0]
    else:
        reason = "it held none"
    if released:
        return
    logger.warning(
        "a probe could not release the lock of incarnation %s it took (%s): its database "
        "session is closed so that the lock goes with it",
        incarnation,
        reason,
    )
    session.connection().invalidate()
    session.rollback()
