"""What the dashboard needs from the API: its pages, plotly.js, presets and responses."""

from __future__ import annotations

import json
import re
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from inertia_id import Scenario, simulate
from service.config import Settings

from .support import GOOD_SEQUENCE, Api, make_settings


def test_the_dashboard_and_plotly_are_served_without_a_cdn(api: Api) -> None:
    page = api.client.get("/")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    assert "/static/vendor/plotly.min.js" in page.text
    assert "https://" not in page.text  # nothing fetched from elsewhere
    script = api.client.get("/static/vendor/plotly.min.js")
    assert script.status_code == 200
    assert script.headers["content-type"].startswith("text/javascript")
    assert len(script.content) > 1_000_000
    module = api.client.get("/static/js/app.js")
    assert module.status_code == 200
    assert "javascript" in module.headers["content-type"]
    assert module.headers["cache-control"] == "no-cache"
    assert api.client.get("/static/js/nothing.js").status_code == 404
    # The pages are not API operations.
    assert "/" not in api.client.get("/openapi.json").json()["paths"]


def test_without_the_frontend_folder_the_api_still_runs_and_says_where_it_looked(
    make_api: object, tmp_path: Path, database_url: str
) -> None:
    settings: Settings = make_settings(
        tmp_path, database_url, INERTIA_ID_FRONTEND_DIR=tmp_path / "no-such-folder"
    )
    built = make_api(settings)  # type: ignore[operator]
    missing = built.client.get("/")
    assert missing.status_code == 404
    assert "no-such-folder" in missing.json()["detail"]
    assert built.client.get("/health").status_code == 200


def test_presets_are_scenario_documents(api: Api, paper: Scenario) -> None:
    presets = api.get("/scenarios/presets").json()
    assert Scenario.model_validate(presets["paper"]) == paper


def test_response_gives_each_candidates_mean_and_band_as_simulated(
    api: Api, paper: Scenario
) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    response = api.get_with_key(
        f"/scenarios/{scenario_id}/response",
        params={"sequence": json.dumps(GOOD_SEQUENCE), "n_realisations": 8, "seed": 3},
    )
    assert response.status_code == 200, response.text
    body = response.json()
    expected = simulate(paper, GOOD_SEQUENCE, 8, np.random.default_rng(3))
    omega = expected.omega_measured
    assert body["time_s"] == pytest.approx(paper.sample_times(4).tolist())
    assert body["impulse_nms"] == pytest.approx(24.0)  # 3 thrusters x 2 N m x 4 s
    assert body["duties"] == [[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]] * 4
    assert [c["name"] for c in body["candidates"]] == paper.candidate_names
    for k, candidate in enumerate(body["candidates"]):
        assert np.allclose(candidate["mean_rad_s"], omega[k].mean(axis=0))
        low = np.asarray(candidate["low_rad_s"])
        high = np.asarray(candidate["high_rad_s"])
        mean = np.asarray(candidate["mean_rad_s"])
        assert np.all(low <= high) and np.all(low <= omega[k].max(axis=0))
        assert np.allclose(low, np.percentile(omega[k], 10, axis=0))
        assert mean.shape == (80, 3)
        assert candidate["final_rate_rad_s"] == pytest.approx(
            float(expected.final_rate_rad_s[k].mean())
        )
    # Same seed, same answer.
    again = api.get_with_key(
        f"/scenarios/{scenario_id}/response",
        params={"sequence": json.dumps(GOOD_SEQUENCE), "n_realisations": 8, "seed": 3},
    ).json()
    assert again == body


