"""A worker's row says when another live process of its name (a twin) last beat.

- ``workers.twin_seen_at``: set by the beat of a process whose name's row another live
  process (a twin, started under the same name by mistake) beat last: the row stays the
  other's, and this says that a second process beats under the name, so that ``/health``
  counts it (``workers.duplicates_seen``) rather than show one worker. NULL: none seen.

Revision ID: 0011
Revises: 0010
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0011"
down_revision = "0010"
branch_labels = None
depends_on = None


# Plain ALTER TABLE, not a batch (see 0006: a batch copy on SQLite cascades).


def upgrade() -> None:
    op.add_column("workers", sa.Column("twin_seen_at", sa.DateTime(timezone=True), nullable=True))


def downgrade() -> None:
    op.drop_column("workers", "twin_seen_at")
