"""Why a database that answered refused to store: a full disk, a read-only database, a
failing disk. The API answers those with a 503 that says so; a worker that cannot store
its job's end waits for the database to take writes and then stores it with the reason."""

from __future__ import annotations

import sqlite3

__all__ = [
    "database_label",
    "driver_said",
    "unreachable",
    "unusable_database",
    "why_cannot_store",
]

# SQLite's primary result codes (the low byte of sqlite3's ``sqlite_errorcode``) and
# PostgreSQL's SQLSTATEs: disk_full, io_error, read_only_sql_transaction (a hot standby,
# or a database whose transactions are read-only by default).
_SQLITE_REFUSALS = {
    sqlite3.SQLITE_FULL: "full",
    sqlite3.SQLITE_READONLY: "read-only",
    sqlite3.SQLITE_IOERR: "io",
}
_PG_REFUSALS = {"53100": "full", "58030": "io", "25006": "read-only"}


def database_label(url: str) -> str:
    """The database as a log line names it: a SQLite file's path, else the URL with any
    password masked."""
    from sqlalchemy import make_url

    parsed = make_url(url)
    if parsed.drivername.startswith("sqlite"):
        return str(parsed.database)
    return parsed.render_as_string(hide_password=True)


def unusable_database(url: str) -> str | None:
    """Why ``url`` names no database this install can open, as one sentence: it is no URL,
    or of a kind with no driver here (``mysql://``: "No module named 'MySQLdb'"); None
    when it can be tried. Checked before anything is started: each was a traceback from
    the first connection (``serve``, the worker's and the API's start). A URL that does
    not parse is not shown: its password cannot be masked."""
    from sqlalchemy import make_url
    from sqlalchemy.exc import ArgumentError, NoSuchModuleError

    try:
        parsed = make_url(url)
    except ArgumentError:
        return (
            "DATABASE_URL is no database URL (sqlite:///PATH or "
            "postgresql+psycopg://USER:PASSWORD@HOST:PORT/NAME)"
        )
    try:
        parsed.get_dialect().import_dbapi()
    except (NoSuchModuleError, ImportError) as exc:
        return (
            f"no driver for the database {database_label(url)}: {exc}; inertia-id runs on "
            "SQLite (sqlite:///PATH) and PostgreSQL (postgresql+psycopg://...)"
        )
    return None


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


# SQLite: the file cannot be opened, or a writer held the lock past the busy timeout.
_SQLITE_UNREACHABLE = {sqlite3.SQLITE_CANTOPEN, sqlite3.SQLITE_BUSY, sqlite3.SQLITE_LOCKED}


def unreachable(exc: BaseException) -> bool:
    """Whether ``exc`` says the database could not be reached for now (its server down or
    refusing connections, the session ended, a SQLite file that cannot be opened or stays
    locked), as opposed to a refusal (:func:`why_cannot_store`) or a statement at fault (a
    missing table is an OperationalError too, and trying it again would never end)."""
    if getattr(exc, "connection_invalidated", False):
        return True
    orig = getattr(exc, "orig", exc)
    code = getattr(orig, "sqlite_errorcode", None)
    if isinstance(code, int):
        return code & 0xFF in _SQLITE_UNREACHABLE
    import psycopg

    if not isinstance(orig, psycopg.OperationalError):
        return False
    # No SQLSTATE: the connection itself failed; class 08 (connection exception) and
    # 57P01-57P03 (the server shutting down, or not yet accepting connections).
    sqlstate = orig.sqlstate
    return sqlstate is None or sqlstate.startswith("08") or sqlstate in ("57P01", "57P02", "57P03")


def driver_said(exc: BaseException) -> str:
    """The first line of what the driver said of ``exc`` (SQLAlchemy's own lines, the
    statement and its parameters, left out), for a one-line refusal."""
    lines = str(getattr(exc, "orig", exc) or exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__
