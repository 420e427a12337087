"""Jobs are delivered reliably and deduplicated by the database; classifier names fit.

- ``classifiers.metric`` and ``classifiers.kind`` widen to 64 characters: the default
  kind's metric, ``marginal-mahalanobis``, is 20 (PostgreSQL refused it in 16).
- ``jobs.superseded`` and a unique index on ``config_hash`` over the jobs that may stand
  in for an identical submission (queued, running or succeeded, not superseded by a
  rerun): two racing submissions cannot both insert. Of the existing reusable jobs of a
  configuration, all but the newest are marked superseded.
- ``jobs.sent_at``: when the job's message last went to the broker (a queued job whose
  message was lost is sent again). Existing rows count as sent when they were created.
- ``jobs.handbacks``: runs handed back by a stopping worker; they cost no attempt.
- ``workers.stopping_since``: a worker told to stop claims no more jobs.

Revision ID: 0003
Revises: 0002
Create Date: 2026-12-01
"""

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

_REUSABLE = ("queued", "running", "succeeded")
# As in service.store.models at this revision (a migration does not import the models it outlives).
REUSABLE_WHERE = "status IN ('queued', 'running', 'succeeded') AND NOT superseded"


def upgrade() -> None:
    with op.batch_alter_table("classifiers") as batch:
        batch.alter_column("metric", type_=sa.String(64), existing_nullable=False)
        batch.alter_column(
            "kind",
            type_=sa.String(64),
            existing_nullable=False,
            existing_server_default="clustering",
        )
    # Plain ALTER TABLE ADD COLUMN, not a batch: on SQLite the batch copied ``jobs`` into a
    # new table and dropped the old one, which (foreign keys on) deleted every job's
    # metrics and unlinked every classifier from its job; see downgrade().
    op.add_column(
        "jobs", sa.Column("superseded", sa.Boolean(), nullable=False, server_default=sa.false())
    )
    op.add_column("jobs", sa.Column("sent_at", sa.DateTime(timezone=True), nullable=True))
    op.add_column("jobs", sa.Column("handbacks", sa.Integer(), nullable=False, server_default="0"))
    op.add_column("workers", sa.Column("stopping_since", sa.DateTime(timezone=True), nullable=True))
    jobs = sa.table(
        "jobs",
        sa.column("id", sa.String),
        sa.column("status", sa.String),
        sa.column("config_hash", sa.String),
        sa.column("created_at", sa.DateTime(timezone=True)),
        sa.column("superseded", sa.Boolean),
        sa.column("sent_at", sa.DateTime(timezone=True)),
    )
    connection = op.get_bind()
    connection.execute(jobs.update().values(sent_at=jobs.c.created_at))
    rows = connection.execute(
        sa.select(jobs.c.id, jobs.c.config_hash)
        .where(jobs.c.status.in_(_REUSABLE))
        .order_by(jobs.c.created_at.desc(), jobs.c.id)
    ).all()
    seen: set[str] = set()
    for job_id, digest in rows:
        if digest in seen:
            connection.execute(jobs.update().where(jobs.c.id == job_id).values(superseded=True))
        seen.add(digest)
    op.create_index(
        "ux_jobs_reusable_config",
        "jobs",
        ["config_hash"],
        unique=True,
        sqlite_where=sa.text(REUSABLE_WHERE),
        postgresql_where=sa.text(REUSABLE_WHERE),
    )


def downgrade() -> None:
    op.drop_index("ux_jobs_reusable_config", table_name="jobs")
    # Plain ALTER TABLE, not a batch (as in 0004 and 0006): on SQLite a batch copies the
    # table into a new one and drops the old, and with foreign keys on (the store's
    # connections turn them on) dropping the old ``jobs`` deleted every job's metrics
    # (ON DELETE CASCADE) and unlinked every classifier from its job (ON DELETE SET
    # NULL). SQLite drops a column in place since 3.35, once no index names it (the
    # partial index above is dropped first).
    op.drop_column("workers", "stopping_since")
    op.drop_column("jobs", "handbacks")
    op.drop_column("jobs", "sent_at")
    op.drop_column("jobs", "superseded")
    with op.batch_alter_table("classifiers") as batch:
        batch.alter_column("kind", type_=sa.String(32), existing_nullable=False)
        batch.alter_column("metric", type_=sa.String(16), existing_nullable=False)
