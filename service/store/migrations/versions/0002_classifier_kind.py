"""Classifiers have a kind (clustering, nearest-centroid, 1nn, minirocket, likelihood,
least-squares); rows from before are the paper's clustering.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-23
"""

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


# Plain ALTER TABLE both ways, not a batch (as in 0003's, 0004's and 0006's columns): on
# SQLite a batch drop_column copied ``classifiers`` into a new table, dropped the old and
# renamed the copy. Nothing points at ``classifiers`` today, but a copy is the whole table
# rewritten, and it is how 0004's downgrade deleted every metric through the ``jobs`` it
# dropped. SQLite adds a column in place, and drops one in place since 3.35 once no index
# or constraint names it (``kind`` is in none).


def upgrade() -> None:
    op.add_column(
        "classifiers",
        sa.Column("kind", sa.String(32), nullable=False, server_default="clustering"),
    )


def downgrade() -> None:
    op.drop_column("classifiers", "kind")
