"""Typed job parameters: what the API accepts for a job and what the worker runs.

The API validates a submission with these models and stores
``params.model_dump(mode="json")`` (every default filled in) on the job row; the worker
parses the row's params with the same model before it runs the job. The defaults are the
core's (the request classes of :mod:`inertia_id.pipelines`), so a job and the command
line mean the same thing by an option left out.

Rules needing only the request are checked here, by the core's own checks; rules that need
the scenario or the database (sequence levels, the exhaustive budget, a classifier's
candidates) are checked by the jobs router. The classifier registry and the search
package are imported by the checks that need them, not with this module, so the API
process starts without them (they are imported in the background at start).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal, Self

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError

from inertia_id.checks import MAX_SEED
from inertia_id.deadline import GRACE_ASKED_MAX_S, GRACE_MAX_S, TIME_LIMIT_MIN_S
from inertia_id.errors import InputError
from inertia_id.pipelines import SearchRequest, SweepRequest, TrainRequest

__all__ = [
    "JOB_PARAMS",
    "MAX_SEED",
    "ClassifierMetric",
    "JobParams",
    "NoiseKind",
    "SearchMethod",
    "SearchObjective",
    "SearchParams",
    "StrictModel",
    "SweepParams",
    "TrainParams",
    "classifier_kinds",
    "parse_params",
]

#: Longest search sequence the API accepts (steps).
MAX_SEARCH_SEQUENCE_LENGTH = 20
#: Largest search budget in environment steps.
MAX_TIMESTEPS = 2_000_000
#: Largest exhaustive-search budget (sequences).
MAX_EXHAUSTIVE_SEQUENCES = 1_000_000_000

# Larger integers are no sensible parameter (and overflow the core's float conversions).
_MAX_INT = 2**53


def _time_limit_field() -> Any:
    return Field(
        default=None,
        ge=TIME_LIMIT_MIN_S,
        description="wall-clock limit of the job in seconds, at least "
        f"{TIME_LIMIT_MIN_S:g} (less is no budget for any job's work, and most likely "
        "milliseconds meant as seconds) and at most the service's "
        "INERTIA_ID_JOB_TIME_LIMIT_S (the ceiling every job has); none: the ceiling. A search "
        "past it stops with its best so far (stopped: time_limit), re-scored only in a grace "
        f"of 10 % of the limit, at least 10 s, at most {GRACE_MAX_S:g} s "
        "(settings.time_limit_grace_s); a sweep keeps the points done (stopped: time_limit); "
        "a training stops at its next checkpoint and the job fails naming the limit, nothing "
        "stored, and so does a sweep stopped before its first point",
        examples=[3600],
    )


SearchMethod = Literal["ppo", "cem", "exhaustive", "random", "nsga2"]
SearchGoal = Literal[
    "accuracy", "final_rate", "peak_rate", "impulse", "on_time", "propellant", "duration"
]
SearchObjective = Literal["f1", "separability"]
ClassifierMetric = Literal["dtw", "euclidean", "softdtw"]
NoiseKind = Literal["process", "measurement", "jitter", "thrust_scale", "gyro_bias"]


def _clip(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def classifier_kinds() -> tuple[str, ...]:
    """Every classifier kind, from the registry (imported now if it was not yet)."""
    from inertia_id.classifiers.registry import CLASSIFIER_KINDS

    return CLASSIFIER_KINDS


def _kinds_schema(schema: dict[str, Any]) -> None:
    # Filled when the OpenAPI document is built, from the registry: no list restated here.
    schema["enum"] = list(classifier_kinds())


def _search_defaults() -> Any:
    from inertia_id.search import CEM_DEFAULTS

    return CEM_DEFAULTS


class StrictModel(BaseModel):
    # Strict: a request means what its JSON types say ("rerun": 0 is not false, 4.0 is
    # not a level index), as the OpenAPI document promises. Unknown fields are refused.
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


class SearchParams(StrictModel):
    """Search for the actuation sequence that best separates the candidates."""

    method: SearchMethod = SearchRequest.default("method")
    sequence_length: int = Field(
        default=SearchRequest.default("sequence_length"), ge=1, le=MAX_SEARCH_SEQUENCE_LENGTH
    )
    timesteps: int = Field(
        default=SearchRequest.default("timesteps"),
        ge=1,
        le=MAX_TIMESTEPS,
        description="environment steps (ppo, random)",
    )
    max_sequences: int = Field(
        default=SearchRequest.default("max_sequences"),
        ge=1,
        le=MAX_EXHAUSTIVE_SEQUENCES,
        description="exhaustive search budget: the largest space it will enumerate",
    )
    n_realisations: int = Field(default=SearchRequest.default("n_realisations"), ge=1, le=200)
    objective: SearchObjective = Field(
        default=SearchRequest.default("objective"),
        description="what scores a sequence: f1 (clustering F1, the paper's) or separability "
        "(the Bhattacharyya bound on the error, no clustering)",
    )
    metric: ClassifierMetric = SearchRequest.default("metric")
    sakoe_chiba_radius: int | None = Field(
        default=SearchRequest.default("sakoe_chiba_radius"), ge=0, le=10_000
    )
    fuel_weight: float = Field(default=SearchRequest.default("fuel_weight"), ge=0.0, le=1e6)
    patience_episodes: int | None = Field(
        default=SearchRequest.default("patience_episodes"), ge=1, le=10_000_000
    )
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

    nsga2: dict[str, Any] = Field(
        default_factory=dict,
        description="overrides of NSGA-II's settings (method nsga2): population, generations, "
        "crossover_eta, mutation_eta, crossover_prob, polish_iterations (local-search rounds "
        "after the generations, 0: none), polish_starts",
        examples=[{"population": 64, "generations": 30}],
    )
    objectives: list[SearchGoal] = Field(
        default_factory=lambda: list(SearchRequest.default("objectives")),
        min_length=2,
        max_length=7,
        description="what the Pareto front trades off (method nsga2), and what every "
        "search's best sequence is judged on beside the baselines",
    )
    design_noise: list[Annotated[list[float], Field(min_length=2, max_length=2)]] = Field(
        default_factory=lambda: [list(p) for p in SearchRequest.default("design_noise")],
        min_length=1,
        max_length=8,
        description="[process multiple, measurement multiple] conditions at which the "
        "accuracy objective is predicted while searching and measured for the front "
        "(their mean)",
    )
    constraints: dict[str, float] = Field(
        default_factory=dict,
        description="bounds by name: max_final_rate_rad_s, max_final_rate_deg_s (the "
        "residual rate of every candidate, mean over flights), max_final_rate_p95_rad_s, "
        "max_final_rate_p95_deg_s (a rate at least 95 % of every candidate's flights stay "
        "under, with 95 % confidence), "
        "max_commanded_residual_rate_rad_s, max_commanded_residual_rate_deg_s (the part the "
        "commands leave: the residual the plan predicts from rest with every noise off, "
        "without the initial rate, mean over candidates), "
        "max_commanded_residual_rate_max_rad_s, max_commanded_residual_rate_max_deg_s (the "
        "same, the candidate the commands leave fastest), "
        "max_peak_rate_rad_s, max_peak_rate_deg_s (the fastest candidate's largest mean "
        "speed over the flights, at any instant, or the plan's peak), "
        "max_peak_rate_p95_rad_s, max_peak_rate_p95_deg_s (a peak rate at least 95 % of "
        "its flights stay under, with 95 % confidence), "
        "max_impulse_nms, max_on_time_s, "
        "max_propellant_kg, max_duration_s, min_accuracy (nsga2 only)",
        examples=[{"max_final_rate_deg_s": 0.2, "max_impulse_nms": 20}],
    )
    constraint_penalty: float = Field(
        default=SearchRequest.default("constraint_penalty"),
        ge=0.0,
        le=1e6,
        description="ppo, cem, random, exhaustive: reward cost per unit of summed relative "
        "constraint violation (the constrained variant of the paper's reward)",
    )
    lagrangian_lr: float = Field(
        default=SearchRequest.default("lagrangian_lr"),
        ge=0.0,
        le=1e5,
        description="ppo: raise the penalty after every rollout by this times the mean "
        "violation (PPO-Lagrangian); 0 keeps it fixed",
    )
    fresh_realisations: int = Field(
        default=SearchRequest.default("fresh_realisations"),
        ge=2,
        le=400,
        description="realisations per candidate when the front is re-scored on fresh draws",
    )
    fresh_test_series: int = Field(
        default=SearchRequest.default("fresh_test_series"),
        ge=0,
        le=5000,
        description="test series per candidate and design condition on which each front "
        "member's accuracy is measured (the noise model's Bayes classifier on fresh "
        "series); 0 keeps the predicted accuracy",
    )
    time_limit_s: float | None = _time_limit_field()
    time_limit_grace_s: float | None = Field(
        default=None,
        ge=0,
        le=GRACE_ASKED_MAX_S,
        allow_inf_nan=False,
        description="seconds the re-score on fresh draws may go on past the time limit "
        "(the best's draws, the front's candidates, the baselines' draws, in that order), "
        f"at most {GRACE_ASKED_MAX_S:g}; 0 stops at the limit, after the front's first "
        "member and the baselines on the fresh draw; none: 10 % of the limit, at least "
        f"10 s, at most {GRACE_MAX_S:g} s",
        examples=[0, 60],
    )

    @field_validator("constraints")
    @classmethod
    def _constraints(cls, value: dict[str, float]) -> dict[str, float]:
        """The core's rules on each bound, refused at the bound's own key (at the params
        before, away from the other constraint refusals, at ``constraints``); the rules
        between bounds (two units of one rate) at ``constraints``."""
        from inertia_id.search.objectives import check_constraints

        for name, bound in value.items():
            try:
                check_constraints({name: bound})
            except InputError as exc:
                # A ValidationError raised here is located below the field's own loc.
                error = PydanticCustomError("value_error", "{reason}", {"reason": str(exc)})
                raise ValidationError.from_exception_data(
                    cls.__name__, [InitErrorDetails(type=error, loc=(name,), input=bound)]
                ) from None
        check_constraints(value)
        return value

    @field_validator("nsga2")
    @classmethod
    def _nsga2(cls, value: dict[str, Any]) -> dict[str, Any]:
        from inertia_id.search.pareto import check_nsga2_params

        check_nsga2_params(value)
        return value

    @field_validator("cem")
    @classmethod
    def _cem(cls, value: dict[str, Any]) -> dict[str, Any]:
        from inertia_id.search.cem import check_cem_params

        defaults = _search_defaults()
        unknown = sorted(set(value) - set(defaults))
        if unknown:
            raise ValueError(f"unknown CEM setting(s) {unknown}; known: {sorted(defaults)}")
        check_cem_params(**{**defaults, **value})
        return value

    @field_validator("ppo")
    @classmethod
    def _ppo(cls, value: dict[str, Any]) -> dict[str, Any]:
        from inertia_id.search.ppo import check_ppo_params

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
        # The core's own rules for the scorer, so that a job the API accepts can start:
        # the worker builds its request from these parameters the same way.
        # options() holds the rule that each method's own settings (ppo, cem, nsga2,
        # lagrangian_lr) go with that method only, so the API refuses what the worker would.
        request = SearchRequest.from_params(self.model_dump(mode="json"))
        request.scorer().check()
        request.options()
        from inertia_id.search.objectives import (
            check_constraints,
            check_design_noise,
            check_objectives,
            check_per_flight_realisations,
        )

        check_objectives(self.objectives)
        check_design_noise(self.design_noise)
        check_constraints(self.constraints)
        # A per-flight bound needs enough realisations to estimate a spread (every method).
        check_per_flight_realisations(self.constraints, self.n_realisations)
        if "min_accuracy" in self.constraints and self.method != "nsga2":
            raise ValueError(
                f"constraint min_accuracy applies to method nsga2 only, not {self.method!r}"
            )
        if self.timesteps < self.sequence_length:
            raise ValueError(
                f"timesteps = {self.timesteps} must be at least one sequence "
                f"(sequence_length = {self.sequence_length})"
            )
        return self


class TrainParams(StrictModel):
    """Train a classifier for a given actuation sequence.

    ``kind`` chooses the classifier (the registry's kinds); with neither kind nor metric
    it is the default kind, and a metric alone means the paper's clustering. ``metric``
    applies to the kinds that take one and must be left out for the others.
    ``n_realisations`` defaults to the kind's own default. ``time_limit_s``, as a
    search's or sweep's: the training stops at its next checkpoint past it and the job
    fails naming the limit.
    """

    sequence: list[Annotated[list[int], Field(min_length=1, max_length=64)]] | None = Field(
        default=None,
        min_length=1,
        max_length=1000,
        description="L x N level indices, one row per step, one column per thruster; or "
        "leave it out and name search_job_id (and front_member). A job too large for a "
        "worker is refused (a series of at most 8,192 rate values, covariances of at most "
        "2^27 values), and so is one whose classifier document could pass the 1 GB a "
        "classifier file may hold: on the paper preset at most 72 steps for the default kind",
        examples=[[[4, 4, 4, 0, 0, 0]] * 4],
    )
    search_job_id: str | None = Field(
        default=None,
        max_length=64,
        description="train on a succeeded search job's sequence: its front member "
        "front_member, or its best sequence; the API fills in sequence from it",
    )
    front_member: int | None = Field(
        default=None,
        ge=0,
        le=10_000,
        description="with search_job_id: the index of the front member (0 = the most accurate)",
    )
    kind: str | None = Field(
        default=TrainRequest.default("kind"), max_length=40, json_schema_extra=_kinds_schema
    )
    metric: ClassifierMetric | None = TrainRequest.default("metric")
    n_realisations: int | None = Field(default=TrainRequest.default("n_realisations"), ge=1, le=400)
    # No grace beside it, as a search has: a training past its limit has nothing to
    # re-score, it stops and keeps nothing.
    time_limit_s: float | None = _time_limit_field()

    @model_validator(mode="after")
    def _metric_fits_kind(self) -> Self:
        from inertia_id.classifiers.registry import (
            default_realisations,
            kind_class,
            kind_metrics,
            make_classifier,
            resolve_kind,
        )

        if self.sequence is None and self.search_job_id is None:
            raise ValueError("give sequence, or search_job_id (and front_member)")
        if self.front_member is not None and self.search_job_id is None:
            raise ValueError("front_member applies with search_job_id")
        if self.kind is not None and self.kind not in classifier_kinds():
            raise ValueError(
                f"classifier kind must be one of {list(classifier_kinds())}, got {self.kind!r}"
            )
        kind = resolve_kind(self.kind, self.metric)
        self.kind = kind
        if self.n_realisations is None:
            self.n_realisations = default_realisations(kind)
        metrics = kind_metrics(kind)
        if self.metric is None and metrics:
            self.metric = metrics[0]  # type: ignore[assignment]
        elif self.metric is not None:
            if not metrics:
                raise ValueError(
                    f"the {kind!r} classifier takes no metric, got metric {self.metric!r}"
                )
            make_classifier(kind, metric=self.metric)
        least = kind_class(kind).MIN_REALISATIONS
        if self.n_realisations < least:
            raise ValueError(
                f"the {kind!r} classifier needs at least {least} realisations per candidate, "
                f"got n_realisations = {self.n_realisations}"
            )
        return self


def _sweep_multiples() -> list[float]:
    from inertia_id.evaluation.sweep import DEFAULT_MULTIPLES

    return [float(m) for m in DEFAULT_MULTIPLES]


def _sweep_noises() -> list[NoiseKind]:
    from inertia_id.evaluation.sweep import DEFAULT_NOISES

    return list(DEFAULT_NOISES)  # type: ignore[arg-type]


class SweepParams(StrictModel):
    """Classifier accuracy against noise multiples."""

    classifier_id: str = Field(max_length=64)
    multiples: list[float] = Field(
        default_factory=_sweep_multiples,
        min_length=1,
        max_length=20,
        description="noise multiples of each source's 1x level, each > 0 and at most 1000 "
        "(inertia_id.evaluation.sweep.MAX_MULTIPLE: beyond it the simulated rates lose "
        "accuracy and then overflow)",
    )
    noises: list[NoiseKind] = Field(
        default_factory=_sweep_noises,
        min_length=1,
        max_length=5,
        description="process, measurement, jitter, thrust_scale, gyro_bias: each scaled in "
        "turn, the others at 1x (a source the scenario leaves at 0 scales a reference level)",
    )
    others: list[Annotated[str, Field(max_length=40)]] = Field(
        default_factory=lambda: list(SweepRequest.default("others")),
        max_length=8,
        description="classifiers trained at 1x on the same sequence and scored on the same "
        "test series, as specs: 'least-squares' (the physics baseline), '1nn:euclidean', "
        "'nearest-centroid:dtw', 'minirocket', 'likelihood', 'clustering:euclidean'",
    )
    ceiling_realisations: int = Field(
        default=SweepRequest.default("ceiling_realisations"),
        ge=0,
        le=8000,
        description="the ceiling: at every point per-candidate Gaussians (a quadratic "
        "discriminant that knows the simulator) are fitted on this many realisations per "
        "candidate simulated at that point's noise and scored on the same series; 0 leaves "
        "it out, else at least 3. The default is where its accuracy stops moving as the "
        "count grows",
    )
    limit_realisations: int | None = Field(
        default=SweepRequest.default("limit_realisations"),
        ge=0,
        le=8000,
        description="deprecated name of ceiling_realisations (wins when given)",
        json_schema_extra={"deprecated": True},
    )
    n_train: int = Field(
        default=SweepRequest.default("n_train"),
        ge=3,
        le=200,
        description="training realisations per candidate for others",
    )
    inertia: bool = Field(
        default=SweepRequest.default("inertia"),
        description="also test bodies off the candidates (scaled, and between the closest "
        "two): how often identify says 'matches none'",
    )
    n_test: int = Field(default=SweepRequest.default("n_test"), ge=5, le=2000)
    time_limit_s: float | None = _time_limit_field()

    @field_validator("others")
    @classmethod
    def _specs(cls, value: list[str]) -> list[str]:
        from inertia_id.classifiers.registry import parse_spec

        for spec in value:
            parse_spec(spec)
        if len(set(value)) != len(value):
            raise ValueError(f"others names a classifier twice: {value}")
        return value

    @field_validator("multiples")
    @classmethod
    def _not_negative(cls, value: list[float]) -> list[float]:
        from inertia_id.evaluation.sweep import check_multiples

        # 0 is that source off (the others at 1x), as from the core and the CLI.
        bad = [m for m in value if not m >= 0]
        if bad:
            raise ValueError(f"noise multiples must be >= 0, got {bad} in {value}")
        return check_multiples(value)

    @field_validator("ceiling_realisations", "limit_realisations")
    @classmethod
    def _ceiling_size(cls, value: int | None, info: ValidationInfo) -> int | None:
        from inertia_id.evaluation.sweep import check_ceiling_realisations

        name = info.field_name or "ceiling_realisations"
        return None if value is None else check_ceiling_realisations(value, name)

    @field_validator("noises")
    @classmethod
    def _unique(cls, value: list[str]) -> list[str]:
        if len(set(value)) != len(value):
            raise ValueError(f"noises must not repeat, got {value}")
        return value

    @model_validator(mode="after")
    def _deprecated_name_moved(self) -> SweepParams:
        # The deprecated name wins when given (as documented): the job stores the count
        # that runs under its one name. Kept apart, a job given limit_realisations 200
        # showed ceiling_realisations 2000 beside it while its sweep used 200.
        if self.limit_realisations is not None:
            self.ceiling_realisations = self.limit_realisations
            self.limit_realisations = None
        return self


JobParams = SearchParams | TrainParams | SweepParams
#: The parameter model of each job type.
JOB_PARAMS: dict[str, type[StrictModel]] = {
    "search": SearchParams,
    "train": TrainParams,
    "sweep": SweepParams,
}


def parse_params(job_type: str, params: dict[str, Any]) -> StrictModel:
    """A stored job's params as its typed model (stored JSON is lax: lists for tuples).

    :raises InputError: one line naming each parameter that does not parse and its value.
    """
    model = JOB_PARAMS.get(job_type)
    if model is None:
        raise InputError(f"job type must be one of {sorted(JOB_PARAMS)}, got {job_type!r}")
    try:
        return model.model_validate(params, strict=False)
    except ValidationError as exc:
        problems = []
        for error in exc.errors(include_url=False):
            where = ".".join(str(part) for part in ("params", *error["loc"]))
            message = str(error["msg"]).removeprefix("Value error, ")
            # A validator's own message quotes the value already, as the API's errors do.
            quoted = error["type"] == "value_error"
            if (
                not quoted
                and "input" in error
                and isinstance(error["input"], str | int | float | bool)
            ):
                message = f"{message}, got {_clip(repr(error['input']))}"
            problems.append(f"{where}: {message}")
        raise InputError(f"the {job_type} job's parameters: {'; '.join(problems)}") from None
