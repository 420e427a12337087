"""Request and response bodies of the REST API (pydantic v2): HTTP models only.

The job parameter models, the contract with the workers, live in :mod:`service.params`;
the job submission bodies here wrap them.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Annotated, Any, Literal, Self

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    StringConstraints,
    computed_field,
    field_validator,
    model_validator,
)

from inertia_id.checks import BIDI_CONTROLS, finite_or_none
from inertia_id.evaluation.telemetry import (
    MAX_TELEMETRY_SAMPLES,
    MIN_COVERED_FRACTION,
    Telemetry,
    same_sequence_start,
)
from inertia_id.physics.presets import PRESETS
from inertia_id.physics.scenario import Scenario
from service.params import (
    MAX_SEED,
    SearchParams,
    StrictModel,
    SweepParams,
    TrainParams,
)
from service.store.models import MAX_NAME_LENGTH, MAX_TAG_LENGTH, MAX_TAGS, utcnow

__all__ = [
    "MAX_SEED",
    "CandidateOut",
    "CandidateResponse",
    "ClassifierOut",
    "ClassifierPage",
    "ClassifierProvenance",
    "ComponentHealth",
    "DatabaseHealth",
    "HealthOut",
    "IdentifyRequest",
    "IdentifyResult",
    "JobCreate",
    "JobListInclude",
    "JobListed",
    "JobOut",
    "JobPage",
    "JobSubmitted",
    "JobUpdate",
    "JudgingClassifier",
    "LostAttempt",
    "MetricSeries",
    "MetricsOut",
    "PartialIdentifyResult",
    "ScenarioCreate",
    "ScenarioOut",
    "ScenarioPage",
    "ScenarioResponse",
    "SearchJobCreate",
    "SearchParams",
    "SweepJobCreate",
    "SweepParams",
    "TagText",
    "TelemetryGapResult",
    "TrainJobCreate",
    "TrainParams",
    "WorkersHealth",
    "finite_or_none",
]

# Larger integers are no sensible parameter (and overflow the core's float conversions).
_MAX_INT = 2**53
# The core's limit on duty levels (Thrusters.levels: 2 to 101 values).
_MAX_LEVELS = 101


def _clip(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


JobType = Literal["search", "train", "sweep"]
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
#: What may have stopped a finished job short of its own end (STOPPED_REASONS).
JobStopped = Literal["time_limit"]
_TERMINAL = ("succeeded", "failed", "cancelled")


def as_utc(value: datetime) -> datetime:
    """SQLite hands back naive datetimes; every stored time is UTC."""
    if value.tzinfo is None:
        return value.replace(tzinfo=UTC)
    return value.astimezone(UTC)


UtcDatetime = Annotated[datetime, AfterValidator(as_utc)]


_Request = StrictModel


# Scenarios.


class ScenarioCreate(_Request):
    """A scenario from a preset with top-level overrides, or a full scenario document.

    Give ``preset`` (and optionally ``overrides``, merged into the preset section by
    section, e.g. ``{"uncertainty": {"gyro_noise_sigma_rad_s": 0.002}}``), or
    ``scenario``, not both.
    """

    preset: str | None = Field(
        default=None,
        max_length=100,
        description=f"name of a preset scenario: one of {sorted(PRESETS)}",
        examples=["paper"],
    )
    overrides: dict[str, Any] = Field(
        default_factory=dict,
        description="top-level Scenario fields merged into the preset",
        examples=[{"name": "paper, noisy gyro", "uncertainty": {"gyro_noise_sigma_rad_s": 0.002}}],
    )
    scenario: Scenario | None = Field(default=None, description="a full scenario document")

    @model_validator(mode="before")
    @classmethod
    def _thrusters_before_expansion(cls, data: Any) -> Any:
        # The core expands n_levels with numpy.linspace before it checks the count, and
        # float(nominal_torque_nm) overflows on a huge integer: check both first, so that
        # {"n_levels": 10**9} cannot make the API allocate gigabytes.
        if not isinstance(data, dict):
            return data
        for source in ("overrides", "scenario"):
            section = data.get(source)
            thrusters = section.get("thrusters") if isinstance(section, dict) else None
            if not isinstance(thrusters, dict):
                continue
            n_levels = thrusters.get("n_levels")
            if isinstance(n_levels, int) and not 2 <= n_levels <= _MAX_LEVELS:
                raise ValueError(
                    f"{source}.thrusters.n_levels must be 2 to {_MAX_LEVELS}, "
                    f"got {_clip(repr(n_levels))}"
                )
            nominal = thrusters.get("nominal_torque_nm")
            if isinstance(nominal, int) and abs(nominal) > _MAX_INT:
                raise ValueError(
                    f"{source}.thrusters.nominal_torque_nm is out of range, "
                    f"got {_clip(repr(nominal))}"
                )
        return data

    @model_validator(mode="after")
    def _one_source(self) -> Self:
        if (self.preset is None) == (self.scenario is None):
            raise ValueError("give exactly one of preset (with optional overrides) or scenario")
        if self.scenario is not None and self.overrides:
            raise ValueError("overrides apply to a preset; put the values in the scenario instead")
        if self.preset is not None and self.preset not in PRESETS:
            raise ValueError(f"unknown preset {self.preset!r}; known: {sorted(PRESETS)}")
        return self


class PlanRequest(_Request):
    """A sequence to plan, in the body (``POST /scenarios/{id}/plan``): the same plan as
    the GET with ``?sequence=``, for a sequence too long for a URL."""

    sequence: list[list[int]] = Field(
        min_length=1,
        description="steps, each a level index per thruster: [[4,4,4,0,0,0], ...]",
    )


class CandidateOut(BaseModel):
    name: str
    inertia_kg_m2: list[list[float]]
    principal_moments_kg_m2: list[float] = Field(description="ascending, kg m^2")


class ScenarioOut(BaseModel):
    id: str
    name: str
    created_at: UtcDatetime
    n_thrusters: int
    n_levels: int
    candidates: list[CandidateOut]
    document: dict[str, Any] = Field(description="the validated Scenario document")
    warnings: list[str] = Field(
        default_factory=list,
        description="what the service found doubtful in the scenario but did not refuse: "
        "a thruster that gives no torque (a zero column of torque_matrix_nm, its thrust "
        "through the centre of mass), named by its number from 1",
    )


class ScenarioPage(BaseModel):
    items: list[ScenarioOut]
    total: int
    limit: int
    offset: int


class CandidateResponse(BaseModel):
    name: str
    mean_rad_s: list[list[float]] = Field(description="mean measured rate per sample, (T, 3)")
    low_rad_s: list[list[float]] = Field(description="10th percentile over realisations, (T, 3)")
    high_rad_s: list[list[float]] = Field(description="90th percentile over realisations, (T, 3)")
    final_rate_rad_s: float = Field(
        description="mean true |omega| over the realisations at the last sample, when the "
        "last command ends, rad/s: before the torque still in the actuation lag is "
        "delivered, not the residual rate once the lag is empty"
    )


class ScenarioResponse(BaseModel):
    """Every candidate's simulated gyro response to one sequence (what the dashboard draws)."""

    scenario_id: str
    sequence: list[list[int]]
    duties: list[list[float]] = Field(description="commanded duty per step and thruster, (L, N)")
    step_duration_s: float
    time_s: list[float] = Field(description="sample times from the sequence start, s")
    n_realisations: int
    seed: int
    impulse_nms: float = Field(description="commanded angular impulse (fuel), N m s")
    candidates: list[CandidateResponse]
    warnings: list[str] = Field(
        default_factory=list,
        description="what the service found doubtful but did not refuse, as a plan's and a "
        "training's warnings: a sequence whose nominal prediction peaks at least 100 times "
        "below the gyro's white noise (its responses are noise to a classifier); empty when "
        "nothing is doubtful",
    )


