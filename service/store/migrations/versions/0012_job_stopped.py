"""A job says, as a field, that its time limit stopped it.

- ``jobs.stopped``: "time_limit" for a job whose time limit stopped it: a training (or a
  sweep before its first point) failed naming the limit, a job its heartbeat ended long
  past it, or a search or sweep that succeeded with what it had by then (its result's
  ``stopped``). NULL: the job ran to its own end, failed otherwise, or was cancelled
  (its status says so). Clients matched the error's text before.
- Rows stored before are filled once: the failures by the text the worker gave them
  ("... exceeded its time limit of N s ..."), the successes by their result's
  ``stopped``.

Revision ID: 0012
Revises: 0011
Create Date: 2026-12-06
"""

import sqlalchemy as sa
from alembic import op

revision = "0012"
down_revision = "0011"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch (see 0006: a batch copy on SQLite cascades).


def upgrade() -> None:
    op.add_column("jobs", sa.Column("stopped", sa.String(16), nullable=True))
    jobs = sa.table(
        "jobs",
        sa.column("status", sa.String),
        sa.column("error", sa.Text),
        sa.column("result", sa.JSON),
        sa.column("stopped", sa.String),
    )
    op.execute(
        jobs.update()
        .where(jobs.c.status == "failed", jobs.c.error.like("%exceeded its time limit of %"))
        .values(stopped="time_limit")
    )
    # JSON_EXTRACT on SQLite, ->> on PostgreSQL: the result's top-level "stopped".
    op.execute(
        jobs.update()
        .where(
            jobs.c.status == "succeeded",
            jobs.c.result["stopped"].as_string() == "time_limit",
        )
        .values(stopped="time_limit")
    )


def downgrade() -> None:
    op.drop_column("jobs", "stopped")
