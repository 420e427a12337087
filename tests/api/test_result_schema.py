"""Job results against the schema ``/openapi.json`` publishes for them, per job type.

The published models allow fields they do not list (a client validating strictly against
``/openapi.json`` reads a later release's results); real results are validated against
its strict variant (:func:`app.result_schema.strict_document`, every described object
closed), so that a field the code emits and the models do not describe fails here.

Before, ``result`` was ``{"type": "object"}`` (``additionalProperties: true``) in every job
model and ``GET /jobs/{id}/result?format=json`` an untyped object: a client learnt
nothing of a training's, a sweep's or a search's result. Each is now described by the
job's ``type`` (train and sweep field by field, a search at its top level), and real
results, from the pipelines the workers run, are validated against the published
document: every way a job is read (``GET /jobs/{id}``, ``GET /jobs?include=result``, the
JSON download).
"""

from __future__ import annotations

import json
from typing import Any

import jsonschema_rs
import pytest

from app.result_schema import strict_document
from inertia_id import InertiaClassifier, Scenario
from inertia_id.pipelines import (
    SearchRequest,
    SweepRequest,
    Trained,
    search_with_baselines,
    sweep_with_limit,
)
from service.store.jobs import claim, finish

from .support import GOOD_SEQUENCE, Api


def _validator(spec: dict[str, Any], schema: dict[str, Any]) -> Any:
    return jsonschema_rs.Draft202012Validator({**schema, "components": spec["components"]})


def _errors(validator: Any, document: Any) -> list[str]:
    return [f"{list(e.instance_path)}: {e.message}" for e in validator.iter_errors(document)]


def _finished(
    api: Api, job_type: str, scenario_id: str, params: dict[str, Any], result: Any
) -> str:
    submitted = api.submit(job_type, scenario_id, params=params)
    assert submitted.status_code == 202, submitted.text
    job_id: str = submitted.json()["id"]
    with api.db.session() as session:
        claim(session, job_id, "tests")
    with api.db.session() as session:
        assert finish(session, job_id, "succeeded", result=result)
    return job_id


@pytest.fixture(scope="module")
def results(classifier: InertiaClassifier) -> dict[str, dict[str, Any]]:
    """A result of each job type, as its worker writes it (small settings)."""
    paper = Scenario.paper()
    search = search_with_baselines(
        paper,
        SearchRequest(
            method="random",
            sequence_length=2,
            timesteps=8,
            n_realisations=4,
            fresh_test_series=0,
            fresh_realisations=4,
        ),
        seed=0,
    )
    sweep = sweep_with_limit(
        classifier,
        SweepRequest(multiples=[1.0], n_test=5, ceiling_realisations=0, others=(), inertia=True),
        seed=0,
        scenario=paper,
    )
    return {
        "search": search.to_dict(),
        # As the runner stores it: the summary with the stored classifier's id and checksum.
        "train": {
            **Trained(classifier, "clustering", 10, ()).summary(),
            "classifier_id": "0" * 32,
            "sha256": "0" * 64,
        },
        "sweep": sweep.to_dict(),
    }


def test_each_job_types_result_is_what_the_published_schema_says(
    api: Api, classifier: InertiaClassifier, results: dict[str, dict[str, Any]]
) -> None:
    spec = strict_document(api.get("/openapi.json").json())
    schemas = spec["components"]["schemas"]
    one = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    listed = _validator(spec, {"$ref": "#/components/schemas/JobListed"})
    operation = spec["paths"]["/jobs/{job_id}/result"]["get"]
    download = _validator(
        spec, operation["responses"]["200"]["content"]["application/json"]["schema"]
    )
    scenario_id = api.create_scenario()["id"]
    params = {
        "search": {"method": "random", "sequence_length": 2, "timesteps": 8},
        "train": {"sequence": GOOD_SEQUENCE},
        "sweep": {"classifier_id": api.insert_classifier(scenario_id, classifier)},
    }
    models = {"search": "SearchJobResult", "train": "TrainJobResult", "sweep": "SweepJobResult"}
    for job_type, model in models.items():
        assert model in schemas
        job_id = _finished(api, job_type, scenario_id, params[job_type], results[job_type])
        job = api.get(f"/jobs/{job_id}").json()
        assert job["result"] is not None
        assert _errors(one, job) == [], job_type
        items = api.get("/jobs", params={"include": "result", "type": job_type}).json()["items"]
        assert items and all(_errors(listed, item) == [] for item in items), job_type
        whole = api.get(f"/jobs/{job_id}/result", params={"format": "json"}).json()
        assert "config_hash" not in whole
        assert _errors(download, whole) == [], job_type
        # The description is by type: the result read as another type's fails.
        for other in models:
            if other != job_type:
                assert _errors(one, {**job, "type": other}), (job_type, other)


