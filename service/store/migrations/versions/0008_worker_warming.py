"""A worker whose task process is being replaced says so.

- ``workers.warming_since``: set by the worker's main process while it has no warm task
  process left (the last one retired after its jobs or its memory limit, or was killed)
  and a replacement imports the core; NULL once one is warm again. The worker keeps
  beating meanwhile, so ``/health`` lists it as warming rather than dropping it.

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch (see 0006: a batch copy on SQLite cascades).


def upgrade() -> None:
    op.add_column("workers", sa.Column("warming_since", sa.DateTime(timezone=True), nullable=True))


def downgrade() -> None:
    op.drop_column("workers", "warming_since")
