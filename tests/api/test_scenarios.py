"""Scenarios: create from a preset or a document, list, get, delete; physics checked."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from inertia_id import Scenario
from service.store import ScenarioRow

from .support import Api

PAPER_DOCUMENT = Scenario.paper().model_dump(mode="json")


def moments(tensor: list[list[float]]) -> list[float]:
    return np.linalg.eigvalsh(np.asarray(tensor)).tolist()


def test_create_from_preset_with_overrides(api: Api, paper: Scenario) -> None:
    response = api.post(
        "/scenarios",
        json={
            "preset": "paper",
            "overrides": {
                "name": "paper, noisy gyro",
                "uncertainty": {"gyro_noise_sigma_rad_s": 0.002},
            },
        },
    )
    assert response.status_code == 201, response.text
    body = response.json()
    assert body["name"] == "paper, noisy gyro"
    assert body["document"]["uncertainty"]["gyro_noise_sigma_rad_s"] == 0.002
    # Merged section by section: the rest of the preset's uncertainty is kept.
    assert (
        body["document"]["uncertainty"]["duty_jitter_sigma"] == paper.uncertainty.duty_jitter_sigma
    )
    assert body["n_thrusters"] == 6
    assert body["n_levels"] == 5
    assert [c["name"] for c in body["candidates"]] == paper.candidate_names
    for candidate, expected in zip(body["candidates"], paper.inertia_candidates, strict=True):
        assert candidate["inertia_kg_m2"] == expected.inertia_kg_m2
        assert candidate["principal_moments_kg_m2"] == pytest.approx(
            expected.principal_moments_kg_m2.tolist()
        )
    # The base tensor diag(100, 60, 90) has principal moments 60, 90, 100 (ascending).
    assert body["candidates"][0]["principal_moments_kg_m2"] == pytest.approx([60, 90, 100])
    assert body["created_at"].endswith("Z")


def test_create_from_full_document(api: Api, paper: Scenario) -> None:
    document = paper.model_dump(mode="json")
    document["name"] = "from a document"
    document["inertia_candidates"] = [
        {"name": "stowed", "inertia_kg_m2": [[10, 0.5, 0], [0.5, 12, 0], [0, 0, 15]]},
        {"name": "deployed", "inertia_kg_m2": [[20, 0, 0], [0, 22, 0], [0, 0, 30]]},
    ]
    document["candidate_generator"] = None
    response = api.post("/scenarios", json={"scenario": document})
    assert response.status_code == 201, response.text
    body = response.json()
    assert body["name"] == "from a document"
    assert [c["name"] for c in body["candidates"]] == ["stowed", "deployed"]
    assert body["candidates"][0]["principal_moments_kg_m2"] == pytest.approx(
        moments([[10, 0.5, 0], [0.5, 12, 0], [0, 0, 15]])
    )
    assert Scenario.model_validate(body["document"]).n_candidates == 2


@pytest.mark.parametrize("source", ["preset", "scenario"])
def test_triangle_inequality_names_rule_and_moments(api: Api, paper: Scenario, source: str) -> None:
    candidates = [
        {"name": "flat", "inertia_kg_m2": [[1, 0, 0], [0, 1, 0], [0, 0, 5]]},
        {"name": "ok", "inertia_kg_m2": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]},
    ]
    if source == "preset":
        body: dict[str, Any] = {
            "preset": "paper",
            "overrides": {"inertia_candidates": candidates},
        }
    else:
        document = paper.model_dump(mode="json")
        document.update(inertia_candidates=candidates, candidate_generator=None)
        body = {"scenario": document}
    response = api.post("/scenarios", json=body)
    assert response.status_code == 422
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "overrides" if source == "preset" else "scenario",
                            "inertia_candidates", 0, "inertia_kg_m2"]  # fmt: skip
    assert "triangle inequality" in error["msg"]
    assert "1 + 1 < 5" in error["msg"]
    assert "[1., 1., 5.]" in error["msg"]


@pytest.mark.parametrize(
    ("body", "fragment"),
    [
        ({"preset": "hubble"}, "unknown preset 'hubble'"),
        ({}, "exactly one of preset"),
        ({"preset": "paper", "scenario": PAPER_DOCUMENT}, "exactly one of preset"),
        ({"scenario": PAPER_DOCUMENT, "overrides": {"name": "x"}}, "overrides apply to a preset"),
        ({"preset": "paper", "overrides": {"colour": "red"}}, "Extra inputs are not permitted"),
        (
            {"preset": "paper", "overrides": {"thrusters": {"n_levels": 1}}},
            "n_levels must be 2 to 101, got 1",
        ),
        # Refused before the core expands it into an array of 10^9 levels.
        (
            {"preset": "paper", "overrides": {"thrusters": {"n_levels": 10**9}}},
            "n_levels must be 2 to 101, got 1000000000",
        ),
        (
            {"preset": "paper", "overrides": {"thrusters": {"nominal_torque_nm": 10**400}}},
            "nominal_torque_nm is out of range",
        ),
        (
            {"preset": "paper", "overrides": {"thrusters": {"levels": [0, 0.5, 1.5]}}},
            "levels must lie within [0, 1], got [0.0, 0.5, 1.5]",
        ),
        (
            {"preset": "paper", "overrides": {"timing": {"integration_step_s": 0.3}}},
            "step_duration_s = 1.0 is not a whole number of integration_step_s = 0.3",
        ),
        (
            {"preset": "paper", "overrides": {"uncertainty": {"gyro_noise_sigma_rad_s": -1}}},
            "got -1",
        ),
        ({"preset": "paper", "overrides": {"name": "nul\x00byte"}}, "NUL"),
        # A right-to-left override reorders what follows on screen.
        (
            {"preset": "paper", "overrides": {"name": "orbit 3\u202etxt.exe"}},
            "holds control characters (U+202E)",
        ),
        # Names go into CSV files a line at a time: a newline would end the line.
        (
            {"preset": "paper", "overrides": {"name": "ops\nstep,start_s\n1,0,1,999"}},
            "holds control characters (U+000A)",
        ),
        # The core divides by the product before checking it (found by schemathesis).
        (
            {
                "preset": "paper",
                "overrides": {"timing": {"integration_step_s": 0.5, "sample_rate_hz": 5e-324}},
            },
            "timing out of range: step_duration_s = 1.0",
        ),
    ],
)
def test_bad_scenarios_are_422_with_the_value(
    api: Api, body: dict[str, Any], fragment: str
) -> None:
    response = api.post("/scenarios", json=body)
    assert response.status_code == 422, response.text
    messages = " | ".join(e["msg"] for e in response.json()["detail"])
    assert fragment in messages


def test_a_candidate_name_with_a_control_character_is_refused_where_it_is(api: Api) -> None:
    document = api.get("/scenarios/presets").json()["paper"]
    document.pop("candidate_generator")
    document["inertia_candidates"] = [
        {"name": "none ejected", "inertia_kg_m2": [[10, 0, 0], [0, 11, 0], [0, 0, 12]]},
        {"name": "payload, one\r\nejected", "inertia_kg_m2": [[11, 0, 0], [0, 11, 0], [0, 0, 12]]},
    ]
    response = api.post("/scenarios", json={"scenario": document})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "scenario", "inertia_candidates", 1, "name"]
    assert "U+000A, U+000D" in error["msg"] and "payload, one" in error["msg"]
    # A comma, a leading "=" or non-ASCII letters are text, not control characters.
    document["inertia_candidates"][1]["name"] = "=payload, one éjecté"
    assert api.post("/scenarios", json={"scenario": document}).status_code == 201


def test_list_get_delete(api: Api) -> None:
    ids = [api.create_scenario(name=f"s{i}")["id"] for i in range(3)]
    listing = api.get("/scenarios").json()
    assert listing["total"] == 3
    assert {s["id"] for s in listing["items"]} == set(ids)
    assert [s["name"] for s in listing["items"]] == ["s2", "s1", "s0"]  # newest first
    page = api.get("/scenarios", params={"limit": 2, "offset": 2}).json()
    assert [s["name"] for s in page["items"]] == ["s0"]
    assert (page["limit"], page["offset"], page["total"]) == (2, 2, 3)

    got = api.get(f"/scenarios/{ids[0]}")
    assert got.status_code == 200
    assert got.json()["name"] == "s0"
    assert len(got.json()["candidates"]) == 5

    assert api.delete(f"/scenarios/{ids[0]}").status_code == 204
    assert api.get(f"/scenarios/{ids[0]}").status_code == 404
    assert api.delete(f"/scenarios/{ids[0]}").status_code == 404
    assert api.get("/scenarios").json()["total"] == 2


def test_delete_refused_while_a_job_uses_it(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    assert api.submit("search", scenario_id).status_code == 202
    response = api.delete(f"/scenarios/{scenario_id}")
    assert response.status_code == 409
    assert "1 job(s)" in response.json()["detail"]
    assert api.get(f"/scenarios/{scenario_id}").status_code == 200


def test_unknown_scenario_is_404(api: Api) -> None:
    assert api.get("/scenarios/0123456789abcdef0123456789abcdef").status_code == 404
    assert api.get("/scenarios/not%00an-id").status_code == 404


@pytest.mark.parametrize("limit", [0, 201])
def test_page_size_is_capped(api: Api, limit: int) -> None:
    response = api.get("/scenarios", params={"limit": limit})
    assert response.status_code == 422
    assert str(limit) in response.json()["detail"][0]["msg"]


def test_baselines_a_short_length_lists_those_that_exist_and_why_the_rest_do_not(
    api: Api, paper: Scenario
) -> None:
    # Before, length 1 or 2 was a 422 for the whole list ("fire then brake needs at least
    # 2 steps"), while a search of that length lists the baselines and marks the rest.
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    one = api.get(f"/scenarios/{scenario_id}/baselines", params={"length": 1})
    assert one.status_code == 200, one.text
    assert one.json() == {
        "hand-designed": [[4, 4, 4, 0, 0, 0]],
        "axis-in-turn": [[4, 0, 0, 0, 0, 0]],
        "fire-then-brake": {"unavailable": "fire then brake needs at least 2 steps, got 1"},
        "fire-coast-brake": {"unavailable": "fire, coast, brake needs at least 3 steps, got 1"},
    }
    two = api.get(f"/scenarios/{scenario_id}/baselines", params={"length": 2}).json()
    assert two["fire-then-brake"] == [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]
    assert two["fire-coast-brake"] == {
        "unavailable": "fire, coast, brake needs at least 3 steps, got 2"
    }
    # A geometry that leaves axis-in-turn nothing but the hand-designed step says so.
    document = paper.model_dump(mode="json")
    document["name"] = "one thruster along the diagonal, one against it"
    document["candidate_generator"] = None
    document["thrusters"]["torque_matrix_nm"] = [[1, -1], [1, -1], [1, -1]]
    created = api.post("/scenarios", json={"scenario": document})
    assert created.status_code == 201, created.text
    got = api.get(f"/scenarios/{created.json()['id']}/baselines", params={"length": 3}).json()
    assert got["hand-designed"] == [[4, 0]] * 3
    assert "the same sequence as hand-designed" in got["axis-in-turn"]["unavailable"]
    assert got["fire-then-brake"] == [[4, 0], [0, 0], [0, 4]]
    assert "same sequence as fire-then-brake" in got["fire-coast-brake"]["unavailable"]


# Noise figures past any spacecraft's (each was stored, and a job accepted that then
# failed or, with a lag of 1e308 s, trained to 0.425 accuracy without a word).
ABSURD_NOISE = [
    ("duty_jitter_sigma", 1e308, "duty_jitter_sigma = 1e+308 (fraction of full", "at most 10"),
    ("thrust_scale_sigma", 0.75, "thrust_scale_sigma = 0.75 (fraction of nominal", "at most 0.5"),
    ("disturbance_torque_sigma_nm", 1e308, "disturbance_torque_sigma_nm = 1e+308 N m", "1e+06"),
    ("lowpass_time_constant_s", 1e308, "lowpass_time_constant_s = 1e+308 s", "at most 100 steps"),
]


@pytest.mark.parametrize(("field", "value", "named", "bound"), ABSURD_NOISE)
def test_a_noise_figure_past_any_spacecrafts_is_422_naming_it(
    api: Api, field: str, value: float, named: str, bound: str
) -> None:
    """As the dashboard's new-scenario form sends it (a whole document) and as a preset's
    overrides."""
    document = Scenario.paper().model_dump(mode="json")
    document["uncertainty"][field] = value
    for body in (
        {"scenario": document},
        {"preset": "paper", "overrides": {"uncertainty": {field: value}}},
    ):
        response = api.post("/scenarios", json=body)
        assert response.status_code == 422, response.text
        (error,) = response.json()["detail"]
        assert named in error["msg"] and bound in error["msg"], error
        where = "scenario" if "scenario" in body else "overrides"
        # The lag's bound is against the steps: the scenario's rule, located at it.
        at = [] if field == "lowpass_time_constant_s" else ["uncertainty", field]
        assert error["loc"] == ["body", where, *at]
    assert api.get("/scenarios").json()["total"] == 0


@pytest.mark.parametrize(("field", "value", "named", "bound"), ABSURD_NOISE)
def test_a_scenario_stored_before_its_noise_was_bounded_is_422_for_jobs_and_plans(
    api: Api, field: str, value: float, named: str, bound: str
) -> None:
    """A scenario stored before these bounds is kept, shown, and refused with a 422 naming
    the figure when a job or a plan reads it, before a job is queued."""
    document = Scenario.paper().model_dump(mode="json")
    document["uncertainty"][field] = value
    with api.db.session() as session:
        row = ScenarioRow(name="stored before the bound", document=document)
        session.add(row)
        session.flush()
        scenario_id = row.id
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    answers = {
        "train": api.submit("train", scenario_id, params={"sequence": sequence}),
        "search": api.submit("search", scenario_id),
        "plan": api.post(f"/scenarios/{scenario_id}/plan", json={"sequence": sequence}),
    }
    for what, response in answers.items():
        assert response.status_code == 422, (what, response.text)
        (error,) = response.json()["detail"]
        assert named in error["msg"] and bound in error["msg"], (what, error)
        # Located in the stored document (the request named only its id).
        at = [] if field == "lowpass_time_constant_s" else ["uncertainty", field]
        assert error["loc"] == at, (what, error)
    assert api.get("/jobs").json()["total"] == 0 and not api.queued_messages()
    shown = api.get(f"/scenarios/{scenario_id}")
    assert shown.status_code == 200 and shown.json()["document"]["uncertainty"][field] == value


def _with_idle_thrusters(*idle: int) -> list[list[float]]:
    """The paper's six thrusters and two more, thrusters 7 and 8 (from 1); those in
    ``idle`` (from 1) give no torque, a zero column: the thrust through the centre of mass."""
    torque = np.zeros((3, 8))
    torque[:, :6] = [[2, -2, 0, 0, 0, 0], [0, 0, 2, -2, 0, 0], [0, 0, 0, 0, 2, -2]]
    torque[:, 6:] = [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    for number in idle:
        torque[:, number - 1] = 0.0
    return torque.tolist()


def test_a_thruster_that_gives_no_torque_is_stored_with_a_warning_naming_it(api: Api) -> None:
    """A zero column of the torque matrix (a lever arm parallel to the force) was stored
    without a word, though no search fires such a thruster and a plan that does warns of
    it. It is stored still, with a warning naming the thruster by its number."""
    one = api.create_scenario(
        thrusters={"torque_matrix_nm": _with_idle_thrusters(7), "n_levels": 5}
    )
    warning = (
        "thruster 7 gives no torque (column 7 of torque_matrix_nm is zero: the thrust passes "
        "through the centre of mass); no search fires such a thruster, and a plan that fires "
        "one warns of it"
    )
    assert one["warnings"] == [warning]
    assert api.get(f"/scenarios/{one['id']}").json()["warnings"] == [warning]
    two = api.post(
        "/scenarios",
        json={
            "scenario": {
                **Scenario.paper().model_dump(mode="json"),
                "thrusters": {"torque_matrix_nm": _with_idle_thrusters(3, 8), "n_levels": 5},
            }
        },
    )
    assert two.status_code == 201, two.text
    (said,) = two.json()["warnings"]
    assert said.startswith("thrusters 3 and 8 give no torque (columns 3 and 8 of ")
    # Every thruster gives some torque: nothing to say.
    assert (
        api.create_scenario(thrusters={"torque_matrix_nm": _with_idle_thrusters()})["warnings"]
        == []
    )
    assert api.create_scenario()["warnings"] == []
