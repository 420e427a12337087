"""What a job's ``result`` holds, per job type, for the OpenAPI schema only.

``JobOut.result`` is the worker's JSON as stored (``dict``); the routes return it
unchanged. These models describe it, and :func:`add_result_schemas` publishes them so that
``/openapi.json`` says, by the job's ``type``, which one a job's result is: ``JobOut``,
``JobSubmitted``, ``JobListed`` and ``JobDownload`` are each a ``oneOf`` of one variant a
job type (``SearchJobOut``, ``TrainJobOut``, ``SweepJobOut``, ...: the job with ``type``
that one value and ``result`` that type's model or null) with an OpenAPI
``discriminator`` on ``type``, which client generators turn into a tagged union (an
``if``/``then`` per type, before, most of them ignored):

- ``train``: :class:`TrainJobResult`, every field;
- ``sweep``: :class:`SweepJobResult`, the core's own :class:`~inertia_id.evaluation.sweep.
  SweepResult` and :class:`~inertia_id.evaluation.sweep.InertiaSweepResult` models, with
  what the worker adds (``stopped``, ``time_limit_s``);
- ``search``: :class:`SearchJobResult`, with its nested parts (``best``, ``fresh``, the
  ``curve``'s points, the ``front``'s members, scores, baselines and confirmation, the
  hand-designed ``baselines``); its ``settings`` (each method's own) and ``scenario``
  (``POST /scenarios``' document) are open objects.

The published models allow fields they do not list (``additionalProperties`` true), so
that a client validating strictly against ``/openapi.json`` still reads what a later
release adds. :func:`strict_document` closes them again (each described object refuses
an unknown field): the tests validate real results against it, so a field the code emits
and the models do not describe fails there. A field added after the first release is
optional: a result stored before it lacks it. A stored result is null while a job runs,
and may be a partial one when a search is cancelled (its best kept, ``front`` null, each
baseline ``unavailable``).
"""

from __future__ import annotations

import copy
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from inertia_id.evaluation.sweep import InertiaSweepResult, SweepResult

__all__ = ["JOB_RESULTS", "add_result_schemas", "result_components", "strict_document"]


class _Open(BaseModel):
    """A described object that allows fields it does not list (a later release's)."""

    model_config = ConfigDict(extra="allow")


class TrainJobResult(_Open):
    """A training's result (:meth:`inertia_id.pipelines.Trained.summary`, with the
    ``classifier_id`` and ``sha256`` of the row the runner stores). Fields added after
    the first release are optional: a result stored before them lacks them (``kind``
    before every kind could be trained, ``warnings`` before weak responses were
    warned of)."""

    classifier_id: str = Field(description="the stored classifier (GET /classifiers/{id})")
    sha256: str = Field(description="the stored classifier document's checksum")
    kind: str | None = Field(
        default=None, description="the classifier kind trained; absent in older results"
    )
    metric: str | None = Field(description="its distance, for the kinds that take one")
    f1: float | None = Field(description="macro F1 on its training series")
    accuracy: float | None
    confusion: list[list[int]] = Field(description="(K, K) true candidate x predicted")
    candidate_names: list[str]
    sequence: list[list[int]]
    n_realisations: int = Field(description="training realisations per candidate")
    warnings: list[str] = Field(
        default_factory=list, description="what the training warns of; absent in older results"
    )


class SweepJobResult(SweepResult):
    """A sweep's result (:meth:`inertia_id.pipelines.SweepOutcome.to_dict`)."""

    model_config = ConfigDict(extra="allow")

    run_seed: int | None = Field(
        default=None,
        description="the job's seed, which gives this result again; `seed` is the test "
        "series' stream derived from it (up to 2**32 - 1, not a job's seed); absent in "
        "older results",
    )
    inertia: InertiaSweepResult | None = Field(
        default=None, description="bodies off the candidates, when the sweep asked (inertia)"
    )
    stopped: Literal["time_limit"] | None = Field(
        default=None, description="time_limit: stopped by the job's time limit"
    )
    time_limit_s: float | None = Field(default=None, description="that limit, s")


Sequence = list[list[int]]


