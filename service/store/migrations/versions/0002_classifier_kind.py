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


def upgrade() -> None:
    with op.batch_alter_table("classifiers") as batch:
        batch.add_column(
            sa.Column("kind", sa.String(32), nullable=False, server_default="clustering")
        )


def downgrade() -> None:
    with op.batch_alter_table("classifiers") as batch:
        batch.drop_column("kind")