@pytest.mark.parametrize(
    ("sequence", "n", "quoted"),
    [
        ("4,4,4,0,0,0", 20, "'4,4,4,0,0,0'"),
        ("[[4, 4, 4, 0, 0]]", 20, "got shape (1, 5)"),
        ("[[4, 4, 4, 0, 0, 9]]", 20, "level index 9"),
        ('[["a", 4, 4, 0, 0, 0]]', 20, '\'[["a"'),
        ("[[4, 4, 4, 0, 0, true]]", 20, "integer level indices, got '[[4, 4, 4, 0, 0, true]]'"),
        ("[[4, 4, 4, 0, 0, 0]]", 1, "greater than or equal to 2, got '1'"),
        (json.dumps([[4, 4, 4, 0, 0, 0]] * 1000), 20, "= 60000 rate values; at most 8192"),
        (json.dumps([[4, 4, 4, 0, 0, 0]] * 64), 200, "= 1280000; at most 400000"),
    ],
)
def test_a_bad_response_request_names_the_value(
    api: Api, sequence: str, n: int, quoted: str
) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    response = api.get_with_key(
        f"/scenarios/{scenario_id}/response", params={"sequence": sequence, "n_realisations": n}
    )
    assert response.status_code == 422, response.text
    assert quoted in response.json()["detail"][0]["msg"]


@pytest.mark.parametrize(
    ("path", "query", "name"),
    [
        ("plan", "sequence=[[4,4,4,0,0,0]]&sequence=[[0,0,0,4,4,4]]", "sequence"),
        ("plan", "sequence=[[4,4,4,0,0,0]]&format=csv&format=json", "format"),
        ("response", "sequence=[[4,4,4,0,0,0]]&sequence=[[0,0,0,4,4,4]]", "sequence"),
        ("response", "sequence=[[4,4,4,0,0,0]]&seed=1&seed=2", "seed"),
    ],
)
def test_a_parameter_given_twice_is_422_not_the_last_one(
    api: Api, path: str, query: str, name: str
) -> None:
    """Starlette keeps the last of repeated values: a plan of a sequence the operator did
    not mean to send. Every route refuses a repeated parameter that is not a list."""
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    response = api.get_with_key(f"/scenarios/{scenario_id}/{path}?{query}")
    assert response.status_code == 422, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == ["query", name]
    assert f"{name} is given 2 times" in detail["msg"]
    # A list parameter repeats: jobs carrying both tags.
    assert api.get("/jobs?tag=a&tag=b").status_code == 200
    assert api.get("/jobs?limit=1&limit=2").status_code == 422


@pytest.mark.parametrize(
    ("path", "name", "takes"),
    [
        # A typo of status: every job was listed, as if no filter had been asked for.
        ("/jobs?stauts=failed", "stauts", "q, scenario_id, sort, status, stopped, tag, type"),
        ("/classifiers?kidn=1nn", "kidn", "kind, limit, offset, order, q, scenario_id"),
        ("/health?verbose=1", "verbose", "takes: none"),
    ],
)
def test_an_unknown_query_parameter_is_422_naming_what_the_route_takes(
    api: Api, path: str, name: str, takes: str
) -> None:
    response = api.get(path)
    assert response.status_code == 422, response.text
    (detail,) = response.json()["detail"]
    assert detail["loc"] == ["query", name]
    assert f"unknown query parameter {name!r}" in detail["msg"] and takes in detail["msg"]
    # The dashboard's page and static files take what a browser adds.
    assert api.get("/?utm_source=x").status_code == 200
    assert api.get("/jobs?status=failed&tag=a&tag=b").status_code == 200


def test_a_plan_too_long_says_how_many_steps_it_may_have(api: Api) -> None:
    """As many RK4 steps as a job may fly (100,000): on a 1 ms RK4 step, 100 steps."""
    scenario_id = api.create_scenario(timing={"integration_step_s": 0.001})["id"]
    response = api.get_with_key(
        f"/scenarios/{scenario_id}/plan", params={"sequence": json.dumps([[0] * 6] * 1000)}
    )
    assert response.status_code == 422, response.text
    assert "1000 steps: at most 100 steps" in response.json()["detail"][0]["msg"]
    # The paper preset's 1,000 steps (20,000 RK4 steps) are planned.
    paper_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    sequence = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]] * 500
    planned = api.post(f"/scenarios/{paper_id}/plan", json={"sequence": sequence})
    assert planned.status_code == 200, planned.text
    assert len(planned.json()["steps"]) == 1000