def _printable(value: str) -> str:
    """A name or tag without bidirectional controls (the pattern refuses the other
    control characters): ``run\u202egnp.exe`` would show as ``runexe.png``."""
    found = sorted({f"U+{ord(c):04X}" for c in value if c in BIDI_CONTROLS})
    if found:
        raise ValueError(
            f"{value!r} holds bidirectional control characters ({', '.join(found)}), which "
            "show text in another order than it is written; remove them"
        )
    return value


def _check_name(value: str | None) -> str | None:
    """The name without surrounding spaces; an empty one is no name."""
    return (value.strip() or None) if value is not None else None


def _check_tags(values: list[str] | None) -> list[str] | None:
    """The tags without surrounding spaces, each once, in the order given."""
    return None if values is None else list(dict.fromkeys(tag.strip() for tag in values))


def _without_controls(value: Any) -> Any:
    """A name or tag's control characters refused in words: the pattern's own message
    ("String should match pattern '^[^\\x00-\\x1f\\x7f]*$'") named no character."""
    if isinstance(value, str):
        found = sorted({f"U+{ord(c):04X}" for c in value if ord(c) < 0x20 or ord(c) == 0x7F})
        if found:
            raise ValueError(
                f"{value!r} holds control characters ({', '.join(found)}); remove them"
            )
    return value


def _readable_tag(value: Any) -> Any:
    """A tag's comma or blankness refused in words, before the pattern (which the
    OpenAPI document keeps) would answer with the regular expression itself."""
    if isinstance(value, str):
        _without_controls(value.lstrip())  # leading white space is dropped, tabs and all
    if isinstance(value, str) and value:
        if "," in value:
            raise ValueError(f"{value!r} holds a comma, which separates tags: send it as two")
        if not value.strip():
            raise ValueError(f"{value!r} is blank: a tag needs a character other than a space")
    return value


#: A tag as a request carries it: 1 to 64 characters with at least one that is not a space,
#: no commas or control characters (surrounding spaces are dropped).
TagText = Annotated[
    str,
    StringConstraints(
        min_length=1,
        max_length=MAX_TAG_LENGTH,
        pattern=r"^\s*[^\s,\x00-\x1f\x7f][^,\x00-\x1f\x7f]*$",
    ),
    BeforeValidator(_readable_tag),
    AfterValidator(_printable),
]
NameText = Annotated[
    str,
    StringConstraints(max_length=MAX_NAME_LENGTH, pattern=r"^[^\x00-\x1f\x7f]*$"),
    BeforeValidator(_without_controls),
    AfterValidator(_printable),
]


