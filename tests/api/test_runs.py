"""Runs a flight team compares: names and tags, summaries, sorted and filtered pages,
results downloaded as JSON and CSV, and a cheap check of the API key."""

from __future__ import annotations

import csv
import io
import json
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from inertia_id import InertiaClassifier, Scenario, simulate
from service.store.jobs import add_metrics, claim, finish
from service.summaries import SUMMARY_COLUMNS

from .support import GOOD_SEQUENCE, Api


def _search_result(fresh_f1: list[float], fuel: float, wall: float) -> dict[str, Any]:
    """A search result shaped like the worker's (SearchOutcome.to_dict)."""
    return {
        "method": "cem",
        "best": {
            "sequence": [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]],
            "f1": 1.0,
            "final_rate_rad_s": 0.12,
            "fuel_nms": fuel,
            "episode_return": 2.0,
            "episode": 3,
            "residual_rate_rad_s": 0.11,
        },
        "fresh": {
            "seed": 9,
            "f1": fresh_f1,
            "final_rate_rad_s": [0.1, 0.2],
            "separability": None,
            "f1_mean": sum(fresh_f1) / len(fresh_f1),
            "f1_min": min(fresh_f1),
        },
        "front": {
            "accuracy_source": "measured",
            "candidates_rescored": 1,
            "confirmation": None,
            "members": [
                {
                    "index": 0,
                    "sequence": [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]],
                    "scores": {"accuracy": 0.93, "final_rate_rad_s": 0.05},
                }
            ],
        },
        "curve": [
            {
                "timesteps": 64 * (i + 1),
                "episodes": 16 * (i + 1),
                "mean_episode_reward": 0.5 + i,
                "mean_f1": 0.4 + 0.1 * i,
                "best_f1": 0.6 + 0.2 * i,
                "best_residual_rate_rad_s": 0.2,
            }
            for i in range(3)
        ],
        "timesteps": 192,
        "episodes": 48,
        "wall_time_s": wall,
        "stopped": "target",
        "space_size": 15625,
        "settings": {"scorer": {"objective": "separability"}},
        "baselines": {
            "hand-designed": {
                "sequence": [[4, 4, 4, 0, 0, 0]] * 2,
                "fresh_f1": [1.0, 0.9],
                "fresh_final_rate_rad_s": [0.19, 0.2],
                "fuel_nms": 12.0,
            },
            "fire-coast-brake": {
                "unavailable": "fire, coast, brake needs at least 3 steps, got 2",
            },
        },
    }


def _finished(
    api: Api,
    scenario_id: str,
    seed: int,
    result: dict[str, Any] | None,
    status: str = "succeeded",
    **labels: Any,
) -> str:
    job = api.submit("search", scenario_id, seed=seed, params={"method": "cem"}, **labels).json()
    with api.db.session() as session:
        claim(session, job["id"], "tests")
    with api.db.session() as session:
        assert finish(session, job["id"], status, result=result)
    return str(job["id"])


def test_names_and_tags_are_labels_not_identity(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    first = api.submit(
        "search", scenario_id, name="  CEM on paper  ", tags=["paper", "cem", "paper"]
    )
    assert first.status_code == 202, first.text
    job = first.json()
    assert job["name"] == "CEM on paper"
    assert job["tags"] == ["cem", "paper"]
    # The same work under another name is the same job, labels as they were.
    again = api.submit("search", scenario_id, name="another name", tags=["x"])
    assert again.status_code == 200 and again.json()["reused"] is True
    assert again.json()["id"] == job["id"] and again.json()["name"] == "CEM on paper"
    assert again.json()["config_hash"] == job["config_hash"]

    renamed = api.client.patch(
        f"/jobs/{job['id']}",
        json={"name": "baseline run", "tags": ["flight-2", "cem"]},
        headers=api.auth,
    )
    assert renamed.status_code == 200, renamed.text
    assert renamed.json()["name"] == "baseline run"
    assert renamed.json()["tags"] == ["cem", "flight-2"]
    assert renamed.json()["config_hash"] == job["config_hash"]
    assert renamed.json()["params"] == job["params"]
    # A field left out is kept; null clears the name.
    cleared = api.client.patch(f"/jobs/{job['id']}", json={"name": None}, headers=api.auth)
    assert cleared.json()["name"] is None and cleared.json()["tags"] == ["cem", "flight-2"]
    assert api.get(f"/jobs/{job['id']}").json()["tags"] == ["cem", "flight-2"]


def test_concurrent_retags_of_one_job_all_succeed(api: Api) -> None:
    """Twenty clients retag one job at once: each is a 200, the last writer's tags stand.
    (Two retags read the same tags, and the second's insert of a tag the first had added
    was a unique violation: a 500 on SQLite and on PostgreSQL.)"""
    from concurrent.futures import ThreadPoolExecutor

    job = api.submit("search", api.create_scenario()["id"]).json()

    def retag(i: int) -> int:
        response = api.client.patch(
            f"/jobs/{job['id']}", json={"tags": ["a", "b", f"t{i % 3}"]}, headers=api.auth
        )
        return int(response.status_code)

    for _ in range(3):
        with ThreadPoolExecutor(max_workers=20) as pool:
            codes = list(pool.map(retag, range(20)))
        assert codes == [200] * 20, codes
        tags = api.get(f"/jobs/{job['id']}").json()["tags"]
        assert tags[:2] == ["a", "b"] and len(tags) == 3 and tags[2] in {"t0", "t1", "t2"}


def test_editing_labels_needs_the_key(api: Api) -> None:
    job = api.submit("search", api.create_scenario()["id"]).json()
    response = api.client.patch(f"/jobs/{job['id']}", json={"name": "x"})
    assert response.status_code == 401
    wrong = api.client.patch(f"/jobs/{job['id']}", json={"name": "x"}, headers={"X-API-Key": "no"})
    assert wrong.status_code == 401
    assert api.client.patch("/jobs/nope", json={"name": "x"}, headers=api.auth).status_code == 404


@pytest.mark.parametrize(
    ("labels", "fragment"),
    [
        ({"name": "x" * 201}, "at most 200 characters"),
        # The pattern's own message quoted the regular expression, naming no character.
        ({"name": "bad\x07name"}, "holds control characters (U+0007); remove them"),
        # A right-to-left override shows "run\u202egnp.exe" as "runexe.png".
        ({"name": "run\u202egnp.exe"}, "bidirectional control characters (U+202E)"),
        ({"tags": ["ok", "a\u2066b"]}, "bidirectional control characters (U+2066)"),
        ({"tags": ["a,b"]}, "'a,b' holds a comma, which separates tags"),
        ({"tags": [" "]}, "' ' is blank"),
        ({"tags": ["x\ty"]}, "holds control characters (U+0009); remove them"),
        ({"tags": ["t" * 65]}, "at most 64 characters"),
        ({"tags": [f"t{i}" for i in range(17)]}, "at most 16 items"),
        ({"tags": "paper"}, "list"),
    ],
)
def test_bad_labels_are_422_naming_the_value(
    api: Api, labels: dict[str, Any], fragment: str
) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, **labels)
    assert response.status_code == 422, response.text
    assert fragment in response.text
    job = api.submit("search", scenario_id).json()
    patched = api.client.patch(f"/jobs/{job['id']}", json=labels, headers=api.auth)
    assert patched.status_code == 422 and fragment in patched.text


def test_a_finished_job_has_its_summary_and_queue_and_run_times(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, scenario_id, 0, _search_result([1.0, 0.8], 20.0, 3.5))
    job = api.get(f"/jobs/{job_id}").json()
    keys = [c.key for c in SUMMARY_COLUMNS["search"]]
    assert list(job["summary"]) == keys
    assert job["summary"]["fresh_f1"] == pytest.approx(0.9)
    assert job["summary"]["fresh_f1_min"] == pytest.approx(0.8)
    # The settled residual rate of the front's best (0.05), not the rate at the last
    # step's end on the fresh draws (0.15) nor on the search's draw (0.12).
    assert job["summary"]["residual_rate_rad_s"] == 0.05
    assert job["summary"]["design_accuracy"] == 0.93
    assert job["summary"]["fuel_nms"] == 20.0 and job["summary"]["wall_time_s"] == 3.5
    assert job["queue_time_s"] >= 0 and job["run_time_s"] >= 0
    queued = api.submit("search", scenario_id, seed=5).json()
    assert queued["run_time_s"] is None and queued["summary"] is None


