"""``inertia-id migrate``: the database to this code's head before any API or worker
starts, ``--check`` for where it stands, and a database newer than the code refused."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from sqlalchemy import create_engine, text

from app.main import create_app
from service.store.session import DatabaseNewerThanCode, head_revision, revisions, upgrade

from .support import make_settings


def migrate(
    url: str, tmp_path: Path, *options: str, **settings: str
) -> subprocess.CompletedProcess[str]:
    """The installed command line, as a deployment runs it, on the database at ``url``
    (``settings``: more environment variables)."""
    env = {
        **os.environ,
        "DATABASE_URL": url,
        "INERTIA_ID_DATA_DIR": str(tmp_path / "data"),
        **settings,
    }
    return subprocess.run(
        [sys.executable, "-m", "inertia_id.cli", "migrate", *options],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=120,
    )


def _set_revision(url: str, revision: str) -> None:
    engine = create_engine(url)
    try:
        with engine.begin() as connection:
            connection.execute(text("UPDATE alembic_version SET version_num = :r"), {"r": revision})
    finally:
        engine.dispose()


def test_migrate_says_from_and_to_and_check_tells_pending_from_done(
    empty_database_url: str, tmp_path: Path
) -> None:
    """Before, there was no such command (``Error: No such command 'migrate'``): a
    database was migrated only by starting the API or ``serve``."""
    url = empty_database_url
    head = head_revision()
    upgrade(url, "0009")

    pending = migrate(url, tmp_path, "--check")
    assert pending.returncode == 1, pending.stderr
    assert f"at 0009; this code's newest is {head}" in pending.stdout, pending.stdout
    assert revisions(url).current == "0009", "--check changed the database"

    done = migrate(url, tmp_path)
    assert done.returncode == 0, done.stderr
    assert f"migrated from 0009 to {head}" in done.stdout, done.stdout
    assert revisions(url).current == head

    again = migrate(url, tmp_path)
    assert again.returncode == 0, again.stderr
    assert f"at {head} already" in again.stdout, again.stdout
    checked = migrate(url, tmp_path, "--check")
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert f"at {head}, this code's newest revision" in checked.stdout


def test_migrate_check_on_a_database_never_migrated_is_pending(
    empty_database_url: str, tmp_path: Path
) -> None:
    checked = migrate(empty_database_url, tmp_path, "--check")
    assert checked.returncode == 1, checked.stdout + checked.stderr
    done = migrate(empty_database_url, tmp_path)
    assert done.returncode == 0, done.stderr
    assert f"migrated from none (no schema yet) to {head_revision()}" in done.stdout


def test_a_database_newer_than_the_code_is_refused_by_name_and_left_alone(
    empty_database_url: str, tmp_path: Path
) -> None:
    """A database a newer inertia-id migrated: Alembic's traceback ended in "Can't locate
    revision identified by '0099'" (serve and the API's start alike). Now one line naming
    both revisions, exit status 3 (1 before, as for pending migrations: a deployment
    script could not tell them apart), and the database unchanged."""
    url = empty_database_url
    upgrade(url)
    _set_revision(url, "0099")
    head = head_revision()
    for options in ((), ("--check",)):
        refused = migrate(url, tmp_path, *options)
        assert refused.returncode == 3, (options, refused.stdout)
        assert "Traceback" not in refused.stderr, refused.stderr
        line = refused.stderr.strip()
        assert line.startswith("inertia-id migrate: the database "), line
        assert "at revision 0099, which this inertia-id" in line and f"newest is {head}" in line
    assert revisions(url).current == "0099"
    with pytest.raises(DatabaseNewerThanCode, match="0099"):
        upgrade(url)
    with pytest.raises(SystemExit, match=r"^inertia-id api: .* at revision 0099"):
        create_app(make_settings(tmp_path, url))
    assert revisions(url).current == "0099"


def test_an_unreachable_database_is_one_line_and_exit_status_4(tmp_path: Path) -> None:
    """Exit status 4 with or without --check (1 before, as for pending migrations)."""
    for options in ((), ("--check",)):
        done = migrate("postgresql+psycopg://nobody@127.0.0.1:1/none", tmp_path, *options)
        assert done.returncode == 4, (options, done.stderr)
        assert done.stderr.startswith("inertia-id migrate: cannot reach the database "), done.stderr
        assert "Traceback" not in done.stderr


def test_help_documents_each_exit_status(tmp_path: Path) -> None:
    helped = migrate("sqlite:///unused.db", tmp_path, "--help")
    assert helped.returncode == 0, helped.stderr
    said = " ".join(helped.stdout.split())
    for status in (
        "0 at this code's newest",
        "1 with --check, migrations pending",
        "2 usage error",
        "3 the database is newer",
        "4 the database cannot be reached",
        "5 the settings name no usable database",
    ):
        assert status in said, (status, said)
    assert migrate("sqlite:///unused.db", tmp_path, "--no-such").returncode == 2


def test_a_bad_setting_is_exit_status_5(tmp_path: Path) -> None:
    done = migrate("sqlite:///unused.db", tmp_path, "--check", INERTIA_ID_PORT="0")
    assert done.returncode == 5, done.stderr
    assert done.stderr.startswith("inertia-id migrate: INERTIA_ID_PORT='0'"), done.stderr


@pytest.mark.parametrize(
    ("url", "said", "status"),
    [
        # A SQLite file where no folder can be made: a FileNotFoundError traceback before.
        ("sqlite:////proc/no-such-folder/inertia-id.db", "cannot open the database ", 4),
        # A database kind with no driver here: "No module named 'MySQLdb'" traceback before.
        ("mysql://user:secret@127.0.0.1/inertia", "no driver for the database ", 5),
        # No URL at all: SQLAlchemy's ArgumentError traceback before.
        ("secret-and-no-url", "DATABASE_URL is no database URL ", 5),
    ],
)
def test_a_database_that_cannot_be_opened_is_one_line(
    tmp_path: Path, url: str, said: str, status: int
) -> None:
    """Exit status 4 where it cannot be opened, 5 where the setting names no usable
    database (both 1 before, as for pending migrations)."""
    done = migrate(url, tmp_path)
    assert done.returncode == status, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    assert done.stderr.startswith(f"inertia-id migrate: {said}"), done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "secret" not in done.stderr


def test_migrations_run_at_once_on_one_database_take_turns(
    empty_database_url: str, tmp_path: Path
) -> None:
    """Three `inertia-id migrate` started together on an empty database (a deployment's
    migrate beside a `serve` or an API starting). Before, each read no schema and each
    created it: all but one failed, exit 1, "cannot reach the database ...: table
    scenarios already exists" (SQLite) or 'duplicate key value violates unique constraint
    "pg_type_typname_nsp_index"' (PostgreSQL). Now they take turns: one migrates, the
    others find it done."""
    url = empty_database_url
    env = {**os.environ, "DATABASE_URL": url, "INERTIA_ID_DATA_DIR": str(tmp_path / "data")}
    runs = [
        subprocess.Popen(
            [sys.executable, "-m", "inertia_id.cli", "migrate"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=tmp_path,
        )
        for _ in range(3)
    ]
    outputs = [(run.wait(120), *run.communicate()) for run in runs]
    assert [code for code, _out, _err in outputs] == [0, 0, 0], outputs
    said = " ".join(out for _code, out, _err in outputs)
    assert said.count("migrated from none (no schema yet)") == 1, outputs
    assert revisions(url).current == head_revision()
