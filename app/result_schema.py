"""What a job's ``result`` holds, per job type, for the OpenAPI schema only.

``JobOut.result`` is the worker's JSON as stored (``dict``); the routes return it
unchanged. These models describe it, and :func:`result_components` publishes them so that
``/openapi.json`` says, by the job's ``type``, which one a job's result is (``allOf`` of
``if type == ... then result is ...``, JSON Schema 2020-12, as OpenAPI 3.1 allows):

- ``train``: :class:`TrainJobResult`, every field (unknown ones forbidden);
- ``sweep``: :class:`SweepJobResult`, the core's own :class:`~inertia_id.evaluation.sweep.
  SweepResult` and :class:`~inertia_id.evaluation.sweep.InertiaSweepResult` models, with
  what the worker adds (``stopped``, ``time_limit_s``);
- ``search``: :class:`SearchJobResult`, its top-level fields and their types; what lies
  inside ``best``, ``fresh``, ``curve``, ``front``, ``baselines``, ``settings`` and
  ``scenario`` is described as objects (arrays of objects) whose fields are open: the
  front's members and scores are read by name in README's "front" table, not here.

A stored result is null while a job runs, and may be a partial one when a search is
cancelled (its best kept, ``front`` null, each baseline ``unavailable``).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from inertia_id.evaluation.sweep import InertiaSweepResult, SweepResult

__all__ = ["JOB_RESULTS", "add_result_schemas", "result_components"]


class TrainJobResult(BaseModel):
    """A training's result (:meth:`inertia_id.pipelines.Trained.summary`, with the
    ``classifier_id`` and ``sha256`` of the row the runner stores). Fields added after
    the first release are optional: a result stored before them lacks them (``kind``
    before every kind could be trained, ``warnings`` before weak responses were
    warned of)."""

    model_config = ConfigDict(extra="forbid")

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

    inertia: InertiaSweepResult | None = Field(
        default=None, description="bodies off the candidates, when the sweep asked (inertia)"
    )
    stopped: Literal["time_limit"] | None = Field(
        default=None, description="time_limit: stopped by the job's time limit"
    )
    time_limit_s: float | None = Field(default=None, description="that limit, s")


class _Open(BaseModel):
    model_config = ConfigDict(extra="allow")


class SearchFront(_Open):
    """A front (:class:`inertia_id.search.pareto.Front` as a dict); fields beyond these
    are open."""

    objectives: list[str]
    constraints: dict[str, float]
    members: list[dict[str, Any]] = Field(
        description="each with index, sequence, scores, search_scores, feasible, "
        "dominated_by, fires"
    )
    baselines: dict[str, dict[str, Any]] = Field(
        description="by name: sequence, scores, feasible, dominates; or unavailable"
    )


class SearchJobResult(_Open):
    """A search's result (:meth:`inertia_id.pipelines.SearchOutcome.to_dict`): its top
    level; fields beyond these (``policy_sha256`` of a PPO search) are open. ``front``
    and ``baselines`` are optional: a result stored before them lacks them."""

    method: Literal["ppo", "cem", "exhaustive", "random", "nsga2"]
    best: dict[str, Any] = Field(description="the best sequence and its scores")
    fresh: dict[str, Any] = Field(description="the best re-scored on fresh draws")
    curve: list[dict[str, Any]] = Field(description="the learning curve's points")
    timesteps: int
    episodes: int
    wall_time_s: float
    stopped: str
    space_size: int
    settings: dict[str, Any]
    policy_path: str | None
    cache_hits: int
    cache_misses: int
    front: SearchFront | None = Field(
        default=None,
        description="the front on fresh draws; null when cancelled, absent in results "
        "stored before fronts",
    )
    baselines: dict[str, dict[str, Any]] = Field(
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


def result_by_type() -> list[dict[str, Any]]:
    """``if type == T then result is T's model (or null)``, one clause a job type: what a
    job's schema gains (a result left out of a list's job stays allowed)."""
    return [
        {
            "if": {"properties": {"type": {"const": job_type}}, "required": ["type"]},
            "then": {
                "properties": {
                    "result": {
                        "anyOf": [{"$ref": _REF.format(model=model.__name__)}, {"type": "null"}]
                    }
                }
            },
        }
        for job_type, model in JOB_RESULTS.items()
    ]


def add_result_schemas(schema: dict[str, Any]) -> None:
    """Publish the result models in an OpenAPI document: as components, in every job
    model (by its type), and in ``GET /jobs/{id}/result``'s JSON (the job, its
    ``config_hash`` left out, or a table's rows)."""
    schemas = schema.setdefault("components", {}).setdefault("schemas", {})
    for name, component in result_components().items():
        schemas.setdefault(name, component)
    for name in ("JobOut", "JobSubmitted", "JobListed"):
        job = schemas.get(name)
        if job is None:
            continue
        job["allOf"] = [*job.get("allOf", []), *result_by_type()]
        job["properties"]["result"]["description"] = (
            job["properties"]["result"].get("description", "")
            + "; by the job's type: search SearchJobResult, train TrainJobResult, sweep "
            "SweepJobResult"
        ).lstrip("; ")
    if "JobOut" in schemas:
        download = {
            **schemas["JobOut"],
            "title": "JobDownload",
            "description": "the job as GET /jobs/{id}/result?format=json writes it: "
            "JobOut without config_hash",
            "properties": {
                k: v for k, v in schemas["JobOut"]["properties"].items() if k != "config_hash"
            },
            "required": [r for r in schemas["JobOut"].get("required", []) if r != "config_hash"],
        }
        schemas["JobDownload"] = download
        operation = schema.get("paths", {}).get("/jobs/{job_id}/result", {}).get("get")
        if operation is not None:
            content = operation["responses"]["200"]["content"]["application/json"]
            content["schema"] = {
                "anyOf": [
                    {"$ref": _REF.format(model="JobDownload")},
                    {"type": "array", "items": {"type": "object"}},
                ]
            }