def test_lists_sort_by_a_summary_figure_and_filter_by_text_tag_and_status(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    low = _finished(api, scenario_id, 1, _search_result([0.6, 0.6], 30.0, 1.0), name="low")
    high = _finished(api, scenario_id, 2, _search_result([1.0, 1.0], 10.0, 9.0), name="high")
    mid = _finished(
        api, scenario_id, 3, _search_result([0.8, 0.8], 20.0, 5.0), name="Mid run", tags=["keep"]
    )
    queued = api.submit("search", scenario_id, seed=4, name="waiting").json()["id"]

    def ids(**query: Any) -> list[str]:
        response = api.get("/jobs", params=query)
        assert response.status_code == 200, response.text
        return [j["id"] for j in response.json()["items"]]

    # Jobs without the figure come last whichever way.
    assert ids(sort="fresh_f1", order="desc") == [high, mid, low, queued]
    assert ids(sort="fresh_f1", order="asc") == [low, mid, high, queued]
    assert ids(sort="fuel_nms", order="asc")[:3] == [high, mid, low]
    assert ids(sort="name", order="asc") == [high, low, mid, queued]
    assert ids(q="mid") == [mid]
    assert ids(q=mid[:6]) == [mid]
    assert ids(q="kee") == [mid]
    assert ids(tag="keep") == [mid]
    assert ids(tag="nothing") == []
    assert ids(status="queued") == [queued]
    page = api.get("/jobs", params={"sort": "fresh_f1", "limit": 2, "offset": 1}).json()
    assert page["total"] == 4 and [j["id"] for j in page["items"]] == [mid, low]
    # LIKE wildcards in the text are plain characters.
    assert ids(q="%") == [] and ids(q="_") == []
    # Any case, in any script: SQLite's own lower() folds ASCII only, and missed these.
    labels = {"name": "Énergie Ökonomie", "tags": ["Überflug"]}
    assert api.client.patch(f"/jobs/{mid}", json=labels, headers=api.auth).status_code == 200
    for text in ("énergie", "ÉNERGIE", "ökonomie", "überflug", "ÜBER"):
        assert ids(q=text) == [mid], text


@pytest.mark.parametrize(
    ("query", "fragment"),
    [
        ({"sort": "colour"}, "'colour'"),
        ({"order": "up"}, "asc"),
        ({"tag": "x" * 65}, "at most 64 characters"),
        ({"tag": ""}, "at least 1 character"),
        ({"tag": "a,b"}, "'a,b'"),
        ({"q": "a\x00b"}, "q"),
    ],
)
def test_bad_list_queries_are_422(api: Api, query: dict[str, str], fragment: str) -> None:
    for path in ("/jobs", "/classifiers"):
        if path == "/classifiers" and query.get("sort") == "colour":
            query = {"sort": "fresh_f1"}
            fragment = "'fresh_f1'"
        response = api.get(path, params=query)
        assert response.status_code == 422, (path, response.text)
        assert fragment in response.text


def test_classifier_lists_sort_filter_and_carry_the_training_jobs_labels(
    api: Api, classifier: InertiaClassifier
) -> None:
    scenario_id = api.create_scenario()["id"]
    job = api.submit(
        "train", scenario_id, params={"sequence": GOOD_SEQUENCE}, name="Flight A", tags=["t1"]
    ).json()
    first = api.insert_classifier(scenario_id, classifier)
    second = api.insert_classifier(scenario_id, classifier)
    with api.db.session() as session:
        from service.store.models import ClassifierRow

        row = session.get(ClassifierRow, second)
        assert row is not None
        row.job_id, row.f1, row.kind = job["id"], 0.5, "1nn"
    listed = api.get("/classifiers", params={"sort": "f1", "order": "asc"}).json()["items"]
    assert [c["id"] for c in listed] == [second, first]
    assert listed[0]["job_name"] == "Flight A" and listed[0]["tags"] == ["t1"]
    assert listed[1]["job_name"] is None and listed[1]["tags"] == []
    assert [c["id"] for c in api.get("/classifiers", params={"tag": "t1"}).json()["items"]] == [
        second
    ]
    assert [c["id"] for c in api.get("/classifiers", params={"q": "flight a"}).json()["items"]] == [
        second
    ]
    assert [c["id"] for c in api.get("/classifiers", params={"kind": "1nn"}).json()["items"]] == [
        second
    ]
    assert api.get(f"/classifiers/{second}").json()["job_name"] == "Flight A"


def _csv(text: str) -> list[list[str]]:
    """The rows after the ``# name: value`` lines a table may begin with."""
    return list(csv.reader(line for line in io.StringIO(text) if not line.startswith("# ")))


def test_a_search_result_downloads_as_json_and_as_each_csv_table(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    result = _search_result([1.0, 0.8], 20.0, 3.5)
    job_id = _finished(api, scenario_id, 0, result, name="run")
    whole = api.get(f"/jobs/{job_id}/result")
    assert whole.status_code == 200
    assert whole.headers["content-type"].startswith("application/json")
    assert f'filename="search-{job_id[:8]}.json"' in whole.headers["content-disposition"]
    document = json.loads(whole.text)
    assert document["result"]["curve"] == result["curve"] and document["name"] == "run"

    curve = api.get(f"/jobs/{job_id}/result", params={"format": "csv", "table": "curve"})
    assert curve.headers["content-type"].startswith("text/csv")
    assert f'filename="search-{job_id[:8]}-curve.csv"' in curve.headers["content-disposition"]
    rows = _csv(curve.text)
    assert rows[0][:3] == ["timesteps", "episodes", "mean_episode_reward"]
    assert [float(r[2]) for r in rows[1:]] == [p["mean_episode_reward"] for p in result["curve"]]
    assert rows[0][5] == "best_residual_rate_rad_s" and rows[1][5] == "0.2"
    # The stored points name the objective's score f1; the columns name what it is.
    assert rows[0][3:5] == ["mean_separability", "best_separability"]
    assert [float(r[4]) for r in rows[1:]] == [p["best_f1"] for p in result["curve"]]

    sequence = _csv(api.get(f"/jobs/{job_id}/result?format=csv&table=sequence").text)
    assert sequence[0] == ["step", *(f"thruster_{j}_level" for j in range(1, 7))]
    assert sequence[1] == ["1", "4", "4", "4", "0", "0", "0"]
    default = api.get(f"/jobs/{job_id}/result?format=csv")
    # The default table is named for what it is (it was "search-…-table.csv").
    assert f'filename="search-{job_id[:8]}-summary.csv"' in default.headers["content-disposition"]
    summary = dict(_csv(default.text)[1:])
    # Every search table says how the search was asked for (only sweeps' did).
    notes = _notes(default.text)
    assert notes["method"] == "cem" and notes["sequence_length"] == "4" and "job_seed" in notes
    # The same lines on every table, but the time each was written.
    curve_notes = _notes(curve.text)
    assert notes.pop("exported_at") and curve_notes.pop("exported_at")
    assert notes["constraints"] == "{}" and notes == curve_notes
    # Commanded impulse, named so: not "fuel", and not propellant (a mass).
    assert summary["impulse_nms"] == "20.0" and not any("fuel" in key for key in summary)
    # The separability search's score is labelled as such, not as an F1.
    assert summary["best_separability_search_draw"] == "1.0"
    assert summary["fresh_f1_mean"] == "0.9"
    # |ω| when the last command ends, named so: not the settled residual rate.
    assert float(summary["fresh_end_rate_rad_s_mean"]) == pytest.approx(0.15)
    assert summary["best_end_rate_rad_s_search_draw"] == "0.12"
    assert summary["best_residual_rate_rad_s_search_draw"] == "0.11"
    assert not any("final_rate" in key for key in summary)
    baselines = _csv(api.get(f"/jobs/{job_id}/result?format=csv&table=baselines").text)
    assert [r[0] for r in baselines[1:]] == [
        "found by the search",
        "hand-designed",
        "fire-coast-brake",
    ]
    # A baseline the length does not allow says why it has no figures.
    assert baselines[0][-1] == "unavailable" and baselines[1][-1] == baselines[2][-1] == ""
    assert baselines[0][5] == "impulse_nms"
    assert baselines[3][-1] == "fire, coast, brake needs at least 3 steps, got 2"

    bad = api.get(f"/jobs/{job_id}/result", params={"format": "csv", "table": "ranking"})
    assert bad.status_code == 422 and "'ranking'" in bad.text and "front" in bad.text
    assert api.get(f"/jobs/{job_id}/result", params={"format": "xml"}).status_code == 422
    queued = api.submit("search", scenario_id, seed=7).json()["id"]
    assert api.get(f"/jobs/{queued}/result").status_code == 409


@pytest.mark.parametrize(
    ("status", "said"),
    [
        ("failed", "it failed before it made one; there is nothing to download"),
        ("cancelled", "it was cancelled before it made one; there is nothing to download"),
    ],
)
def test_a_finished_job_without_a_result_is_409_saying_none_will_come(
    api: Api, status: str, said: str
) -> None:
    """It said "has no result (cancelled); nothing to download yet", as if one might come."""
    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, scenario_id, 3, None, status)
    for params in ({}, {"format": "csv", "table": "front"}):
        response = api.get(f"/jobs/{job_id}/result", params=params)
        assert response.status_code == 409
        assert response.json()["detail"] == f"job {job_id} has no result: {said}"
    queued = api.submit("search", scenario_id, seed=4).json()["id"]
    waiting = api.get(f"/jobs/{queued}/result")
    assert waiting.status_code == 409
    assert waiting.json()["detail"] == (
        f"job {queued} has no result: it is queued; nothing to download yet"
    )


def _with_front(sequences: list[Any]) -> dict[str, Any]:
    """A search result holding a real front of ``sequences`` (paper scenario, small draw)."""
    from inertia_id.search import OperatorSettings, build_front

    front = build_front(
        Scenario.paper(),
        sequences,
        OperatorSettings(n_realisations=3),
        seed=4,
        fresh_realisations=3,
        keep_infeasible=True,
    )
    return {**_search_result([1.0, 0.8], 20.0, 3.5), "front": front.to_dict()}


def test_a_plan_of_a_search_without_a_result_is_409_and_of_another_job_422(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    queued = api.submit("search", scenario_id, params={"method": "cem"}).json()["id"]
    waiting = api.get_with_key(f"/jobs/{queued}/plan")
    assert waiting.status_code == 409 and "is queued" in waiting.text
    training = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    other = api.get_with_key(f"/jobs/{training}/plan")
    assert other.status_code == 422 and "is a train job" in other.text


def test_a_cancelled_search_plans_the_best_sequence_it_had_found(api: Api) -> None:
    """A search cancelled after it found something keeps a partial result (its download
    works); its plan is that sequence's, and says the job was cancelled."""
    scenario_id = api.create_scenario()["id"]
    partial = _finished(api, scenario_id, 1, _search_result([0.9], 12.0, 2.0), "cancelled")
    plan = api.get_with_key(f"/jobs/{partial}/plan")
    assert plan.status_code == 200, plan.text
    document = plan.json()
    assert document["source"]["job_status"] == "cancelled"
    assert document["sequence"] == _search_result([0.9], 12.0, 2.0)["best"]["sequence"]
    as_csv = api.get_with_key(f"/jobs/{partial}/plan", params={"format": "csv"})
    # After the job's lines (test_a_plan_csv_says_which_job...) and the member.
    assert as_csv.text.splitlines()[7:9] == ["# member: best", "# job_status: cancelled"]
    assert as_csv.headers["content-disposition"] == (
        f'attachment; filename="plan-scenario-{scenario_id[:8]}-job-{partial[:8]}'
        '-member-best-cancelled.csv"'
    )
    # Training on it is refused by its id (a training names a succeeded search), saying
    # how to train on what it had found: it said only "name a succeeded search job".
    best = document["sequence"]
    train = api.submit("train", scenario_id, params={"search_job_id": partial})
    assert train.status_code == 422, train.text
    said = train.json()["detail"][0]["msg"]
    assert f"give the best sequence it had found as params.sequence: {best}" in said, said
    # Cancelled before it found anything: nothing to plan, nor to train on.
    empty = _finished(api, scenario_id, 2, None, "cancelled")
    nothing = api.get_with_key(f"/jobs/{empty}/plan")
    assert nothing.status_code == 409 and "is cancelled" in nothing.text
    none = api.submit("train", scenario_id, params={"search_job_id": empty})
    assert none.status_code == 422 and "params.sequence" not in none.text, none.text
    # A succeeded search's plan does not carry the status.
    done = _finished(api, scenario_id, 3, _search_result([0.9], 12.0, 2.0))
    assert "job_status" not in api.get_with_key(f"/jobs/{done}/plan").json()["source"]


def test_a_front_downloads_as_csv_its_members_plan_by_index_and_a_member_trains(
    api: Api,
) -> None:
    scenario_id = api.create_scenario()["id"]
    brake = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]
    result = _with_front([[[4, 4, 4, 0, 0, 0]] * 2, brake, [[4, 0, 0, 0, 0, 0]] * 2])
    result["scenario"] = Scenario.paper().model_dump(mode="json")  # what it ran on
    members = result["front"]["members"]
    assert len(members) >= 2
    job_id = _finished(api, scenario_id, 0, result)

    rows = _csv(api.get(f"/jobs/{job_id}/result?format=csv&table=front").text)
    header, body = rows[0], rows[1:]
    column = {name: i for i, name in enumerate(header)}
    listed = [r for r in body if r[column["kind"]] == "member"]
    assert [int(r[column["member"]]) for r in listed] == [m["index"] for m in members]
    for row, member in zip(listed, members, strict=True):
        for figure in ("accuracy", "final_rate_rad_s", "final_rate_deg_s", "attitude_change_deg"):
            assert float(row[column[figure]]) == member["scores"][figure]
        assert json.loads(row[column["sequence"]]) == member["sequence"]
        # Measured on fresh series, the prediction beside it.
        assert row[column["accuracy_source"]] == "measured"
        predicted = member["scores"]["predicted_accuracy_by_noise"]
        assert float(row[column["predicted_accuracy"]]) == pytest.approx(np.mean(predicted))
        # Each design condition's figures, and the worst candidate's residual rate (what
        # a residual-rate bound is held to).
        for c, (process, gyro) in enumerate(result["front"]["design_noise"]):
            suffix = f"{process:g}x_process_{gyro:g}x_gyro"
            assert (
                float(row[column[f"accuracy_{suffix}"]]) == member["scores"]["accuracy_by_noise"][c]
            )
            assert float(row[column[f"predicted_accuracy_{suffix}"]]) == predicted[c]
        # and the rate 95 % of its flights stay under (what a per-flight bound is held to);
        # the peak rates, as the residual rates, in rad/s and deg/s.
        for figure in (
            "final_rate_max_rad_s",
            "final_rate_max_deg_s",
            "final_rate_p95_rad_s",
            "final_rate_p95_deg_s",
            "peak_rate_rad_s",
            "peak_rate_deg_s",
            "peak_rate_p95_rad_s",
            "peak_rate_p95_deg_s",
            # The part of the residual the commands leave (from rest), mean and worst.
            "commanded_residual_rate_rad_s",
            "commanded_residual_rate_deg_s",
            "commanded_residual_rate_max_rad_s",
            "commanded_residual_rate_max_deg_s",
        ):
            assert float(row[column[figure]]) == member["scores"][figure]
        assert member["scores"]["final_rate_p95_rad_s"] >= member["scores"]["final_rate_max_rad_s"]
        assert member["scores"]["peak_rate_p95_rad_s"] >= member["scores"]["peak_rate_rad_s"]
    # Rates in deg/s are the rad/s ones converted.
    assert float(listed[0][column["final_rate_deg_s"]]) == pytest.approx(
        np.degrees(float(listed[0][column["final_rate_rad_s"]]))
    )
    available = [n for n, b in result["front"]["baselines"].items() if "unavailable" not in b]
    assert [r[column["member"]] for r in body if r[column["kind"]] == "baseline"] == available
    # The same table as JSON: one object per row, lists kept as lists.
    records = api.get(f"/jobs/{job_id}/result?format=json&table=front")
    assert records.status_code == 200
    assert f'filename="search-{job_id[:8]}-front.json"' in records.headers["content-disposition"]
    objects = records.json()
    assert [o["member"] for o in objects if o["kind"] == "member"] == [m["index"] for m in members]
    for row, member in zip(objects[: len(members)], members, strict=True):
        assert row["sequence"] == member["sequence"]
        assert row["dominated_by"] == member["dominated_by"]
        assert row["attitude_change_deg"] == member["scores"]["attitude_change_deg"]
    bases = [o for o in objects if o["kind"] == "baseline"]
    assert [o["dominates_members"] for o in bases] == [
        result["front"]["baselines"][o["member"]]["dominates"] for o in bases
    ]

    # The plan of one member: its sequence, attitude change per candidate, as JSON and CSV.
    chosen = members[-1]
    plan = api.get_with_key(f"/jobs/{job_id}/plan", params={"member": chosen["index"]})
    assert plan.status_code == 200, plan.text
    document = plan.json()
    assert document["sequence"] == chosen["sequence"]
    assert len(document["candidates"]) == 5
    assert max(c["attitude_change_deg"] for c in document["candidates"]) > 0
    as_csv = api.get_with_key(
        f"/jobs/{job_id}/plan", params={"member": chosen["index"], "format": "csv"}
    )
    assert as_csv.status_code == 200 and as_csv.headers["content-type"].startswith("text/csv")
    assert "# scenario:" in as_csv.text
    # Where a plan comes from, so that plans downloaded side by side can be told apart.
    source = {"scenario_id": scenario_id, "job_id": job_id, "member": chosen["index"]}
    assert document["source"] == source
    lines = as_csv.text.splitlines()
    assert [lines[0], lines[2], lines[7]] == [
        f"# job_id: {job_id}",
        f"# scenario_id: {scenario_id}",
        f"# member: {chosen['index']}",
    ]
    name = f"plan-scenario-{scenario_id[:8]}-job-{job_id[:8]}-member-{chosen['index']}"
    assert f'filename="{name}.csv"' in as_csv.headers["content-disposition"]
    assert f'filename="{name}.json"' in plan.headers["content-disposition"]
    best = api.get_with_key(f"/jobs/{job_id}/plan").json()
    assert best["source"]["member"] == "best"
    # The member flown 100 times a candidate: how single flights spread, on every candidate.
    flown = api.get_with_key(
        f"/jobs/{job_id}/plan", params={"member": chosen["index"], "flights": 100, "seed": 1}
    ).json()
    assert flown["flights"]["flights_per_candidate"] == 100 and flown["flights"]["seed"] == 1
    assert flown["candidates"][0]["rates_rad_s"] == document["candidates"][0]["rates_rad_s"]
    assert all(
        c["flights"]["residual_rate_max_rad_s"] >= c["flights"]["residual_rate_p95_rad_s"]
        for c in flown["candidates"]
    )
    twice = api.get_with_key(f"/jobs/{job_id}/plan?member=0&member=1")
    assert twice.status_code == 422 and "member is given 2 times" in twice.text
    missing = api.get_with_key(f"/jobs/{job_id}/plan", params={"member": len(members)})
    assert missing.status_code == 422 and f"no front member {len(members)}" in missing.text
    assert api.get(f"/jobs/{job_id}/plan", params={"member": 0}).status_code == 401

    # Training on a member: the API fills in its sequence.
    train = api.submit(
        "train",
        scenario_id,
        params={"search_job_id": job_id, "front_member": chosen["index"]},
    )
    assert train.status_code == 202, train.text
    assert train.json()["params"]["sequence"] == chosen["sequence"]
    wrong = api.submit(
        "train", scenario_id, params={"search_job_id": job_id, "front_member": len(members)}
    )
    assert wrong.status_code == 422 and "front_member" in wrong.text
    # On another spacecraft the member's level indices would fly other duties: refused,
    # unless the scenario differs from the one searched in name only.
    other = api.create_scenario(
        candidate_generator={
            "base_inertia_kg_m2": [[50, 0, 0], [0, 40, 0], [0, 0, 45]],
            "n_variations": 2,
        }
    )["id"]
    elsewhere = api.submit(
        "train", other, params={"search_job_id": job_id, "front_member": chosen["index"]}
    )
    assert elsewhere.status_code == 422, elsewhere.text
    assert f"ran on scenario {scenario_id!r}, not {other!r}" in elsewhere.text
    renamed = api.create_scenario(name="the same spacecraft")["id"]
    same = api.submit(
        "train", renamed, params={"search_job_id": job_id, "front_member": chosen["index"]}
    )
    assert same.status_code == 202, same.text


def test_a_search_on_a_scenario_stored_before_exact_levels_trains_on_its_copy(api: Api) -> None:
    """Scenarios of ``n_levels`` held numpy.linspace's duties (0.30000000000000004 for
    0.3) until their levels became i / (M - 1): the same spacecraft stored again since
    (its levels 0.3) was called another, and training on a search's member on it was
    refused, though every level is the same duty to the last bit of rounding."""
    document = Scenario.paper().model_dump(mode="json")
    document["thrusters"]["levels"] = np.linspace(0.0, 1.0, 11).tolist()
    stored = Scenario.model_validate(document)
    assert stored.thrusters.levels[3] == 0.30000000000000004
    before = api.insert_scenario(stored)
    result = _with_front([[[4, 4, 4, 0, 0, 0]] * 2, [[2, 2, 2, 0, 0, 0]] * 2])
    result["scenario"] = stored.model_dump(mode="json")
    job_id = _finished(api, before, 0, result)
    again = api.create_scenario(
        name="stored again", thrusters={"levels": [i / 10 for i in range(11)]}
    )
    assert again["document"]["thrusters"]["levels"][3] == 0.3
    train = api.submit("train", again["id"], params={"search_job_id": job_id, "front_member": 0})
    assert train.status_code == 202, train.text
    # A level another duty (0.05 for 0.1) is another spacecraft still.
    other = api.create_scenario(thrusters={"levels": [0.0, 0.05, *stored.thrusters.levels[2:]]})
    elsewhere = api.submit(
        "train", other["id"], params={"search_job_id": job_id, "front_member": 0}
    )
    assert elsewhere.status_code == 422 and "not the same spacecraft" in elsewhere.text


def test_a_sequence_that_fires_nothing_is_on_the_front_but_is_not_trained_on(api: Api) -> None:
    """The all-off sequence is the front's zero-impulse end (kept, marked); before, a
    train on it was accepted and scored at chance."""
    scenario_id = api.create_scenario()["id"]
    off = [[0, 0, 0, 0, 0, 0]] * 2
    result = _with_front([off, [[4, 4, 4, 0, 0, 0]] * 2])
    result["scenario"] = Scenario.paper().model_dump(mode="json")
    members = result["front"]["members"]
    silent = [m for m in members if m["sequence"] == off]
    assert len(silent) == 1 and silent[0]["fires"] is False
    assert all(m["fires"] for m in members if m["sequence"] != off)
    job_id = _finished(api, scenario_id, 0, result)
    by_member = api.submit(
        "train", scenario_id, params={"search_job_id": job_id, "front_member": silent[0]["index"]}
    )
    assert by_member.status_code == 422, by_member.text
    detail = by_member.json()["detail"][0]
    assert detail["loc"][-1] == "front_member"
    assert f"front member {silent[0]['index']}" in detail["msg"]
    assert "fires no thruster at any step" in detail["msg"]
    by_sequence = api.submit("train", scenario_id, params={"sequence": off})
    assert by_sequence.status_code == 422, by_sequence.text
    detail = by_sequence.json()["detail"][0]
    assert detail["loc"][-1] == "sequence" and "fires no thruster" in detail["msg"]


def test_a_sweep_result_downloads_its_points_and_confusion_matrices(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    names = ["a", "b"]

    def point(noise: str, multiple: float, accuracy: float) -> dict[str, Any]:
        return {
            "noise": noise,
            "multiple": multiple,
            "value": 0.001 * multiple,
            "accuracy": accuracy,
            "ci_low": accuracy - 0.1,
            "ci_high": min(1.0, accuracy + 0.1),
            "f1": accuracy,
            "n_series": 10,
            "confusion": [[5, 0], [1, 4]],
        }

    result = {
        "candidate_names": names,
        "points": [point("process", 1, 0.9), point("process", 8, 0.6)],
        "ceiling": [point("process", 1, 0.95), point("process", 8, 0.75)],
        # Least squares at 8x lies above the ceiling's interval (0.75, up to 0.85).
        "others": {"least-squares": [point("process", 1, 0.85), point("process", 8, 0.9)]},
        "units": {"process": "N m"},
        "seed": 123,
        "sequence": GOOD_SEQUENCE,
        "ceiling_realisations": 2000,
        "inertia": {
            "candidate_names": names,
            "base": 1,
            "pair": [0, 1],
            "seed": 77,
            "points": [
                {
                    "body": body,
                    "parameter": parameter,
                    "inertia_kg_m2": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]],
                    "n_series": 10,
                    "matches_none_rate": 0.2,
                    "ci_low": 0.05,
                    "ci_high": 0.5,
                    "predicted": [3, 7],
                }
                for body, parameter in (("scaled", 1.2), ("between", 0.5))
            ],
        },
    }
    job = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()
    with api.db.session() as session:
        claim(session, job["id"], "tests")
    with api.db.session() as session:
        # Stored as a sweep's result on a job row of type sweep.
        from service.store.models import JobRow

        row = session.get(JobRow, job["id"])
        assert row is not None
        row.type = "sweep"
        row.params = {"classifier_id": "c" * 32, "multiples": [1.0, 8.0], "noises": ["process"]}
        row.seed = 5
    with api.db.session() as session:
        add_metrics(
            session, job["id"], [("accuracy_process", 0, 0.9), ("accuracy_process", 1, 0.6)]
        )
        finish(session, job["id"], "succeeded", result=result)
    stored = api.get(f"/jobs/{job['id']}").json()
    assert stored["summary"] == {
        "accuracy_min": 0.6,
        "accuracy_mean": pytest.approx(0.75),
        "ceiling_shortfall": pytest.approx(0.15),
    }
    text = api.get(f"/jobs/{job['id']}/result?format=csv&table=points").text
    points = _csv(text)
    assert [r[0] for r in points[1:]] == ["classifier"] * 2 + ["other:least-squares"] * 2 + [
        "ceiling"
    ] * 2
    # What was swept, and how, as "# name: value" lines; the multiple beside the step the
    # metrics number it by; whether each point lies above the ceiling's interval.
    import pandas

    table = pandas.read_csv(io.StringIO(text), comment="#", keep_default_na=False)
    assert list(table["multiple"]) == [1.0, 8.0] * 3 and list(table["step"]) == [0, 1] * 3
    assert list(table["above_ceiling_interval"]) == ["False", "False", "False", "True", "", ""]
    notes = _notes(text)
    assert notes["classifier_id"] == "c" * 32 and notes["job_seed"] == "5"
    assert notes["test_series_seed"] == "123" and notes["ceiling_realisations"] == "2000"
    assert json.loads(notes["sequence"]) == GOOD_SEQUENCE
    assert json.loads(notes["multiples"]) == [1.0, 8.0]
    assert "not a paired test" in notes["above_ceiling_interval"]
    inertia_text = api.get(f"/jobs/{job['id']}/result?format=csv&table=inertia").text
    inertia = pandas.read_csv(io.StringIO(inertia_text), comment="#", keep_default_na=False)
    assert list(inertia["body"]) == ["scaled", "between"]
    assert list(inertia["base"]) == ["b", ""] and list(inertia["pair"]) == ["", '["a","b"]']
    assert list(inertia["predicted_a"]) == [3, 3] and list(inertia["predicted_b"]) == [7, 7]
    assert (
        inertia["parameter_meaning"][0]
        == "multiple of b's inertia tensor (1: the candidate itself)"
    )
    assert inertia["parameter_meaning"][1].startswith("position from a (0) to b (1)")
    assert _notes(inertia_text)["classifier_id"] == "c" * 32
    assert _notes(inertia_text)["inertia_seed"] == "77"
    # Stored before the sweep counted identify's verdicts: its rate says which rule gave
    # it, and the verdicts' columns are empty.
    assert "novelty threshold" in _notes(inertia_text)["matches_none_rate"]
    assert list(inertia["identified_right_rate"]) == ["", ""]
    assert list(inertia["matches_none_rate"]) == [0.2, 0.2]
    metrics = api.get(f"/jobs/{job['id']}/metrics?format=csv").text
    assert json.loads(_notes(metrics)["multiples"]) == [1.0, 8.0]
    assert "index among multiples" in _notes(metrics)["step"]
    assert _csv(metrics) == [
        ["key", "step", "value"],
        ["accuracy_process", "0", "0.9"],
        ["accuracy_process", "1", "0.6"],
    ]
    confusion = _csv(api.get(f"/jobs/{job['id']}/result?format=csv&table=confusion").text)
    assert confusion[0] == ["who", "noise", "multiple", "true", "predicted", "count"]
    assert confusion[1:5] == [
        ["classifier", "process", "1", "a", "a", "5"],
        ["classifier", "process", "1", "a", "b", "0"],
        ["classifier", "process", "1", "b", "a", "1"],
        ["classifier", "process", "1", "b", "b", "4"],
    ]


