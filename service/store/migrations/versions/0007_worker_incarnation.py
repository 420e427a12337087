"""A worker started again under the same name is a new incarnation.

- ``workers.incarnation``: the id of the worker process that holds the name now (a new
  one each time a worker starts, also under a name it had before: docker keeps a
  container's hostname across a restart).
- ``jobs.worker_incarnation``: the incarnation whose run claimed the job. A worker that
  starts takes at once the jobs still running under its name for an earlier incarnation
  that is no longer alive (``worker.incarnation``). NULL on rows stored before.

Revision ID: 0007
Revises: 0006
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch (see 0006: a batch copy of ``jobs`` on SQLite cascades).


def upgrade() -> None:
    op.add_column("workers", sa.Column("incarnation", sa.String(32), nullable=True))
    op.add_column("jobs", sa.Column("worker_incarnation", sa.String(32), nullable=True))


def downgrade() -> None:
    op.drop_column("jobs", "worker_incarnation")
    op.drop_column("workers", "incarnation")
