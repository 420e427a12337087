"""Why a database that answered refused to store: a full disk, a read-only database, a
failing disk. The API answers those with a 503 that says so; a worker that cannot store
its job's end waits for the database to take writes and then stores it with the reason."""

from __future__ import annotations

import sqlite3

__all__ = ["why_cannot_store"]

# SQLite's primary result codes (the low byte of sqlite3's ``sqlite_errorcode``) and
# PostgreSQL's SQLSTATEs: disk_full, io_error, read_only_sql_transaction (a hot standby,
# or a database whose transactions are read-only by default).
_SQLITE_REFUSALS = {
    sqlite3.SQLITE_FULL: "full",
    sqlite3.SQLITE_READONLY: "read-only",
    sqlite3.SQLITE_IOERR: "io",
}
_PG_REFUSALS = {"53100": "full", "58030": "io", "25006": "read-only"}


def why_cannot_store(exc: BaseException) -> str | None:
    """``full``, ``read-only`` or ``io`` when the database answered but refused to store
    (a full disk, a read-only file or server, a failing disk); None otherwise (it could
    not be reached, or the statement was at fault)."""
    orig = getattr(exc, "orig", exc)
    code = getattr(orig, "sqlite_errorcode", None)
    if isinstance(code, int):
        return _SQLITE_REFUSALS.get(code & 0xFF)
    sqlstate = getattr(orig, "sqlstate", None)
    return _PG_REFUSALS.get(sqlstate) if isinstance(sqlstate, str) else None