def _stored_sweep(api: Api, status: str, result: dict[str, Any], params: dict[str, Any]) -> str:
    """A job row of type sweep ended as ``status`` with ``result`` (as a worker stores a
    sweep it stopped between points)."""
    scenario_id = api.create_scenario()["id"]
    job = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()
    with api.db.session() as session:
        claim(session, job["id"], "tests")
    with api.db.session() as session:
        from service.store.models import JobRow

        row = session.get(JobRow, job["id"])
        assert row is not None
        row.type = "sweep"
        row.params = params
    with api.db.session() as session:
        add_metrics(session, job["id"], [("accuracy_process", 0, 0.9)])
        finish(session, job["id"], status, result=result)
    return str(job["id"])


def test_a_sweep_stopped_before_its_last_point_says_so_in_every_csv(api: Api) -> None:
    """A sweep cancelled (or cut by its time limit) keeps the points it measured; its
    tables listed ``multiples: [1.0, 2.0, 4.0, 8.0]`` over one point with nothing saying
    the job was cancelled or the rest never measured."""
    point = {
        "noise": "process",
        "multiple": 1.0,
        "value": 0.05,
        "accuracy": 0.9,
        "ci_low": 0.8,
        "ci_high": 0.95,
        "f1": 0.9,
        "n_series": 10,
        "confusion": [[5, 0], [1, 4]],
    }
    result = {
        "candidate_names": ["a", "b"],
        "points": [point],
        "units": {"process": "N m"},
        "seed": 123,
        "sequence": GOOD_SEQUENCE,
    }
    params = {"classifier_id": "c" * 32, "multiples": [1.0, 2.0, 4.0, 8.0], "noises": ["process"]}
    cancelled = _stored_sweep(api, "cancelled", result, params)
    for path in (
        f"/jobs/{cancelled}/result?format=csv&table=points",
        f"/jobs/{cancelled}/result?format=csv&table=confusion",
        f"/jobs/{cancelled}/metrics?format=csv",
    ):
        notes = _notes(api.get(path).text)
        assert notes["job_status"] == "cancelled", path
    notes = _notes(api.get(f"/jobs/{cancelled}/result?format=csv&table=points").text)
    assert notes["points_measured"].startswith("1 of the 4 asked for")
    assert "it was cancelled before the rest" in notes["points_measured"]
    timed = _stored_sweep(api, "succeeded", {**result, "stopped": "time_limit"}, params)
    notes = _notes(api.get(f"/jobs/{timed}/result?format=csv&table=points").text)
    assert "job_status" not in notes
    assert "it reached its time limit before the rest" in notes["points_measured"]
    # A sweep that measured every point says neither.
    whole = _stored_sweep(api, "succeeded", result, {**params, "multiples": [1.0]})
    notes = _notes(api.get(f"/jobs/{whole}/result?format=csv&table=points").text)
    assert "job_status" not in notes and "points_measured" not in notes


