"""Numbers in the query, the path and a scenario document are read as the command line
reads them: ASCII digits, an optional sign, point and exponent (spaces around allowed).

Pydantic's lax mode read ``?seed=1_0`` as 10, ``"sample_rate_hz": "1_0"`` as 10 and
``true`` as 1; the command line, the telemetry CSV and the identify form refused them.
"""

from __future__ import annotations

import copy
import re
from typing import Any

import pytest

from .support import Api

NOT_AS_WRITTEN = ["1_0", "１０", "1e1", "0x10", "inf", "nan", "true", "10.0", ""]


def _number_parameters(api: Api) -> list[tuple[str, str, str, str]]:
    """(method, path, where, name) of every integer or number parameter the API declares."""
    found = []
    for path, operations in api.app.openapi()["paths"].items():
        for method, operation in operations.items():
            for parameter in operation.get("parameters", []):
                schema = parameter["schema"]
                kinds = {schema.get("type")} | {s.get("type") for s in schema.get("anyOf", [])}
                if kinds & {"integer", "number"}:
                    found.append((method, path, parameter["in"], parameter["name"]))
    return found


def test_every_number_parameter_refuses_1_0_by_name(api: Api) -> None:
    """One rule for every route: each number parameter given ``1_0`` is a 422 that names
    it and quotes the value, before the route looks anything up."""
    parameters = _number_parameters(api)
    assert len(parameters) >= 17  # limit, offset, seed, flights, member, after, length, ...
    for method, path, where, name in parameters:
        # Ids that name no row: the number is refused before any look-up.
        url = path.replace(f"{{{name}}}", "1_0") if where == "path" else path
        url = re.sub(r"\{[^}]+\}", "0" * 32, url)
        params = {name: "1_0"} if where == "query" else {}
        response = api.client.request(method.upper(), url, params=params, headers=api.auth)
        assert response.status_code == 422, (method, path, name, response.text)
        detail = response.json()["detail"][0]
        assert detail["loc"] == [where, name], (method, path, detail)
        assert f"{name} must be a whole number" in detail["msg"]
        assert detail["msg"].endswith("got '1_0'")


@pytest.mark.parametrize("text", NOT_AS_WRITTEN)
def test_a_number_not_as_written_is_422(api: Api, text: str) -> None:
    response = api.get("/jobs", params={"limit": text})
    assert response.status_code == 422, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == ["query", "limit"]
    assert detail["msg"] == (
        f"limit must be a whole number (ASCII digits with no separator, e.g. 42), got {text!r}"
    )


@pytest.mark.parametrize("text", ["10", " 10 ", "+10", "010"])
def test_a_number_as_written_is_read(api: Api, text: str) -> None:
    response = api.get("/scenarios", params={"limit": text})
    assert response.status_code == 200, response.text
    assert response.json()["limit"] == 10


def _paper_document(api: Api) -> dict[str, Any]:
    document: dict[str, Any] = api.get("/scenarios/presets").json()["paper"]
    return document


@pytest.mark.parametrize("value", ["1_0", "２０", "inf", True, " "])
def test_a_scenario_number_not_as_written_is_422_at_its_field(api: Api, value: Any) -> None:
    document = copy.deepcopy(_paper_document(api))
    document["timing"]["sample_rate_hz"] = value
    response = api.post("/scenarios", json={"scenario": document})
    assert response.status_code == 422, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == ["body", "scenario", "timing", "sample_rate_hz"]
    assert detail["msg"] == (
        "sample_rate_hz must be a decimal number (ASCII digits with no separator, "
        f"e.g. -0.25 or 1e-3), got {value!r}"
    )
    overrides = {"uncertainty": {"gyro_bias_rad_s": [0.0, value, 0.0]}}
    response = api.post("/scenarios", json={"preset": "paper", "overrides": overrides})
    assert response.status_code == 422, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == ["body", "overrides", "uncertainty", "gyro_bias_rad_s", 1]
    assert detail["msg"].startswith("gyro_bias_rad_s must be a decimal number")
    response = api.post(
        "/scenarios",
        json={"preset": "paper", "overrides": {"candidate_generator": {"n_variations": value}}},
    )
    assert response.status_code == 422, response.text
    assert "n_variations must be a whole number" in response.json()["detail"][0]["msg"]


def test_scenario_numbers_as_written_are_read_as_before(api: Api) -> None:
    """JSON numbers, and a plain decimal in a string, as the command line reads one."""
    document = copy.deepcopy(_paper_document(api))
    document["name"] = "quoted numbers"
    document["timing"]["sample_rate_hz"] = " 10 "
    document["uncertainty"]["gyro_noise_sigma_rad_s"] = "2e-3"
    document["candidate_generator"]["seed"] = 0
    response = api.post("/scenarios", json={"scenario": document})
    assert response.status_code == 201, response.text
    stored = response.json()["document"]
    assert stored["timing"]["sample_rate_hz"] == 10.0
    assert stored["uncertainty"]["gyro_noise_sigma_rad_s"] == 2e-3
