"""``inertia-id migrate``: bring the configured database's schema to this code's head.

``python -m service.store.migrate [--data-dir DIR] [--check]``

The database is the one the service uses: ``DATABASE_URL``, else the SQLite file in
``--data-dir`` (or ``INERTIA_ID_DATA_DIR``, default ``./inertia-id-data``), as for
``inertia-id serve``. The API and ``serve`` migrate when they start; this command is for
a deployment that migrates once before any API or worker starts (docker-compose.yml's
``migrate`` service), and for checking where a database stands.

Exit status, one per case so that a deployment script can tell them apart (see
``EXIT_STATUS``): 0 the database is at this code's head (after migrating it, or with
``--check``, as found); 1 with ``--check``, migrations are pending; 2 a usage error (an
unknown option: argparse's own); 3 the database is newer than this code (migrated by a
newer inertia-id); 4 the database cannot be reached or opened (refused connection, bad
password, a SQLite folder that cannot be made: worth retrying once it is up); 5 the
settings name no usable database (a bad setting, a ``DATABASE_URL`` that is no URL or of
a kind with no driver here: retrying will not help). Each but 0 and 1 is one line on
stderr, and nothing is changed.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from pydantic import ValidationError
from sqlalchemy.exc import SQLAlchemyError

from service.config import get_settings, setting_problems

from .refusals import database_label, driver_said, unusable_database
from .session import DatabaseNewerThanCode, head_revision, revisions, upgrade

__all__ = ["main"]

PROGRAM = "inertia-id migrate"

# Before, pending, newer and unreachable were all 1. 2 is argparse's usage error.
PENDING = 1
NEWER = 3
UNREACHABLE = 4
MISCONFIGURED = 5
#: A connect to PostgreSQL given up after this many seconds (libpq's connect_timeout and
#: keepalives, as :class:`~service.store.session.Database` sets them): behind a proxy that
#: takes the connection and never answers, ``migrate`` waited for ever, printing nothing.
#: The migration's own statements get no such bound: one may wait, on purpose, for
#: another migration's lock.
DATABASE_SILENT_S = 10.0

EXIT_STATUS = f"""exit status: 0 at this code's newest revision; {PENDING} with --check, \
migrations pending; 2 usage error; {NEWER} the database is newer than this code (migrated by \
a newer inertia-id); {UNREACHABLE} the database cannot be reached or opened; \
{MISCONFIGURED} the settings name no usable database (bad setting, DATABASE_URL no URL \
or of a kind with no driver here)."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=PROGRAM,
        description="Apply the database migrations (Alembic) up to this code's newest, on "
        "DATABASE_URL, else the SQLite database in --data-dir, and print the revision "
        "before and after. A database migrated by a newer inertia-id is refused, unchanged.",
        epilog=EXIT_STATUS,
    )
    parser.add_argument(
        "--data-dir",
        default=None,
        help="Folder of the SQLite database when DATABASE_URL is unset (default "
        "INERTIA_ID_DATA_DIR, else ./inertia-id-data), as for `inertia-id serve`.",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help="Change nothing: exit 0 if the database is at this code's newest revision, "
        f"{PENDING} if migrations are pending (saying how many); other statuses below.",
    )
    return parser


def _name(revision: str | None) -> str:
    return "none (no schema yet)" if revision is None else revision


def _unreachable(label: str, exc: SQLAlchemyError) -> str:
    return f"{PROGRAM}: cannot reach the database {label}: {driver_said(exc)}"


def _pending(current: str | None, head: str) -> int:
    from alembic.script import ScriptDirectory

    from .session import _config

    scripts = ScriptDirectory.from_config(_config(""))
    return sum(1 for _ in scripts.iterate_revisions(head, current or "base"))


def _sqlite_file_exists(url: str) -> bool:
    from sqlalchemy import make_url

    database = make_url(url).database
    return not database or database == ":memory:" or Path(database).exists()


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.data_dir is not None:
        os.environ["INERTIA_ID_DATA_DIR"] = str(Path(args.data_dir).expanduser())
    get_settings.cache_clear()
    try:
        settings = get_settings()
    except ValidationError as exc:
        print("\n".join(f"{PROGRAM}: {line}" for line in setting_problems(exc)), file=sys.stderr)
        return MISCONFIGURED
    url = settings.resolved_database_url
    problem = unusable_database(url)
    if problem:
        print(f"{PROGRAM}: {problem}", file=sys.stderr)
        return MISCONFIGURED
    label = database_label(url)
    if args.check and url.startswith("sqlite") and not _sqlite_file_exists(url):
        # Connecting would create the file: --check changes nothing.
        print(f"{label}: no database yet; this code's newest revision is {head_revision()}")
        return PENDING
    try:
        found = revisions(url, silent_after_s=DATABASE_SILENT_S)
        if not found.known:
            raise DatabaseNewerThanCode(url, str(found.current), found.head)
        if args.check:
            if found.at_head:
                print(f"{label}: at {found.head}, this code's newest revision")
                return 0
            print(
                f"{label}: at {_name(found.current)}; this code's newest is {found.head}: "
                f"{found.pending} migration(s) pending (run `{PROGRAM}`)"
            )
            return PENDING
        if found.at_head:
            print(f"{label}: at {found.head} already, this code's newest revision; nothing to do")
            return 0
        # The revision before is read again under the migration lock: another migration
        # that ran meanwhile (a second `migrate`, serve or the API starting) made it.
        before = upgrade(url, silent_after_s=DATABASE_SILENT_S)
        after = revisions(url, silent_after_s=DATABASE_SILENT_S)
        if before == after.current:
            print(f"{label}: at {after.current}, migrated meanwhile by another run; nothing to do")
            return 0
        applied = found.pending if before == found.current else _pending(before, after.head)
        print(
            f"{label}: migrated from {_name(before)} to {after.current} "
            f"({applied} migration(s) applied)"
        )
    except DatabaseNewerThanCode as exc:
        print(f"{PROGRAM}: {exc}", file=sys.stderr)
        return NEWER
    except SQLAlchemyError as exc:
        print(_unreachable(label, exc), file=sys.stderr)
        return UNREACHABLE
    except OSError as exc:
        # The SQLite file's folder cannot be made (read-only, no such parent): a traceback.
        where = f": {exc.filename}" if exc.filename else ""
        print(
            f"{PROGRAM}: cannot open the database {label}: {exc.strerror or exc}{where}",
            file=sys.stderr,
        )
        return UNREACHABLE
    return 0


if __name__ == "__main__":
    sys.exit(main())