def test_metrics_download_every_point_as_csv(api: Api) -> None:
    job_id = api.submit("search", api.create_scenario()["id"]).json()["id"]
    with api.db.session() as session:
        add_metrics(session, job_id, [("reward", step, step / 4) for step in range(5000)])
    response = api.get(f"/jobs/{job_id}/metrics", params={"format": "csv"})
    assert response.status_code == 200
    assert "metrics.csv" in response.headers["content-disposition"]
    rows = _csv(response.text)
    assert rows[0] == ["key", "step", "value"] and len(rows) == 5001
    assert rows[4001] == ["reward", "4000", "1000.0"]


def _rates_in_both_units(what: str, records: list[dict[str, Any]]) -> int:
    """Every ``_rad_s`` figure of ``records`` (the rows of a table as objects) has its
    ``_deg_s`` twin beside it, the same rate converted; how many pairs there are."""
    pairs = 0
    for record in records:
        names = list(record)
        for i, name in enumerate(names):
            if "_rad_s" not in name:
                continue
            twin = name.replace("_rad_s", "_deg_s")
            assert names[i + 1 : i + 2] == [twin], f"{what}: no {twin} beside {name}: {names}"
            rad, deg = record[name], record[twin]
            if rad in ("", None):
                assert deg in ("", None), (what, name, deg)
                continue
            rad = json.loads(rad) if isinstance(rad, str) else rad
            deg = json.loads(deg) if isinstance(deg, str) else deg
            assert np.degrees(rad) == pytest.approx(deg, rel=1e-12), (what, name)
            pairs += 1
    return pairs


