"""The domain's words, as the core defines them, for clients that show or ask for them.

The dashboard reads this instead of restating the core: which classifier kinds exist and
what each takes, which sources of error a sweep can scale and in what units, the search
methods and objectives, the job types and statuses. One request at start, cached by the
client.
"""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from service.exports import RESULT_TABLES
from service.store.models import JOB_STATUSES, JOB_TYPES, STOPPED_REASONS, TERMINAL_STATUSES
from service.summaries import SUMMARY_COLUMNS

from .routing import UniqueKeysRoute

__all__ = ["router"]

router = APIRouter(tags=["vocabulary"], route_class=UniqueKeysRoute)


class KindOut(BaseModel):
    kind: str
    label: str
    metrics: list[str] = Field(description="the metrics it takes, its default first; empty: none")
    default_realisations: int
    min_realisations: int
    online: bool = Field(
        description="a posterior for part of a series (POST /identify/partial): the "
        "likelihood kinds"
    )


class NoiseOut(BaseModel):
    noise: str
    label: str
    unit: str
    reference_level: float | None = Field(
        description="the 1x level used where a scenario leaves this source at 0"
    )


class NamedOut(BaseModel):
    name: str
    label: str


class SummaryColumnOut(BaseModel):
    key: str = Field(description="in a job's summary, and a GET /jobs sort key")
    label: str
    unit: str = Field(description='SI unit; "" for a fraction or a count')
    better: str = Field(description="high or low")
    digits: int = Field(
        description='decimals to show a fraction (unit "") with; 0 for a count; the '
        "dashboard writes a figure with a unit to three significant digits"
    )


class ResultTableOut(BaseModel):
    name: str = Field(description="GET /jobs/{id}/result?format=csv&table=NAME")
    label: str


class OperatorObjectiveOut(BaseModel):
    name: str
    label: str
    sense: str = Field(description="min or max")
    unit: str


class ConstraintOut(BaseModel):
    name: str
    bounds: str = Field(
        description="the figure it bounds: an objective's name, or "
        "commanded_residual_rate (the residual the command plan predicts from rest with "
        "every noise off, which every front member and baseline reports beside final_rate; "
        "no objective)"
    )
    sense: str = Field(description="max: the figure <= the bound; min: >=")
    worst_candidate: bool = Field(
        default=False,
        description="the bound holds for the candidate with the largest figure (the "
        "objective itself is the mean over candidates)",
    )
    flight_quantile: float | None = Field(
        default=None,
        description="the bound holds on at least this fraction of the candidate's "
        "flights, with flight_confidence (a front reads it from flights of its own, "
        "distribution-free); null: on their mean",
    )
    flight_confidence: float | None = Field(
        default=None, description="the confidence with which the per-flight bound holds"
    )


class VocabularyOut(BaseModel):
    classifier_kinds: list[KindOut]
    default_kind: str
    kind_for_metric_only: str = Field(description="the kind a metric alone asks for")
    noises: list[NoiseOut]
    default_noises: list[str]
    default_multiples: list[float]
    search_methods: list[NamedOut]
    search_objectives: list[NamedOut]
    operator_objectives: list[OperatorObjectiveOut] = Field(
        description="what a Pareto search (method nsga2) may trade off, and what every "
        "search's best sequence is judged on"
    )
    default_operator_objectives: list[str]
    default_design_noise: list[list[float]] = Field(
        description="[process multiple, measurement multiple] conditions of the accuracy objective"
    )
    constraints: list[ConstraintOut] = Field(description="bounds a search may be given")
    nsga2_defaults: dict[str, int | float] = Field(description="NSGA-II's settings by default")
    baselines: list[str] = Field(description="baseline sequences: GET /scenarios/{id}/baselines")
    job_types: list[str]
    job_statuses: list[str]
    terminal_statuses: list[str]
    stopped_reasons: list[str] = Field(
        description="what may have stopped a finished job short of its own end: a job's "
        "stopped, and GET /jobs?stopped="
    )
    job_summaries: dict[str, list[SummaryColumnOut]] = Field(
        description="each job type's headline figures: list columns and sort keys"
    )
    result_tables: dict[str, list[ResultTableOut]] = Field(
        description="each job type's result tables, as CSV downloads"
    )


_OBJECTIVE_LABELS = {
    "f1": "clustering F1 (the paper's)",
    "separability": "separability bound (fast, no clustering)",
}