def _unstamped(text: str) -> object:
    """A plan's lines but its ``# exported_at`` one (CSV), or its JSON but ``exported_at``."""
    if text.startswith("{"):
        document = json.loads(text)
        assert document.pop("exported_at").endswith("Z"), document
        return document
    return [line for line in text.splitlines() if not line.startswith("# exported_at: ")]


def test_a_plan_posted_in_the_body_is_the_plan_of_the_query(api: Api) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    sequence = [[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2
    for fmt in ("json", "csv"):
        by_query = api.get_with_key(
            f"/scenarios/{scenario_id}/plan",
            params={"sequence": json.dumps(sequence), "format": fmt},
        )
        by_body = api.post(
            f"/scenarios/{scenario_id}/plan?format={fmt}", json={"sequence": sequence}
        )
        assert by_body.status_code == 200, by_body.text
        # The same file but for the CSV's export time (a line of its own).
        assert _unstamped(by_body.text) == _unstamped(by_query.text)
        assert ("# exported_at: " in by_body.text) == (fmt == "csv")
        assert by_body.headers["content-disposition"] == by_query.headers["content-disposition"]
    # It computes, so it needs the key.
    anonymous = api.client.post(f"/scenarios/{scenario_id}/plan", json={"sequence": sequence})
    assert anonymous.status_code == 401


def test_a_sequence_too_long_for_a_url_is_planned_from_the_body(api: Api) -> None:
    """1,000 steps (the most a sequence may have; a scenario on 1 s integration steps may
    plan them) are 14 kB of compact JSON, 30 kB in a URL: past what proxies pass in a
    request line by default (nginx: 8 kB). In the body they are planned, and the plan is
    the query's."""
    scenario_id = api.create_scenario(
        timing={"integration_step_s": 1.0, "sample_rate_hz": 1.0},
        uncertainty={"disturbance_interval_s": 1.0, "lowpass_time_constant_s": 0.0},
    )["id"]
    sequence = ([[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2) * 250  # 1,000 steps
    compact = json.dumps(sequence, separators=(",", ":"))
    assert len(urllib.parse.quote(compact)) > 30_000
    response = api.post(f"/scenarios/{scenario_id}/plan", json={"sequence": sequence})
    assert response.status_code == 200, response.text
    plan = response.json()
    assert len(plan["steps"]) == 1000
    assert plan["propellant"]["impulse_nms"] == pytest.approx(1000 * 6.0)
    by_query = api.get_with_key(f"/scenarios/{scenario_id}/plan", params={"sequence": compact})
    assert _unstamped(response.text) == _unstamped(by_query.text)


def test_a_huge_bad_plan_body_is_named_not_echoed(api: Api) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    ragged = [[4, 4, 4, 0, 0, 0]] * 100_000 + [[1]]  # 2 MB, one short row at the end
    response = api.post(f"/scenarios/{scenario_id}/plan", json={"sequence": ragged})
    assert response.status_code == 422
    assert len(response.content) < 2_000
    assert "is not an array of level indices" in response.text
    assert "characters)" in response.text


def test_a_plan_flies_the_sequence_when_asked(api: Api, paper: Scenario) -> None:
    """``flights``: how single flights spread around the nominal prediction, the same
    figures as the core's for the same seed, from the query, the body and a search's
    member alike; past the service's budget a 422 names the product."""
    from inertia_id.search.plan import command_plan

    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    sequence = [[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2
    expected = command_plan(paper, sequence, flights=300, seed=5).to_dict()
    by_query = api.get_with_key(
        f"/scenarios/{scenario_id}/plan",
        params={"sequence": json.dumps(sequence), "flights": 300, "seed": 5},
    )
    assert by_query.status_code == 200, by_query.text
    assert by_query.json()["flights"] == expected["flights"]
    assert [c["flights"] for c in by_query.json()["candidates"]] == [
        c["flights"] for c in expected["candidates"]
    ]
    by_body = api.post(
        f"/scenarios/{scenario_id}/plan?flights=300&seed=5&format=csv", json={"sequence": sequence}
    )
    assert by_body.status_code == 200, by_body.text
    assert "# flights: 300 per candidate at the scenario's noise, seed 5" in by_body.text
    # 5 candidates x 3,000 flights x 80 RK4 steps is past the budget of one request.
    too_many = api.get_with_key(
        f"/scenarios/{scenario_id}/plan",
        params={"sequence": json.dumps(sequence), "flights": 3000},
    )
    assert too_many.status_code == 422, too_many.text
    detail = too_many.json()["detail"][0]
    assert detail["loc"] == ["query", "flights"]
    assert (
        "5 candidates x 3000 flights x 80 RK4 steps = 1200000; at most 1000000" in (detail["msg"])
    )
    for bad, quoted in (
        (1, "flights must be 0 (none) or an integer in 2..100000, got 1"),
        (-1, "greater than or equal to 0"),
    ):
        refused = api.post(
            f"/scenarios/{scenario_id}/plan?flights={bad}", json={"sequence": sequence}
        )
        assert refused.status_code == 422, refused.text
        assert refused.json()["detail"][0]["loc"] == ["query", "flights"]
        assert quoted in refused.json()["detail"][0]["msg"]


@pytest.mark.parametrize(
    ("body", "loc", "quoted"),
    [
        ({"sequence": [[4, 4, 4, 0, 0, True]]}, ["body", "sequence", 0, 5], "valid integer"),
        ({"sequence": [[4, 4, 4, 0, 0, 4.0]]}, ["body", "sequence", 0, 5], "valid integer"),
        ({"sequence": []}, ["body", "sequence"], "at least 1 item"),
        ({"sequence": [[4, 4, 4, 0, 0]]}, ["body", "sequence"], "got shape (1, 5)"),
        ({"sequence": [[4, 4, 4, 0, 0, 9]]}, ["body", "sequence"], "level index 9"),
        ({"sequence": [[0] * 6] * 1001}, ["body", "sequence"], "1001 steps; at most 1000"),
        ({"sequence": [[0] * 6], "format": "csv"}, ["body", "format"], "Extra inputs"),
        ({}, ["body", "sequence"], "Field required"),
    ],
)
def test_a_bad_plan_body_names_the_value(
    api: Api, body: dict[str, Any], loc: list[Any], quoted: str
) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    response = api.post(f"/scenarios/{scenario_id}/plan", json=body)
    assert response.status_code == 422, response.text
    detail = response.json()["detail"][0]
    assert detail["loc"] == loc
    assert quoted in detail["msg"]


def test_response_of_an_unknown_scenario_is_404(api: Api) -> None:
    response = api.get_with_key("/scenarios/nope/response", params={"sequence": "[[4,4,4,0,0,0]]"})
    assert response.status_code == 404


def test_the_response_simulation_costs_cpu_and_so_needs_the_key(api: Api) -> None:
    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    params = {"sequence": json.dumps(GOOD_SEQUENCE), "n_realisations": 8}
    response = api.get(f"/scenarios/{scenario_id}/response", params=params)
    assert response.status_code == 401
    response = api.client.get(
        f"/scenarios/{scenario_id}/response", params=params, headers={"X-API-Key": "wrong"}
    )
    assert response.status_code == 401
    assert api.get_with_key(f"/scenarios/{scenario_id}/response", params=params).status_code == 200


def test_the_vocabulary_is_the_cores(api: Api) -> None:
    from typing import get_args

    from app.schemas import JobStopped
    from inertia_id.classifiers.registry import CLASSIFIER_KINDS, DEFAULT_KIND, kind_metrics
    from inertia_id.evaluation.sweep import DEFAULT_NOISES, NOISE_KINDS, NOISE_UNITS
    from inertia_id.search import SEARCH_METHODS
    from service.store.models import STOPPED_REASONS, TERMINAL_STATUSES

    words = api.get("/vocabulary").json()
    assert [k["kind"] for k in words["classifier_kinds"]] == list(CLASSIFIER_KINDS)
    for k in words["classifier_kinds"]:
        assert k["metrics"] == list(kind_metrics(k["kind"])) and k["label"]
    assert words["default_kind"] == DEFAULT_KIND
    # The kinds that answer POST /identify/partial: the dashboard calls it only for them.
    online = {k["kind"] for k in words["classifier_kinds"] if k["online"]}
    assert online == {"likelihood", "marginal-likelihood"}
    assert DEFAULT_KIND in online
    assert words["kind_for_metric_only"] == "clustering"
    assert [n["noise"] for n in words["noises"]] == list(NOISE_KINDS)
    assert {n["noise"]: n["unit"] for n in words["noises"]} == NOISE_UNITS
    assert words["default_noises"] == list(DEFAULT_NOISES)
    assert [m["name"] for m in words["search_methods"]] == list(SEARCH_METHODS)
    assert words["terminal_statuses"] == list(TERMINAL_STATUSES)
    # What a job's stopped may say and GET /jobs?stopped= takes: the store's reasons.
    assert words["stopped_reasons"] == list(STOPPED_REASONS) == list(get_args(JobStopped))


def test_the_vocabulary_lists_the_commanded_residual_bounds(api: Api) -> None:
    """The dashboard's constraint hint lists the vocabulary's names: the commanded
    residual's bounds are among them, the mean over candidates and the worst one, in
    rad/s and deg/s. (Before, the names were not constraints at all.)"""
    from inertia_id.search.objectives import CONSTRAINTS

    listed = {c["name"]: c for c in api.get("/vocabulary").json()["constraints"]}
    assert list(listed) == list(CONSTRAINTS)
    for unit in ("rad_s", "deg_s"):
        mean = listed[f"max_commanded_residual_rate_{unit}"]
        worst = listed[f"max_commanded_residual_rate_max_{unit}"]
        for entry in (mean, worst):
            assert entry["bounds"] == "commanded_residual_rate" and entry["sense"] == "max"
            assert entry["flight_quantile"] is None
        assert mean["worst_candidate"] is False and worst["worst_candidate"] is True
    # The final rate's bounds stay as they were: the worst candidate's total.
    assert listed["max_final_rate_deg_s"]["bounds"] == "final_rate"
    assert listed["max_final_rate_deg_s"]["worst_candidate"] is True


def test_baselines_are_the_cores_for_the_scenarios_thrusters(api: Api, paper: Scenario) -> None:
    from inertia_id.physics.sequences import baseline_sequences

    scenario_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    got = {}
    for length in (3, 4):
        got[length] = api.get(f"/scenarios/{scenario_id}/baselines", params={"length": length})
        made = baseline_sequences(paper, length)
        assert got[length].json() == {
            name: {"unavailable": sequence} if isinstance(sequence, str) else sequence.tolist()
            for name, sequence in made.items()
        }
        assert got[length].json()["hand-designed"] == [[4, 4, 4, 0, 0, 0]] * length
    # At 3 steps fire-coast-brake is fire-then-brake itself; at 4 every baseline exists.
    assert "same sequence as fire-then-brake" in got[3].json()["fire-coast-brake"]["unavailable"]
    assert all(isinstance(sequence, list) for sequence in got[4].json().values())
    bad = api.get(f"/scenarios/{scenario_id}/baselines", params={"length": 0})
    assert bad.status_code == 422 and "0" in bad.text
    assert api.get("/scenarios/nope/baselines").status_code == 404


def test_a_plan_whose_scenario_overflows_names_the_sequence_not_flights(api: Api) -> None:
    """A scenario the service stores but whose bodies overflow under a sequence (torques
    of 1e300 N m) was refused at ``query.flights`` although no flights were asked for; the
    plan's nominal prediction is what overflowed, so the sequence is named, and
    the scenario's noise only when the nominal plan alone goes through."""
    scenario_id = api.create_scenario(thrusters={"nominal_torque_nm": 1e300})["id"]
    sequence = [[4, 4, 4, 0, 0, 0]] * 2
    by_query = api.get_with_key(
        f"/scenarios/{scenario_id}/plan", params={"sequence": json.dumps(sequence)}
    )
    by_body = api.post(f"/scenarios/{scenario_id}/plan?flights=20", json={"sequence": sequence})
    for response, loc in ((by_query, ["query", "sequence"]), (by_body, ["body", "sequence"])):
        assert response.status_code == 422, response.text
        (detail,) = response.json()["detail"]
        assert detail["loc"] == loc
        assert "overflowed to inf or nan" in detail["msg"]
    # A disturbance that overflows only the noisy flights: the nominal plan is fine, and
    # what is named is the scenario's own noise, as a job names it (the flights asked for
    # were named before: a number the client had not got wrong). Such a scenario is no
    # longer stored (its own noise overflows the rates): a row stored before that check.
    noisy_id = api.insert_scenario(
        Scenario.paper().with_uncertainty(disturbance_torque_sigma_nm=1e6)
    )
    assert api.post(f"/scenarios/{noisy_id}/plan", json={"sequence": sequence}).status_code == 200
    flown = api.post(f"/scenarios/{noisy_id}/plan?flights=20", json={"sequence": sequence})
    assert flown.status_code == 422, flown.text
    assert flown.json()["detail"][0]["loc"] == ["uncertainty", "disturbance_torque_sigma_nm"]


def _noisy_small_body(api: Api) -> str:
    """A scenario whose first candidate (0.06 kg m^2) two full-duty steps spin to 67 rad/s
    an axis nominally, and past 100 rad/s in some flights at its thrust-scale error of
    0.5, the most a scenario may state (its torque 1 + 0.5 z times the nominal)."""
    candidates = Scenario.paper().model_dump(mode="json")["inertia_candidates"]
    candidates[0]["inertia_kg_m2"] = (0.06 * np.eye(3)).tolist()
    noisy = {"inertia_candidates": candidates, "uncertainty": {"thrust_scale_sigma": 0.5}}
    return str(api.create_scenario(**noisy)["id"])


def test_a_plan_and_a_response_past_any_gyros_range_are_refused_alike(api: Api) -> None:
    """A scenario with an inertia of 1e-30 kg m² is stored; its plan was a 200 predicting
    1e30 rad/s, while its response was refused (at no parameter) only because its noisy
    realisations overflowed (now both by the nominal rule, before any realisation); at
    1e-2 kg m² both were 200s (780 and 1,340 rad/s). Both
    routes now refuse rates past any gyro's range at the sequence, naming the candidate and the rate
    in rad/s and deg/s; a plan whose nominal prediction is in range but whose flights are
    not names the flights."""
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    for moment in (1e-30, 1e-2):
        candidates = Scenario.paper().model_dump(mode="json")["inertia_candidates"]
        candidates[0]["inertia_kg_m2"] = (moment * np.eye(3)).tolist()
        scenario_id = api.create_scenario(inertia_candidates=candidates)["id"]
        query = {"sequence": json.dumps(sequence)}
        answers = {
            ("query", "sequence"): api.get_with_key(f"/scenarios/{scenario_id}/plan", params=query),
            ("body", "sequence"): api.post(
                f"/scenarios/{scenario_id}/plan", json={"sequence": sequence}
            ),
            ("query", "sequence", "response"): api.get_with_key(
                f"/scenarios/{scenario_id}/response", params=query
            ),
        }
        for loc, response in answers.items():
            assert response.status_code == 422, (moment, loc, response.text)
            (detail,) = response.json()["detail"]
            assert tuple(detail["loc"]) == loc[:2]
            message = detail["msg"]
            assert message.startswith(f"sequence {sequence} spins candidate 'none ejected'")
            assert re.search(r"to [0-9.e+]+ rad/s \([0-9.e+]+ deg/s\)", message), message
            assert "no attitude gyro measures it" in message
            assert "likely wrong in units" in message
    # In range nominally, past it in single flights (a thrust-scale error on a small body).
    noisy_id = _noisy_small_body(api)
    two = sequence[:2]
    assert api.post(f"/scenarios/{noisy_id}/plan", json={"sequence": two}).status_code == 200
    flown = api.post(f"/scenarios/{noisy_id}/plan?flights=20&seed=3", json={"sequence": two})
    assert flown.status_code == 422, flown.text
    (detail,) = flown.json()["detail"]
    assert detail["loc"] == ["query", "flights"]
    assert "of 20 at the scenario's noise (seed 3)" in detail["msg"]


def test_a_plan_and_a_response_refuse_the_same_sequence_near_the_gyro_ceiling(api: Api) -> None:
    """One rule decides both: a sphere of 0.019 kg m² under one full-duty step reads at
    most 94 to 96 rad/s at the gyro's samples, but is left at 2 / 0.019 = 105 rad/s once the
    actuation lag has emptied. The response answered 200 while the plan refused; now both
    refuse with the same message, at query.sequence, naming the peak, the candidate and
    the ceiling; at 0.025 kg m² (80 rad/s settled) both answer 200."""
    sequence = [[4, 4, 4, 0, 0, 0]]
    query = {"sequence": json.dumps(sequence)}
    for moment, refused in ((0.019, True), (0.025, False)):
        candidates = Scenario.paper().model_dump(mode="json")["inertia_candidates"]
        candidates[0]["inertia_kg_m2"] = (moment * np.eye(3)).tolist()
        scenario_id = api.create_scenario(inertia_candidates=candidates)["id"]
        plan = api.get_with_key(f"/scenarios/{scenario_id}/plan", params=query)
        posted = api.post(f"/scenarios/{scenario_id}/plan", json={"sequence": sequence})
        response = api.get_with_key(f"/scenarios/{scenario_id}/response", params=query)
        if not refused:
            assert [plan.status_code, posted.status_code, response.status_code] == [200] * 3
            continue
        messages = set()
        for answer in (plan, posted, response):
            assert answer.status_code == 422, answer.text
            (detail,) = answer.json()["detail"]
            assert detail["loc"][-1] == "sequence"
            messages.add(detail["msg"])
        (message,) = messages  # one message, word for word
        assert "spins candidate 'none ejected' to 105 rad/s (6,031 deg/s)" in message
        assert "once the actuation lag has emptied" in message
        assert "at most 100 rad/s, 5,730 deg/s" in message
    # In range nominally, past it in the noisy realisations shown (a thrust-scale error
    # on a small body): named at n_realisations, as a plan's flights are at flights.
    noisy_id = _noisy_small_body(api)
    two = {"sequence": json.dumps(sequence * 2)}
    assert api.get_with_key(f"/scenarios/{noisy_id}/plan", params=two).status_code == 200
    shown = api.get_with_key(f"/scenarios/{noisy_id}/response", params=two)
    assert shown.status_code == 422, shown.text
    (detail,) = shown.json()["detail"]
    assert detail["loc"] == ["query", "n_realisations"]
    assert re.search(r"in realisation \d+ of 20 \(seed 0\)", detail["msg"]), detail["msg"]


def test_a_plan_far_below_the_gyro_noise_says_so_in_its_warnings(api: Api) -> None:
    # Inertia typed in kg mm^2 as kg m^2: planned, as before, but no longer without a word.
    paper = api.post("/scenarios", json={"preset": "paper"}).json()["document"]
    candidates = [
        {**c, "inertia_kg_m2": [[v * 1e6 for v in row] for row in c["inertia_kg_m2"]]}
        for c in paper["inertia_candidates"]
    ]
    overrides = {"name": "mm", "inertia_candidates": candidates}
    scenario_id = api.post("/scenarios", json={"preset": "paper", "overrides": overrides}).json()[
        "id"
    ]
    sequence = json.dumps([[4, 4, 4, 0, 0, 0]] * 2)
    response = api.get_with_key(f"/scenarios/{scenario_id}/plan", params={"sequence": sequence})
    assert response.status_code == 200, response.text
    (warning,) = response.json()["warnings"]
    assert "peak at 1.02e-07 rad/s" in warning and "by 9.83e+03x" in warning
    assert "kg mm^2 typed as kg m^2" in warning
    paper_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    plain = api.get_with_key(f"/scenarios/{paper_id}/plan", params={"sequence": sequence})
    assert plain.json()["warnings"] == []


def test_a_response_far_below_the_gyro_noise_says_so_in_its_warnings(api: Api) -> None:
    # The search page's best-sequence charts and the classifier page draw this response:
    # with inertia typed in kg mm^2 as kg m^2 they drew noise without a word, where the
    # plan of the same sequence warned.
    paper = api.post("/scenarios", json={"preset": "paper"}).json()["document"]
    candidates = [
        {**c, "inertia_kg_m2": [[v * 1e6 for v in row] for row in c["inertia_kg_m2"]]}
        for c in paper["inertia_candidates"]
    ]
    overrides = {"name": "mm", "inertia_candidates": candidates}
    scenario_id = api.post("/scenarios", json={"preset": "paper", "overrides": overrides}).json()[
        "id"
    ]
    query = {"sequence": json.dumps([[4, 4, 4, 0, 0, 0]] * 2), "n_realisations": 4}
    response = api.get_with_key(f"/scenarios/{scenario_id}/response", params=query)
    assert response.status_code == 200, response.text
    (warning,) = response.json()["warnings"]
    assert "peak at 1.02e-07 rad/s" in warning and "by 9.83e+03x" in warning
    assert "kg mm^2 typed as kg m^2" in warning
    # The plan's text, word for word.
    plan = api.get_with_key(
        f"/scenarios/{scenario_id}/plan", params={"sequence": query["sequence"]}
    )
    assert plan.json()["warnings"] == [warning]
    paper_id = api.post("/scenarios", json={"preset": "paper"}).json()["id"]
    plain = api.get_with_key(f"/scenarios/{paper_id}/response", params=query)
    assert plain.status_code == 200 and plain.json()["warnings"] == []


def test_the_response_of_every_sequence_a_search_may_find_is_drawn(api: Api) -> None:
    """A search's page draws its best sequence's response (20 realisations). On a 10 ms
    RK4 step (a 20 ms thruster lag) a 16-step best sequence is 1,600 RK4 steps: the
    response took 1,280 and answered 422, so the page of a search the service had
    accepted and run could not draw what it found. It takes what a job may fly (100,000
    RK4 steps, 8,192 rate values a series), the work cap kept (0.02 s for 20 steps)."""
    scenario_id = api.create_scenario(
        timing={"integration_step_s": 0.01},
        uncertainty={"lowpass_time_constant_s": 0.02, "disturbance_interval_s": 0.05},
    )["id"]
    sequence = [[4, 4, 4, 0, 0, 0]] * 8 + [[0, 0, 0, 4, 4, 4]] * 8
    response = api.get_with_key(
        f"/scenarios/{scenario_id}/response",
        params={"sequence": json.dumps(sequence), "n_realisations": 20},
    )
    assert response.status_code == 200, response.text
    assert len(response.json()["time_s"]) == 16 * 20