def test_every_rate_in_a_search_or_sweep_export_is_in_rad_s_and_deg_s(api: Api) -> None:
    """A flight team reads deg/s: each rad/s column (or summary quantity) of the search's
    tables, of its metric series and of a sweep's points, CSV and JSON alike, has the
    deg/s one beside it (fresh_end_rate_rad_s_mean, the curve's rate and the metrics'
    best_residual_rate_rad_s had none); no rad/s name is gone."""
    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, scenario_id, 0, _search_result([1.0, 0.8], 20.0, 3.5))
    pairs = {}
    for table in ("summary", "curve", "baselines", "front"):
        csv_rows = _csv(api.get(f"/jobs/{job_id}/result?format=csv&table={table}").text)
        as_json = api.get(f"/jobs/{job_id}/result?format=json&table={table}").json()
        if table == "summary":  # quantity, value rows: one record of every quantity
            records = [dict((r[0], r[1]) for r in csv_rows[1:])]
            as_json = [{r["quantity"]: r["value"] for r in as_json}]
        else:
            records = [dict(zip(csv_rows[0], r, strict=True)) for r in csv_rows[1:]]
        pairs[table] = _rates_in_both_units(f"{table} CSV", records)
        assert _rates_in_both_units(f"{table} JSON", as_json) == pairs[table]
    # The names clients read are all still there.
    summary = dict(_csv(api.get(f"/jobs/{job_id}/result?format=csv").text)[1:])
    assert float(summary["fresh_end_rate_deg_s_mean"]) == pytest.approx(np.degrees(0.15))
    assert {"fresh_end_rate_rad_s_mean", "best_end_rate_rad_s_search_draw"} <= set(summary)
    assert pairs == {"summary": 3, "curve": 3, "baselines": 2, "front": 1}

    # The job's metric series: the residual rate had rad/s alone. Long form (key, step,
    # value) in the CSV and a list of series in the JSON: a step's figures read in the
    # series' order, the deg/s series next to its rad/s one.
    rates = [0.02, 0.01, 0.005]
    with api.db.session() as session:
        add_metrics(
            session,
            job_id,
            [
                *(("best_residual_rate_rad_s", step, rate) for step, rate in enumerate(rates)),
                *(("mean_f1", step, 0.5) for step in range(3)),
                *(("best_f1", step, 0.75) for step in range(3)),
            ],
        )
    csv_rows = _csv(api.get(f"/jobs/{job_id}/metrics?format=csv").text)
    assert csv_rows[0] == ["key", "step", "value"]
    by_step: dict[int, dict[str, Any]] = {}
    for key, step, value in csv_rows[1:]:
        by_step.setdefault(int(step), {})[key] = value
    assert _rates_in_both_units("metrics CSV", list(by_step.values())) == 3
    series = api.get(f"/jobs/{job_id}/metrics").json()["series"]
    by_step = {}
    for one in series:
        for step, value in zip(one["steps"], one["values"], strict=True):
            by_step.setdefault(step, {})[one["key"]] = value
    assert _rates_in_both_units("metrics JSON", list(by_step.values())) == 3
    assert [one["key"] for one in series] == [
        "best_f1",
        "best_residual_rate_rad_s",
        "best_residual_rate_deg_s",
        "mean_f1",
    ]
    # One series asked for by name: the deg/s one too; the rad/s one stays alone.
    for name, values in [
        ("best_residual_rate_deg_s", np.degrees(rates)),
        ("best_residual_rate_rad_s", rates),
    ]:
        only = api.get(f"/jobs/{job_id}/metrics", params={"key": name, "after": 0}).json()
        assert [(one["key"], one["steps"]) for one in only["series"]] == [(name, [1, 2])]
        assert only["series"][0]["values"] == pytest.approx(values[1:], rel=1e-12)
        text = api.get(f"/jobs/{job_id}/metrics", params={"key": name, "format": "csv"}).text
        assert [(k, int(step), float(v)) for k, step, v in _csv(text)[1:]] == [
            (name, step, pytest.approx(value, rel=1e-12)) for step, value in enumerate(values)
        ]

    # A sweep's gyro-noise level is a rate: in deg/s beside its value; a torque's is not.
    sweep = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()
    with api.db.session() as session:
        claim(session, sweep["id"], "tests")
    with api.db.session() as session:
        from service.store.models import JobRow

        row = session.get(JobRow, sweep["id"])
        assert row is not None
        row.type = "sweep"
        row.params = {"classifier_id": "c" * 32, "multiples": [2.0], "noises": ["measurement"]}
    point = {"multiple": 2.0, "accuracy": 0.9, "ci_low": 0.8, "ci_high": 0.95, "n_series": 10}
    result = {
        "candidate_names": ["a", "b"],
        "points": [
            {**point, "noise": "measurement", "value": 0.002},
            {**point, "noise": "process", "value": 0.5},
        ],
        "units": {"measurement": "rad/s", "process": "N m"},
    }
    with api.db.session() as session:
        finish(session, sweep["id"], "succeeded", result=result)
    for fmt in ("csv", "json"):
        answer = api.get(f"/jobs/{sweep['id']}/result?format={fmt}&table=points")
        if fmt == "csv":
            rows = _csv(answer.text)
            points = [dict(zip(rows[0], r, strict=True)) for r in rows[1:]]
        else:
            points = answer.json()
        assert [p["value_unit"] for p in points] == ["rad/s", "N m"]
        assert float(points[0]["value_deg_s"]) == pytest.approx(np.degrees(0.002))
        assert points[1]["value_deg_s"] in ("", None)