@router.get("/vocabulary")
def vocabulary() -> VocabularyOut:
    """Classifier kinds, noise sources, search methods and objectives, job types and
    statuses: the words the core and the service use, with labels for people."""
    from inertia_id.classifiers.registry import (
        CLASSIFIER_KINDS,
        DEFAULT_KIND,
        kind_class,
        resolve_kind,
    )
    from inertia_id.evaluation.sweep import (
        DEFAULT_MULTIPLES,
        DEFAULT_NOISES,
        NOISE_KINDS,
        NOISE_LABELS,
        NOISE_UNITS,
        REFERENCE_LEVELS,
    )
    from inertia_id.physics.sequences import BASELINES
    from inertia_id.pipelines import SearchRequest
    from inertia_id.search import SCORER_OBJECTIVES, SEARCH_METHOD_LABELS, SEARCH_METHODS
    from inertia_id.search.objectives import (
        CONSTRAINTS,
        FLIGHT_CONFIDENCE,
        FLIGHT_QUANTILE,
        OBJECTIVE_FIELDS,
        OPERATOR_OBJECTIVES,
    )
    from inertia_id.search.pareto import NSGA2_DEFAULTS

    by_field = {figure: name for name, figure in OBJECTIVE_FIELDS.items()}
    # Figures of the worst candidate (its mean, or the rate 95 % of its flights stay under)
    worst = {
        "final_rate_max_rad_s": "final_rate",
        "final_rate_p95_rad_s": "final_rate",
        "commanded_residual_rate_max_rad_s": "commanded_residual_rate",
    }
    # Figures reported beside the objectives, bounded by a constraint of their own.
    by_field["commanded_residual_rate_rad_s"] = "commanded_residual_rate"
    # Figures bounded on 95 % of flights (the peak's objective is the fastest candidate's
    # already), and the objective each one bounds.
    per_flight = {"final_rate_p95_rad_s": "final_rate", "peak_rate_p95_rad_s": "peak_rate"}
    defaults = SearchRequest(method="nsga2")

    kinds = []
    for kind in CLASSIFIER_KINDS:
        cls = kind_class(kind)
        kinds.append(
            KindOut(
                kind=kind,
                label=cls.LABEL or kind,
                metrics=list(cls.METRICS),
                default_realisations=int(cls.DEFAULT_REALISATIONS),
                min_realisations=int(cls.MIN_REALISATIONS),
                online=cls.has_partial_posterior(),
            )
        )
    return VocabularyOut(
        classifier_kinds=kinds,
        default_kind=DEFAULT_KIND,
        kind_for_metric_only=resolve_kind(None, "dtw"),
        noises=[
            NoiseOut(
                noise=noise,
                label=NOISE_LABELS[noise],
                unit=NOISE_UNITS[noise],
                reference_level=REFERENCE_LEVELS.get(noise),
            )
            for noise in NOISE_KINDS
        ],
        default_noises=list(DEFAULT_NOISES),
        default_multiples=[float(m) for m in DEFAULT_MULTIPLES],
        search_methods=[NamedOut(name=m, label=SEARCH_METHOD_LABELS[m]) for m in SEARCH_METHODS],
        search_objectives=[
            NamedOut(name=o, label=_OBJECTIVE_LABELS.get(o, o)) for o in SCORER_OBJECTIVES
        ],
        operator_objectives=[
            OperatorObjectiveOut(name=name, label=label, sense=sense, unit=unit)
            for name, (label, sense, unit) in OPERATOR_OBJECTIVES.items()
        ],
        default_operator_objectives=list(defaults.objectives),
        default_design_noise=[[float(p), float(q)] for p, q in defaults.design_noise],
        constraints=[
            ConstraintOut(
                name=name,
                bounds=worst.get(figure) or per_flight.get(figure) or by_field[figure],
                sense=sense,
                worst_candidate=figure in worst,
                flight_quantile=FLIGHT_QUANTILE if figure in per_flight else None,
                flight_confidence=FLIGHT_CONFIDENCE if figure in per_flight else None,
            )
            for name, (figure, sense, _) in CONSTRAINTS.items()
        ],
        nsga2_defaults=dict(NSGA2_DEFAULTS),
        baselines=list(BASELINES),
        job_types=list(JOB_TYPES),
        job_statuses=list(JOB_STATUSES),
        terminal_statuses=list(TERMINAL_STATUSES),
        stopped_reasons=list(STOPPED_REASONS),
        job_summaries={
            job_type: [SummaryColumnOut(**c.as_dict()) for c in columns]
            for job_type, columns in SUMMARY_COLUMNS.items()
        },
        result_tables={
            job_type: [ResultTableOut(name=n, label=label) for n, (label, _) in tables.items()]
            for job_type, tables in RESULT_TABLES.items()
        },
    )