class SearchBest(_Open):
    """The best sequence a search found and what it saw of it
    (:class:`~inertia_id.search.records.EpisodeRecord`)."""

    sequence: Sequence = Field(description="(L, N) level indices")
    f1: float | None = Field(description="what the search ranked by: best.score_name")
    final_rate_rad_s: float | None = Field(description="mean |ω| when the last command ends")
    fuel_nms: float = Field(description="commanded angular impulse, N m s")
    episode_return: float | None = Field(description="the environment's summed reward")
    episode: int = Field(description="1-based episode in which it was found")
    constraint_violation: float | None = Field(
        default=None, description="summed relative violation of the constraints (0: hold)"
    )
    residual_rate_rad_s: float | None = Field(
        default=None, description="|ω| once the lag has delivered its torque, mean over candidates"
    )
    score_name: str | None = Field(
        default=None, description="f1, separability or predicted_accuracy"
    )
    score_meaning: str | None = Field(default=None, description="score_name in words")


class SearchFresh(_Open):
    """The best re-scored on fresh draws (:class:`~inertia_id.search.records.
    FreshEvaluation`); no draw in a cancelled search."""

    seed: int = Field(description="the independent seed the draws came from")
    f1: list[float | None] = Field(description="clustering F1 on each draw")
    final_rate_rad_s: list[float | None] = Field(description="mean final rate on each draw")
    separability: list[float | None] | None = Field(
        default=None, description="the separability score on each draw, for that objective"
    )
    draws_asked: int | None = Field(
        default=None, description="the draws asked for (more than f1 holds when stopped)"
    )
    f1_mean: float | None = Field(default=None, description="null without draws")
    f1_min: float | None = Field(default=None, description="null without draws")


class SearchCurvePoint(_Open):
    """The learning curve at one report (:class:`~inertia_id.search.records.CurvePoint`);
    null figures before any episode."""

    timesteps: int
    episodes: int
    mean_episode_reward: float | None
    mean_f1: float | None
    best_f1: float | None
    best_residual_rate_rad_s: float | None = Field(
        default=None, description="rad/s; results stored before it have best_final_rate_rad_s"
    )
    best_final_rate_rad_s: float | None = Field(
        default=None,
        description="rad/s, in results stored before best_residual_rate_rad_s (b4cfab5) "
        "only: NSGA-II's residual rate, the other methods' |ω| when the last command ends",
    )
    best_feasible: bool | None = Field(
        default=None,
        description="whether the best so far meets the search's constraints (always true "
        "without constraints; while none has, the best is the most accurate of all); null "
        "in results stored before it",
    )


class SearchScores(_Open):
    """A sequence's figures on the operator's objectives (:meth:`~inertia_id.search.
    objectives.SequenceScores.as_dict`); the p95 and commanded figures are null where not
    measured, and absent in results stored before them."""

    accuracy: float = Field(description="mean over the design noise")
    accuracy_by_noise: list[float]
    final_rate_rad_s: float
    final_rate_deg_s: float
    final_rate_max_rad_s: float
    final_rate_max_deg_s: float
    final_rate_p95_rad_s: float | None = None
    final_rate_p95_deg_s: float | None = None
    commanded_residual_rate_rad_s: float | None = None
    commanded_residual_rate_deg_s: float | None = None
    commanded_residual_rate_max_rad_s: float | None = None
    commanded_residual_rate_max_deg_s: float | None = None
    peak_rate_rad_s: float
    peak_rate_deg_s: float
    peak_rate_p95_rad_s: float | None = None
    peak_rate_p95_deg_s: float | None = None
    impulse_nms: float
    on_time_s: float
    propellant_kg: float | None = Field(description="null unless thrust and Isp are stated")
    duration_s: float
    attitude_change_deg: float = Field(
        description="the net rotation when the last command ends, degrees (0 to 180), "
        "of the candidate that turns most"
    )
    predicted_accuracy_by_noise: list[float] | None = Field(
        default=None, description="the prediction a measured accuracy replaced"
    )


class SearchFrontMember(_Open):
    """One member of the front (README's "front" table)."""

    index: int = Field(description="stable, 0 = most accurate")
    sequence: Sequence
    scores: SearchScores = Field(description="on the fresh draw")
    search_scores: SearchScores | None = Field(description="what the search saw, when known")
    feasible: bool
    dominated_by: list[str] = Field(description="the baselines that dominate it")
    fires: bool | None = Field(
        default=None, description="false: it applies no torque (no classifier trains on it)"
    )


class SearchFrontBaseline(_Open):
    """A hand-designed baseline scored beside the front, on the same draw."""

    sequence: Sequence
    scores: SearchScores
    feasible: bool
    dominates: list[int] = Field(description="indices of the members it dominates")
    fires: bool | None = Field(
        default=None, description="false: it applies no torque (no classifier trains on it)"
    )


