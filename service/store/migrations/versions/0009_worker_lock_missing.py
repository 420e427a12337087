"""A worker that does not hold its incarnation lock says so.

- ``workers.lock_missing_since``: set by the worker's main process at each beat while
  it does not hold its incarnation lock (``worker.incarnation``: it could not take it at
  its start, or lost it and could not take it again), since the first beat that found it
  missing; NULL while it holds it. Such a worker claims no job, so ``/health`` lists it
  and is "degraded" when no live worker holds its lock.

Revision ID: 0009
Revises: 0008
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch (see 0006: a batch copy on SQLite cascades).


def upgrade() -> None:
    op.add_column(
        "workers", sa.Column("lock_missing_since", sa.DateTime(timezone=True), nullable=True)
    )


def downgrade() -> None:
    op.drop_column("workers", "lock_missing_since")