def test_a_deg_s_metric_series_is_made_from_rad_s_once_and_only_beside_it() -> None:
    """The twin follows its rad/s series (not sorted before it as ``d`` < ``r``), keeps a
    non-finite point non-finite, and is not made again where the job stored one."""
    from service.exports import metrics_with_degrees

    made = metrics_with_degrees(
        [("a_rad_s", 0, 1.0), ("a_rad_s", 1, float("inf")), ("b", 0, 2.0), ("c_rad_s", 0, 3.0)]
    )
    assert [(k, s) for k, s, _v in made] == [
        ("a_rad_s", 0),
        ("a_rad_s", 1),
        ("a_deg_s", 0),
        ("a_deg_s", 1),
        ("b", 0),
        ("c_rad_s", 0),
        ("c_deg_s", 0),
    ]
    assert made[2][2] == pytest.approx(np.degrees(1.0)) and made[3][2] == float("inf")
    stored = [("c_deg_s", 0, 9.0), ("c_rad_s", 0, 3.0)]
    assert metrics_with_degrees(stored) == stored


@pytest.mark.parametrize(
    ("params", "held"),
    [
        ({"method": "cem", "objective": "separability"}, "the separability score"),
        ({"method": "cem"}, "the clustering F1"),
        ({"method": "nsga2"}, "predicted accuracy at the design noise"),
    ],
)
def test_a_search_metrics_csv_says_what_its_f1_series_hold(
    api: Api, params: dict[str, Any], held: str
) -> None:
    # The series are stored as best_f1 and mean_f1 whatever the search scores.
    job_id = api.submit("search", api.create_scenario()["id"], params=params).json()["id"]
    with api.db.session() as session:
        add_metrics(session, job_id, [("best_f1", 0, 0.5)])
    text = api.get(f"/jobs/{job_id}/metrics", params={"format": "csv"}).text
    assert held in _notes(text)["mean_f1 and best_f1"]


def _notes(text: str) -> dict[str, str]:
    """The ``# name: value`` lines before a CSV's header."""
    lines = [line for line in text.splitlines() if line.startswith("# ")]
    return dict(line[2:].split(": ", 1) for line in lines)


def _utc(text: str) -> datetime:
    """An ISO 8601 time that must name UTC with ``Z``."""
    assert text.endswith("Z"), text
    stamp = datetime.fromisoformat(text)
    assert stamp.utcoffset() == timedelta(0), text
    return stamp


def test_every_job_csv_says_which_job_it_comes_from_and_when_it_was_written(api: Api) -> None:
    """A training's CSV tables had no ``# name: value`` line at all, and no job CSV
    named its job or the time it was written except through its file name: a table
    renamed or handed on could not be traced to its job or seed. Every job CSV (each
    result table of each type, and the metrics) now begins with the same lines; the
    existing lines and the columns are kept."""
    import pandas

    scenario_id = api.create_scenario()["id"]
    search_id = _finished(api, scenario_id, 11, _search_result([1.0, 0.8], 20.0, 3.5))
    train = api.submit("train", scenario_id, seed=12, params={"sequence": GOOD_SEQUENCE}).json()
    with api.db.session() as session:
        claim(session, train["id"], "tests")
    with api.db.session() as session:
        add_metrics(session, train["id"], [("f1", 0, 0.75)])
        result = {
            "classifier_id": "c" * 32,
            "kind": "kmeans",
            "metric": "euclidean",
            "f1": 0.75,
            "accuracy": 0.8,
            "candidate_names": ["a", "config #2"],
            "confusion": [[4, 1], [1, 4]],
            "sequence": GOOD_SEQUENCE,
        }
        assert finish(session, train["id"], "succeeded", result=result)
    downloads = [
        (search_id, 11, f"/jobs/{search_id}/result?format=csv&table={table}")
        for table in ("summary", "curve", "sequence", "baselines", "front")
    ]
    downloads += [
        (train["id"], 12, f"/jobs/{train['id']}/result?format=csv&table={table}")
        for table in ("summary", "confusion", "sequence")
    ]
    downloads += [(search_id, 11, f"/jobs/{search_id}/metrics?format=csv")]
    downloads += [(train["id"], 12, f"/jobs/{train['id']}/metrics?format=csv")]
    for job_id, seed, path in downloads:
        before = datetime.now(UTC)
        response = api.get(path)
        after = datetime.now(UTC)
        assert response.status_code == 200, (path, response.text)
        job = api.get(f"/jobs/{job_id}").json()
        lines = response.text.splitlines()
        names = [line[2:].split(": ", 1)[0] for line in lines if line.startswith("# ")]
        # The job's lines first, in this order; the table's own (if any) follow.
        assert names[:7] == [
            "job_id",
            "job_type",
            "scenario_id",
            "job_seed",
            "created_at",
            "finished_at",
            "exported_at",
        ], path
        notes = _notes(response.text)
        assert notes["job_id"] == job_id and notes["job_type"] == job["type"], path
        assert notes["scenario_id"] == scenario_id and notes["job_seed"] == str(seed), path
        assert _utc(notes["created_at"]) == _utc(job["created_at"]), path
        assert _utc(notes["finished_at"]) == _utc(job["finished_at"]), path
        assert before <= _utc(notes["exported_at"]) <= after, path
        # Still a table a reader told that "#" starts a comment reads whole.
        table = pandas.read_csv(io.StringIO(response.text), comment="#")
        assert len(table) == len(_csv(response.text)) - 1 and len(table.columns) > 1, path
    confusion = _csv(api.get(f"/jobs/{train['id']}/result?format=csv&table=confusion").text)
    assert confusion == [
        ["true \\ predicted", "a", "config #2"],
        ["a", "4", "1"],
        ["config #2", "1", "4"],
    ]


_JOB_LINES = [
    "job_id",
    "job_type",
    "scenario_id",
    "job_seed",
    "created_at",
    "finished_at",
    "exported_at",
]