class _Labels(_Request):
    name: Annotated[
        NameText | None,
        Field(
            default=None,
            description=f"a name for people (at most {MAX_NAME_LENGTH} characters); not part "
            "of the job's identity",
            examples=["PPO, paper preset, fuel-weighted"],
        ),
    ]
    tags: Annotated[
        list[TagText] | None,
        Field(
            default=None,
            max_length=MAX_TAGS,
            description=f"labels to filter by (at most {MAX_TAGS}, each 1 to "
            f"{MAX_TAG_LENGTH} characters, no commas); not part of the job's identity",
            examples=[["baseline", "flight-2"]],
        ),
    ]

    @field_validator("name", mode="after")
    @classmethod
    def _name(cls, value: str | None) -> str | None:
        return _check_name(value)

    @field_validator("tags", mode="after")
    @classmethod
    def _tags(cls, value: list[str] | None) -> list[str] | None:
        return _check_tags(value)


class _JobCreate(_Labels):
    scenario_id: str = Field(max_length=64)
    seed: int = Field(default=0, ge=0, le=MAX_SEED)
    rerun: bool = Field(
        default=False,
        description="run again even if the same job succeeded: a new job takes its place. "
        "While an identical job is queued or running (not asked to stop) that job is "
        'returned instead (200, `"reused": true`; same seed, same result), so identical '
        "reruns sent at once or while their job waits or runs make one new job. To run "
        "an unfinished job again, cancel it first or name it in `rerun_of`",
    )
    rerun_of: str | None = Field(
        default=None,
        min_length=1,
        max_length=64,
        description="the id of the job this submission reruns (implies `rerun`; a job of "
        "the same type, scenario, params and seed, else a 422): a new job is made only "
        "while that job still stands for the configuration, or none does; once another "
        "stands in its place (an identical rerun's, sent at once or earlier) that one is "
        'returned (200, `"reused": true`), so sending the same rerun again makes no '
        "second job",
        examples=["5f0c3a9e2b7d4e61a8c9d0f1e2a3b4c5"],
    )


class JobUpdate(_Labels):
    """New labels for a job: a field given replaces the old value (``"name": null``
    clears the name, ``"tags": []`` removes every tag); a field left out is kept."""


class SearchJobCreate(_JobCreate):
    type: Literal["search"]
    params: SearchParams = Field(default_factory=SearchParams)


class TrainJobCreate(_JobCreate):
    type: Literal["train"]
    params: TrainParams


class SweepJobCreate(_JobCreate):
    type: Literal["sweep"]
    params: SweepParams


JobCreate = Annotated[
    SearchJobCreate | TrainJobCreate | SweepJobCreate, Field(discriminator="type")
]


class LostAttempt(BaseModel):
    """A run taken from its job before it ended it: its worker died, its heartbeat
    stopped, or its worker was told to stop and handed the job back."""

    attempt: int = Field(description="the run's number (1 = the first run)")
    worker: str | None = Field(description="the worker that ran it, when known")
    started_at: UtcDatetime | None = Field(description="when the run claimed the job")
    last_heartbeat_at: UtcDatetime | None = Field(
        default=None, description="the run's last heartbeat"
    )
    ended_at: UtcDatetime = Field(description="when it was declared lost or handed back")
    outcome: str = Field(description="lost, or handed back (costs no attempt)")
    cause: str = Field(
        description="worker lost, heartbeat missed, asked to stop, or how the run's task "
        "process died (task process killed by signal 9 (SIGKILL))"
    )
    reason: str = Field(description="the cause in words, with the times it rests on")
    then: str = Field(description="what became of the job: re-queued, failed or cancelled")


class JobOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: str
    type: str
    status: str
    scenario_id: str
    params: dict[str, Any]
    seed: int
    config_hash: str
    progress: float = Field(description="fraction done, 0 to 1")
    error: str | None
    stopped: JobStopped | None = Field(
        default=None,
        description="time_limit: the job's time limit stopped it (a training, or a sweep "
        "before its first point, failed naming it; a search or sweep succeeded with what "
        "it had, as its result's stopped says); null: it ran to its own end, failed "
        "otherwise, or was cancelled (the status says so)",
    )
    result: dict[str, Any] | None = Field(description="summary written by the worker")
    cancel_requested: bool
    attempts: int = Field(
        description="runs started, hand-backs included (see handbacks and counted_attempts)"
    )
    handbacks: int = Field(
        default=0,
        description="runs handed back to the queue by a stopping worker, through no fault "
        "of the job's: not counted against INERTIA_ID_MAX_ATTEMPTS",
    )
    worker: str | None
    created_at: UtcDatetime
    started_at: UtcDatetime | None
    finished_at: UtcDatetime | None
    heartbeat_at: UtcDatetime | None
    sent_at: UtcDatetime | None = Field(
        default=None,
        description="when the job's message last went to the broker; null while it waits "
        "to be sent (the broker was unreachable)",
    )
    name: str | None = Field(default=None, description="a person's name for the run")
    tags: list[str] = Field(default_factory=list)
    summary: dict[str, float | None] | None = Field(
        default=None,
        description="the result's headline figures (keys: GET /vocabulary job_summaries)",
    )
    attempt_history: list[LostAttempt] = Field(
        default_factory=list,
        description="the earlier runs that did not end the job, oldest first: when each "
        "started, when and why it was lost or handed back, its worker; the current run's "
        "started_at and worker overwrite theirs (empty for jobs stored before it was kept)",
    )

    @field_validator("params", "result", "summary", mode="after")
    @classmethod
    def _finite(cls, value: Any) -> Any:
        return finite_or_none(value)

    @field_validator("attempt_history", mode="before")
    @classmethod
    def _no_history_kept(cls, value: Any) -> Any:
        return [] if value is None else value

    @computed_field(
        description="runs that count against INERTIA_ID_MAX_ATTEMPTS: attempts less handbacks "
        "(the run under way, the one that ended the job, and those lost to a dead or hung "
        "task process or worker); the job fails for good when a run is lost at the limit"
    )
    def counted_attempts(self) -> int:
        # attempts alone read like failed tries: 6 after 5 worker restarts that each
        # handed the run back, though none of those counted.
        return max(0, self.attempts - self.handbacks)

    @computed_field(description="s from submission to the start of its last run (or to now)")
    def queue_time_s(self) -> float:
        end = self.started_at or (self.finished_at if self.status in _TERMINAL else None)
        return max(0.0, ((end or utcnow()) - self.created_at).total_seconds())

    @computed_field(description="s the last run took (so far, while it runs); null before")
    def run_time_s(self) -> float | None:
        if self.started_at is None:
            return None
        end = self.finished_at or utcnow()
        return max(0.0, (end - self.started_at).total_seconds())


