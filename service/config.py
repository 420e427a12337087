"""Service settings, from the environment (pydantic-settings).

The embedded default needs nothing installed: a SQLite file and Celery's filesystem
broker, both under ``INERTIA_ID_DATA_DIR``. Scale-out is configuration only:
``DATABASE_URL=postgresql+psycopg://...`` and ``BROKER_URL=redis://...``.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from inertia_id.deadline import TIME_LIMIT_MIN_S

__all__ = [
    "LONGEST_S",
    "LOOPBACK_HOSTS",
    "MAX_COMPUTE_QUEUE",
    "MAX_COMPUTE_THREADS",
    "Settings",
    "get_settings",
    "setting_problems",
    "settings_or_exit",
]

#: The longest any duration setting may be, s: a year. Longer is a typo (a value in ms,
#: a stray exponent), and past about 1e10 s the waits and clock arithmetic they feed
#: (``threading.Event.wait``, ``now - timedelta(...)``) raise OverflowError at run time
#: instead of at start.
LONGEST_S = 365 * 86400.0

#: Most compute threads the API process may have (``INERTIA_ID_COMPUTE_THREADS``): more
#: than the cores of any machine it runs on, where one thread already serves best (a
#: verdict holds the GIL). Unbounded, 10**9 was accepted and made the gate no gate: every
#: request in flight took an OS thread of its own (1,000 at once: 1,001 threads, none
#: answered 503), bounded by nothing but the system's thread limit.
MAX_COMPUTE_THREADS = 256

#: Most requests ``INERTIA_ID_COMPUTE_QUEUE`` lets wait for a compute thread. Each waiter
#: holds its connection and its request body (up to ``INERTIA_ID_MAX_BODY_BYTES``, 5 MB
#: by default): 10,000 of them is already 50 GB at the default body limit and ten times
#: the usual 1,024 open files of a process, so a longer queue only moves the failure from
#: a 503 with Retry-After to memory or file descriptors running out.
MAX_COMPUTE_QUEUE = 10_000

#: Host header names the API always answers to: those of this machine's loopback.
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1", "[::1]")


class Settings(BaseSettings):
    """Every knob of the service; each can be set by an environment variable."""

    model_config = SettingsConfigDict(extra="ignore", populate_by_name=True)

    data_dir: Path = Field(default=Path("inertia-id-data"), alias="INERTIA_ID_DATA_DIR")
    database_url: str | None = Field(default=None, alias="DATABASE_URL")
    broker_url: str = Field(default="filesystem://", alias="BROKER_URL")
    api_key: str | None = Field(default=None, alias="INERTIA_ID_API_KEY")
    host: str = Field(default="127.0.0.1", alias="INERTIA_ID_HOST")
    port: int = Field(default=8000, ge=1, le=65535, alias="INERTIA_ID_PORT")
    max_body_bytes: int = Field(default=5_000_000, ge=1, alias="INERTIA_ID_MAX_BODY_BYTES")
    max_page_size: int = Field(default=200, ge=1, alias="INERTIA_ID_MAX_PAGE_SIZE")
    #: How long a POST's ``Idempotency-Key`` and its answer are kept: a retry within this
    #: gets the first answer back, a later one is a new request. 24 h: Stripe's.
    idempotency_key_ttl_s: float = Field(
        default=86_400.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_IDEMPOTENCY_KEY_TTL_S",
    )
    #: A connection whose request head is not complete this long after it opened, or
    #: after the previous response on it, is closed (slow clients, ``slowloris``; uvicorn
    #: has no such timeout: ``app.request_deadlines``). 10 s: a head is one packet or a
    #: few, sent at once by any real client.
    request_head_timeout_s: float = Field(
        default=10.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_REQUEST_HEAD_TIMEOUT_S",
    )
    #: A request head with more header fields than this, or more bytes (its target and
    #: header fields) is answered 431, a request target alone over the byte limit 414, and
    #: the connection closed (``app.request_deadlines``;
    #: uvicorn's httptools has no limit at all, its h11 only 16 KiB on a head still
    #: incomplete). 100 fields: gunicorn's ``limit_request_fields`` and Apache's
    #: ``LimitRequestFields`` (both 100 by default); 16 KiB: uvicorn's own
    #: ``h11_max_incomplete_event_size``, between gunicorn's 8,190 bytes a field and
    #: nginx's 32 KiB a head (``large_client_header_buffers 4 8k``). A browser's request
    #: to the API or the dashboard has about 15 fields and 1-2 KB.
    request_header_max_count: int = Field(
        default=100, ge=1, alias="INERTIA_ID_REQUEST_HEADER_MAX_COUNT"
    )
    request_header_max_bytes: int = Field(
        default=16_384, ge=1024, alias="INERTIA_ID_REQUEST_HEADER_MAX_BYTES"
    )
    #: A connection whose request body brings less than 1 KiB (and does not end) in this
    #: long: a slow but steady upload is never cut, a byte every few seconds is.
    request_body_timeout_s: float = Field(
        default=20.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_REQUEST_BODY_TIMEOUT_S",
    )
    #: A downsampled metric series keeps its first and last points: at least 2.
    max_metric_points: int = Field(default=2000, ge=2, alias="INERTIA_ID_MAX_METRIC_POINTS")
    #: A running job's heartbeat, and each worker's beat, reaper and re-sender, every
    #: this many seconds; at most half the timeout (checked below).
    heartbeat_interval_s: float = Field(
        default=5.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_HEARTBEAT_INTERVAL_S",
    )
    heartbeat_timeout_s: float = Field(
        default=60.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_HEARTBEAT_TIMEOUT_S",
    )
    max_attempts: int = Field(default=2, ge=1, alias="INERTIA_ID_MAX_ATTEMPTS")
    #: A queued job never sent this long after its creation is sent by a worker.
    unsent_grace_s: float = Field(
        default=10.0, gt=0, le=LONGEST_S, allow_inf_nan=False, alias="INERTIA_ID_UNSENT_GRACE_S"
    )
    #: A queued job whose message went out this long ago while a worker sat idle lost
    #: its message (a live idle worker takes a message within a poll): it is sent again.
    resend_after_s: float = Field(
        default=30.0, gt=0, le=LONGEST_S, allow_inf_nan=False, alias="INERTIA_ID_RESEND_AFTER_S"
    )
    worker_max_jobs_per_process: int = Field(default=100, ge=1, alias="INERTIA_ID_WORKER_MAX_JOBS")
    worker_max_memory_mb: int = Field(default=4096, ge=1, alias="INERTIA_ID_WORKER_MAX_MEMORY_MB")
    #: How long a worker waits for a new task process to warm up (import the core,
    #: compile the kernels) and report in before it kills it and starts another. Celery's
    #: own 4 s is shorter than the warm-up (7-9 s on an idle machine, 38 s measured under
    #: load), so every replacement was killed in turn and the worker never ran another job.
    worker_start_timeout_s: float = Field(
        default=300.0,
        gt=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_WORKER_START_TIMEOUT_S",
    )
    #: /health is "degraded" when a queued job has waited this long while a live worker
    #: sat idle: twice the re-sender's wait for a lost message, plus a task process's
    #: warm-up under load, and then some.
    queue_stall_s: float = Field(
        default=120.0, gt=0, le=LONGEST_S, allow_inf_nan=False, alias="INERTIA_ID_QUEUE_STALL_S"
    )
    #: Classifiers kept loaded (0: none, each verdict loads its own).
    classifier_cache_size: int = Field(default=32, ge=0, alias="INERTIA_ID_CLASSIFIER_CACHE")
    #: CPU work in the API process (identify, response simulation): threads of its own,
    #: and how many requests may wait for one, and for how long, before a 503.
    #: One thread by default: a verdict is small numpy work that holds the GIL most of
    #: the time, so a second thread in the same process only adds GIL hand-offs (20
    #: clients on one API process: 160 req/s with two threads, 215 with one). Scale with
    #: --api-workers instead. At most :data:`MAX_COMPUTE_THREADS`.
    compute_threads: int = Field(
        default=1, ge=1, le=MAX_COMPUTE_THREADS, alias="INERTIA_ID_COMPUTE_THREADS"
    )
    #: Requests allowed to wait for a compute thread; one more is a 503. At most
    #: :data:`MAX_COMPUTE_QUEUE`.
    compute_queue: int = Field(
        default=200, ge=0, le=MAX_COMPUTE_QUEUE, alias="INERTIA_ID_COMPUTE_QUEUE"
    )
    #: Where /identify computes: "eager" (a process of its own, started with the API),
    #: "lazy" (the same, started by the first identify), "off" (the compute threads).
    verdict_process: Literal["eager", "lazy", "off"] = Field(
        default="eager", alias="INERTIA_ID_VERDICT_PROCESS"
    )
    compute_wait_s: float = Field(
        default=10.0, gt=0, le=LONGEST_S, allow_inf_nan=False, alias="INERTIA_ID_COMPUTE_WAIT_S"
    )
    #: Longest a verdict may take in the verdict process (a cold classifier's load
    #: included) before the process is killed, replaced and the request answered 503.
    verdict_timeout_s: float = Field(
        default=30.0, gt=0, le=LONGEST_S, allow_inf_nan=False, alias="INERTIA_ID_VERDICT_TIMEOUT_S"
    )
    #: Longest a statement of the API (a query, a commit, the pool's ping; PostgreSQL)
    #: may wait for the database's answer before its connection is cut and the request
    #: answered 503 (``the database cannot be reached``, Retry-After): a proxy that
    #: acknowledges for a server that does not answer (frozen) held the request for
    #: ever, as no network bound fires there. A server that answers within it, however
    #: slowly, is never cut (a 12 s statement answered under the 30 s default), nor one
    #: past it that the server says it is at work on (a lock wait, a long query). At
    #: least 1 s: below, every statement was cut (50 of 50 at 1 ms), as the pool's ping
    #: and the server's own answer to "are you at work on it" take longer.
    database_answer_timeout_s: float = Field(
        default=30.0,
        ge=1.0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S",
    )
    #: Host header values accepted besides the loopback names (127.0.0.1, localhost,
    #: ::1, [::1]) and INERTIA_ID_HOST when it names one address; comma-separated.
    #: "*" accepts any (behind a proxy that checks it).
    allowed_hosts: str = Field(default="", alias="INERTIA_ID_ALLOWED_HOSTS")
    frontend_dir: Path | None = Field(default=None, alias="INERTIA_ID_FRONTEND_DIR")
    #: The ceiling on every job's run time, s; a job may ask for less (``time_limit_s``),
    #: never more. 6 h: a working day's share of a worker. The paper's PPO search (20,480
    #: steps, 20 realisations, L = 4) and the largest sweeps take minutes, so this leaves
    #: room for searches a hundred times larger, while a runaway (an exhaustive search of
    #: 1e9 sequences runs for weeks) frees its worker the same day. At least a second, as
    #: a job's own ``time_limit_s`` (:data:`~inertia_id.deadline.TIME_LIMIT_MIN_S`).
    job_time_limit_s: float = Field(
        default=6 * 3600.0,
        ge=TIME_LIMIT_MIN_S,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_JOB_TIME_LIMIT_S",
    )

    #: How long a finished run keeps an outcome the database refuses to store (a full
    #: disk, a read-only database), trying it every heartbeat interval, before the job
    #: fails with the refusal named. An hour: time for an operator to free the disk,
    #: while a result too large for the room left does not hold its worker for ever.
    outcome_refused_wait_s: float = Field(
        default=3600.0,
        ge=0,
        le=LONGEST_S,
        allow_inf_nan=False,
        alias="INERTIA_ID_OUTCOME_REFUSED_WAIT_S",
    )

    @field_validator("allowed_hosts")
    @classmethod
    def _host_names_only(cls, value: str) -> str:
        # The Host header is compared without its port, so "api:8000" (or a URL) would be
        # accepted here and then match no request: every one a 400. Refused at start.
        for entry in (h.strip() for h in value.split(",")):
            if re.fullmatch(r"(\[[^\]]*\]|[^:\[\]]+):\d*", entry) or re.search(r"[/@]", entry):
                raise ValueError(
                    f"{entry!r} is not a host name: write the name alone, without a scheme, "
                    "path or port (the port is not compared), e.g. "
                    f"{_bare_host(entry)!r}"
                )
        return value

    @model_validator(mode="after")
    def _heartbeat_within_timeout(self) -> Settings:
        # The reaper takes a job whose last beat is older than the timeout. With the
        # interval merely shorter (59 s beats, a 60 s timeout) one beat late by a second
        # (a busy machine, a slow commit) or lost got a live job reaped; two beats a
        # timeout at least leave one to miss.
        if self.heartbeat_interval_s > self.heartbeat_timeout_s / 2:
            raise ValueError(
                f"INERTIA_ID_HEARTBEAT_INTERVAL_S={self.heartbeat_interval_s:g} must be at "
                f"most half INERTIA_ID_HEARTBEAT_TIMEOUT_S={self.heartbeat_timeout_s:g} (at "
                f"most {self.heartbeat_timeout_s / 2:g} s): with fewer than two heartbeats "
                "a timeout, one late or lost beat gets a running job reaped"
            )
        return self

    @model_validator(mode="after")
    def _stall_after_resend(self) -> Settings:
        # /health calls the queue stalled after queue_stall_s with a worker idle; the
        # re-sender sends a lost message again after resend_after_s. Shorter, the health
        # said "degraded" about a queue the re-sender had not yet had its turn to mend.
        if self.queue_stall_s <= self.resend_after_s:
            raise ValueError(
                f"INERTIA_ID_QUEUE_STALL_S={self.queue_stall_s:g} must be longer than "
                f"INERTIA_ID_RESEND_AFTER_S={self.resend_after_s:g}: /health would call the "
                "queue stalled before a lost message is sent again"
            )
        return self

    @property
    def resolved_database_url(self) -> str:
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'inertia-id.db').resolve()}"

    @property
    def resolved_frontend_dir(self) -> Path:
        """The dashboard's files: ``INERTIA_ID_FRONTEND_DIR``, else the checkout's ``frontend/``."""
        if self.frontend_dir is not None:
            return self.frontend_dir.resolve()
        return Path(__file__).resolve().parent.parent / "frontend"

    @property
    def resolved_allowed_hosts(self) -> list[str]:
        """Host header values the API accepts (the port is not part of them): the
        loopback names, INERTIA_ID_HOST when it names one address, and those of
        INERTIA_ID_ALLOWED_HOSTS. The setting adds to the loopback names rather than
        replacing them, as its 400 says ("set INERTIA_ID_ALLOWED_HOSTS to add one"): a
        deployment that named only its public host refused its own healthcheck's
        ``Host: 127.0.0.1``."""
        configured = [h.strip() for h in self.allowed_hosts.split(",") if h.strip()]
        if "*" in configured:
            return ["*"]
        if not configured and self.host in ("0.0.0.0", "::", ""):
            # Bound to every address with no names configured: the names it will be
            # reached by are unknown here (serve warns about it).
            return ["*"]
        hosts = list(LOOPBACK_HOSTS)
        wildcard = self.host in ("0.0.0.0", "::", "")
        for name in ([] if wildcard else [self.host]) + configured:
            if name.lower() not in hosts:
                hosts.append(name.lower())
        return hosts

    @property
    def broker_dir(self) -> Path:
        """Folder of the filesystem broker's messages (embedded default)."""
        return (self.data_dir / "broker").resolve()


