"""Runs a person can name, tag and compare.

- ``jobs.name``: a person's name for the run (labels are not part of ``config_hash``).
- ``job_tags``: tags on jobs, one row per (job, tag), indexed by tag for filtering.
- ``jobs.summary``: the result's headline figures (fresh F1, residual rate, propellant,
  time; training F1; sweep accuracy), written when a job finishes; filled here for the
  jobs that already have a result.

Revision ID: 0004
Revises: 0003
Create Date: 2027-01-10
"""

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("jobs") as batch:
        batch.add_column(sa.Column("name", sa.String(200), nullable=True))
        batch.add_column(sa.Column("summary", sa.JSON(), nullable=True))
    op.create_table(
        "job_tags",
        sa.Column(
            "job_id",
            sa.String(32),
            sa.ForeignKey("jobs.id", ondelete="CASCADE"),
            primary_key=True,
        ),
        sa.Column("tag", sa.String(64), primary_key=True),
    )
    op.create_index("ix_job_tags_tag", "job_tags", ["tag"])
    # Summaries of the results stored before: the same pure function the store uses when
    # a job finishes (it only reads result dictionaries).
    from service.summaries import summarise

    jobs = sa.table(
        "jobs",
        sa.column("id", sa.String),
        sa.column("type", sa.String),
        sa.column("result", sa.JSON),
        sa.column("summary", sa.JSON),
    )
    connection = op.get_bind()
    rows = connection.execute(
        sa.select(jobs.c.id, jobs.c.type, jobs.c.result).where(jobs.c.result.is_not(None))
    ).all()
    for job_id, job_type, result in rows:
        connection.execute(
            jobs.update().where(jobs.c.id == job_id).values(summary=summarise(job_type, result))
        )


def downgrade() -> None:
    op.drop_index("ix_job_tags_tag", table_name="job_tags")
    op.drop_table("job_tags")
    # Plain ALTER TABLE, not a batch (as in 0006): on SQLite a batch copies ``jobs`` into
    # a new table and drops the old one, and with foreign keys on (the store's connections
    # turn them on) that drop deleted every job's metrics (ON DELETE CASCADE) and unlinked
    # every classifier from its job (ON DELETE SET NULL). SQLite drops a column in place
    # since 3.35.
    op.drop_column("jobs", "summary")
    op.drop_column("jobs", "name")