class JobSubmitted(JobOut):
    reused: bool = Field(
        description="true: an identical job (same scenario, parameters and seed) was "
        "returned, not a new one: the one that stands, or for a rerun the one that already "
        "replaced the job it asked to replace (`rerun_of`), or an identical one that is queued "
        "or running"
    )
    reused_note: str | None = Field(
        default=None,
        description="null when a new job was made; else why this job was returned rather "
        "than a new one made, and how to run it anew (a rerun of a queued or running job: "
        "cancel it, or name it in `rerun_of`); then the submission's `name` and `tags` "
        "that job lacks, if any: they are not applied to it (a job that stands is "
        "relabelled only on purpose), and the `PATCH /jobs/{id}` body that sets them",
    )


class JobListed(JobOut):
    """A job as a list shows it: everything of :class:`JobOut` but its result, which is
    there only when the list is asked for it (``GET /jobs?include=result``)."""

    result: dict[str, Any] | None = Field(
        default=None,
        description="the worker's result: only with include=result (GET /jobs/{id} always "
        "has it); the summary holds its headline figures",
    )


#: What ``GET /jobs?include=`` may add to each job.
JobListInclude = Literal["result"]


class JobPage(BaseModel):
    items: list[JobListed]
    total: int
    limit: int
    offset: int


class MetricSeries(BaseModel):
    key: str
    steps: list[int]
    values: list[float | None] = Field(description="null where the value was not finite")
    total_points: int = Field(description="points after `after` before downsampling")
    downsampled: bool
    last_step: int | None = Field(description="pass as `after` to get only newer points")


class MetricsOut(BaseModel):
    job_id: str
    series: list[MetricSeries]
    keys: list[str] = Field(
        default_factory=list,
        description="every series the job has recorded so far, whatever `key` and `after` "
        "ask (a queued or running job's `key` not among them is one it has not written yet)",
    )


# Classifiers.


