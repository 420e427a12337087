"""Each run a job lost is recorded, not overwritten.

- ``jobs.attempt_history``: one JSON object per run that did not end the job itself (its
  worker died, its heartbeat stopped, or its worker was asked to stop and handed it
  back): the attempt's number, its worker, when it started and last beat, when and why it
  was declared lost, and what became of the job (re-queued, failed, cancelled). The
  next run's claim overwrites ``started_at``, ``worker`` and ``error``; before this
  column only ``attempts: 2`` said that a worker had died during a job. Rows stored
  before hold NULL (no history was kept), which the API shows as an empty list.

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch: a batch that copies ``jobs`` into a new table on SQLite
# drops the old one, and with foreign keys on (the store's connections turn them on) that
# deletes every job's metrics and tags by their ON DELETE CASCADE (a downgrade through a
# batch drop_column left no metrics). SQLite adds and (since 3.35) drops a column in place.


def upgrade() -> None:
    op.add_column("jobs", sa.Column("attempt_history", sa.JSON(), nullable=True))


def downgrade() -> None:
    op.drop_column("jobs", "attempt_history")