class Unavailable(_Open):
    """A baseline the geometry or the length does not allow, or one left unscored."""

    unavailable: str = Field(description="why")


class SearchConfirmationFigures(_Open):
    accuracy: float
    accuracy_by_noise: list[float]
    interval_by_noise: list[list[float]] = Field(description="Wilson 95 % interval per noise")


class SearchConfirmationBaseline(SearchConfirmationFigures):
    dominates_member_0: bool | None = None


class SearchConfirmation(SearchConfirmationFigures):
    """Member 0 measured again on independent series, with the baselines that could
    dominate it."""

    member: int
    seed: int
    test_series: int
    series_per_condition: int
    baselines: dict[str, SearchConfirmationBaseline] | None = Field(
        default=None,
        description="by name; absent in confirmations stored before the baselines were "
        "measured on its series (13426f5)",
    )


class SearchNotRescored(_Open):
    """A candidate left out once the re-score was stopped (a time limit's grace spent)."""

    sequence: Sequence
    search_scores: SearchScores | None


class SearchFront(_Open):
    """A front (:class:`inertia_id.search.pareto.Front` as a dict)."""

    objectives: list[str]
    design_noise: list[list[float]] = Field(description="(noise multiple pairs) designed at")
    constraints: dict[str, float]
    n_realisations: int
    fresh_seed: int
    fresh_realisations: int
    fresh_test_series: int | None = None
    accuracy_source: Literal["measured", "predicted"] | None = None
    candidates_rescored: int
    members: list[SearchFrontMember]
    baselines: dict[str, SearchFrontBaseline | Unavailable] = Field(
        description="by name: scored beside the members, or unavailable (why)"
    )
    dominated_by_baseline: bool
    confirmation: SearchConfirmation | None = Field(
        default=None, description="null when nothing was chosen, predicted or stopped"
    )
    measurement_stopped: bool | None = None
    not_rescored: list[SearchNotRescored] = Field(default_factory=list)


class SearchBaseline(_Open):
    """A hand-designed baseline on the best's fresh draws
    (:func:`~inertia_id.search.baselines.compare_with_baselines`)."""

    sequence: Sequence
    fresh_f1: list[float | None]
    fresh_final_rate_rad_s: list[float | None]
    fuel_nms: float


class SearchFiringsTakenOff(_Open):
    """What the best sequence found fired for no torque, taken off after the search."""

    sequence_found: Sequence = Field(description="the best sequence as the search found it")
    score_found: float = Field(
        description="its score on the search's draw (what best.f1 holds: best.score_name)"
    )
    impulse_found_nms: float = Field(description="its impulse, N m s")
    impulse_saved_nms: float = Field(description="impulse taken off, N m s")
    on_time_saved_s: float = Field(description="thruster on-time taken off, s")
    steps: list[int] = Field(description="the steps changed, from 1")


class SearchJobResult(_Open):
    """A search's result (:meth:`inertia_id.pipelines.SearchOutcome.to_dict`);
    ``front`` and ``baselines`` are optional: a result stored before them lacks them."""

    method: Literal["ppo", "cem", "exhaustive", "random", "nsga2"]
    best: SearchBest = Field(description="the best sequence and its scores")
    fresh: SearchFresh = Field(description="the best re-scored on fresh draws")
    curve: list[SearchCurvePoint] = Field(description="the learning curve's points")
    timesteps: int
    episodes: int
    wall_time_s: float
    stopped: str = Field(
        description="budget, target, cancelled, time_limit, exhausted or converged"
    )
    space_size: int
    settings: dict[str, Any] = Field(description="the search's parameters (per method)")
    policy_path: str | None
    cache_hits: int
    cache_misses: int
    policy_sha256: str | None = Field(default=None, description="a PPO search's policy")
    firings_taken_off: SearchFiringsTakenOff | None = Field(
        default=None,
        description="firings of the sequence found whose torques cancelled, taken off its "
        "best after the search (the same torque each step, less impulse); null when none "
        "cancelled, absent in results stored before it",
    )
    front: SearchFront | None = Field(
        default=None,
        description="the front on fresh draws; null when cancelled, absent in results "
        "stored before fronts",
    )
    baselines: dict[str, SearchBaseline | Unavailable] = Field(
        default_factory=dict,
        description="the hand-designed baselines by name; absent in results stored before them",
    )
    scenario: dict[str, Any] | None = Field(
        default=None, description="the scenario searched (POST /scenarios' document)"
    )