@pytest.mark.parametrize(
    ("job_type", "change", "path"),
    [
        ("train", lambda r: r.update(unknown=1), "[]"),
        ("train", lambda r: r.pop("confusion"), "[]"),
        (
            "sweep",
            lambda r: r["points"][0].update(accuracy="high"),
            "['points', 0, 'accuracy']",
        ),
        ("search", lambda r: r.update(method="annealing"), "['method']"),
        ("search", lambda r: r.pop("best"), "[]"),
        # A search's nested parts are described too (before, open objects).
        ("search", lambda r: r["best"].update(sequence=[["4"]]), "['best', 'sequence', 0, 0]"),
        ("search", lambda r: r["curve"][0].pop("timesteps"), "['curve', 0]"),
        ("search", lambda r: r["fresh"].update(seed="s"), "['fresh', 'seed']"),
        (
            "search",
            lambda r: r["baselines"]["hand-designed"].update(fuel_nms=None),
            "['baselines', 'hand-designed']",
        ),
    ],
)
def test_the_published_result_schema_refuses_a_result_it_does_not_describe(
    api: Api, results: dict[str, dict[str, Any]], job_type: str, change: Any, path: str
) -> None:
    spec = strict_document(api.get("/openapi.json").json())
    # The type's own variant of the job (JobOut is the union of them, by type).
    variant = {"search": "SearchJobOut", "train": "TrainJobOut", "sweep": "SweepJobOut"}
    one = _validator(spec, {"$ref": f"#/components/schemas/{variant[job_type]}"})
    union = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    scenario_id = api.create_scenario()["id"]
    params = {"search": {"method": "random"}, "train": {"sequence": GOOD_SEQUENCE}}
    kind = "search" if job_type == "sweep" else job_type  # a sweep needs a classifier row
    job = api.get(f"/jobs/{_finished(api, kind, scenario_id, params[kind], None)}").json()
    result = json.loads(json.dumps(results[job_type]))
    change(result)
    document = {**job, "type": job_type, "result": result}
    errors = [str(list(e.instance_path)) for e in one.iter_errors(document)]
    # Under the type's anyOf (its model or null), the error is the result's; the
    # type's own model says where in it.
    assert errors and all(e.startswith("['result'") for e in errors), errors
    assert _errors(union, document)
    model = {"search": "SearchJobResult", "train": "TrainJobResult", "sweep": "SweepJobResult"}
    own = _validator(spec, {"$ref": f"#/components/schemas/{model[job_type]}"})
    assert path in [str(list(e.instance_path)) for e in own.iter_errors(result)]


@pytest.mark.parametrize(
    ("change", "path"),
    [
        (
            lambda f: f["members"][0]["scores"].update(accuracy="high"),
            "['members', 0, 'scores', 'accuracy']",
        ),
        (lambda f: f["members"][0].update(added=1), "['members', 0]"),
        (lambda f: f["members"][0].pop("dominated_by"), "['members', 0]"),
        (
            lambda f: f["baselines"]["hand-designed"].pop("dominates"),
            "['baselines', 'hand-designed']",
        ),
        (lambda f: f.update(dominated_by_baseline="no"), "['dominated_by_baseline']"),
    ],
)
def test_the_published_schema_describes_a_search_fronts_members_and_baselines(
    api: Api, results: dict[str, dict[str, Any]], change: Any, path: str
) -> None:
    """Before, a front's members and baselines were objects whose fields were open: any
    value passed. (The front is ``SearchFront`` or null: an error in it is reported at
    ``front``, so the front is checked against its own model.)"""
    spec = strict_document(api.get("/openapi.json").json())
    front = json.loads(json.dumps(results["search"]["front"]))
    own = _validator(spec, {"$ref": "#/components/schemas/SearchFront"})
    assert _errors(own, front) == []
    change(front)
    assert path in [str(list(e.instance_path)) for e in own.iter_errors(front)]
    whole = _validator(spec, {"$ref": "#/components/schemas/SearchJobResult"})
    assert _errors(whole, {**results["search"], "front": front})