class ClassifierOut(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: str
    job_id: str | None
    scenario_id: str
    kind: str = Field(
        description="clustering, nearest-centroid, 1nn, minirocket, likelihood, least-squares"
    )
    metric: str
    f1: float
    accuracy: float
    sequence: list[list[int]]
    candidate_names: list[str]
    confusion: list[list[int]] = Field(description="row = true candidate, column = predicted")
    sha256: str
    created_at: UtcDatetime
    job_name: str | None = Field(default=None, description="the training job's name")
    tags: list[str] = Field(default_factory=list, description="the training job's tags")


class ClassifierPage(BaseModel):
    items: list[ClassifierOut]
    total: int
    limit: int
    offset: int


# Identification.


#: The longest window of telemetry before the start a request may ask to be used, s.
MAX_PRE_START_WINDOW_S = 3600.0
#: The widest start search a request may ask for, s: the core tries at most 4,001 starts
#: one grid period apart (±100 s on a 20 Hz grid) and refuses a wider one by name.
MAX_ESTIMATE_START_WITHIN_S = 100.0


def _comparable(value: Any) -> bool:
    """A start that :func:`same_sequence_start` can compare (any other is refused later, by
    name, by the telemetry's own check)."""
    return isinstance(value, str | int | float) and not isinstance(value, bool)


def _finite(value: Any) -> bool:
    return not isinstance(value, float) or math.isfinite(value)


class IdentifyRequest(_Request):
    classifier_id: str = Field(max_length=64)
    sequence_start: float | str | None = Field(
        default=None,
        description="start of the actuation sequence in the stamps' clock (seconds, or an "
        "ISO-8601 UTC time such as 2025-03-01T12:00:00Z); given beside telemetry.sequence_start "
        "or ?sequence_start=, it must name the same moment",
    )
    telemetry: Telemetry = Field(
        description=f"time stamps (seconds in any clock, or ISO-8601 UTC strings), omega rows "
        f"(rad/s) and the sequence start, at most {MAX_TELEMETRY_SAMPLES} samples"
    )

    @model_validator(mode="before")
    @classmethod
    def _start_into_telemetry(cls, data: Any) -> Any:
        # The telemetry is validated against its start, so the start goes in first. A start
        # given both here and in the telemetry must name the same moment: which one was
        # meant cannot be told, and taking either silently reads the pass from a start the
        # sender may not have meant.
        # A start that is no start (true, a list, NaN) stays where it was sent, to be refused
        # there once: copied, the telemetry refused it again, at a key the client did not use.
        start = data.get("sequence_start") if isinstance(data, dict) else None
        if start is not None and _comparable(start) and _finite(start):
            inner = data.get("telemetry")
            if isinstance(inner, dict):
                start, given = data["sequence_start"], inner.get("sequence_start")
                if given is not None and _comparable(start) and _comparable(given):
                    if not same_sequence_start(start, given):
                        raise ValueError(
                            f"sequence_start = {start!r} and telemetry.sequence_start = "
                            f"{given!r} differ; give the start once"
                        )
                data = {**data, "telemetry": {**inner, "sequence_start": start}}
        return data

    confidence: float | None = Field(
        default=None,
        gt=0,
        lt=1,
        description="posterior the top candidate needs to be named (default 0.99); for "
        "/identify/partial, the online stop rule decides at 1 - alpha with alpha = "
        "1 - confidence (default alpha 0.001)",
    )
    pre_start_window_s: float | None = Field(
        default=None,
        ge=0,
        le=MAX_PRE_START_WINDOW_S,
        description="seconds of telemetry before the sequence start that measure the body's "
        "rate plus the gyro bias there and the noise level, which the default classifier "
        "conditions on (default 30; 0 ignores them)",
    )
    estimate_start_within_s: float | None = Field(
        default=None,
        ge=0,
        le=MAX_ESTIMATE_START_WITHIN_S,
        description="search the starts within this many seconds of the stated one, one grid "
        "period apart, for the one whose series lies closest to a candidate (refined below "
        "the period for the likelihood kinds), and judge from it (the CLI's "
        "--estimate-start-within); the verdict reports sequence_start_shift_s and "
        "sequence_start_refined. POST /identify only",
    )


class TelemetryGapResult(BaseModel):
    from_s: float = Field(description="the last sample before the gap, s from the start")
    to_s: float = Field(description="the first sample after it, s from the start")
    length_s: float = Field(description="its length, s")


class ClassifierProvenance(BaseModel):
    """Where a stored classifier came from, as its download's ``provenance`` and the CLI
    verdict's ``classifier.provenance`` state it."""

    classifier_id: str = Field(description="the service's id of the classifier")
    job_id: str | None = Field(
        description="the training job that made it; null once that job was deleted"
    )
    scenario_id: str = Field(description="the scenario it was trained on")
    created_at: UtcDatetime = Field(description="when it was stored (UTC)")


class JudgingClassifier(BaseModel):
    """Which version of a classifier judged: its checksum, kind and provenance, the
    fields the CLI's verdict names under ``classifier`` (less the file's path)."""

    sha256: str = Field(
        description="the checksum over the stored document's payload: the classifier's "
        "sha256 in GET /classifiers/{id}, its download's sha256 and ETag"
    )
    kind: str = Field(
        description="clustering, nearest-centroid, 1nn, minirocket, likelihood, least-squares"
    )
    provenance: ClassifierProvenance


_JUDGING_CLASSIFIER = (
    "the classifier that judged: its sha256, kind and provenance (classifier_id, job_id, "
    "scenario_id, created_at), as the CLI's verdict names it"
)


class IdentifyResult(BaseModel):
    classifier_id: str
    classifier: JudgingClassifier = Field(description=_JUDGING_CLASSIFIER)
    candidate_index: int
    candidate: str = Field(description="nearest candidate, even when it matches none")
    inertia_kg_m2: list[list[float]] | None
    distances: dict[str, float | None] = Field(
        description="distance to each candidate's centroid; null: no cluster matched it"
    )
    margin: float | None
    relative_margin: float | None
    threshold: float | None
    matches_none: bool
    verdict: str
    estimated_inertia_kg_m2: list[list[float]] | None = Field(
        default=None,
        description="the inertia tensor integral-form least squares estimates from the "
        "telemetry and the commanded torques (kg m^2); null if not finite",
    )
    estimated_principal_moments_kg_m2: list[float] | None = None
    estimate_condition_number: float | None = Field(
        default=None, description="of the least-squares problem; large: poorly excited"
    )
    poorly_excited: list[str] = Field(
        default_factory=list,
        description="inertia parameters the sequence hardly excites (their estimate is unreliable)",
    )
    status: Literal["identified", "ambiguous", "matches-none", "not-this-sequence"] = Field(
        default="identified",
        description="identified: the top posterior reaches the confidence and the telemetry "
        "does not fit another body near the candidates better (where the classifier cannot "
        "test that, off_candidates_note says so and the name is the posterior's alone); "
        "ambiguous: none does (the "
        "verdict names the top two), or one does but the telemetry fits another body better "
        "(fits_off_candidates: thrusters off their stated torque, for one); matches-none: "
        "'none of these' is the most probable or the series is beyond the novelty "
        "threshold; not-this-sequence: far "
        "beyond every candidate's threshold, or rates that show no response to the sequence "
        "(they move less than 0.2 times the candidates' response: no thruster fired at the "
        "start stated)",
    )
    posterior: dict[str, float] = Field(
        default_factory=dict, description="posterior probability of each candidate"
    )
    p_none: float = Field(default=0.0, description="probability of 'none of these'")
    confidence: float = Field(default=0.0, description="the top candidate's posterior")
    required_confidence: float = Field(default=0.99, description="what naming one takes")
    not_this_sequence: bool = False
    off_candidates_log_bayes: float | None = Field(
        default=None,
        description="log Bayes factor of another body near the candidates against them "
        "(the default classifier's model of 'none'); null for a kind without one",
    )
    fits_off_candidates: bool | None = Field(
        default=False,
        description="a candidate reached the confidence, but that log Bayes factor was not "
        "below 0, so the verdict is ambiguous, not identified; null where the classifier "
        "cannot test for other bodies (off_candidates_note says so)",
    )
    off_candidates_note: str | None = Field(
        default=None,
        description="where the classifier has no model of other bodies near the "
        "candidates (every kind but the default, marginal-likelihood): that it cannot test "
        "for them, so a pass no candidate gives (thrusters off their stated torque) can be "
        "named with full confidence; null where it can",
    )
    estimated_inertia_std_kg_m2: dict[str, float] | None = Field(
        default=None,
        description="standard error of each estimated parameter (kg m^2), allowing for the "
        "errors the least-squares windows share (a random walk of disturbance and gyro "
        "noise at the window ends, sized from this telemetry's own residuals, and the "
        "scenario's stated duty jitter per actuation step); a bias (a thrust scale off "
        "nominal, a poorly excited tensor) is not in it",
    )
    estimate_rejected: str | None = Field(
        default=None,
        description="why the estimated tensor is withheld: not positive definite, the "
        "triangle inequality broken, or poorly excited",
    )
    initial_offset_rad_s: list[float] | None = Field(
        default=None,
        description="the body's rate plus the gyro bias at the sequence start (rad/s), "
        "measured by the samples in the 30 s before it; the default classifier conditions "
        "on it; null when the telemetry starts at the sequence start",
    )
    initial_offset_std_rad_s: list[float] | None = Field(
        default=None, description="that offset's standard error per axis at 1x noise (rad/s)"
    )
    initial_offset_deg_s: list[float] | None = Field(
        default=None, description="the same offset in deg/s"
    )
    initial_offset_std_deg_s: list[float] | None = Field(
        default=None, description="its standard error per axis at 1x noise (deg/s)"
    )
    pre_start_samples: int = Field(
        default=0, description="telemetry samples before the start that measured it"
    )
    sequence_start: float | str | None = Field(
        default=None,
        description="the sequence start the verdict used (the stated one plus any shift "
        "found): seconds in the stamps' clock, or ISO-8601 UTC ending in Z",
    )
    sequence_start_shift_s: float = Field(
        default=0.0, description="how much later than stated the start was taken, s"
    )
    sequence_start_refined: bool | None = Field(
        default=None,
        description="with a start search: true when the start was refined below the grid "
        "period (the vertex of a parabola through the scores of the grid start found and "
        "its neighbours; on a grid coarse for the response, such as 1 Hz, the start "
        "between those neighbours that scores lowest), false when the grid's start was "
        "kept (a neighbour the telemetry does not reach, scores that bracket no minimum, "
        "or a kind that compares whole series) or the stated start kept (no sample "
        "before it, a scenario that draws an initial rate or gyro bias, and a grid fine "
        "for the response: no score then tells it from the next start); null: no search",
    )
    sequence_start_note: str | None = Field(
        default=None,
        description="with a start search on a kind that compares whole series (the "
        "clustering kinds, sequence_start_refined false): in words, that the start taken "
        "is the grid time its distance favours, not refined below the grid period, and may "
        "lie a period or two off the true one; null without a search or for the likelihood "
        "kinds, which refine it",
    )
    estimate_start_within_s: float | None = Field(
        default=None, description="the start search asked for, s; null: none"
    )
    sequence_start_shifts_tried_s: list[float] | None = Field(
        default=None,
        description="the least and greatest shifts tried (narrower than asked where the "
        "telemetry does not cover a start)",
    )
    start_window_hint: str | None = Field(
        default=None,
        description="with a start search whose start lies within a grid period of the "
        "window's edge while a start beyond the edge fits the telemetry better (the best "
        "found walking outwards while the fit improves): says so (the true start may lie "
        "outside the window) and how wide a window reaches that start; whatever the "
        "status, and in the verdict's text where it is not identified (the status is "
        "unchanged); null otherwise",
    )
    start_window_better_shift_s: float | None = Field(
        default=None,
        description="the best start found beyond the window, s from the stated one",
    )
    telemetry_first_stamp: float | str | None = Field(
        default=None, description="the first stamp as given (ISO ones in UTC)"
    )
    telemetry_last_stamp: float | str | None = Field(
        default=None, description="the last stamp as given (ISO ones in UTC)"
    )
    telemetry_samples: int = Field(default=0, description="samples in the telemetry")
    telemetry_span_s: list[float] | None = Field(
        default=None, description="first and last sample, s from the start used"
    )
    telemetry_gaps: list[TelemetryGapResult] = Field(
        default_factory=list,
        description="gaps in the sequence that the verdict judged across (between "
        "samples, longer than 4 periods; or at an end, longer than 1.5: from 0 s when the "
        "pass started late, to the end when it ended early; the likelihood kinds only, on "
        "the grid times the samples cover), in s from the start used",
    )
    sequence_covered_fraction: float = Field(
        default=1.0,
        description="the part of the sequence's grid times outside those gaps: the span "
        f"the samples cover (at least {MIN_COVERED_FRACTION:g}, else the telemetry is "
        "refused); 1.0 with no gap judged across, however sparse the samples",
    )
    sequence_measured_fraction: float = Field(
        default=1.0,
        description="the part of the sequence's grid times with a real sample within half "
        "a grid period, the values a likelihood kind judges (0.5 for 10 Hz telemetry on a "
        "20 Hz grid, or for 20 Hz telemetry that lost 3 of every 6 samples)",
    )
    start_hint: str | None = Field(
        default=None,
        description="with a matches-none or not-this-sequence verdict and no start search "
        "asked for: a start near the stated one that identifies a candidate (the status "
        "is unchanged)",
    )
    start_hint_shift_s: float | None = None
    start_hint_candidate: str | None = None
    unit_hint: str | None = Field(
        default=None,
        description="with a matches-none or not-this-sequence verdict and no start hint: "
        "the candidate the rates identify when read in the other unit (deg/s sent as "
        "rad/s, or the reverse), or that they read ambiguous among the candidates there "
        "(the status is unchanged)",
    )
    unit_hint_candidate: str | None = Field(
        default=None,
        description="the candidate the rates identify in the other unit; null where they "
        "read ambiguous there",
    )
    unit_hint_rates_unit: str | None = Field(
        default=None,
        description="the unit the rates match the candidates in: deg/s or rad/s",
    )
    pre_start_hint: str | None = Field(
        default=None,
        description="with an ambiguous verdict from a kind that conditions on the "
        "telemetry before the start (the default kind), and no sample there: says so and "
        "asks for the telemetry from up to pre_start_window_s before the start (the "
        "status is unchanged)",
    )
    pre_start_activity_hint: str | None = Field(
        default=None,
        description="whatever the status: the rates changed before the sequence start by "
        "more than 8 times what the gyro noise and the disturbance give (a thruster "
        "firing or a manoeuvre before the start, or a start stated late), when and by "
        "how much, and the pre_start_window_s that leaves it out; in the verdict's text "
        "too where it is not identified (the status is unchanged); null: no such change "
        "in the pre_start_window_s before the start",
    )
    pre_start_activity_at_s: float | None = Field(
        default=None, description="when that change began, s from the start (negative)"
    )
    pre_start_activity_step_rad_s: list[float] | None = Field(
        default=None,
        description="the change per axis: the mean rate over the step duration after it "
        "less that over the step duration before it (rad/s)",
    )
    pre_start_activity_step_deg_s: list[float] | None = Field(
        default=None, description="the same change in deg/s"
    )
    pre_start_activity_sigmas: float | None = Field(
        default=None,
        description="its largest axis' change in standard deviations of the noise's",
    )

    @computed_field(
        description="the candidate's number as plan tables, exports and the CLI number it "
        "(from 1, the scenario's order); candidate_index is its position in "
        "candidate_names (from 0)"
    )
    def candidate_number(self) -> int:
        return self.candidate_index + 1


class PartialIdentifyResult(BaseModel):
    classifier_id: str
    classifier: JudgingClassifier = Field(description=_JUDGING_CLASSIFIER)
    time_s: list[float] = Field(description="grid times covered, s from the sequence start")
    posterior: dict[str, list[float]] = Field(description="each candidate's posterior over time")
    p_none: list[float]
    alpha: float
    decided: bool = Field(
        description="the top posterior reached 1 - alpha while the data so far did not fit "
        "another body near the candidates better (off_candidates_log_bayes below 0 then: the "
        "verdict's rule, on each prefix). A decision stands once taken (a stop rule's is "
        "final), even where the data since disown it: read fits_off_candidates beside it"
    )
    decision_time_s: float | None = Field(description="when decided; null until then")
    candidate_index: int | None = Field(description="the candidate decided on, from 0")
    candidate: str | None = Field(
        description="the candidate decided on, kept when later data disown it "
        "(fits_off_candidates true: the data so far fit another body near the candidates "
        "better, so this name is not a confirmed identification); null until decided"
    )
    current: dict[str, float] = Field(description="the posterior at the last covered sample")
    current_p_none: float
    off_candidates_log_bayes: list[float | None] | None = Field(
        default=None,
        description="after every time of time_s, the log Bayes factor of another body near "
        "the candidates against them (null before the first measured point; the whole list "
        "null for a kind without that model)",
    )
    current_off_candidates_log_bayes: float | None = Field(
        default=None, description="that factor at the last covered sample"
    )
    decision_off_candidates_log_bayes: float | None = Field(
        default=None, description="that factor at the decision; null until decided"
    )
    fits_off_candidates: bool | None = Field(
        default=False,
        description="the top posterior reached 1 - alpha at some sample, but the data so far "
        "fit another body near the candidates better (current_off_candidates_log_bayes not "
        "below 0): undecided for that reason, or decided earlier and disowned since "
        "(thrusters off their stated torque?); null where the classifier cannot test for "
        "other bodies (off_candidates_note says so)",
    )
    off_candidates_note: str | None = Field(
        default=None,
        description="as the verdict's: that the classifier cannot test for other bodies "
        "near the candidates, so a decision here is the posterior's alone; null where it can",
    )
    withheld_time_s: float | None = Field(
        default=None,
        description="the first sample at which the top posterior reached 1 - alpha but the "
        "factor held the decision back (before decision_time_s where decided: the rule stops "
        "there); null if none",
    )
    covers_s: float
    sequence_s: float
    telemetry_gaps: list[TelemetryGapResult] = Field(
        default_factory=list,
        description="gaps so far that the posterior judged across (between samples, longer "
        "than 4 periods; or from 0 s when the pass started more than 1.5 late; on the grid "
        "times the samples cover), in s from the start used",
    )
    sequence_covered_fraction: float = Field(
        default=1.0,
        description="the part of the grid times so far (time_s) outside those gaps (at "
        f"least {MIN_COVERED_FRACTION:g}, else the telemetry is refused)",
    )
    sequence_measured_fraction: float = Field(
        default=1.0,
        description="the part of the grid times so far (time_s) with a real sample within "
        "half a grid period, the values the posterior judges",
    )

    @computed_field(
        description="the decided candidate's number (from 1, as plan tables number it); "
        "null until decided"
    )
    def candidate_number(self) -> int | None:
        return None if self.candidate_index is None else self.candidate_index + 1


# Health.


class ComponentHealth(BaseModel):
    ok: bool
    detail: str


class DatabaseHealth(ComponentHealth):
    takes_writes: bool | None = Field(
        default=None,
        description="false when the database answers but refuses writes (its disk full, "
        "its file or folder read-only, its transactions read-only, a standby): the "
        "workers' heartbeats and results cannot be stored meanwhile; null when it cannot "
        "be reached",
    )


class WarmingWorker(BaseModel):
    name: str
    warming_s: float = Field(
        description="how long the worker has had no warm task process, s: as it starts, "
        "since the worker process started; later, since its replacement started (the first "
        "of them, when one was killed before it was warm); read from the worker's last beat"
    )


class WorkerWithoutLock(BaseModel):
    name: str
    without_lock_s: float = Field(
        description="how long the worker has not held its incarnation lock, s: since the "
        "first of its beats that found it missing (not taken at its start, or lost and not "
        "taken again); read from the worker's last beat"
    )


class GoneWorker(BaseModel):
    name: str
    silent_s: float = Field(
        description="how long ago the worker's process last beat, s: it is gone since "
        "(killed, its machine lost: its incarnation lock is free)"
    )


class WorkersHealth(BaseModel):
    ok: bool = Field(
        description="false when no worker is live, when one has been warming longer "
        "than warming_limit_s, or when none holds its incarnation lock"
    )
    count: int
    names: list[str] = Field(description="live workers, those warming included")
    duplicates_seen: int = Field(
        default=0,
        description="live workers of `names` under which a second live process (a twin, "
        "started under the same name by mistake) beat within window_s: each name is listed "
        "and counted once, with the state of the process that beat its row last; the "
        "other's is in its own log. Give each worker its own name (celery -n)",
    )
    window_s: float = Field(description="a worker counts if seen within this many seconds")
    warming: list[WarmingWorker] = Field(
        default_factory=list,
        description="live workers whose task process imports the core: the first one, as "
        "the worker starts, or a replacement (the last one retired after its jobs or its "
        "memory limit, or was killed): each takes queued jobs as soon as it is warm",
    )
    without_lock: list[WorkerWithoutLock] = Field(
        default_factory=list,
        description="live workers that do not hold their incarnation lock: each claims no "
        "job (a job sent to it stays queued and is sent again) until it takes the lock "
        "again, which it tries at every beat; its log says why it could not",
    )
    gone: list[GoneWorker] = Field(
        default_factory=list,
        description="workers seen within window_s whose process is gone (its incarnation "
        "lock is free: killed, its machine lost): not counted nor listed above, and listed "
        "here until window_s after their last beat",
    )
    warming_limit_s: float = Field(
        description="a warm-up longer than this (INERTIA_ID_HEARTBEAT_TIMEOUT_S, or "
        "INERTIA_ID_WORKER_START_TIMEOUT_S when shorter) makes the workers not ok"
    )
    state_unknown_since: UtcDatetime | None = Field(
        default=None,
        description="while the database refuses writes and no beat is within window_s: "
        "the last beat it stored (any worker's). The workers' beats are refused as every "
        "write is, so whether they live since is unknown; null otherwise",
    )
    last_known: list[str] = Field(
        default_factory=list,
        description="with state_unknown_since: the workers that beat within window_s of it "
        "(live when the database began refusing their beats, as far as it knows)",
    )
    detail: str | None = Field(
        default=None, description="what is wrong, when not ok; and any twin (duplicates_seen)"
    )


class QueueHealth(BaseModel):
    ok: bool = Field(
        description="false when a queued job has waited long for its message, or long "
        "while a worker sat idle"
    )
    queued: int
    running: int
    unsent: int = Field(
        description="queued jobs whose message has not reached the broker for a while "
        "(the broker is down, or no worker is there to send it)"
    )
    oldest_queued_s: float | None = Field(description="age of the oldest queued job, s")
    stalled: bool = Field(
        default=False,
        description="the oldest queued job has waited longer than INERTIA_ID_QUEUE_STALL_S "
        "while a live worker had no job: that worker is not taking jobs",
    )
    detail: str | None = Field(default=None, description="what is wrong, when not ok")


class HealthOut(BaseModel):
    status: Literal["ok", "degraded"]
    version: str
    database: DatabaseHealth
    broker: ComponentHealth
    workers: WorkersHealth
    queue: QueueHealth
