"""POSTs sent with an ``Idempotency-Key`` and their answers.

- ``idempotency_keys``: one row per client (the SHA-256 of its API key) and key, with
  the route and a fingerprint of the request, the token of the request that claimed
  it, when, when it expires, and the answer's status and JSON body once there is one
  (``service.store.idempotency``). A new table: nothing stored before changes.

Revision ID: 0010
Revises: 0009
Create Date: 2026-12-05
"""

import sqlalchemy as sa
from alembic import op

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "idempotency_keys",
        sa.Column("client", sa.String(64), nullable=False),
        sa.Column("key", sa.String(255), nullable=False),
        sa.Column("route", sa.String(200), nullable=False),
        sa.Column("fingerprint", sa.String(64), nullable=False),
        sa.Column("claim", sa.String(32), nullable=False),
        sa.Column("claimed_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("expires_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("answer_status", sa.Integer(), nullable=True),
        sa.Column("answer_body", sa.JSON(), nullable=True),
        sa.PrimaryKeyConstraint("client", "key"),
    )
    op.create_index("ix_idempotency_keys_expires_at", "idempotency_keys", ["expires_at"])


def downgrade() -> None:
    # ``if_exists``: Python's sqlite3 runs DDL sent before any DML of a transaction
    # outside it, so when a later step of the same downgrade fails (0009's DROP COLUMN
    # on an SQLite older than 3.35, refused by name) this drop stays done while the
    # version stays 0010; the downgrade run again must get past it.
    op.drop_index("ix_idempotency_keys_expires_at", table_name="idempotency_keys", if_exists=True)
    op.drop_table("idempotency_keys", if_exists=True)