@pytest.mark.parametrize("kind", ["clustering", "likelihood", "least-squares"])
def test_a_train_job_run_by_the_worker_has_the_result_the_schema_describes(
    api: Api, kind: str
) -> None:
    # The runner adds the stored classifier's classifier_id and sha256 to the training's
    # summary: a schema of the summary alone (unknown fields forbidden) refused every
    # train job's real result.
    from worker.runner import execute_job

    spec = strict_document(api.get("/openapi.json").json())
    one = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    scenario_id = api.create_scenario()["id"]
    params: dict[str, Any] = {"sequence": GOOD_SEQUENCE, "kind": kind, "n_realisations": 4}
    if kind == "clustering":
        params["metric"] = "euclidean"
    submitted = api.submit("train", scenario_id, params=params)
    assert submitted.status_code == 202, submitted.text
    job_id = submitted.json()["id"]
    assert execute_job(job_id, settings=api.settings, worker_name="tests") == "succeeded"
    job = api.get(f"/jobs/{job_id}").json()
    assert {"classifier_id", "sha256"} <= set(job["result"])
    assert _errors(one, job) == []


def _older(result: dict[str, Any], *missing: str) -> dict[str, Any]:
    return {k: v for k, v in json.loads(json.dumps(result)).items() if k not in missing}


@pytest.mark.parametrize(
    ("job_type", "missing"),
    [
        # Train results before every kind could be trained (ca6a06a) had no kind, and
        # before weak responses were warned of (4302f51) no warnings.
        ("train", ("kind", "warnings")),
        ("train", ("warnings",)),
        # Search results before the baselines (721d0dc) and the front (0cb27c9).
        ("search", ("front", "baselines")),
        ("search", ("front",)),
    ],
)
def test_a_result_stored_by_an_older_release_still_meets_the_published_schema(
    api: Api, results: dict[str, dict[str, Any]], job_type: str, missing: tuple[str, ...]
) -> None:
    # A client typed from /openapi.json reads every stored row, the old ones included:
    # a field added to results later must not be required.
    spec = api.get("/openapi.json").json()
    one = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    scenario_id = api.create_scenario()["id"]
    params = {
        "search": {"method": "random", "sequence_length": 2, "timesteps": 8},
        "train": {"sequence": GOOD_SEQUENCE},
    }
    result = _older(results[job_type], *missing)
    job_id = _finished(api, job_type, scenario_id, params[job_type], result)
    job = api.get(f"/jobs/{job_id}").json()
    assert not set(missing) & set(job["result"])
    assert _errors(one, job) == []


def test_a_search_job_run_by_the_worker_has_the_result_the_schema_describes(api: Api) -> None:
    """A real NSGA-II search through the worker's runner (its front measured, member 0
    confirmed, the baselines beside): every nested part is described, none of its
    fields unknown to the strict variant."""
    from worker.runner import execute_job

    spec = strict_document(api.get("/openapi.json").json())
    one = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    scenario_id = api.create_scenario()["id"]
    params: dict[str, Any] = {
        "method": "nsga2",
        "sequence_length": 2,
        "n_realisations": 4,
        "fresh_test_series": 2,
        "fresh_realisations": 4,
        "nsga2": {"population": 8, "generations": 2},
    }
    submitted = api.submit("search", scenario_id, params=params)
    assert submitted.status_code == 202, submitted.text
    job_id = submitted.json()["id"]
    assert execute_job(job_id, settings=api.settings, worker_name="tests") == "succeeded"
    job = api.get(f"/jobs/{job_id}").json()
    result = job["result"]
    assert result["front"]["members"] and result["front"]["confirmation"] is not None
    assert result["curve"] and result["baselines"]
    assert _errors(one, job) == []
    member = _validator(spec, {"$ref": "#/components/schemas/SearchFrontMember"})
    assert _errors(member, result["front"]["members"][0]) == []


def test_the_published_schemas_allow_a_field_a_later_release_adds(
    api: Api, results: dict[str, dict[str, Any]]
) -> None:
    """A client validating strictly against /openapi.json must still read a later
    release's results and plans: the published models allow fields they do not list
    (before, TrainJobResult and PlanOut refused any), the strict variant the tests use
    does not."""
    published = api.get("/openapi.json").json()
    strict = strict_document(published)
    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, "search", scenario_id, {"method": "random"}, None)
    job = api.get(f"/jobs/{job_id}").json()
    later = {
        "train": lambda r: r.update(added_later=1),
        "sweep": lambda r: r["points"][0].update(added_later=1),
        "search": lambda r: r["front"]["members"][0]["scores"].update(added_later=1),
    }
    for job_type, change in later.items():
        result = json.loads(json.dumps(results[job_type]))
        change(result)
        document = {**job, "type": job_type, "result": result, "added_later": True}
        ref = {"$ref": "#/components/schemas/JobOut"}
        assert _errors(_validator(published, ref), document) == [], job_type
        assert _errors(_validator(strict, ref), document), job_type


