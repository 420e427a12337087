"""Tables. The ``jobs`` table is the source of truth; Celery only delivers work."""

from __future__ import annotations

import uuid
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    false,
    text,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

__all__ = [
    "JOB_STATUSES",
    "JOB_TYPES",
    "MAX_IDEMPOTENCY_KEY_LENGTH",
    "MAX_NAME_LENGTH",
    "MAX_TAGS",
    "MAX_TAG_LENGTH",
    "REUSABLE_STATUSES",
    "REUSABLE_WHERE",
    "STOPPED_REASONS",
    "TERMINAL_STATUSES",
    "ApiKey",
    "Base",
    "ClassifierRow",
    "IdempotencyKeyRow",
    "JobRow",
    "JobTagRow",
    "MetricRow",
    "ScenarioRow",
    "WorkerRow",
    "new_id",
    "utcnow",
]

JOB_TYPES = ("search", "train", "sweep")
JOB_STATUSES = ("queued", "running", "succeeded", "failed", "cancelled")
TERMINAL_STATUSES = ("succeeded", "failed", "cancelled")
#: What may have stopped a finished job short of its own end (``JobRow.stopped``).
STOPPED_REASONS = ("time_limit",)
#: Statuses whose job may stand in for an identical new submission.
REUSABLE_STATUSES = ("queued", "running", "succeeded")
#: The rows of the unique index on reusable configurations.
REUSABLE_WHERE = "status IN ('queued', 'running', 'succeeded') AND NOT superseded"
#: Labels a person puts on a job: how many, how long.
MAX_TAGS = 16
MAX_TAG_LENGTH = 64
#: A job's name, for people; not part of its identity.
MAX_NAME_LENGTH = 200
#: The longest ``Idempotency-Key`` kept (Stripe's limit too).
MAX_IDEMPOTENCY_KEY_LENGTH = 255


def new_id() -> str:
    return uuid.uuid4().hex


def utcnow() -> datetime:
    return datetime.now(UTC)


class Base(DeclarativeBase):
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}  # noqa: RUF012


class ScenarioRow(Base):
    __tablename__ = "scenarios"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(200))
    document: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class JobRow(Base):
    __tablename__ = "jobs"
    __table_args__ = (
        Index("ix_jobs_status", "status"),
        Index("ix_jobs_config_hash", "config_hash"),
        Index("ix_jobs_scenario", "scenario_id"),
        # One reusable job per configuration: identical submissions racing each other
        # meet here, in the database, and all but one get the existing job back. A job
        # leaves the index by itself when it fails or is cancelled, or is superseded by
        # a rerun.
        Index(
            "ux_jobs_reusable_config",
            "config_hash",
            unique=True,
            sqlite_where=text(REUSABLE_WHERE),
            postgresql_where=text(REUSABLE_WHERE),
        ),
    )

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    type: Mapped[str] = mapped_column(String(16))
    status: Mapped[str] = mapped_column(String(16), default="queued")
    scenario_id: Mapped[str] = mapped_column(ForeignKey("scenarios.id", ondelete="RESTRICT"))
    params: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)
    seed: Mapped[int] = mapped_column(Integer, default=0)
    config_hash: Mapped[str] = mapped_column(String(64))
    #: A later rerun of the same configuration stands in for it now.
    superseded: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    error: Mapped[str | None] = mapped_column(Text, default=None)
    #: "time_limit" when the job's time limit stopped it (failed naming the limit, or
    #: succeeded with what it had then: a search's or sweep's result says ``stopped``);
    #: NULL otherwise. A cancel is the status's to say.
    stopped: Mapped[str | None] = mapped_column(String(16), default=None)
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, default=False)
    #: Runs started (each claim adds one; also the run's token, see ``finish``).
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    #: Runs handed back by a worker that was asked to stop (SIGTERM): they do not count
    #: against ``max_attempts``.
    handbacks: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    worker: Mapped[str | None] = mapped_column(String(200), default=None)
    #: The incarnation of ``worker`` (``workers.incarnation``) whose run claimed the job.
    worker_incarnation: Mapped[str | None] = mapped_column(String(32), default=None)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    heartbeat_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: When the job's message was last handed to the broker; NULL while it never was
    #: (the broker was down, or the API died between commit and send). Queued jobs whose
    #: message is missing are sent again by the workers' monitor (see ``worker.monitor``).
    sent_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: A person's name for the run and its tags (``job_tags``): labels only, never part
    #: of ``config_hash`` (an identical job under another name is the same work).
    name: Mapped[str | None] = mapped_column(String(MAX_NAME_LENGTH), default=None)
    #: The result's headline figures (``service.summaries``), written when the job
    #: finishes: what lists show and sort by.
    summary: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
    #: The runs that did not end the job themselves, oldest first: each a JSON object
    #: with the attempt, its worker, when it started and last beat, when and why it was
    #: lost or handed back, and what became of the job (``service.store.jobs``). The
    #: next claim overwrites ``started_at``, ``worker`` and ``error``; this keeps them.
    #: NULL on rows stored before it was kept.
    attempt_history: Mapped[list[Any] | None] = mapped_column(JSON, default=list)
    tag_rows: Mapped[list[JobTagRow]] = relationship(
        back_populates="job",
        cascade="all, delete-orphan",
        passive_deletes=True,
        lazy="selectin",
        order_by="JobTagRow.tag",
    )

    @property
    def tags(self) -> list[str]:
        return [row.tag for row in self.tag_rows]