#: Job type -> the model of its result.
JOB_RESULTS: dict[str, type[BaseModel]] = {
    "search": SearchJobResult,
    "train": TrainJobResult,
    "sweep": SweepJobResult,
}

_REF = "#/components/schemas/{model}"


def result_components() -> dict[str, Any]:
    """Each job type's result model and the models it refers to, as components."""
    components: dict[str, Any] = {}
    for model in JOB_RESULTS.values():
        schema = model.model_json_schema(mode="serialization", ref_template=_REF)
        components.update(schema.pop("$defs", {}))
        components[model.__name__] = schema
    return components


#: The job models whose ``result`` is described by the job's type.
JOB_MODELS = ("JobOut", "JobSubmitted", "JobListed")


def _variant_name(job_type: str, job_model: str) -> str:
    return f"{job_type.capitalize()}{job_model}"


def _by_type(schemas: dict[str, Any], name: str, base: dict[str, Any]) -> None:
    """``schemas[name]`` becomes a ``oneOf`` of ``base`` narrowed to each job type
    (``type`` that value, ``result`` its model or null), with a discriminator on
    ``type``; each narrowed copy is a component of its own."""
    mapping = {}
    for job_type, model in JOB_RESULTS.items():
        variant = _variant_name(job_type, name)
        properties = dict(base["properties"])
        properties["type"] = {**properties["type"], "const": job_type}
        result = properties["result"]
        properties["result"] = {
            **{
                k: v
                for k, v in result.items()
                if k not in ("anyOf", "type", "additionalProperties")
            },
            "anyOf": [{"$ref": _REF.format(model=model.__name__)}, {"type": "null"}],
            "description": f"the {job_type} job's result ({model.__name__}); "
            + result.get("description", ""),
        }
        schemas[variant] = {
            **base,
            "title": variant,
            "description": f"{base.get('description') or name}: a {job_type} job",
            "properties": properties,
        }
        mapping[job_type] = _REF.format(model=variant)
    schemas[name] = {
        "title": name,
        "description": (base.get("description") or name)
        + " (one variant a job type, told apart by type: the discriminator)",
        "oneOf": [{"$ref": ref} for ref in mapping.values()],
        "discriminator": {"propertyName": "type", "mapping": mapping},
    }


def add_result_schemas(schema: dict[str, Any]) -> None:
    """Publish the result models in an OpenAPI document: as components, and in every job
    model and ``GET /jobs/{id}/result``'s JSON (the job, its ``config_hash`` left out, or
    a table's rows) as a ``oneOf`` by the job's type, with a discriminator."""
    schemas = schema.setdefault("components", {}).setdefault("schemas", {})
    for name, component in result_components().items():
        schemas.setdefault(name, component)
    job_out = copy.deepcopy(schemas.get("JobOut"))
    for name in JOB_MODELS:
        if name in schemas:
            _by_type(schemas, name, schemas[name])
    if job_out is None:
        return
    download = {
        **job_out,
        "title": "JobDownload",
        "description": "the job as GET /jobs/{id}/result?format=json writes it: "
        "JobOut without config_hash",
        "properties": {k: v for k, v in job_out["properties"].items() if k != "config_hash"},
        "required": [r for r in job_out.get("required", []) if r != "config_hash"],
    }
    _by_type(schemas, "JobDownload", download)
    operation = schema.get("paths", {}).get("/jobs/{job_id}/result", {}).get("get")
    if operation is not None:
        content = operation["responses"]["200"]["content"]["application/json"]
        content["schema"] = {
            "anyOf": [
                {"$ref": _REF.format(model="JobDownload")},
                {"type": "array", "items": {"type": "object"}},
            ]
        }


def strict_document(document: dict[str, Any]) -> dict[str, Any]:
    """A copy of an OpenAPI document (or any JSON Schema) whose described objects refuse
    the fields they do not list: every schema with ``properties`` gets
    ``additionalProperties: false`` (an open mapping, such as a search's ``settings``,
    lists none and stays open). The published document allows unknown fields, for the
    clients of a later release; the tests validate real answers against this one, so a
    field the code emits and the models do not describe fails."""
    out = copy.deepcopy(document)

    def close(node: Any) -> None:
        if isinstance(node, dict):
            if (
                isinstance(node.get("properties"), dict)
                and node.get("additionalProperties", True) is True
            ):
                node["additionalProperties"] = False
            for value in node.values():
                close(value)
        elif isinstance(node, list):
            for value in node:
                close(value)

    close(out)
    return out
