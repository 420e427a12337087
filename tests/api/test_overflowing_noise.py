"""A scenario within every per-field bound whose noise still overflows the simulated rates
is refused when it is given: stored, or asked of by a job, a plan's flights or a response,
with a 422 naming the noise figure, its value, the multiple and the step by which the rates
overflow. Before, it was stored, every job on it was accepted (202), queued, and failed
at run time with ``SimulationOverflow``."""

from __future__ import annotations

from typing import Any

import pytest

from inertia_id import InertiaClassifier, Scenario

from .support import GOOD_SEQUENCE, Api

#: On the paper preset the rates overflow within 2 of the hand-designed sequence's 4 steps.
OVERFLOWING_NM = 1e4
#: Large but finite at 1x on 4 steps (rates of tens of rad/s); 8x of it overflows.
LOUD_NM = 3e3
FIELD = "disturbance_torque_sigma_nm"


def _one_error(response: Any) -> dict[str, Any]:
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert isinstance(error, dict)
    return error


def test_a_scenario_whose_own_noise_overflows_is_refused_when_stored(
    api: Api, paper: Scenario
) -> None:
    document = paper.model_dump(mode="json")
    document["uncertainty"][FIELD] = OVERFLOWING_NM
    bodies = {
        "overrides": {"preset": "paper", "overrides": {"uncertainty": {FIELD: OVERFLOWING_NM}}},
        "scenario": {"scenario": document},
    }
    for source, body in bodies.items():
        error = _one_error(api.post("/scenarios", json=body))
        assert error["loc"] == ["body", source, "uncertainty", FIELD]
        assert f"{FIELD} = 10000 N m at noise multiple 1" in error["msg"], error
        assert "inf or nan within" in error["msg"]
    assert api.get("/scenarios").json()["total"] == 0
    # Merely large but finite is stored.
    api.create_scenario(uncertainty={FIELD: LOUD_NM})


def test_a_noise_that_overflows_only_in_a_jobs_tail_is_refused_when_stored(api: Api) -> None:
    """An initial rate sigma of 40 rad/s on the paper preset: 8 realisations a candidate
    flew through it, so it was stored (201) and a train job on it accepted (202), yet
    every job of 210 realisations a candidate overflowed in the worker. The check flies
    256 on the 4-step check and refuses it when it is stored."""
    field = "initial_rate_sigma_rad_s"
    body = {"preset": "paper", "overrides": {"uncertainty": {field: 40}}}
    error = _one_error(api.post("/scenarios", json=body))
    assert error["loc"] == ["body", "overrides", "uncertainty", field]
    assert f"{field} = 40 rad/s at noise multiple 1 (the scenario's own)" in error["msg"]
    assert "a seeded check of 256 realisations a candidate" in error["msg"]
    assert api.get("/scenarios").json()["total"] == 0


def test_a_stored_scenario_whose_noise_overflows_is_refused_by_every_job_and_flight(
    api: Api, paper: Scenario, classifier: InertiaClassifier
) -> None:
    """A row stored before the check is kept and shown; what would simulate it is a 422
    naming the figure, and nothing is queued."""
    scenario_id = api.insert_scenario(paper.with_uncertainty(**{FIELD: OVERFLOWING_NM}))
    classifier_id = api.insert_classifier(scenario_id, classifier)
    answers = {
        "train": api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}),
        "sweep": api.submit("sweep", scenario_id, params={"classifier_id": classifier_id}),
        "search": api.submit("search", scenario_id, params={"method": "cem"}),
    }
    for what, response in answers.items():
        error = _one_error(response)
        assert error["loc"] == ["uncertainty", FIELD], (what, error)
        assert f"{FIELD} = 10000 N m at noise multiple 1" in error["msg"], (what, error)
    assert api.get("/jobs").json()["total"] == 0 and not api.queued_messages()
    assert api.get(f"/scenarios/{scenario_id}").status_code == 200


@pytest.mark.parametrize("route", ["GET plan", "POST plan", "GET response"])
def test_a_stored_scenarios_overflowing_noise_is_named_at_its_figure_by_plans_and_responses(
    api: Api, paper: Scenario, route: str
) -> None:
    """Where the jobs name it: the scenario's noise figure, not a query parameter. The
    plan's flights and the response's realisations put it at ``query.flights`` and
    ``query.n_realisations``, blaming a number the client had not got wrong (20 flights
    of a scenario that can be flown overflow as surely as 2 do)."""
    scenario_id = api.insert_scenario(paper.with_uncertainty(**{FIELD: OVERFLOWING_NM}))
    sequence = str(GOOD_SEQUENCE)
    if route == "GET plan":
        answer = api.get_with_key(
            f"/scenarios/{scenario_id}/plan", params={"sequence": sequence, "flights": 20}
        )
    elif route == "POST plan":
        answer = api.post(
            f"/scenarios/{scenario_id}/plan?flights=20", json={"sequence": GOOD_SEQUENCE}
        )
    else:
        answer = api.get_with_key(
            f"/scenarios/{scenario_id}/response", params={"sequence": sequence}
        )
    error = _one_error(answer)
    assert error["loc"] == ["uncertainty", FIELD], error
    assert f"{FIELD} = 10000 N m at noise multiple 1" in error["msg"], error
    # The nominal plan flies no noise, and the row is still there.
    assert api.post(f"/scenarios/{scenario_id}/plan", json={"sequence": GOOD_SEQUENCE}).is_success
    assert api.get(f"/scenarios/{scenario_id}").status_code == 200


@pytest.mark.parametrize(
    ("job", "params", "loc", "named"),
    [
        (
            "sweep",
            {"multiples": [1, 8]},
            "multiples",
            "process noise at multiple 8 (24000 N m), the sweep's largest",
        ),
        ("search", {"method": "cem"}, "design_noise", "no search on scenario"),
    ],
)
def test_a_job_whose_noise_multiple_overflows_is_refused_at_the_multiple(
    api: Api, classifier: InertiaClassifier, job: str, params: dict[str, Any], loc: str, named: str
) -> None:
    """The scenario simulates at 1x; the sweep's largest multiple, or the search's design
    noise (6x process by default), does not."""
    scenario_id = api.create_scenario(uncertainty={FIELD: LOUD_NM})["id"]
    if job == "sweep":
        params = {**params, "classifier_id": api.insert_classifier(scenario_id, classifier)}
    error = _one_error(api.submit(job, scenario_id, params=params))
    assert error["loc"] == ["body", "params", loc]
    assert named in error["msg"] and f"{FIELD} = 3000 N m at noise multiple" in error["msg"]
    assert api.get("/jobs").json()["total"] == 0 and not api.queued_messages()
    # At multiples it simulates, the same job is accepted.
    within = {"multiples": [0.5, 1]} if job == "sweep" else {"design_noise": [[1, 6]]}
    accepted = api.submit(job, scenario_id, params={**params, **within})
    assert accepted.status_code == 202, accepted.text
    trained = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE})
    assert trained.status_code == 202, trained.text
