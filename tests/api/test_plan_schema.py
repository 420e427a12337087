"""The plan JSON against the schema ``/openapi.json`` publishes for it.

The plan routes answer a plain Response (the plan's JSON as the core writes it); before,
their 200 carried no schema at all (``"application/json": {}``), so a generated client
knew nothing of its fields. Real answers are validated against the strict variant of
the published schema (:func:`app.result_schema.strict_document`: unknown fields refused),
so a field the plan gains or loses without the schema fails here; the published schema
itself allows unknown fields, for a client of a later release.
"""

from __future__ import annotations

from typing import Any

import jsonschema_rs
import pytest

from app.result_schema import strict_document

from .support import GOOD_SEQUENCE, Api
from .test_runs import _finished, _search_result, _with_front

PLAN_PATHS = (
    ("/scenarios/{scenario_id}/plan", "get"),
    ("/scenarios/{scenario_id}/plan", "post"),
    ("/jobs/{job_id}/plan", "get"),
)


def _validator(spec: dict[str, Any], path: str, method: str) -> Any:
    content = spec["paths"][path][method]["responses"]["200"]["content"]
    assert set(content) == {"application/json", "text/csv"}
    schema = content["application/json"].get("schema")
    assert schema, f"{method.upper()} {path}: no schema for the plan's JSON"
    # The $refs point into the document's components.
    return jsonschema_rs.Draft202012Validator(
        {**schema, "components": spec["components"]}, validate_formats=True
    )


def _check(validator: Any, document: dict[str, Any]) -> None:
    errors = [f"{list(e.instance_path)}: {e.message}" for e in validator.iter_errors(document)]
    assert not errors, errors


def test_the_plan_json_is_what_the_published_schema_describes(api: Api) -> None:
    spec = strict_document(api.get("/openapi.json").json())
    validators = {(p, m): _validator(spec, p, m) for p, m in PLAN_PATHS}
    # The paper preset at rest: no floor, no flights, no propellant mass.
    paper = api.create_scenario()["id"]
    plain = api.get_with_key(f"/scenarios/{paper}/plan", params={"sequence": "[[4,4,4,0,0,0]]"})
    assert plain.status_code == 200, plain.text
    assert plain.json()["initial_rate_floor"] is None and plain.json()["flights"] is None
    _check(validators[PLAN_PATHS[0]], plain.json())
    # In orbit (an initial-rate spread: the floor), with thrust and Isp (a propellant
    # mass) and flights (each candidate's spread and the summary), from the body.
    created = api.post(
        "/scenarios",
        json={
            "preset": "paper-in-orbit",
            "overrides": {"thrusters": {"thrust_n": 1.0, "specific_impulse_s": 220.0}},
        },
    )
    assert created.status_code == 201, created.text
    orbit = created.json()["id"]
    flown = api.post(
        f"/scenarios/{orbit}/plan",
        json={"sequence": GOOD_SEQUENCE},
        params={"flights": 60, "seed": 3},
    )
    assert flown.status_code == 200, flown.text
    document = flown.json()
    assert document["initial_rate_floor"] is not None and document["flights"] is not None
    assert document["propellant"]["propellant_kg"] is not None
    assert all("flights" in c for c in document["candidates"])
    _check(validators[PLAN_PATHS[1]], document)
    # A search job's best and a front member's: the source names the job and member.
    result = {**_with_front([[[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]])}
    done = _finished(api, paper, 1, result)
    for params in ({}, {"member": 0}):
        planned = api.get_with_key(f"/jobs/{done}/plan", params=params)
        assert planned.status_code == 200, planned.text
        _check(validators[PLAN_PATHS[2]], planned.json())
    cancelled = _finished(api, paper, 2, _search_result([0.9], 12.0, 2.0), "cancelled")
    partial = api.get_with_key(f"/jobs/{cancelled}/plan").json()
    assert partial["source"]["job_status"] == "cancelled"
    _check(validators[PLAN_PATHS[2]], partial)


@pytest.mark.parametrize(
    ("change", "path"),
    [
        (lambda d: d.update(unknown=1), "[]"),
        (lambda d: d["candidates"][0].pop("residual_rate_rad_s"), "['candidates', 0]"),
        (lambda d: d["steps"][0].update(levels=["4"]), "['steps', 0, 'levels', 0]"),
        (lambda d: d["propellant"].update(extra=0.0), "['propellant']"),
    ],
)
def test_the_published_plan_schema_refuses_a_plan_it_does_not_describe(
    api: Api, change: Any, path: str
) -> None:
    """The strict variant: a field more, a field less or a wrong type is an error."""
    spec = strict_document(api.get("/openapi.json").json())
    validator = _validator(spec, *PLAN_PATHS[0])
    paper = api.create_scenario()["id"]
    document = api.get_with_key(
        f"/scenarios/{paper}/plan", params={"sequence": "[[4,4,4,0,0,0]]"}
    ).json()
    change(document)
    errors = [str(list(e.instance_path)) for e in validator.iter_errors(document)]
    assert path in errors, errors


def test_the_published_plan_schema_allows_a_field_a_later_release_adds(api: Api) -> None:
    """Before, PlanOut forbade unknown fields: a client validating strictly against
    /openapi.json would refuse a later release's plan for a field it added."""
    published = api.get("/openapi.json").json()
    paper = api.create_scenario()["id"]
    document = api.get_with_key(
        f"/scenarios/{paper}/plan", params={"sequence": "[[4,4,4,0,0,0]]"}
    ).json()
    document["added_later"] = 1
    document["propellant"]["added_later"] = 1
    document["steps"][0]["added_later"] = 1
    for path, method in PLAN_PATHS:
        assert list(_validator(published, path, method).iter_errors(document)) == []
    strict = _validator(strict_document(published), *PLAN_PATHS[0])
    assert {str(list(e.instance_path)) for e in strict.iter_errors(document)} == {
        "[]",
        "['propellant']",
        "['steps', 0]",
    }
