"""Request and response bodies of the REST API (pydantic v2).

Job parameter models are the contract with the workers: a job row stores
``params.model_dump(mode="json")`` (every default filled in) and the worker reads exactly
these names. Every rule is checked here when it needs nothing but the request; rules that
need the scenario or the database (sequence levels, the exhaustive budget, a classifier's
candidates) are checked by the jobs router.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Annotated, Any, Literal, Self

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    field_validator,
    model_validator,
)

from inertia_id.classifiers.registry import (
    default_realisations,
    make_classifier,
    parse_spec,
    resolve_kind,
)
from inertia_id.evaluation.telemetry import MAX_TELEMETRY_SAMPLES, Telemetry
from inertia_id.physics.presets import PRESETS
from inertia_id.physics.scenario import Scenario
from inertia_id.search import CEM_DEFAULTS, ScorerSettings, check_ppo_params
from inertia_id.search.cem import check_cem_params

__all__ = [
    "MAX_SEED",
    "CandidateOut",
    "CandidateResponse",
    "ClassifierOut",
    "ClassifierPage",
    "ComponentHealth",
    "HealthOut",
    "IdentifyRequest",
    "IdentifyResult",
    "JobCreate",
    "JobOut",
    "JobPage",
    "JobSubmitted",
    "MetricSeries",
    "MetricsOut",
    "ScenarioCreate",
    "ScenarioOut",
    "ScenarioPage",
    "ScenarioResponse",
    "SearchJobCreate",
    "SearchParams",
    "SweepJobCreate",
    "SweepParams",
    "TrainJobCreate",
    "TrainParams",
    "WorkersHealth",
    "finite_or_none",
]

#: Seeds are stored in a 32-bit INTEGER column (PostgreSQL ``integer``).
MAX_SEED = 2**31 - 1
#: Longest search sequence the API accepts (steps).
MAX_SEARCH_SEQUENCE_LENGTH = 20
#: Largest search budget in environment steps.
MAX_TIMESTEPS = 2_000_000
#: Largest exhaustive-search budget (sequences).
MAX_EXHAUSTIVE_SEQUENCES = 1_000_000_000

# Larger integers are no sensible parameter (and overflow the core's float conversions).
_MAX_INT = 2**53
# The core's limit on duty levels (Thrusters.levels: 2 to 101 values).
_MAX_LEVELS = 101


def _clip(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


JobType = Literal["search", "train", "sweep"]
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
SearchMethod = Literal["ppo", "cem", "exhaustive", "random"]
SearchObjective = Literal["f1", "separability"]
ClassifierMetric = Literal["dtw", "euclidean", "softdtw"]
NoiseKind = Literal["process", "measurement", "jitter", "thrust_scale", "gyro_bias"]
ClassifierKind = Literal[
    "clustering",
    "nearest-centroid",
    "1nn",
    "minirocket",
    "likelihood",
    "least-squares",
    "marginal-likelihood",
]


def as_utc(value: datetime) -> datetime:
    """SQLite hands back naive datetimes; every stored time is UTC."""
    if value.tzinfo is None:
        return value.replace(tzinfo=UTC)
    return value.astimezone(UTC)


UtcDatetime = Annotated[datetime, AfterValidator(as_utc)]


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (JSON has no NaN or inf)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    return value


class _Request(BaseModel):
    # Strict: a request means what its JSON types say ("rerun": 0 is not false, 4.0 is
    # not a level index), as the OpenAPI document promises. Unknown fields are refused.
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


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
    final_rate_rad_s: float = Field(description="mean |omega| at the end, true rate")


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


# Job parameters: the worker reads exactly these names from JobRow.params.


class SearchParams(_Request):
    """Search for the actuation sequence that best separates the candidates."""

    method: SearchMethod = "ppo"
    sequence_length: int = Field(default=4, ge=1, le=MAX_SEARCH_SEQUENCE_LENGTH)
    timesteps: int = Field(
        default=20_480, ge=1, le=MAX_TIMESTEPS, description="environment steps (ppo, random)"
    )
    max_sequences: int = Field(
        default=100_000,
        ge=1,
        le=MAX_EXHAUSTIVE_SEQUENCES,
        description="exhaustive search budget: the largest space it will enumerate",
    )
    n_realisations: int = Field(default=20, ge=1, le=200)
    objective: SearchObjective = Field(
        default="f1",
        description="what scores a sequence: f1 (clustering F1, the paper's) or separability "
        "(the Bhattacharyya bound on the error, no clustering)",
    )
    metric: ClassifierMetric = "dtw"
    sakoe_chiba_radius: int | None = Field(default=2, ge=0, le=10_000)
    fuel_weight: float = Field(default=0.0, ge=0.0, le=1e6)
    patience_episodes: int | None = Field(default=500, ge=1, le=10_000_000)
    ppo: dict[str, Any] = Field(
        default_factory=dict,
        description="overrides of the paper's PPO hyperparameters (stable-baselines3 names)",
        examples=[{"learning_rate": 0.0003, "n_steps": 2048}],
    )
    cem: dict[str, Any] = Field(
        default_factory=dict,
        description="overrides of the cross-entropy method's settings: population, "
        "elite_fraction, smoothing",
        examples=[{"population": 64, "elite_fraction": 0.125, "smoothing": 0.7}],
    )

    @field_validator("cem")
    @classmethod
    def _cem(cls, value: dict[str, Any]) -> dict[str, Any]:
        unknown = sorted(set(value) - set(CEM_DEFAULTS))
        if unknown:
            raise ValueError(f"unknown CEM setting(s) {unknown}; known: {sorted(CEM_DEFAULTS)}")
        check_cem_params(**{**CEM_DEFAULTS, **value})
        return value

    @field_validator("ppo")
    @classmethod
    def _ppo(cls, value: dict[str, Any]) -> dict[str, Any]:
        for name, given in value.items():
            if isinstance(given, float) and not math.isfinite(given):
                raise ValueError(f"PPO parameter {name} must be finite, got {given!r}")
            if isinstance(given, int) and not isinstance(given, bool) and abs(given) > _MAX_INT:
                raise ValueError(
                    f"PPO parameter {name} must be at most {_MAX_INT}, got {_clip(repr(given))}"
                )
        checked = check_ppo_params(value)
        # Keep only the overrides (normalised), so the job records what was asked for.
        return {name: checked[name] for name in value}

    @model_validator(mode="after")
    def _budget(self) -> Self:
        # The core's own rules for the scorer, so that a job the API accepts can start.
        ScorerSettings(
            n_realisations=self.n_realisations,
            metric=self.metric,
            sakoe_chiba_radius=self.sakoe_chiba_radius,
            objective=self.objective,
        ).check()
        if self.cem and self.method != "cem":
            raise ValueError(f"cem settings apply to method cem, not {self.method!r}")
        if self.timesteps < self.sequence_length:
            raise ValueError(
                f"timesteps = {self.timesteps} must be at least one sequence "
                f"(sequence_length = {self.sequence_length})"
            )
        return self


class TrainParams(_Request):
    """Train a classifier for a given actuation sequence.

    ``kind`` chooses the classifier: the paper's clustering, a supervised one, the
    likelihood, the least-squares physics baseline, or the marginal likelihood (the
    default when neither kind nor metric is given: closest to the limit); ``metric``
    applies to clustering (dtw, softdtw, euclidean; default dtw), nearest-centroid and
    1nn (dtw, euclidean; default dtw) and must be left out for the others. A metric
    without a kind means the paper's clustering. ``n_realisations`` defaults to 100 for
    the marginal likelihood, 20 for the others.
    """

    sequence: list[Annotated[list[int], Field(min_length=1, max_length=64)]] = Field(
        min_length=1,
        max_length=1000,
        description="L x N level indices, one row per step, one column per thruster",
        examples=[[[4, 4, 4, 0, 0, 0]] * 4],
    )
    kind: ClassifierKind | None = None
    metric: ClassifierMetric | None = None
    n_realisations: int | None = Field(default=None, ge=1, le=400)

    @model_validator(mode="after")
    def _metric_fits_kind(self) -> Self:
        kind = resolve_kind(self.kind, self.metric)
        self.kind = kind  # type: ignore[assignment]
        if self.n_realisations is None:
            self.n_realisations = default_realisations(kind)
        if self.metric is None and self.kind in _KINDS_WITH_METRIC:
            self.metric = "dtw"
        elif self.metric is not None:
            if self.kind not in _KINDS_WITH_METRIC:
                raise ValueError(
                    f"the {self.kind!r} classifier takes no metric, got metric {self.metric!r}"
                )
            make_classifier(self.kind, metric=self.metric)
        needs_three = ("likelihood", "1nn", "nearest-centroid", "marginal-likelihood")
        if self.kind in needs_three and self.n_realisations < 3:
            raise ValueError(
                f"the {self.kind!r} classifier needs at least 3 realisations per candidate, "
                f"got n_realisations = {self.n_realisations}"
            )
        return self


_KINDS_WITH_METRIC = ("clustering", "nearest-centroid", "1nn")


def _default_others() -> list[str]:
    return ["least-squares"]


def _default_multiples() -> list[float]:
    return [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]


def _all_noises() -> list[NoiseKind]:
    return ["process", "measurement"]


class SweepParams(_Request):
    """Classifier accuracy against noise multiples."""

    classifier_id: str = Field(max_length=64)
    multiples: list[float] = Field(default_factory=_default_multiples, min_length=1, max_length=20)
    noises: list[NoiseKind] = Field(
        default_factory=_all_noises,
        min_length=1,
        max_length=5,
        description="process, measurement, jitter, thrust_scale, gyro_bias: each scaled in "
        "turn, the others at 1x (a source the scenario leaves at 0 scales a reference level)",
    )
    others: list[Annotated[str, Field(max_length=40)]] = Field(
        default_factory=_default_others,
        max_length=8,
        description="classifiers trained at 1x on the same sequence and scored on the same "
        "test series, as specs: 'least-squares' (the physics baseline), '1nn:euclidean', "
        "'nearest-centroid:dtw', 'minirocket', 'likelihood', 'clustering:euclidean'",
    )
    limit_realisations: int = Field(
        default=200,
        ge=0,
        le=1000,
        description="the limit: at every point a likelihood classifier (matched filter) is "
        "fitted on this many realisations per candidate simulated at that point's noise and "
        "scored on the same series; 0 leaves it out",
    )
    n_train: int = Field(
        default=20, ge=3, le=200, description="training realisations per candidate for others"
    )
    inertia: bool = Field(
        default=True,
        description="also test bodies off the candidates (scaled, and between the closest "
        "two): how often identify says 'matches none'",
    )

    @field_validator("others")
    @classmethod
    def _specs(cls, value: list[str]) -> list[str]:
        for spec in value:
            parse_spec(spec)
        if len(set(value)) != len(value):
            raise ValueError(f"others names a classifier twice: {value}")
        return value

    n_test: int = Field(default=200, ge=5, le=2000)

    @field_validator("multiples")
    @classmethod
    def _positive(cls, value: list[float]) -> list[float]:
        bad = [m for m in value if not m > 0]
        if bad:
            raise ValueError(f"noise multiples must be > 0, got {bad} in {value}")
        return value

    @field_validator("noises")
    @classmethod
    def _unique(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise ValueError(f"noises must not repeat, got {value}")
        return value


class _JobCreate(_Request):
    scenario_id: str = Field(max_length=64)
    seed: int = Field(default=0, ge=0, le=MAX_SEED)
    rerun: bool = Field(
        default=False, description="run again even if the same job exists (not failed/cancelled)"
    )


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
    result: dict[str, Any] | None = Field(description="summary written by the worker")
    cancel_requested: bool
    attempts: int = Field(description="runs started, hand-backs included")
    handbacks: int = Field(
        default=0, description="runs handed back by a stopping worker (not counted as attempts)"
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

    @field_validator("params", "result", mode="after")
    @classmethod
    def _finite(cls, value: Any) -> Any:
        return finite_or_none(value)


class JobSubmitted(JobOut):
    reused: bool = Field(
        description="true: an identical job (same scenario, parameters and seed) was returned"
    )


class JobPage(BaseModel):
    items: list[JobOut]
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


class ClassifierPage(BaseModel):
    items: list[ClassifierOut]
    total: int
    limit: int
    offset: int


# Identification.


class IdentifyRequest(_Request):
    classifier_id: str = Field(max_length=64)
    telemetry: Telemetry = Field(
        description=f"time stamps (s from the sequence start) and omega rows (rad/s), at most "
        f"{MAX_TELEMETRY_SAMPLES} samples"
    )


class IdentifyResult(BaseModel):
    classifier_id: str
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


# Health.


class ComponentHealth(BaseModel):
    ok: bool
    detail: str


class WorkersHealth(BaseModel):
    ok: bool
    count: int
    names: list[str]
    window_s: float = Field(description="a worker counts if seen within this many seconds")


class QueueHealth(BaseModel):
    ok: bool = Field(description="false when a queued job has waited long for its message")
    queued: int
    running: int
    unsent: int = Field(
        description="queued jobs whose message has not reached the broker for a while "
        "(the broker is down, or no worker is there to send it)"
    )
    oldest_queued_s: float | None = Field(description="age of the oldest queued job, s")


class HealthOut(BaseModel):
    status: Literal["ok", "degraded"]
    version: str
    database: ComponentHealth
    broker: ComponentHealth
    workers: WorkersHealth
    queue: QueueHealth
