"""Job results against the schema ``/openapi.json`` publishes for them, per job type.

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
    spec = api.get("/openapi.json").json()
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
    ],
)
def test_the_published_result_schema_refuses_a_result_it_does_not_describe(
    api: Api, results: dict[str, dict[str, Any]], job_type: str, change: Any, path: str
) -> None:
    spec = api.get("/openapi.json").json()
    one = _validator(spec, {"$ref": "#/components/schemas/JobOut"})
    scenario_id = api.create_scenario()["id"]
    params = {"search": {"method": "random"}, "train": {"sequence": GOOD_SEQUENCE}}
    kind = "search" if job_type == "sweep" else job_type  # a sweep needs a classifier row
    job = api.get(f"/jobs/{_finished(api, kind, scenario_id, params[kind], None)}").json()
    result = json.loads(json.dumps(results[job_type]))
    change(result)
    errors = [
        str(list(e.instance_path))
        for e in one.iter_errors({**job, "type": job_type, "result": result})
    ]
    # Under the type's anyOf (its model or null), the error is the result's; the
    # type's own model says where in it.
    assert errors and all(e.startswith("['result'") for e in errors), errors
    model = {"search": "SearchJobResult", "train": "TrainJobResult", "sweep": "SweepJobResult"}
    own = _validator(spec, {"$ref": f"#/components/schemas/{model[job_type]}"})
    assert path in [str(list(e.instance_path)) for e in own.iter_errors(result)]


@pytest.mark.parametrize("kind", ["clustering", "likelihood", "least-squares"])
def test_a_train_job_run_by_the_worker_has_the_result_the_schema_describes(
    api: Api, kind: str
) -> None:
    # The runner adds the stored classifier's classifier_id and sha256 to the training's
    # summary: a schema of the summary alone (unknown fields forbidden) refused every
    # train job's real result.
    from worker.runner import execute_job

    spec = api.get("/openapi.json").json()
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