class JobTagRow(Base):
    """One tag on one job; a job has each tag at most once."""

    __tablename__ = "job_tags"
    __table_args__ = (Index("ix_job_tags_tag", "tag"),)

    job_id: Mapped[str] = mapped_column(ForeignKey("jobs.id", ondelete="CASCADE"), primary_key=True)
    tag: Mapped[str] = mapped_column(String(MAX_TAG_LENGTH), primary_key=True)
    job: Mapped[JobRow] = relationship(back_populates="tag_rows")


class MetricRow(Base):
    __tablename__ = "metrics"
    __table_args__ = (Index("ix_metrics_job_key_step", "job_id", "key", "step"),)

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    job_id: Mapped[str] = mapped_column(ForeignKey("jobs.id", ondelete="CASCADE"))
    key: Mapped[str] = mapped_column(String(64))
    step: Mapped[int] = mapped_column(Integer)
    value: Mapped[float] = mapped_column(Float)


class ClassifierRow(Base):
    __tablename__ = "classifiers"

    id: Mapped[str] = mapped_column(String(32), primary_key=True, default=new_id)
    job_id: Mapped[str | None] = mapped_column(
        ForeignKey("jobs.id", ondelete="SET NULL"), default=None
    )
    scenario_id: Mapped[str] = mapped_column(ForeignKey("scenarios.id", ondelete="RESTRICT"))
    kind: Mapped[str] = mapped_column(String(64), default="clustering", server_default="clustering")
    metric: Mapped[str] = mapped_column(String(64))
    f1: Mapped[float] = mapped_column(Float)
    accuracy: Mapped[float] = mapped_column(Float)
    sequence: Mapped[list[Any]] = mapped_column(JSON)
    candidate_names: Mapped[list[Any]] = mapped_column(JSON)
    confusion: Mapped[list[Any]] = mapped_column(JSON)
    #: Loaded only where it is read (download, calibration, identify, the worker): a list
    #: or a GET of classifiers loaded every document whole, hundreds of MB for a 1-NN
    #: classifier of long series, on routes that need no key.
    document: Mapped[str] = mapped_column(Text, deferred=True)
    sha256: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class WorkerRow(Base):
    """A worker process seen alive: it upserts its row every heartbeat interval."""

    __tablename__ = "workers"

    name: Mapped[str] = mapped_column(String(200), primary_key=True)
    broker_url: Mapped[str] = mapped_column(String(500))
    started_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    last_seen_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    #: Set when the worker was told to stop: it claims no more jobs, and hands back any.
    stopping_since: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: The worker process that holds the name now: a new id each time a worker starts
    #: under it (``service.store.jobs.start_worker``). NULL on rows stored before.
    incarnation: Mapped[str | None] = mapped_column(String(32), default=None)
    #: Since when the worker has had no warm task process: it started (its first task
    #: process is importing the core), or its last one retired (after its jobs, or its
    #: memory limit) or was killed, and the replacement, started then, is importing the
    #: core (``worker.process.cold_since``). It takes no job meanwhile, and takes the
    #: queued ones once warm. NULL: warm. Written by the worker's main process.
    warming_since: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)
    #: Since when the worker has not held its incarnation lock (``worker.incarnation``):
    #: not taken at its start, or lost and not taken again. It claims no job meanwhile.
    #: NULL: held (or none is needed). Written by the worker's main process at each beat.
    lock_missing_since: Mapped[datetime | None] = mapped_column(
        DateTime(timezone=True), default=None
    )
    #: When another live process of this name (a twin, started under the same name by
    #: mistake) last beat: its beats leave the row (its state, its incarnation) to the
    #: process that beat it last, and set this. NULL: none seen.
    twin_seen_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), default=None)


class ApiKey(Base):
    __tablename__ = "api_keys"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class IdempotencyKeyRow(Base):
    """A POST sent with an ``Idempotency-Key``, and the answer it got.

    One row per client (the SHA-256 of its API key, as ``api_keys.key_hash``) and key:
    the first request with the key claims the row (``claim``), a second one at once
    finds it claimed (409), a later one with the same request gets ``answer_*`` back,
    and one with another request is refused (422). Kept until ``expires_at``.
    """

    __tablename__ = "idempotency_keys"
    __table_args__ = (Index("ix_idempotency_keys_expires_at", "expires_at"),)

    client: Mapped[str] = mapped_column(String(64), primary_key=True)
    key: Mapped[str] = mapped_column(String(MAX_IDEMPOTENCY_KEY_LENGTH), primary_key=True)
    #: The route the key was used on (``POST /jobs``), for the refusal of another use.
    route: Mapped[str] = mapped_column(String(200))
    #: SHA-256 of the route and the request's body as parsed (``service.store.idempotency``).
    fingerprint: Mapped[str] = mapped_column(String(64))
    #: The token of the request that holds the key: only it stores the answer or lets
    #: the key go.
    claim: Mapped[str] = mapped_column(String(32))
    claimed_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    #: The answer's status and JSON body; NULL while the request is in progress.
    answer_status: Mapped[int | None] = mapped_column(Integer, default=None)
    answer_body: Mapped[dict[str, Any] | None] = mapped_column(JSON, default=None)
