"""Alembic environment: runs on the connection given by service.store.session.upgrade."""

from __future__ import annotations

import sqlite3
from typing import Any

from alembic import context
from sqlalchemy import Connection, create_engine, event

from service.store.models import Base

config = context.config
target_metadata = Base.metadata

#: SQLite drops a column in place from 3.35 on. The downgrades drop columns with plain
#: ALTER TABLE, never with a batch copy, which on SQLite deleted rows through the foreign
#: keys (see 0006); an older SQLite is refused a downgrade by name, not with its "near
#: DROP: syntax error". Upgrades only add columns, which every SQLite does.
SQLITE_DROP_COLUMN = (3, 35, 0)


def _refuse_drop_column(
    conn: Connection, cursor: Any, statement: str, parameters: Any, *args: Any
) -> None:
    if "DROP COLUMN" in statement.upper():
        raise RuntimeError(
            f"this downgrade drops a column, which needs SQLite "
            f"{'.'.join(map(str, SQLITE_DROP_COLUMN))} or newer; this Python's SQLite is "
            f"{sqlite3.sqlite_version} (statement: {statement.strip()!r}). Nothing of this "
            "step was changed: run the downgrade with a Python built on a newer SQLite"
        )


def _run(connection: Connection) -> None:
    old_sqlite = (
        connection.dialect.name == "sqlite" and sqlite3.sqlite_version_info < SQLITE_DROP_COLUMN
    )
    if old_sqlite:
        event.listen(connection, "before_cursor_execute", _refuse_drop_column)
    try:
        context.configure(connection=connection, target_metadata=target_metadata)
        with context.begin_transaction():
            context.run_migrations()
    finally:
        if old_sqlite:
            event.remove(connection, "before_cursor_execute", _refuse_drop_column)


def run_migrations_online() -> None:
    connection = config.attributes.get("connection")
    if connection is not None:
        _run(connection)
        return
    engine = create_engine(config.get_main_option("sqlalchemy.url") or "")
    with engine.begin() as conn:
        _run(conn)


if context.is_offline_mode():
    context.configure(url=config.get_main_option("sqlalchemy.url"), target_metadata=target_metadata)
    with context.begin_transaction():
        context.run_migrations()
else:
    run_migrations_online()
