"""Engine and sessions for SQLite (embedded default) or PostgreSQL, and migrations."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from alembic import command
from alembic.config import Config
from alembic.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import Engine, create_engine, event, text
from sqlalchemy.orm import Session, sessionmaker

__all__ = [
    "Database",
    "DatabaseNewerThanCode",
    "Revisions",
    "head_revision",
    "revisions",
    "upgrade",
]

MIGRATIONS = Path(__file__).with_name("migrations")


#: The libpq options :class:`Database` gives for ``silent_after_s`` (a URL that names one
#: keeps its own), each the kernel's or libpq's: a connect given up after that many
#: seconds (``connect_timeout``, per address, whole seconds, at least 2), and an
#: established connection given up once the server's machine has left what was sent
#: unacknowledged that long (``tcp_user_timeout``) or stopped answering keepalive
#: probes (``keepalives_*``, within about that long). A slow server is no silent one:
#: its machine acknowledges at once. A proxy still acknowledging for a server that
#: does not answer (frozen) is bounded by none of them but the connect: ``Database``'s
#: ``answer_within_s`` bounds that (service.store.answers).
SILENT_NETWORK_OPTIONS = (
    "connect_timeout",
    "keepalives",
    "keepalives_idle",
    "keepalives_interval",
    "keepalives_count",
    "tcp_user_timeout",
)


def _silent_network_args(url: str, silent_after_s: float) -> dict[str, Any]:
    from sqlalchemy import make_url

    given = set(make_url(url).query)
    probe_s = max(1, round(silent_after_s / 4))
    options = {
        "connect_timeout": max(2, round(silent_after_s)),
        "keepalives": 1,
        "keepalives_idle": probe_s,
        "keepalives_interval": probe_s,
        "keepalives_count": 3,
        "tcp_user_timeout": round(silent_after_s * 1000),
    }
    return {key: value for key, value in options.items() if key not in given}


def _engine(url: str, silent_after_s: float | None = None) -> Engine:
    if url.startswith("sqlite"):
        path = url.split("///", 1)[-1]
        if path and path != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30})

        @event.listens_for(engine, "connect")
        def _pragmas(dbapi_connection: Any, _record: Any) -> None:
            # The API and the worker write from different processes: WAL lets readers
            # go on during a write, busy_timeout waits for the lock instead of failing,
            # and SQLite enforces foreign keys only when asked.
            cursor = dbapi_connection.cursor()
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA busy_timeout=30000")
            cursor.execute("PRAGMA foreign_keys=ON")
            cursor.close()
            # SQLite's own lower() folds ASCII only: a search for "énergie" missed a job
            # named "Énergie" that PostgreSQL found. Python's folds every script.
            dbapi_connection.create_function(
                "lower",
                1,
                lambda text: text.lower() if isinstance(text, str) else text,
                deterministic=True,
            )

        return engine
    connect_args = {} if silent_after_s is None else _silent_network_args(url, silent_after_s)
    engine = create_engine(url, pool_pre_ping=True, connect_args=connect_args)

    @event.listens_for(engine, "handle_error")
    def _drop_read_only_sessions(context: Any) -> None:
        # A PostgreSQL session takes default_transaction_read_only as it starts (ALTER
        # DATABASE ... SET) and keeps it: a pooled connection opened while the database
        # was read-only refused every write after the setting was reset, for the life
        # of its process (a worker's heartbeat, its run's outcome, the API's writes),
        # while the sessions opened before went on writing, so another worker's reaper
        # could judge the refused run dead. Closed at its refusal (this connection
        # only: the writable ones stay), the next write opens a session that reads the
        # database's current setting.
        if getattr(context.original_exception, "sqlstate", None) == "25006":
            context.is_disconnect = True
            context.invalidate_pool_on_disconnect = False

    return engine


class Database:
    """One engine and its session factory.

    :param url: SQLAlchemy URL, e.g. ``sqlite:////path/db.sqlite`` or
        ``postgresql+psycopg://user@host/db``.
    :param silent_after_s: PostgreSQL: give up a connect, or a connection whose
        server's machine stopped acknowledging, after about this many seconds (see
        :data:`SILENT_NETWORK_OPTIONS`); None: libpq's defaults (a connect, or a wait
        for an answer, without end).
    :param answer_within_s: PostgreSQL: a statement (a query, a commit, the pool's
        ping) still unanswered this many seconds after it was sent has its connection
        cut, and fails as on a lost connection (see
        :class:`service.store.answers.AnswerDeadline`): what ``silent_after_s`` cannot
        bound, a proxy that acknowledges for a server that does not answer. None: a
        statement waits for its answer without end.
    """

    def __init__(
        self,
        url: str,
        *,
        silent_after_s: float | None = None,
        answer_within_s: float | None = None,
    ) -> None:
        self.url = url
        self.engine = _engine(url, silent_after_s)
        self._sessions = sessionmaker(self.engine, expire_on_commit=False)
        if answer_within_s is not None and self.engine.dialect.name == "postgresql":
            from .answers import AnswerDeadline
            from .refusals import database_label

            # The server asked whether it is at work on a late statement as a request
            # connects: within silent_after_s, where given.
            AnswerDeadline(
                self.engine, answer_within_s, what=database_label(url), ask_s=silent_after_s
            )

    @contextmanager
    def session(self) -> Iterator[Session]:
        """A session that commits on success and rolls back on error."""
        session = self._sessions()
        try:
            yield session
            session.commit()
        except BaseException:
            session.rollback()
            raise
        finally:
            session.close()

    def ping(self) -> bool:
        try:
            with self.engine.connect() as connection:
                connection.execute(text("SELECT 1"))
            return True
        except Exception:
            return False

    def dispose(self) -> None:
        self.engine.dispose()


class DatabaseNewerThanCode(RuntimeError):
    """The database is at a revision this code's migrations do not have: a newer
    inertia-id migrated it. Upgrading it (Alembic's "Can't locate revision") or serving
    from it (columns this code does not know) would be wrong either way."""

    def __init__(self, url: str, current: str, head: str) -> None:
        from .refusals import database_label

        self.current, self.head = current, head
        super().__init__(
            f"the database {database_label(url)} is at revision {current}, which this "
            f"inertia-id ({_version()}) does not have: its newest is {head}. A newer "
            "inertia-id migrated it; run that version, or downgrade the database with it "
            f"to {head} first. Nothing was changed"
        )


@dataclass(frozen=True)
class Revisions:
    """Where a database stands against this code's migrations.

    :param current: the database's revision; None for a database never migrated.
    :param head: the newest revision of this code's migrations.
    :param known: whether this code has ``current`` (None always is).
    :param pending: how many of this code's migrations ``current`` lacks (0 if unknown).
    """

    current: str | None
    head: str
    known: bool
    pending: int

    @property
    def at_head(self) -> bool:
        return self.current == self.head


def _version() -> str:
    from inertia_id import __version__

    return __version__


def _config(url: str) -> Config:
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    return config


def head_revision() -> str:
    """The newest revision of this code's migrations."""
    head = ScriptDirectory.from_config(_config("")).get_current_head()
    assert head is not None, "no migrations found"
    return head


def revisions(url: str, *, silent_after_s: float | None = None) -> Revisions:
    """The database's revision at ``url`` beside this code's head (reads only).

    :param silent_after_s: as :class:`Database`'s: the connect given up after it.
    """
    scripts = ScriptDirectory.from_config(_config(url))
    head = head_revision()
    engine = _engine(url, silent_after_s)
    try:
        with engine.connect() as connection:
            current = MigrationContext.configure(connection).get_current_revision()
    finally:
        engine.dispose()
    known = current is None or any(s.revision == current for s in scripts.walk_revisions())
    pending = sum(1 for _ in scripts.iterate_revisions(head, current or "base")) if known else 0
    return Revisions(current=current, head=head, known=known, pending=pending)


def upgrade(url: str, revision: str = "head", *, silent_after_s: float | None = None) -> str | None:
    """Apply the Alembic migrations to the database at ``url``, up to ``revision``.

    :param silent_after_s: as :class:`Database`'s: the connect given up after it (the
        API and ``inertia-id serve`` as they start; before, a silent database held their
        start for ever). The migration's statements are not given a deadline: one may
        wait on purpose, for another migration's lock.
    :returns: the database's revision before (None: no schema), read once the other
        migrations running on it have ended (see :func:`_migration_lock`).
    :raises DatabaseNewerThanCode: the database is at a revision this code does not
        have (Alembic said only "Can't locate revision identified by '0012'").
    """
    return _migrate(url, command.upgrade, revision, silent_after_s)


def downgrade(url: str, revision: str) -> None:
    """Undo the Alembic migrations after ``revision`` on the database at ``url``."""
    _migrate(url, command.downgrade, revision)


#: Key of the PostgreSQL advisory lock that migrations hold (any number: the same in every
#: inertia-id process). Bytes of "inertia-id migrate".
_MIGRATION_LOCK_KEY = 0x69642D6D69677261


@contextmanager
def _migration_lock(url: str) -> Iterator[Callable[[Any], None]]:
    """One migration at a time on a database: two at once (two `inertia-id migrate`, or
    one beside `serve` or the API starting) both read no schema and both created it; the
    second failed on "table scenarios already exists" (SQLite) or a duplicate key in
    pg_type (PostgreSQL) and exited 1 saying it could not reach the database. The other
    now waits, then finds the schema the first made.

    SQLite: an exclusive ``flock`` on a file beside the database, held here until the
    migration's transaction has committed (Python's sqlite3 commits before DDL: no one
    transaction holds it all). PostgreSQL: the function given, called on the migration's
    connection once its transaction has begun, takes an advisory lock that transaction
    holds to its end."""
    from sqlalchemy import make_url

    parsed = make_url(url)
    if parsed.get_backend_name() == "postgresql":

        def advisory(connection: Any) -> None:
            connection.execute(
                text("SELECT pg_advisory_xact_lock(:key)"), {"key": _MIGRATION_LOCK_KEY}
            )

        yield advisory
        return
    database = parsed.database
    if parsed.get_backend_name() != "sqlite" or not database or database == ":memory:":
        yield lambda _connection: None
        return
    import fcntl

    Path(database).parent.mkdir(parents=True, exist_ok=True)
    with open(f"{database}.migrate-lock", "a+b") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield lambda _connection: None
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _migrate(
    url: str,
    action: Callable[[Config, str], None],
    revision: str,
    silent_after_s: float | None = None,
) -> str | None:
    config = _config(url)
    scripts = ScriptDirectory.from_config(config)
    engine = _engine(url, silent_after_s)
    try:
        with _migration_lock(url) as lock, engine.begin() as connection:
            lock(connection)
            current = MigrationContext.configure(connection).get_current_revision()
            if current is not None and not any(
                s.revision == current for s in scripts.walk_revisions()
            ):
                head = scripts.get_current_head()
                raise DatabaseNewerThanCode(url, current, str(head))
            config.attributes["connection"] = connection
            action(config, revision)
            return current
    finally:
        engine.dispose()