def test_a_plan_csv_says_which_job_or_scenario_it_comes_from_and_when_it_was_written(
    api: Api, tmp_path: Path
) -> None:
    """A plan's CSV began with its source alone (``# scenario_id``, ``# job_id``,
    ``# member``): no job type, seed, times or export time, which every job CSV now
    gives. A plan of a search job's sequence begins with the job's lines, then the
    member; a plan of a sequence given to a scenario with the scenario's id and the
    export time. ``inertia-id plan --search`` on the job as downloaded writes the job's
    lines too. Each is still read whole by ``pandas.read_csv(path, comment="#")``."""
    import pandas
    from cli_support import run_cli

    scenario_id = api.create_scenario()["id"]
    job_id = _finished(api, scenario_id, 11, _search_result([1.0, 0.8], 20.0, 3.5))
    job = api.get(f"/jobs/{job_id}").json()
    steps = len(_search_result([1.0], 1.0, 1.0)["best"]["sequence"])

    def read(text: str) -> tuple[list[str], dict[str, str]]:
        names = [line[2:].split(": ", 1)[0] for line in text.splitlines() if line[:2] == "# "]
        table = pandas.read_csv(io.StringIO(text), comment="#")
        assert len(table) == steps and "step" in table.columns, text
        return names, _notes(text)

    before = datetime.now(UTC)
    from_job = api.get_with_key(f"/jobs/{job_id}/plan", params={"member": 0, "format": "csv"})
    after = datetime.now(UTC)
    assert from_job.status_code == 200, from_job.text
    names, notes = read(from_job.text)
    assert names[:9] == [*_JOB_LINES, "member", "scenario"]
    assert notes["job_id"] == job_id and notes["job_type"] == "search"
    assert notes["scenario_id"] == scenario_id and notes["job_seed"] == "11"
    assert _utc(notes["created_at"]) == _utc(job["created_at"])
    assert _utc(notes["finished_at"]) == _utc(job["finished_at"])
    assert before <= _utc(notes["exported_at"]) <= after and notes["member"] == "0"
    # The same lines as the job's own tables (the export time aside).
    summary = _notes(api.get(f"/jobs/{job_id}/result?format=csv").text)
    assert {k: notes[k] for k in _JOB_LINES[:-1]} == {k: summary[k] for k in _JOB_LINES[:-1]}

    before = datetime.now(UTC)
    planned = api.get_with_key(
        f"/scenarios/{scenario_id}/plan",
        params={"sequence": json.dumps(GOOD_SEQUENCE[:steps]), "format": "csv"},
    )
    after = datetime.now(UTC)
    assert planned.status_code == 200, planned.text
    names, notes = read(planned.text)
    assert names[:3] == ["scenario_id", "exported_at", "scenario"]
    assert notes["scenario_id"] == scenario_id
    assert before <= _utc(notes["exported_at"]) <= after
    # The JSON says when it was written too (UTC, Z), as the CSV's line does.
    before = datetime.now(UTC)
    as_json = api.get_with_key(
        f"/scenarios/{scenario_id}/plan", params={"sequence": json.dumps(GOOD_SEQUENCE[:steps])}
    ).json()
    after = datetime.now(UTC)
    assert as_json["exported_at"].endswith("Z")
    assert before <= _utc(as_json["exported_at"]) <= after

    # The CLI's plan of the job as downloaded: the same job lines.
    downloaded = tmp_path / "job.json"
    downloaded.write_text(api.get(f"/jobs/{job_id}/result").text, encoding="utf-8")
    out = tmp_path / "plan.csv"
    before = datetime.now(UTC)
    run_cli(["plan", "--search", str(downloaded), "--member", "0", "--out", str(out)])
    after = datetime.now(UTC)
    names, cli_notes = read(out.read_text(encoding="utf-8"))
    assert names[:10] == [*_JOB_LINES, "search", "member", "scenario"]
    assert {k: cli_notes[k] for k in _JOB_LINES[:-1]} == {k: summary[k] for k in _JOB_LINES[:-1]}
    assert before <= _utc(cli_notes["exported_at"]) <= after
    assert json.loads(cli_notes["search"]) == str(downloaded.resolve())


def test_an_identify_verdict_downloads_as_csv(
    api: Api, classifier: InertiaClassifier, paper: Scenario
) -> None:
    import pandas

    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    flight = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(7))
    body = {
        "classifier_id": classifier_id,
        "telemetry": {
            "time_s": flight.time_s.tolist(),
            "omega_rad_s": flight.omega_measured[3, 0].tolist(),
        },
    }
    verdict = api.post("/identify", json=body).json()
    response = api.post("/identify?format=csv", json=body)
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/csv")
    table = pandas.read_csv(io.StringIO(response.text), comment="#")
    # One row per candidate with its posterior: the CSV alone says which one it is and
    # how sure, not that the series "matches" every candidate.
    assert list(table.columns) == ["candidate", "distance", "nearest", "posterior", "number"]
    assert list(table["candidate"]) == list(verdict["distances"])
    assert list(table.loc[table["nearest"], "candidate"]) == [verdict["candidate"]]
    assert verdict["candidate"] == "payload 3 ejected"
    # Numbered from 1 as the plan's tables number it; candidate_index keeps its 0-based
    # meaning beside it.
    assert (verdict["candidate_number"], verdict["candidate_index"]) == (4, 3)
    assert list(table["number"]) == [1, 2, 3, 4, 5]
    assert list(table.loc[table["nearest"], "number"]) == [verdict["candidate_number"]]
    planned = {"sequence": GOOD_SEQUENCE}
    plan = api.post(f"/scenarios/{scenario_id}/plan", json=planned).json()
    assert [c["number"] for c in plan["candidates"]] == [1, 2, 3, 4, 5]
    assert plan["candidates"][3]["name"] == verdict["candidate"]
    plan_csv = api.post(f"/scenarios/{scenario_id}/plan?format=csv", json=planned).text
    assert f'# candidate_4 "{verdict["candidate"]}": ' in plan_csv
    assert list(table["posterior"]) == pytest.approx(list(verdict["posterior"].values()))
    assert list(table["distance"]) == pytest.approx(list(verdict["distances"].values()))
    notes = _notes(response.text)
    assert notes["candidate_number"] == "4"
    assert notes["status"] == verdict["status"] and notes["verdict"] == verdict["verdict"]
    assert notes["classifier_id"] == classifier_id
    for key in ("confidence", "required_confidence", "p_none", "threshold"):
        assert float(notes[key]) == verdict[key], key
    assert float(notes["p_none"]) + table["posterior"].sum() == pytest.approx(1.0)
    assert "probabilities in [0, 1]" in notes["units"] and "rad/s" in notes["units"]
    assert "initial_offset_rad_s" not in notes  # the telemetry starts at the start

    # Telemetry 4 s before the start: the offset it measured is part of the verdict's basis.
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    flown = [[0] * paper.n_thrusters] * 4 + GOOD_SEQUENCE
    early = simulate(paper, flown, 1, np.random.default_rng(5))
    body = {
        "classifier_id": api.insert_classifier(api.create_scenario()["id"], model),
        "telemetry": {
            "time_s": (early.time_s - 4.0).tolist(),
            "omega_rad_s": early.omega_measured[1, 0].tolist(),
        },
    }
    verdict = api.post("/identify", json=body).json()
    notes = _notes(api.post("/identify?format=csv", json=body).text)
    assert json.loads(notes["initial_offset_rad_s"]) == verdict["initial_offset_rad_s"]
    assert json.loads(notes["initial_offset_std_rad_s"]) == verdict["initial_offset_std_rad_s"]
    # and in deg/s, as a flight team reads a rate.
    for name in ("initial_offset", "initial_offset_std"):
        degrees = json.loads(notes[f"{name}_deg_s"])
        assert degrees == pytest.approx(np.degrees(verdict[f"{name}_rad_s"]), rel=1e-12)
    assert int(notes["pre_start_samples"]) == verdict["pre_start_samples"] > 0


def test_the_key_check_is_204_for_the_key_and_401_otherwise(api: Api) -> None:
    assert api.get("/auth/check", headers=api.auth).status_code == 204
    assert api.get("/auth/check").status_code == 401
    assert api.get("/auth/check", headers={"X-API-Key": "wrong"}).status_code == 401


def test_the_docs_are_served_from_the_package_with_no_outside_address(api: Api) -> None:
    page = api.get("/docs")
    assert page.status_code == 200
    assert "/docs-assets/swagger-ui-bundle.js" in page.text
    assert "http://" not in page.text and "https://" not in page.text
    script = api.get("/docs-assets/swagger-ui-bundle.js")
    assert script.status_code == 200 and len(script.content) > 100_000
    assert api.get("/docs-assets/swagger-ui.css").status_code == 200


def test_the_vocabulary_names_every_summary_column_and_result_table(api: Api) -> None:
    words = api.get("/vocabulary").json()
    assert [c["key"] for c in words["job_summaries"]["search"]][:2] == ["fresh_f1", "fresh_f1_min"]
    assert [t["name"] for t in words["result_tables"]["search"]] == [
        "summary",
        "curve",
        "sequence",
        "baselines",
        "front",
    ]
    assert {t["name"] for t in words["result_tables"]["sweep"]} >= {"points", "confusion"}