def _bare_host(entry: str) -> str:
    """The host name in ``entry`` ("https://api:8000/x" -> "api"), for the message that
    refuses it."""
    rest = entry.split("://", 1)[-1].split("/", 1)[0].rsplit("@", 1)[-1]
    if rest.startswith("["):
        return rest.split("]", 1)[0] + "]"
    return rest.split(":", 1)[0]


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    return Settings()


def setting_problems(error: ValidationError) -> list[str]:
    """One line per bad setting: ``NAME='value': why``, or the rule broken by two
    settings together (which names both and their values)."""
    lines = []
    for problem in error.errors(include_url=False):
        name = ".".join(str(part) for part in problem["loc"])
        reason = problem["msg"]
        if problem["type"] == "value_error":
            # pydantic's "Value error, " before our own message adds nothing.
            reason = str(problem.get("ctx", {}).get("error", reason))
        lines.append(f"{name}={problem.get('input')!r}: {reason}" if name else reason)
    return lines


def settings_or_exit(program: str) -> Settings:
    """:func:`get_settings`, or ``SystemExit`` with one line per bad setting, each
    starting with ``program:``: the worker's and the API's start (``celery -A
    worker.celery_app``, ``uvicorn app.main:create_app --factory``) end with status 1
    and those lines rather than a pydantic traceback; so does a ``DATABASE_URL`` that is
    no URL or of a kind with no driver here, rather than SQLAlchemy's."""
    try:
        settings = get_settings()
    except ValidationError as exc:
        lines = [f"{program}: {line}" for line in setting_problems(exc)]
        raise SystemExit("\n".join(lines)) from None
    from service.store.refusals import unusable_database

    problem = unusable_database(settings.resolved_database_url)
    if problem:
        raise SystemExit(f"{program}: {problem}")
    return settings
