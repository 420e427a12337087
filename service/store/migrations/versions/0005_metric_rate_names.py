"""The search curve's rate, one name for one meaning in stored metrics.

Searches recorded their best sequence's rate as the metric ``best_final_rate_rad_s``,
which meant two things: NSGA-II's was the residual rate once the actuation lag is empty
(the front's figure), the other searches' |ω| when the last command ends. Searches now
record ``best_residual_rate_rad_s`` for every method. The rows stored before are renamed
for what they hold: NSGA-II's to ``best_residual_rate_rad_s``, the others' to
``best_end_rate_rad_s``, so a job's metrics (JSON, CSV, dashboard) never carry the
ambiguous name. The results' own curves keep what they stored; the exports read both.

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-04
"""

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None

OLD = "best_final_rate_rad_s"
RESIDUAL = "best_residual_rate_rad_s"
END = "best_end_rate_rad_s"

_jobs = sa.table("jobs", sa.column("id", sa.String), sa.column("params", sa.JSON))
_metrics = sa.table("metrics", sa.column("job_id", sa.String), sa.column("key", sa.String))


def _method(connection: sa.Connection, job_id: str) -> object:
    """The search method in the job's parameters (JSON; read in Python, the same on
    SQLite and PostgreSQL), or None."""
    params = connection.execute(
        sa.select(_jobs.c.params).where(_jobs.c.id == job_id)
    ).scalar_one_or_none()
    return params.get("method") if isinstance(params, dict) else None


def _rename(connection: sa.Connection, job_id: str, old: str, new: str) -> None:
    connection.execute(
        _metrics.update().where(_metrics.c.job_id == job_id, _metrics.c.key == old).values(key=new)
    )


def _jobs_with(connection: sa.Connection, key: str) -> list[str]:
    query = sa.select(_metrics.c.job_id).where(_metrics.c.key == key).distinct()
    return list(connection.execute(query).scalars())


def upgrade() -> None:
    connection = op.get_bind()
    for job_id in _jobs_with(connection, OLD):
        new = RESIDUAL if _method(connection, job_id) == "nsga2" else END
        _rename(connection, job_id, OLD, new)


def downgrade() -> None:
    # The code before this revision read NSGA-II's residual rate under the old name, and
    # the other searches' end-of-command rate.
    connection = op.get_bind()
    for job_id in _jobs_with(connection, END):
        _rename(connection, job_id, END, OLD)
    for job_id in _jobs_with(connection, RESIDUAL):
        if _method(connection, job_id) == "nsga2":
            _rename(connection, job_id, RESIDUAL, OLD)