def test_the_sweeps_of_a_classifier_are_listed_by_its_id(
    api: Api, classifier: InertiaClassifier
) -> None:
    scenario_id = api.create_scenario()["id"]
    mine = api.insert_classifier(scenario_id, classifier)
    other = api.insert_classifier(scenario_id, classifier)
    first = api.submit("sweep", scenario_id, params={"classifier_id": mine, "n_test": 10}).json()
    api.submit("sweep", scenario_id, params={"classifier_id": other, "n_test": 10})
    listed = api.get("/jobs", params={"classifier_id": mine}).json()
    assert [j["id"] for j in listed["items"]] == [first["id"]] and listed["total"] == 1
    assert api.get("/jobs", params={"classifier_id": "nope"}).json()["items"] == []


@pytest.mark.parametrize(
    ("method", "column"), [("cem", "best_end_rate_rad_s"), ("nsga2", "best_residual_rate_rad_s")]
)
def test_a_curve_stored_before_its_rate_was_named_is_exported_for_what_it_was(
    api: Api, method: str, column: str
) -> None:
    """Results stored before the curve's rate had one meaning wrote it as
    best_final_rate_rad_s: |ω| when the last command ends for the reinforcement-learning
    searches, the settled residual for NSGA-II. The CSV names each for what it was."""
    scenario_id = api.create_scenario()["id"]
    result = _search_result([1.0, 0.8], 20.0, 3.5)
    result["method"] = method
    del result["best"]["residual_rate_rad_s"]
    for point in result["curve"]:
        point["best_final_rate_rad_s"] = point.pop("best_residual_rate_rad_s")
    job_id = _finished(api, scenario_id, 0, result, name="old")
    rows = _csv(api.get(f"/jobs/{job_id}/result", params={"format": "csv", "table": "curve"}).text)
    assert rows[0][5] == column and [r[5] for r in rows[1:]] == ["0.2"] * 3
    score = "predicted_accuracy_design_noise" if method == "nsga2" else "separability"
    assert rows[0][3:5] == [f"mean_{score}", f"best_{score}"]
    summary = dict(_csv(api.get(f"/jobs/{job_id}/result?format=csv").text)[1:])
    if method == "nsga2":
        assert summary["best_residual_rate_rad_s_search_draw"] == "0.12"
        assert "best_end_rate_rad_s_search_draw" not in summary
    else:
        assert summary["best_end_rate_rad_s_search_draw"] == "0.12"
        assert summary["best_residual_rate_rad_s_search_draw"] == ""


def test_a_curve_that_says_whether_its_best_met_the_constraints_exports_it(api: Api) -> None:
    # While no sequence met a search's constraints its best so far broke them; the curve
    # says which of its points did, and so does its CSV.
    scenario_id = api.create_scenario()["id"]
    result = _search_result([1.0, 0.8], 20.0, 3.5)
    for point, feasible in zip(result["curve"], (False, False, True), strict=True):
        point["best_feasible"] = feasible
    job_id = _finished(api, scenario_id, 0, result, name="constrained")
    rows = _csv(api.get(f"/jobs/{job_id}/result", params={"format": "csv", "table": "curve"}).text)
    assert rows[0][-1] == "best_feasible"
    assert [r[-1] for r in rows[1:]] == ["False", "False", "True"]


def test_every_sequence_a_search_may_find_has_its_command_plan(api: Api) -> None:
    """A thruster lag of 20 ms needs a 10 ms RK4 step (two a time constant), 100 a
    1 s step: the service accepts a 20-step search on it, whose sequences are 2,000 RK4
    steps, but its plan took at most 1,280 and answered the search's best sequence with
    a 422 ("16 steps: at most 12 steps on this scenario"): the team could not download
    the plan of the sequence it had searched for. The plan takes what a job may fly."""
    from inertia_id.search.plan import command_plan

    scenario_id = api.create_scenario(
        timing={"integration_step_s": 0.01},
        uncertainty={"lowpass_time_constant_s": 0.02, "disturbance_interval_s": 0.05},
    )["id"]
    scenario = Scenario.model_validate(api.get(f"/scenarios/{scenario_id}").json()["document"])
    length = 20
    submitted = api.submit(
        "search", scenario_id, params={"method": "cem", "sequence_length": length}
    )
    assert submitted.status_code == 202, submitted.text
    sequence = ([[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2) * (length // 4)
    result = _search_result([0.9], 240.0, 2.0)
    result["best"]["sequence"] = sequence
    result["front"]["members"][0]["sequence"] = sequence
    with api.db.session() as session:
        claim(session, submitted.json()["id"], "tests")
    with api.db.session() as session:
        assert finish(session, submitted.json()["id"], "succeeded", result=result)
    for member in (None, 0):
        params = {} if member is None else {"member": member}
        planned = api.get_with_key(f"/jobs/{submitted.json()['id']}/plan", params=params)
        assert planned.status_code == 200, planned.text
        document = planned.json()
        assert len(document["steps"]) == length
        expected = command_plan(scenario, sequence).to_dict()
        assert document["residual_rate_max_rad_s"] == expected["residual_rate_max_rad_s"]
        assert document["propellant"] == expected["propellant"]
    typed = api.get_with_key(
        f"/scenarios/{scenario_id}/plan", params={"sequence": json.dumps(sequence)}
    )
    assert typed.status_code == 200, typed.text


def test_a_fronts_csv_says_which_members_fire(api: Api) -> None:
    """The front's JSON marks a member that applies no torque (``fires: false``: the
    all-off sequence, or firings whose torques cancel, on which no classifier trains);
    its CSV, the table a flight team reads to pick a member, did not say it. A ``fires``
    column comes last (every earlier column where it was), for members and baselines."""
    scenario_id = api.create_scenario()["id"]
    idle, cancel = [[0] * 6] * 2, [[4, 0, 0, 4, 0, 0]] * 2
    result = _with_front([[[4, 4, 4, 0, 0, 0]] * 2, idle, cancel])
    job_id = _finished(api, scenario_id, 0, result)
    rows = _csv(api.get(f"/jobs/{job_id}/result?format=csv&table=front").text)
    header, body = rows[0], rows[1:]
    assert header[-1] == "fires" and header[-5:-1] == [
        "commanded_residual_rate_rad_s",
        "commanded_residual_rate_deg_s",
        "commanded_residual_rate_max_rad_s",
        "commanded_residual_rate_max_deg_s",
    ]
    fires = {row[header.index("sequence")]: row[-1] for row in body if row[0] == "member"}
    members = result["front"]["members"]
    assert {json.dumps(m["sequence"], separators=(",", ":")): str(m["fires"]) for m in members} == (
        fires
    )
    assert fires[json.dumps(idle, separators=(",", ":"))] == "False"
    assert {row[-1] for row in body if row[0] == "baseline"} == {"True"}
    records = api.get(f"/jobs/{job_id}/result?format=json&table=front").json()
    assert [r["fires"] for r in records if r["kind"] == "member"] == [m["fires"] for m in members]


def test_the_clis_plan_of_a_cancelled_search_says_so_as_the_services_does(
    api: Api, tmp_path: Path
) -> None:
    """The service's plan of a cancelled search's best sequence says ``job_status:
    cancelled`` (JSON source, CSV line); ``inertia-id plan --search`` on the same job as
    downloaded said nothing of it: a best-so-far read as a finished search's best."""
    from cli_support import run_cli

    scenario_id = api.create_scenario()["id"]
    result = _search_result([0.9], 12.0, 2.0)
    job_id = _finished(api, scenario_id, 1, result, "cancelled")
    served = _notes(api.get_with_key(f"/jobs/{job_id}/plan", params={"format": "csv"}).text)
    assert served["job_status"] == "cancelled"
    downloaded = tmp_path / "job.json"
    downloaded.write_text(api.get(f"/jobs/{job_id}/result").text, encoding="utf-8")
    out = tmp_path / "plan.csv"
    run_cli(["plan", "--search", str(downloaded), "--out", str(out)])
    names = [
        line[2:].split(": ", 1)[0] for line in out.read_text().splitlines() if line[:2] == "# "
    ]
    assert names[:11] == [*_JOB_LINES, "search", "member", "job_status", "scenario"]
    assert _notes(out.read_text())["job_status"] == "cancelled"
    as_json = tmp_path / "plan.json"
    run_cli(["plan", "--search", str(downloaded), "--out", str(as_json)])
    assert json.loads(as_json.read_text())["source"]["job_status"] == "cancelled"
    # A succeeded search's plan does not carry it, as the service's.
    done = _finished(api, scenario_id, 2, result)
    downloaded.write_text(api.get(f"/jobs/{done}/result").text, encoding="utf-8")
    run_cli(["plan", "--search", str(downloaded), "--out", str(as_json)])
    assert "job_status" not in json.loads(as_json.read_text())["source"]