def test_a_jobs_result_is_a_union_tagged_by_the_job_type(api: Api) -> None:
    """Every job model is a oneOf of one variant a job type with an OpenAPI
    discriminator on ``type`` (client generators make a tagged union of it); before,
    an ``allOf`` of ``if``/``then`` clauses, which most generators ignore."""
    spec = api.get("/openapi.json").json()
    schemas = spec["components"]["schemas"]
    models = {"search": "SearchJobResult", "train": "TrainJobResult", "sweep": "SweepJobResult"}
    for name in ("JobOut", "JobSubmitted", "JobListed", "JobDownload"):
        union = schemas[name]
        assert "allOf" not in union and "if" not in json.dumps(union)
        mapping = union["discriminator"]["mapping"]
        assert union["discriminator"]["propertyName"] == "type"
        assert set(mapping) == set(models)
        assert [v["$ref"] for v in union["oneOf"]] == list(mapping.values())
        for job_type, ref in mapping.items():
            variant = schemas[ref.rsplit("/", 1)[1]]
            assert "type" in variant["required"]
            assert variant["properties"]["type"]["const"] == job_type
            targets = [r.get("$ref") for r in variant["properties"]["result"]["anyOf"]]
            assert targets == [f"#/components/schemas/{models[job_type]}", None]
        assert ("config_hash" in schemas[ref.rsplit("/", 1)[1]]["properties"]) == (
            name != "JobDownload"
        )
    # The routes point at the unions.
    one = spec["paths"]["/jobs/{job_id}"]["get"]["responses"]["200"]["content"]
    assert one["application/json"]["schema"] == {"$ref": "#/components/schemas/JobOut"}


def test_an_nsga2_result_stored_before_its_confirmation_measured_the_baselines_still_meets_the_published_schema(  # noqa: E501
    api: Api,
) -> None:
    """A front's confirmation gained ``baselines`` in 13426f5 (2026-12-03); the NSGA-II
    results stored between f34c58e and it have a confirmation without them. The
    published schema required them: GET /jobs/{id} of such a job failed a client's
    validation (a datamodel-code-generator client: 'confirmation.baselines Field
    required'), on a real result of that release as on this one without the key."""
    request = SearchRequest.from_params(
        {
            "method": "nsga2",
            "sequence_length": 2,
            "n_realisations": 4,
            "fresh_test_series": 2,
            "fresh_realisations": 4,
            "nsga2": {"population": 8, "generations": 2},
        }
    )
    result = search_with_baselines(Scenario.paper(), request, seed=0).to_dict()
    assert result["front"]["confirmation"] is not None
    result["front"]["confirmation"].pop("baselines")
    spec = api.get("/openapi.json").json()
    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, "search", scenario_id, {"method": "random"}, result)
    job = api.get(f"/jobs/{job_id}").json()
    assert "baselines" not in job["result"]["front"]["confirmation"]
    assert _errors(_validator(spec, {"$ref": "#/components/schemas/JobOut"}), job) == []
    # Every field it holds is still described.
    strict = strict_document(spec)
    assert _errors(_validator(strict, {"$ref": "#/components/schemas/JobOut"}), job) == []


def test_a_curve_stored_before_the_residual_rate_was_named_is_described(
    api: Api, results: dict[str, dict[str, Any]]
) -> None:
    """Curves stored before b4cfab5 hold ``best_final_rate_rad_s`` where later ones hold
    ``best_residual_rate_rad_s`` (the dashboard and the CSV export still read it). The
    schema named it in a description only: a client typed from /openapi.json could not
    read it by name, the strict variant refused every such stored result, and any value
    passed there."""
    spec = strict_document(api.get("/openapi.json").json())
    point = _validator(spec, {"$ref": "#/components/schemas/SearchCurvePoint"})
    old = json.loads(json.dumps(results["search"]["curve"][-1]))
    old["best_final_rate_rad_s"] = old.pop("best_residual_rate_rad_s")
    assert _errors(point, old) == []
    assert [str(list(e.instance_path)) for e in point.iter_errors(
        {**old, "best_final_rate_rad_s": "fast"}
    )] == ["['best_final_rate_rad_s']"]  # fmt: skip
