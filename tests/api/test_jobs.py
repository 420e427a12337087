"""Jobs: submit, dedupe, list, get, cancel, metrics; parameters validated per type."""

from __future__ import annotations

import base64
import json
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from service_support import job_clock

from inertia_id import METRICS, InertiaClassifier, Scenario
from inertia_id.classifiers.registry import CLASSIFIER_KINDS
from inertia_id.evaluation.sweep import DEFAULT_NOISES, NOISE_KINDS
from inertia_id.search import SEARCH_METHODS
from service.config import Settings
from service.exports import metric_keys
from service.params import SearchParams, SweepParams, TrainParams
from service.queue import RUN_JOB_TASK
from service.store.jobs import add_metrics, claim, config_hash, finish, hand_back, reap_stale
from service.store.models import JobRow

from .support import GOOD_SEQUENCE, Api, make_settings


def set_status(api: Api, job_id: str, status: str) -> None:
    with api.db.session() as session:
        job = session.get(JobRow, job_id)
        assert job is not None
        job.status = status


def message_job_ids(api: Api) -> list[str]:
    """Job ids in the filesystem broker's messages (kombu envelope, JSON body)."""
    ids = []
    for path in api.queued_messages():
        envelope = json.loads(path.read_text())
        assert envelope["headers"]["task"] == RUN_JOB_TASK
        args, _kwargs, _embed = json.loads(base64.b64decode(envelope["body"]))
        ids.append(args[0])
    return ids


# Submission.


def test_submit_queues_a_job_and_a_message(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, seed=7)
    assert response.status_code == 202, response.text
    job = response.json()
    assert job["reused"] is False
    assert job["status"] == "queued"
    assert job["progress"] == 0.0
    assert job["seed"] == 7
    # Defaults filled in: the worker reads exactly these names.
    assert job["params"] == {
        "method": "ppo",
        "sequence_length": 4,
        "timesteps": 20480,
        "max_sequences": 100000,
        "n_realisations": 20,
        "objective": "f1",
        "metric": "dtw",
        "sakoe_chiba_radius": 2,
        "fuel_weight": 0.0,
        "patience_episodes": 500,
        "ppo": {},
        "cem": {},
        "nsga2": {},
        "objectives": ["accuracy", "final_rate", "impulse"],
        "design_noise": [[6.0, 1.0], [1.0, 6.0]],
        "constraints": {},
        "constraint_penalty": 0.0,
        "lagrangian_lr": 0.0,
        "fresh_realisations": 40,
        "fresh_test_series": 200,
        "time_limit_s": None,
        "time_limit_grace_s": None,
    }
    assert job["config_hash"] == config_hash("search", scenario_id, job["params"], 7)
    assert message_job_ids(api) == [job["id"]]
    with api.db.session() as session:
        row = session.get(JobRow, job["id"])
        assert row is not None and row.params == job["params"]


def test_identical_submission_returns_the_existing_job(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    params = {"method": "random", "timesteps": 4096}
    first = api.submit("search", scenario_id, params=params, seed=1)
    assert first.status_code == 202
    # Defaults spelled out or left out: the same work, the same job.
    again = api.submit("search", scenario_id, params={**params, "metric": "dtw"}, seed=1)
    assert again.status_code == 200
    assert again.json()["id"] == first.json()["id"]
    assert again.json()["reused"] is True
    assert len(api.queued_messages()) == 1

    other_seed = api.submit("search", scenario_id, params=params, seed=2)
    assert other_seed.status_code == 202
    assert other_seed.json()["id"] != first.json()["id"]

    # A rerun of a job still queued is handed that job: it has yet to run.
    waiting = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert (waiting.status_code, waiting.json()["id"]) == (200, first.json()["id"])
    assert waiting.json()["reused"] is True
    set_status(api, first.json()["id"], "succeeded")
    rerun = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert rerun.status_code == 202
    assert rerun.json()["id"] not in (first.json()["id"], other_seed.json()["id"])
    assert len(api.queued_messages()) == 3


def test_a_rerun_handed_an_unfinished_job_says_why_and_how_to_run_it_anew(api: Api) -> None:
    # A job stuck "running" on a dead worker (before the reaper notices) answers a plain
    # rerun: the answer says so, and how to get a new run (before: only "reused": true).
    scenario_id = api.create_scenario()["id"]
    params = {"method": "random", "timesteps": 4096}
    first = api.submit("search", scenario_id, params=params, seed=1).json()
    assert first["reused_note"] is None
    set_status(api, first["id"], "running")
    handed = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert (handed.status_code, handed.json()["id"]) == (200, first["id"])
    note = handed.json()["reused_note"]
    assert "still running" in note, note
    assert f"POST /jobs/{first['id']}/cancel" in note and f'"rerun_of": "{first["id"]}"' in note
    # What it says works: cancelled, the same rerun makes a new job, which says nothing.
    assert api.post(f"/jobs/{first['id']}/cancel").status_code == 200
    fresh = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert fresh.status_code == 202 and fresh.json()["id"] != first["id"]
    assert fresh.json()["reused_note"] is None
    # A plain submission of a finished job is told how to run it again.
    set_status(api, fresh.json()["id"], "succeeded")
    same = api.submit("search", scenario_id, params=params, seed=1)
    assert same.status_code == 200 and '"rerun": true' in same.json()["reused_note"]
    # The OpenAPI text of the 200 says a plain rerun of an unfinished job is answered so.
    answers = api.get("/openapi.json").json()["paths"]["/jobs"]["post"]["responses"]
    assert "queued or running" in answers["200"]["description"]


def test_a_submission_handed_a_standing_job_says_which_labels_it_did_not_apply(
    api: Api,
) -> None:
    # A rerun handed a job still running kept that job's labels, and the new name and
    # tags it carried were dropped without a word (before: the note said nothing of them).
    scenario_id = api.create_scenario()["id"]
    params = {"method": "random", "timesteps": 4096}
    first = api.submit("search", scenario_id, params=params, seed=1, tags=["baseline"]).json()
    set_status(api, first["id"], "running")
    handed = api.submit(
        "search",
        scenario_id,
        params=params,
        seed=1,
        rerun=True,
        name="flight 2",
        tags=["baseline", "flight-2"],
    )
    assert (handed.status_code, handed.json()["id"]) == (200, first["id"])
    # Not applied: the job that stands is relabelled only on purpose.
    assert (handed.json()["name"], handed.json()["tags"]) == (None, ["baseline"])
    note = handed.json()["reused_note"]
    assert "still running" in note, note
    assert "name 'flight 2' (it is unnamed)" in note, note
    assert "tag 'flight-2' (it is tagged ['baseline']) were not applied" in note, note
    change = (
        f'PATCH /jobs/{first["id"]} with {{"name": "flight 2", "tags": ["baseline", "flight-2"]}}'
    )
    assert note.endswith(change), note
    # What it says works.
    patched = api.client.patch(
        f"/jobs/{first['id']}",
        json={"name": "flight 2", "tags": ["baseline", "flight-2"]},
        headers=api.auth,
    )
    assert patched.status_code == 200, patched.text
    assert (patched.json()["name"], patched.json()["tags"]) == (
        "flight 2",
        ["baseline", "flight-2"],
    )
    # One label "was" not applied, several "were" (a name alone read "name ... were").
    for labels, said in (
        ({"name": "A again"}, "name 'A again' (it is named 'flight 2') was not applied"),
        ({"tags": ["x", "y"]}, "tags ['x', 'y'] (it is tagged ['baseline', 'flight-2']) were"),
    ):
        note = api.submit("search", scenario_id, params=params, seed=1, **labels).json()
        assert said in note["reused_note"], note["reused_note"]
        assert ("to set it," in note["reused_note"]) == ("was" in said), note["reused_note"]
    # A submission whose labels the job has (or that sends none) is told nothing of them.
    for labels in ({}, {"name": "flight 2", "tags": ["flight-2"]}):
        same = api.submit("search", scenario_id, params=params, seed=1, **labels)
        assert same.status_code == 200
        assert "not applied" not in same.json()["reused_note"], labels


def test_a_submission_is_not_handed_a_job_that_is_being_cancelled(api: Api) -> None:
    # A running job asked to stop ends cancelled, with no result: a plain submission of
    # its configuration was handed it all the same (200), and its user got nothing.
    scenario_id = api.create_scenario()["id"]
    params = {"method": "random", "timesteps": 4096}
    first = api.submit("search", scenario_id, params=params, seed=1).json()["id"]
    set_status(api, first, "running")
    assert api.post(f"/jobs/{first}/cancel").json()["cancel_requested"] is True
    made = [api.submit("search", scenario_id, params=params, seed=1) for _ in range(2)]
    assert [a.status_code for a in made] == [202, 200], [a.text for a in made]
    assert made[0].json()["id"] != first and made[1].json()["id"] == made[0].json()["id"]
    assert len(api.queued_messages()) == 2
    # A job that finished before it saw the request to stop stands, as any finished one.
    set_status(api, made[0].json()["id"], "running")
    api.post(f"/jobs/{made[0].json()['id']}/cancel")
    set_status(api, made[0].json()["id"], "succeeded")
    again = api.submit("search", scenario_id, params=params, seed=1)
    assert (again.status_code, again.json()["id"]) == (200, made[0].json()["id"])


def test_a_rerun_that_names_the_job_it_replaces_makes_one_job_however_often_sent(
    api: Api,
) -> None:
    # A double click or a retry sends the same rerun again after its job was made: with
    # rerun_of it is handed that job (before: each one a new job that ran).
    scenario_id = api.create_scenario()["id"]
    params = {"method": "random", "timesteps": 4096}
    first = api.submit("search", scenario_id, params=params, seed=1).json()["id"]
    rerun = api.submit("search", scenario_id, params=params, seed=1, rerun_of=first)
    assert rerun.status_code == 202, rerun.text
    fresh = rerun.json()["id"]
    assert fresh != first and rerun.json()["reused"] is False
    for fields in ({"rerun_of": first}, {"rerun_of": first, "rerun": True}):
        again = api.submit("search", scenario_id, params=params, seed=1, **fields)
        assert again.status_code == 200, again.text
        assert (again.json()["id"], again.json()["reused"]) == (fresh, True)
        assert f"job {first} was already replaced" in again.json()["reused_note"]
    assert len(api.queued_messages()) == 2
    # Rerunning the job that stands now makes a new one, queued as it is (named); a
    # plain rerun is handed that one while it waits or runs, and makes one once it ended.
    third = api.submit("search", scenario_id, params=params, seed=1, rerun_of=fresh)
    assert third.status_code == 202 and third.json()["id"] not in (first, fresh)
    plain = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert (plain.status_code, plain.json()["id"]) == (200, third.json()["id"])
    set_status(api, third.json()["id"], "succeeded")
    plain = api.submit("search", scenario_id, params=params, seed=1, rerun=True)
    assert plain.status_code == 202 and plain.json()["id"] != third.json()["id"]
    assert api.get(f"/jobs/{first}").json()["status"] == "queued"


def test_a_rerun_of_a_failed_job_makes_one_new_job(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    first = api.submit("search", scenario_id, seed=3).json()["id"]
    set_status(api, first, "failed")
    made = api.submit("search", scenario_id, seed=3, rerun_of=first)
    assert made.status_code == 202, made.text
    again = api.submit("search", scenario_id, seed=3, rerun_of=first)
    assert (again.status_code, again.json()["id"]) == (200, made.json()["id"])


def test_a_bad_rerun_of_is_422_naming_it(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job = api.submit("search", scenario_id, seed=1).json()["id"]
    missing = "0123456789abcdef0123456789abcdef"
    for fields, fragment in (
        ({"rerun_of": missing}, f"no job '{missing}' to rerun"),
        ({"rerun_of": job, "seed": 2}, f"job '{job}' is not this submission's job"),
        ({"rerun_of": job, "seed": 1, "rerun": False}, "asks for a rerun, but rerun is false"),
        ({"rerun_of": ""}, "at least 1 character"),
        ({"rerun_of": "a\x00b"}, "no job 'a\\x00b' to rerun"),
        ({"rerun_of": 7}, "Input should be a valid string"),
    ):
        response = api.submit("search", scenario_id, **fields)
        assert response.status_code == 422, (fields, response.text)
        (error,) = response.json()["detail"]
        assert error["loc"][-1] == "rerun_of"
        assert fragment in error["msg"], error
    assert len(api.queued_messages()) == 1


@pytest.mark.parametrize("status", ["failed", "cancelled"])
def test_failed_or_cancelled_job_is_not_reused(api: Api, status: str) -> None:
    scenario_id = api.create_scenario()["id"]
    first = api.submit("search", scenario_id).json()
    set_status(api, first["id"], status)
    again = api.submit("search", scenario_id)
    assert again.status_code == 202
    assert again.json()["id"] != first["id"]


def test_succeeded_job_is_reused(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    first = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()
    set_status(api, first["id"], "succeeded")
    again = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE})
    assert again.status_code == 200
    assert again.json()["id"] == first["id"]
    assert again.json()["status"] == "succeeded"


def test_exhaustive_search_within_budget_is_accepted(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    # (5^6)^1 = 15625 sequences, within the default budget of 100000.
    response = api.submit(
        "search", scenario_id, params={"method": "exhaustive", "sequence_length": 1}
    )
    assert response.status_code == 202, response.text


def test_exhaustive_search_too_large_is_refused_with_its_size(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, params={"method": "exhaustive"})
    assert response.status_code == 422
    (error,) = response.json()["detail"]
    assert error["loc"][-1] == "max_sequences"
    assert "(5^6)^4 = 5.96e+16 sequences" in error["msg"]
    assert "max_sequences = 100000" in error["msg"]
    assert api.queued_messages() == []


@pytest.mark.parametrize(
    ("timing", "job_type", "params", "field", "fragment"),
    [
        # Hour-long steps: 20 steps are 1.44 million RK4 steps a flight (a review's
        # worker grew past 4 GB and was killed twice; the job failed saying nothing).
        (
            {"step_duration_s": 3600},
            "train",
            {"sequence": [[4, 4, 4, 0, 0, 0]] * 20, "n_realisations": 400},
            "n_realisations",
            "are 1440000 RK4 steps a flight; at most 100,000",
        ),
        (
            {"step_duration_s": 3600},
            "search",
            {"method": "random", "sequence_length": 2},
            "sequence_length",
            "2 steps of 3600 s (RK4 step 0.05 s, gyro at 20 Hz) are 144000 RK4 steps",
        ),
        # 1-NN on 140 steps stored a 374 MB document that every read then loaded.
        (
            {},
            "train",
            {"sequence": [[4, 4, 4, 0, 0, 0]] * 140, "kind": "1nn", "metric": "euclidean"},
            "n_realisations",
            "are 8400 rate values a series; at most 8,192",
        ),
        (
            {},
            "train",
            {"sequence": [[4, 4, 4, 0, 0, 0]] * 100, "n_realisations": 400},
            "n_realisations",
            "5 candidates x 400 flights x 6000 values a series = 12,000,000 values",
        ),
    ],
)
def test_a_job_too_large_for_a_worker_is_refused_naming_its_size(
    api: Api,
    timing: dict[str, Any],
    job_type: str,
    params: dict[str, Any],
    field: str,
    fragment: str,
) -> None:
    scenario_id = api.create_scenario(**({"timing": timing} if timing else {}))["id"]
    response = api.submit(job_type, scenario_id, params=params)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", field]
    assert "the job is too large for a worker" in error["msg"] and fragment in error["msg"]
    assert api.queued_messages() == []
    # The paper preset at its largest training still fits.
    largest = {"sequence": [[4, 4, 4, 0, 0, 0]] * 64, "n_realisations": 400}
    assert api.submit("train", api.create_scenario()["id"], params=largest).status_code == 202


def test_a_job_on_candidates_with_the_same_tensor_is_refused_before_it_runs(
    api: Api,
) -> None:
    """Two candidates given one tensor (a flight team's copy and paste) are told apart by
    no response: a training on them is refused when it is submitted, naming both, as the
    worker would refuse it, and so is a search, whose accuracy could never pass (K-1)/K.
    (Both were queued: the training failed in the worker with that message, and the
    search ran its whole budget and succeeded, its best accuracy 0.66 of 3 candidates,
    with no word of why.)"""
    paper = Scenario.paper()
    copied = paper.inertia_candidates[0].inertia_kg_m2
    candidates = [c.model_dump() for c in paper.inertia_candidates]
    candidates[1]["inertia_kg_m2"] = copied
    scenario_id = api.create_scenario(inertia_candidates=candidates)["id"]
    expected = (
        "candidates 'none ejected' and 'payload 1 ejected' have the same inertia tensor: no "
        "rate response tells them apart"
    )
    for job_type, params in (
        ("train", {"sequence": GOOD_SEQUENCE}),
        ("search", {"method": "nsga2", "sequence_length": 2}),
    ):
        response = api.submit(job_type, scenario_id, params=params)
        assert response.status_code == 422, (job_type, response.text)
        (error,) = response.json()["detail"]
        assert error["loc"] == ["body", "scenario_id"], job_type
        assert expected in error["msg"], job_type
    assert api.queued_messages() == []


def test_a_training_whose_classifier_the_cli_could_not_load_is_refused(api: Api) -> None:
    # Before: a training was held to the worker's sizes only, and the default kind on 86
    # steps of the paper preset (a 2-candidate scenario on 136) made a document past the
    # 1 GB a classifier file may hold, which GET /classifiers/{id}/download offered and
    # `inertia-id identify --classifier` refused. Its bound (document_bytes) decides.
    scenario_id = api.create_scenario()["id"]
    over = {"sequence": [[4, 4, 4, 0, 0, 0]] * 73}
    response = api.submit("train", scenario_id, params=over)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", "sequence"]
    from inertia_id.classifiers.registry import document_bytes
    from inertia_id.physics.presets import preset

    bound = document_bytes("marginal-likelihood", preset("paper"), 73, 100)
    assert error["msg"].endswith(
        "the job's classifier is too large: a marginal-likelihood classifier of 5 candidates "
        "on 73 steps (4,380 rate values a series, 100 realisations a candidate) writes a "
        f"document of up to {bound:,} bytes, over the limit of 1,000,000,000 bytes a "
        "classifier file may hold (the CLI refuses to load one past it): ask for a shorter "
        "sequence"
    )
    assert api.queued_messages() == []
    under = {"sequence": [[4, 4, 4, 0, 0, 0]] * 72}
    assert api.submit("train", scenario_id, params=under).status_code == 202


@pytest.mark.parametrize(
    ("method", "own", "message"),
    [
        ("cem", {"ppo": {"gamma": 0.9}}, "ppo settings apply to method ppo only, not 'cem'"),
        ("random", {"ppo": {"n_steps": 64}}, "ppo settings apply to method ppo only, not 'random'"),
        ("ppo", {"cem": {"population": 16}}, "cem settings apply to method cem only, not 'ppo'"),
        ("cem", {"nsga2": {"generations": 2}}, "nsga2 settings apply to method nsga2 only"),
        ("random", {"lagrangian_lr": 0.5}, "lagrangian_lr applies to method ppo only"),
        # Settings NSGA-II and the exhaustive search never read: taken (202) and dropped
        # without a word before, as the CLI refuses their options.
        (
            "nsga2",
            {"timesteps": 100},
            "timesteps = 100 applies to method ppo, cem or random, not 'nsga2'",
        ),
        (
            "nsga2",
            {"patience_episodes": 3},
            "patience_episodes = 3 applies to method ppo, cem or random, not 'nsga2'",
        ),
        ("nsga2", {"fuel_weight": 1.0}, "fuel_weight = 1 weighs the reward of method ppo"),
        ("nsga2", {"constraint_penalty": 2.0}, "constraint_penalty = 2 weighs the reward"),
        (
            "exhaustive",
            {"timesteps": 5},
            "timesteps = 5 applies to method ppo, cem or random, not 'exhaustive'",
        ),
    ],
)
def test_another_methods_settings_are_refused_before_the_job_is_queued(
    api: Api, method: str, own: dict[str, object], message: str
) -> None:
    # The worker would fail such a job; the API refuses it with the rule and stores nothing.
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, params={"method": method, **own})
    assert response.status_code == 422, response.text
    assert message in response.text
    assert api.queued_messages() == []
    assert api.get_with_key("/jobs").json()["items"] == []


def test_sweep_job_for_a_stored_classifier(api: Api, classifier: InertiaClassifier) -> None:
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    response = api.submit(
        "sweep", scenario_id, params={"classifier_id": classifier_id, "multiples": [1, 4]}
    )
    assert response.status_code == 202, response.text
    assert response.json()["params"] == {
        "classifier_id": classifier_id,
        "multiples": [1.0, 4.0],
        "noises": ["process", "measurement"],
        "n_test": 200,
        "others": ["least-squares"],
        "ceiling_realisations": 2000,
        "limit_realisations": None,
        "n_train": 20,
        "inertia": True,
        "time_limit_s": None,
    }
    # A multiple of 0 switches that source off, as the core and the CLI take it.
    off = api.submit(
        "sweep", scenario_id, params={"classifier_id": classifier_id, "multiples": [0, 1]}
    )
    assert off.status_code == 202, off.text
    assert off.json()["params"]["multiples"] == [0.0, 1.0]
    # The deprecated name wins and is stored under the one the sweep runs by: it showed
    # ceiling_realisations 2000 beside limit_realisations 200, and the sweep used 200.
    old_name = api.submit(
        "sweep",
        scenario_id,
        params={"classifier_id": classifier_id, "limit_realisations": 200},
    )
    assert old_name.status_code == 202, old_name.text
    stored = api.get_with_key(f"/jobs/{old_name.json()['id']}").json()["params"]
    assert (stored["ceiling_realisations"], stored["limit_realisations"]) == (200, None)


def test_sweep_refuses_a_classifier_of_other_candidates(
    api: Api, classifier: InertiaClassifier
) -> None:
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    other = api.create_scenario(
        candidate_generator={
            "base_inertia_kg_m2": [[50, 0, 0], [0, 40, 0], [0, 0, 45]],
            "n_variations": 2,
        }
    )["id"]
    response = api.submit("sweep", other, params={"classifier_id": classifier_id})
    assert response.status_code == 422
    assert "trained for candidates" in response.json()["detail"][0]["msg"]


BAD_PARAMS: list[tuple[str, dict[str, Any], str]] = [
    ("search", {"method": "genetic"}, "got 'genetic'"),
    ("search", {"sequence_length": 21}, "less than or equal to 20, got 21"),
    ("search", {"sequence_length": 0}, "greater than or equal to 1, got 0"),
    ("search", {"timesteps": 2_000_001}, "got 2000001"),
    ("search", {"timesteps": 3}, "timesteps = 3 must be at least one sequence"),
    ("search", {"max_sequences": 0}, "got 0"),
    ("search", {"n_realisations": 201}, "got 201"),
    ("search", {"metric": "cosine"}, "got 'cosine'"),
    ("search", {"objective": "entropy"}, "got 'entropy'"),
    ("search", {"method": "cem", "cem": {"population": 1}}, "got 1"),
    ("search", {"method": "cem", "cem": {"elites": 3}}, "['elites']"),
    ("search", {"method": "ppo", "cem": {"population": 8}}, "not 'ppo'"),
    ("search", {"sakoe_chiba_radius": -1}, "got -1"),
    ("search", {"fuel_weight": -0.5}, "got -0.5"),
    ("search", {"patience_episodes": 0}, "got 0"),
    ("search", {"ppo": {"n_steps": 0}}, "n_steps must be a positive integer, got 0"),
    ("search", {"ppo": {"batch_size": 4096}}, "batch_size (4096) must not exceed n_steps"),
    ("search", {"ppo": {"warp_drive": 1}}, "unknown PPO parameters ['warp_drive']"),
    ("search", {"population": 10}, "Extra inputs are not permitted, got 10"),
    (
        "search",
        {"method": "nsga2", "constraints": {"min_accuracy": 2}},
        "min_accuracy is a fraction in [0, 1], got 2",
    ),
    # Refused at submission, as the worker would refuse it: a per-flight bound needs
    # enough realisations to estimate a spread, for every method.
    (
        "search",
        {"method": "nsga2", "n_realisations": 5, "constraints": {"max_peak_rate_p95_deg_s": 4}},
        "the search needs n_realisations >= 10",
    ),
    (
        "search",
        {"method": "cem", "n_realisations": 9, "constraints": {"max_final_rate_p95_rad_s": 0.01}},
        "the search needs n_realisations >= 10",
    ),
    # Decidable at submission (each was accepted, then failed in the worker or ranked
    # nothing): a design condition without noise, a duration no sequence of L meets.
    (
        "search",
        {"method": "nsga2", "design_noise": [[6, 1], [0, 0]]},
        "design_noise condition [0, 0] leaves neither disturbance nor gyro noise",
    ),
    (
        "search",
        {"method": "nsga2", "sequence_length": 4, "constraints": {"max_duration_s": 1}},
        "max_duration_s = 1 s is below the duration of every sequence of 4 steps",
    ),
    # A search that "succeeded" with the all-off sequence (predicted accuracy 0.25): no
    # firing meets a cost bound below the cheapest one.
    (
        "search",
        {"method": "nsga2", "constraints": {"max_impulse_nms": 0}},
        "max_impulse_nms = 0 N m s is below the cheapest firing, 0.5 N m s (one thruster at "
        "duty 0.25 for one step)",
    ),
    (
        "search",
        {"method": "cem", "constraints": {"max_on_time_s": 0.2}},
        "max_on_time_s = 0.2 s is below the cheapest firing, 0.25 s",
    ),
    ("train", {"sequence": [[9, 0, 0, 0, 0, 0]]}, "level index 9 is outside 0..4"),
    ("train", {"sequence": [[1, 2]]}, "got shape (1, 2)"),
    ("train", {"sequence": []}, "at least 1 item"),
    ("train", {"sequence": [[0.5, 0, 0, 0, 0, 0]]}, "got 0.5"),
    ("train", {"sequence": GOOD_SEQUENCE, "metric": "cosine"}, "got 'cosine'"),
    ("train", {"sequence": GOOD_SEQUENCE, "n_realisations": 0}, "got 0"),
    ("train", {}, "give sequence, or search_job_id"),
    ("sweep", {"multiples": [0, -1]}, "noise multiples must be >= 0, got [-1.0]"),
    ("sweep", {"multiples": [1, -2]}, "got [-2.0]"),
    ("sweep", {"multiples": [1.0] * 21}, "at most 20 items"),
    ("sweep", {"multiples": []}, "at least 1 item"),
    # Beyond 1000x the simulated rates lose accuracy, then overflow to nan in the worker.
    ("sweep", {"multiples": [1, 1e6]}, "at most 1000 (beyond it the simulated rates"),
    ("sweep", {"multiples": [1, 1e6]}, "got [1000000.0] in [1.0, 1000000.0]"),
    ("sweep", {"multiples": [1e300]}, "got [1e+300]"),
    # The ceiling's own rule (inertia_id.evaluation.sweep.check_ceiling_realisations).
    ("sweep", {"ceiling_realisations": 1}, "must be 0 (no ceiling) or at least 3, got 1"),
    ("sweep", {"ceiling_realisations": 2}, "must be 0 (no ceiling) or at least 3, got 2"),
    ("sweep", {"limit_realisations": 2}, "limit_realisations must be 0 (no ceiling)"),
    ("sweep", {"noises": ["thermal"]}, "got 'thermal'"),
    ("sweep", {"noises": ["process", "process"]}, "must not repeat"),
    ("sweep", {"n_test": 4}, "got 4"),
    ("sweep", {"n_test": 2001}, "got 2001"),
    # Refused at submission, not after the job has waited in the queue: the paper
    # preset's thrusters state no thrust or specific impulse.
    (
        "search",
        {"method": "nsga2", "constraints": {"max_propellant_kg": 0.1}},
        "constraint max_propellant_kg needs the scenario's thrusters to state thrust_n",
    ),
    (
        "search",
        {"method": "nsga2", "objectives": ["accuracy", "propellant"]},
        "the propellant objective needs the scenario's thrusters",
    ),
    (
        "search",
        {"constraints": {"max_final_rate_rad_s": 0.5, "max_final_rate_deg_s": 1}},
        "max_final_rate_rad_s = 0.5 and max_final_rate_deg_s = 1 bound the same rate",
    ),
    # The commanded residual's bounds follow the same rules (both units of one figure
    # refused; the mean and the worst candidate are two figures).
    (
        "search",
        {
            "constraints": {
                "max_commanded_residual_rate_rad_s": 0.003,
                "max_commanded_residual_rate_deg_s": 0.2,
            }
        },
        "max_commanded_residual_rate_rad_s = 0.003 and max_commanded_residual_rate_deg_s = "
        "0.2 bound the same rate",
    ),
    (
        "search",
        {
            "constraints": {
                "max_commanded_residual_rate_max_rad_s": 0.003,
                "max_commanded_residual_rate_max_deg_s": 0.2,
            }
        },
        "max_commanded_residual_rate_max_rad_s = 0.003 and "
        "max_commanded_residual_rate_max_deg_s = 0.2 bound the same rate",
    ),
    (
        "search",
        {"constraints": {"max_commanded_residual_rate_max_deg_s": -0.2}},
        "constraint max_commanded_residual_rate_max_deg_s must be a finite number >= 0, got -0.2",
    ),
]


@pytest.mark.parametrize(("job_type", "params", "fragment"), BAD_PARAMS)
def test_bad_params_are_422_naming_the_value(
    api: Api, classifier: InertiaClassifier, job_type: str, params: dict[str, Any], fragment: str
) -> None:
    scenario_id = api.create_scenario()["id"]
    if job_type == "sweep":
        params = {"classifier_id": api.insert_classifier(scenario_id, classifier), **params}
    response = api.submit(job_type, scenario_id, params=params)
    assert response.status_code == 422, response.text
    messages = " | ".join(e["msg"] for e in response.json()["detail"])
    assert fragment in messages
    assert api.queued_messages() == []


@pytest.mark.parametrize(
    ("fields", "fragment"),
    [
        ({"seed": -1}, "got -1"),
        ({"seed": 2**31}, "got 2147483648"),
        ({"rerun": "perhaps"}, "got 'perhaps'"),
        ({"type": "dance"}, "Input tag 'dance'"),
    ],
)
def test_bad_common_fields_are_422(api: Api, fields: dict[str, Any], fragment: str) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.post("/jobs", json={"type": "search", "scenario_id": scenario_id, **fields})
    assert response.status_code == 422, response.text
    assert fragment in " | ".join(e["msg"] for e in response.json()["detail"])


def test_non_finite_json_numbers_are_422(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    for token in ("NaN", "Infinity", "-Infinity"):
        body = (
            f'{{"type": "search", "scenario_id": "{scenario_id}", '
            f'"params": {{"fuel_weight": {token}, "ppo": {{"learning_rate": {token}}}}}}}'
        )
        response = api.post_raw_json("/jobs", body)
        assert response.status_code == 422, response.text
        locs = [e["loc"][-1] for e in response.json()["detail"]]
        assert "fuel_weight" in locs
        assert "ppo" in locs


def test_unknown_ids_are_404(api: Api) -> None:
    missing = "0123456789abcdef0123456789abcdef"
    assert api.submit("search", missing).status_code == 404
    scenario_id = api.create_scenario()["id"]
    response = api.submit("sweep", scenario_id, params={"classifier_id": missing})
    assert response.status_code == 404
    assert "classifier" in response.json()["detail"]
    assert api.get(f"/jobs/{missing}").status_code == 404
    assert api.get(f"/jobs/{missing}/metrics").status_code == 404
    assert api.post(f"/jobs/{missing}/cancel").status_code == 404


# Reading.


def test_get_job(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    job = api.get(f"/jobs/{job_id}").json()
    assert job["id"] == job_id
    assert job["type"] == "train"
    assert job["params"] == {
        "sequence": GOOD_SEQUENCE,
        "search_job_id": None,
        "front_member": None,
        "kind": "marginal-likelihood",
        "metric": None,
        "n_realisations": 100,
    }
    assert job["status"] == "queued"
    assert job["error"] is None and job["result"] is None
    assert job["started_at"] is None and job["finished_at"] is None
    assert datetime.fromisoformat(job["created_at"]).utcoffset() == timedelta(0)


def test_a_run_lost_before_the_one_that_succeeded_shows_in_the_job_and_its_download(
    api: Api,
) -> None:
    """The second run's claim overwrote the first's ``started_at`` and ``error``: the job
    and its downloaded JSON said only ``attempts: 2``. Both now list the lost run: its
    worker, when it started (with its zone), when and why it was lost, what followed."""
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    with api.db.session() as session:
        first = claim(session, job_id, "worker1-3fa2c1@host")
        assert first is not None
        first.heartbeat_at = first.started_at = datetime.now(UTC) - timedelta(seconds=600)
        first_started = first.started_at
    with api.db.session() as session:
        assert reap_stale(session, timeout_s=60.0, max_attempts=2) == ([job_id], [])
    with api.db.session() as session:
        assert claim(session, job_id, "worker1-3fa2c1@host") is not None
        assert finish(session, job_id, "succeeded", result={"f1": 1.0}, attempt=2)

    job = api.get(f"/jobs/{job_id}").json()
    assert job["attempts"] == 2 and job["error"] is None
    (lost,) = job["attempt_history"]
    assert lost["attempt"] == 1 and lost["worker"] == "worker1-3fa2c1@host"
    assert datetime.fromisoformat(lost["started_at"]) == first_started
    assert datetime.fromisoformat(lost["ended_at"]).utcoffset() == timedelta(0)
    assert datetime.fromisoformat(lost["started_at"]) != datetime.fromisoformat(job["started_at"])
    assert (lost["outcome"], lost["cause"], lost["then"]) == (
        "lost",
        "heartbeat missed",
        "re-queued",
    )
    assert lost["reason"].startswith("heartbeat missed: the run's last heartbeat at")
    download = json.loads(api.get(f"/jobs/{job_id}/result").text)
    assert download["attempt_history"] == job["attempt_history"]
    # A job with no lost run has an empty history, not null.
    other = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}, seed=5).json()
    assert api.get(f"/jobs/{other['id']}").json()["attempt_history"] == []


def test_a_job_handed_back_at_each_restart_says_its_runs_counted_apart(api: Api) -> None:
    """Five worker restarts, each handing the run back, then a run that succeeds: the
    job said only ``attempts: 6``, which read as six tries though the failure rule
    (INERTIA_ID_MAX_ATTEMPTS) counted one. ``counted_attempts`` now says what the rule
    counts; ``attempts`` and ``handbacks`` are kept as they were."""
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    for restart in range(5):
        with api.db.session() as session:
            assert claim(session, job_id, f"worker{restart}@host") is not None
        with api.db.session() as session:
            assert hand_back(session, f"worker{restart}@host", "asked to stop") == [job_id]
    job = api.get(f"/jobs/{job_id}").json()
    assert (job["status"], job["attempts"], job["handbacks"], job["counted_attempts"]) == (
        "queued",
        5,
        5,
        0,
    )
    with api.db.session() as session:
        assert claim(session, job_id, "worker5@host") is not None
        assert finish(session, job_id, "succeeded", result={"f1": 1.0}, attempt=6)
    job = api.get(f"/jobs/{job_id}").json()
    assert (job["attempts"], job["handbacks"], job["counted_attempts"]) == (6, 5, 1)
    [listed] = [j for j in api.get("/jobs").json()["items"] if j["id"] == job_id]
    assert listed["counted_attempts"] == 1
    assert [run["outcome"] for run in job["attempt_history"]] == ["handed back"] * 5


def test_list_filters_and_paging(api: Api) -> None:
    first = api.create_scenario(name="first")["id"]
    second = api.create_scenario(name="second")["id"]
    searches = [api.submit("search", first, seed=seed).json()["id"] for seed in range(4)]
    train = api.submit("train", second, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    assert api.post(f"/jobs/{searches[0]}/cancel").status_code == 200

    def ids(**params: Any) -> list[str]:
        response = api.get("/jobs", params=params)
        assert response.status_code == 200, response.text
        return [j["id"] for j in response.json()["items"]]

    assert ids() == [train, *reversed(searches)]  # newest first
    assert ids(type="train") == [train]
    assert ids(type="sweep") == []
    assert ids(status="cancelled") == [searches[0]]
    assert set(ids(status="queued")) == {*searches[1:], train}
    assert ids(scenario_id=second) == [train]
    assert ids(scenario_id=first, status="queued") == list(reversed(searches[1:]))
    assert ids(scenario_id="no such scenario") == []

    page = api.get("/jobs", params={"limit": 2, "offset": 1}).json()
    assert page["total"] == 5
    assert [j["id"] for j in page["items"]] == ids()[1:3]
    assert api.get("/jobs", params={"status": "sleeping"}).status_code == 422
    assert api.get("/jobs", params={"limit": 1000}).status_code == 422


def test_list_sends_summaries_and_results_only_when_asked(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    queued = api.submit("search", scenario_id).json()["id"]
    done = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE}).json()["id"]
    result = {"classifier_id": "c" * 32, "f1": 0.75, "accuracy": 0.8, "confusion": [[3, 1]]}
    with api.db.session() as session:
        assert claim(session, done, "tests") is not None
    with api.db.session() as session:
        assert finish(session, done, "succeeded", result=result)
    whole = api.get(f"/jobs/{done}").json()
    assert whole["result"] == result  # the job itself keeps its result

    listed = {j["id"]: j for j in api.get("/jobs").json()["items"]}
    assert "result" not in listed[done] and "result" not in listed[queued]
    assert listed[done] == {k: v for k, v in whole.items() if k != "result"}
    assert listed[done]["summary"] == {"f1": 0.75, "accuracy": 0.8}
    assert listed[queued]["params"]["method"] == "ppo" and listed[queued]["summary"] is None

    asked = api.get("/jobs", params={"include": "result"})
    assert asked.status_code == 200, asked.text
    with_results = {j["id"]: j for j in asked.json()["items"]}
    assert with_results[done] == whole
    assert with_results[queued]["result"] is None  # asked for: null until there is one

    for bad in ("results", "summary", ""):
        refused = api.get("/jobs", params={"include": bad})
        assert refused.status_code == 422, refused.text
        (error,) = refused.json()["detail"]
        assert error["loc"] == ["query", "include"] and f"got {bad!r}" in error["msg"], error
    unknown = api.get("/jobs", params={"includes": "result"})
    assert unknown.status_code == 422
    assert "'includes'" in unknown.json()["detail"][0]["msg"]
    assert "include" in unknown.json()["detail"][0]["msg"]  # among the names it takes
    twice = api.get("/jobs?include=result&include=result")
    assert twice.status_code == 422


def test_openapi_lists_jobs_without_results_by_default(api: Api) -> None:
    spec = api.get("/openapi.json").json()
    route = spec["paths"]["/jobs"]["get"]
    (include,) = [p for p in route["parameters"] if p["name"] == "include"]
    assert {"const": "result", "type": "string"} in include["schema"]["anyOf"]
    schemas = spec["components"]["schemas"]
    page = route["responses"]["200"]["content"]["application/json"]["schema"]["$ref"]
    items = schemas[page.rsplit("/", 1)[1]]["properties"]["items"]["items"]["$ref"]
    # Each job model is a oneOf of one variant a job type (app.result_schema).
    for ref in schemas[items.rsplit("/", 1)[1]]["oneOf"]:
        listed = schemas[ref["$ref"].rsplit("/", 1)[1]]
        assert "result" in listed["properties"] and "result" not in listed["required"]
        assert "summary" in listed["properties"] and "params" in listed["required"]
    for ref in schemas["JobOut"]["oneOf"]:  # GET /jobs/{id}: always there
        assert "result" in schemas[ref["$ref"].rsplit("/", 1)[1]]["required"]


# Cancelling.


def test_cancel_queued_job(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    response = api.post(f"/jobs/{job_id}/cancel")
    assert response.status_code == 200
    job = response.json()
    assert job["status"] == "cancelled"
    assert job["cancel_requested"] is True
    assert job["finished_at"] is not None
    assert api.get(f"/jobs/{job_id}").json()["status"] == "cancelled"
    # Idempotent.
    assert api.post(f"/jobs/{job_id}/cancel").json()["status"] == "cancelled"


def test_cancel_running_job_asks_the_worker(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    set_status(api, job_id, "running")
    job = api.post(f"/jobs/{job_id}/cancel").json()
    assert job["status"] == "running"
    assert job["cancel_requested"] is True


def test_cancel_finished_job_is_409(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    set_status(api, job_id, "succeeded")
    response = api.post(f"/jobs/{job_id}/cancel")
    assert response.status_code == 409
    assert "succeeded" in response.json()["detail"]


# Metrics.


def test_metrics_incremental(api: Api) -> None:
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    with api.db.session() as session:
        add_metrics(session, job_id, [("reward", step, step / 10) for step in range(100)])
        add_metrics(session, job_id, [("best_f1", step, 1.0) for step in range(10)])

    series = {s["key"]: s for s in api.get(f"/jobs/{job_id}/metrics").json()["series"]}
    assert set(series) == {"reward", "best_f1"}
    assert series["reward"]["steps"] == list(range(100))
    assert series["reward"]["values"][42] == pytest.approx(4.2)
    assert series["reward"]["last_step"] == 99
    assert series["reward"]["downsampled"] is False

    newer = api.get(f"/jobs/{job_id}/metrics", params={"key": "reward", "after": 89}).json()
    (reward,) = newer["series"]
    assert reward["steps"] == list(range(90, 100))
    assert reward["total_points"] == 10

    with api.db.session() as session:
        add_metrics(session, job_id, [("reward", 100, 10.0)])
    latest = api.get(f"/jobs/{job_id}/metrics", params={"key": "reward", "after": 99}).json()
    assert latest["series"][0]["steps"] == [100]
    nothing = api.get(f"/jobs/{job_id}/metrics", params={"key": "reward", "after": 100}).json()
    assert nothing["series"] == []
    # A key no search records is a 404 (test_a_metric_key_the_job_never_records_is_a_404).
    assert api.get(f"/jobs/{job_id}/metrics", params={"key": "loss"}).status_code == 404


def test_a_metric_key_the_job_never_records_is_a_404(api: Api) -> None:
    """``?key=nope`` answered 200 with no series, as a series not written yet does: a typo
    read as a curve still to come, and a finished job's missing series as one that may
    yet come. A key the job's type (or its parameters) never records is a 404 naming the
    key and the job's series; so is any key a finished job did not record. A queued or
    running job's key that it records later is a 200 with no series, and ``keys`` says
    which it has."""
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    with api.db.session() as session:
        add_metrics(session, job_id, [("best_f1", 0, 0.5), ("best_residual_rate_rad_s", 0, 0.01)])
    has = "it has best_f1, best_residual_rate_rad_s, best_residual_rate_deg_s"
    search_keys = (
        "mean_episode_reward, mean_f1, best_f1, best_residual_rate_rad_s, best_residual_rate_deg_s"
    )
    # best_feasible is written only by a search with constraints; this one has none.
    for key in ("nope", "best_feasible"):
        for format in ("json", "csv"):
            response = api.get(f"/jobs/{job_id}/metrics", params={"key": key, "format": format})
            assert response.status_code == 404, (key, format, response.text)
            assert response.json()["detail"] == (
                f"job {job_id!r} (search) never records a series {key!r}: its series are "
                f"{search_keys}; {has}"
            )
    # Queued: a key it records but has not yet is no error.
    pending = api.get(f"/jobs/{job_id}/metrics", params={"key": "mean_f1"})
    assert pending.status_code == 200, pending.text
    assert pending.json()["series"] == []
    assert pending.json()["keys"] == has.removeprefix("it has ").split(", ")
    # Finished: what it did not record, it never will.
    set_status(api, job_id, "succeeded")
    done = api.get(f"/jobs/{job_id}/metrics", params={"key": "mean_f1"})
    assert done.status_code == 404, done.text
    assert done.json()["detail"] == (
        f"job {job_id!r} has no series 'mean_f1' (it succeeded without recording it); {has}"
    )
    # What it recorded is served as before, the deg/s twin too.
    for key in ("best_f1", "best_residual_rate_deg_s"):
        (series,) = api.get(f"/jobs/{job_id}/metrics", params={"key": key}).json()["series"]
        assert series["key"] == key
    # A search with constraints records best_feasible.
    bounded = api.submit(
        "search", scenario_id, params={"method": "cem", "constraints": {"max_impulse_nms": 24}}
    )
    assert bounded.status_code == 202, bounded.text
    feasible = api.get(f"/jobs/{bounded.json()['id']}/metrics", params={"key": "best_feasible"})
    assert feasible.status_code == 200 and feasible.json() == {
        "job_id": bounded.json()["id"],
        "series": [],
        "keys": [],
    }


def test_each_job_type_names_the_metric_series_it_records() -> None:
    """What the 404 of an unrecorded ``?key=`` lists: a training's two figures, and a
    sweep's accuracy for each noise it sweeps (process and measurement by default)."""
    assert metric_keys("train", {}) == ["f1", "accuracy"]
    assert metric_keys("sweep", {"noises": ["jitter", "gyro_bias"]}) == [
        "accuracy_jitter",
        "accuracy_gyro_bias",
    ]
    assert metric_keys("sweep", {}) == ["accuracy_process", "accuracy_measurement"]
    assert metric_keys("search", {"constraints": {"max_impulse_nms": 24}})[-1] == "best_feasible"
    assert metric_keys("another", {}) is None


def test_metrics_downsampled_on_the_server(
    make_api: Callable[[Settings], Api], tmp_path: Path, database_url: str
) -> None:
    api = make_api(make_settings(tmp_path, database_url, INERTIA_ID_MAX_METRIC_POINTS=50))
    scenario_id = api.create_scenario()["id"]
    job_id = api.submit("search", scenario_id).json()["id"]
    with api.db.session() as session:
        add_metrics(session, job_id, [("reward", step, float(step)) for step in range(1000)])
    (series,) = api.get(f"/jobs/{job_id}/metrics").json()["series"]
    assert series["downsampled"] is True
    assert series["total_points"] == 1000
    assert len(series["steps"]) == 50
    assert series["steps"][0] == 0 and series["steps"][-1] == 999
    assert series["last_step"] == 999
    # Real points, evenly spread: each value is its own step.
    assert series["values"] == [float(s) for s in series["steps"]]
    gaps = {b - a for a, b in zip(series["steps"], series["steps"][1:], strict=False)}
    assert gaps <= {20, 21}


def test_the_api_accepts_every_method_metric_and_noise_of_the_core() -> None:
    for method in SEARCH_METHODS:
        assert SearchParams.model_validate({"method": method}).method == method
    for metric in METRICS:
        assert SearchParams.model_validate({"metric": metric}).metric == metric
        train = TrainParams.model_validate({"sequence": GOOD_SEQUENCE, "metric": metric})
        assert train.metric == metric
    assert SweepParams(classifier_id="x").noises == list(DEFAULT_NOISES)
    for noise in NOISE_KINDS:
        assert SweepParams(classifier_id="x", noises=[noise]).noises == [noise]
    for kind in CLASSIFIER_KINDS:
        assert TrainParams.model_validate({"sequence": GOOD_SEQUENCE, "kind": kind}).kind == kind
        assert SweepParams(classifier_id="x", others=[kind]).others == [kind]


def test_an_unreachable_broker_leaves_the_job_queued_until_it_can_be_sent(
    make_api: Callable[[Settings], Api], tmp_path: Path, database_url: str
) -> None:
    api = make_api(make_settings(tmp_path, database_url, BROKER_URL="redis://127.0.0.1:1/0"))
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id)
    # Accepted and stored; the workers' monitor sends it once the broker is back.
    assert response.status_code == 202, response.text
    job = response.json()
    assert job["status"] == "queued" and job["sent_at"] is None
    # The same submission again is that job, not a second one.
    again = api.submit("search", scenario_id)
    assert again.status_code == 200 and again.json()["id"] == job["id"]
    assert api.get("/jobs").json()["total"] == 1


@pytest.mark.parametrize(
    ("params", "quoted"),
    [
        ({"kind": "likelihood", "metric": "dtw"}, "takes no metric, got metric 'dtw'"),
        ({"kind": "1nn", "metric": "softdtw"}, "softdtw"),
        ({"kind": "likelihood", "n_realisations": 2}, "n_realisations = 2"),
        ({"kind": "forest"}, "'forest'"),
    ],
)
def test_a_train_job_of_a_bad_kind_or_metric_is_refused_by_name(
    api: Api, params: dict[str, Any], quoted: str
) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE, **params})
    assert response.status_code == 422, response.text
    assert quoted in response.text


def test_a_sweep_names_a_bad_other_classifier(api: Api, classifier: Any) -> None:
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    for others, quoted in ((["knn"],), "got 'knn'"), ((["likelihood", "likelihood"],), "twice"):
        response = api.submit(
            "sweep", scenario_id, params={"classifier_id": classifier_id, "others": others[0]}
        )
        assert response.status_code == 422, response.text
        assert quoted in response.text


# Time limits.


def test_a_job_may_ask_for_less_time_than_the_ceiling_and_it_is_stored(
    make_api: Callable[..., Api], settings: Settings, classifier: InertiaClassifier
) -> None:
    api = make_api(settings.model_copy(update={"job_time_limit_s": 600.0}))
    scenario_id = api.create_scenario()["id"]
    search = api.submit("search", scenario_id, params={"time_limit_s": 600})
    assert search.status_code == 202, search.text
    assert api.get(f"/jobs/{search.json()['id']}").json()["params"]["time_limit_s"] == 600
    unasked = api.submit("search", scenario_id, params={"method": "random"}).json()
    assert api.get(f"/jobs/{unasked['id']}").json()["params"]["time_limit_s"] is None
    classifier_id = api.insert_classifier(scenario_id, classifier)
    sweep = api.submit(
        "sweep", scenario_id, params={"classifier_id": classifier_id, "time_limit_s": 1.5}
    )
    assert sweep.status_code == 202, sweep.text
    assert api.get(f"/jobs/{sweep.json()['id']}").json()["params"]["time_limit_s"] == 1.5
    train = api.submit("train", scenario_id, params={"sequence": GOOD_SEQUENCE, "time_limit_s": 90})
    assert train.status_code == 202, train.text
    assert api.get(f"/jobs/{train.json()['id']}").json()["params"]["time_limit_s"] == 90


@pytest.mark.parametrize("job_type", ["search", "sweep", "train"])
def test_a_job_asking_for_more_time_than_the_ceiling_is_422_naming_both(
    make_api: Callable[..., Api],
    settings: Settings,
    classifier: InertiaClassifier,
    job_type: str,
) -> None:
    api = make_api(settings.model_copy(update={"job_time_limit_s": 3600.0}))
    scenario_id = api.create_scenario()["id"]
    params: dict[str, Any] = {"time_limit_s": 3600.5}
    if job_type == "sweep":
        params["classifier_id"] = api.insert_classifier(scenario_id, classifier)
    if job_type == "train":
        params["sequence"] = GOOD_SEQUENCE
    response = api.submit(job_type, scenario_id, params=params)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", "time_limit_s"]
    assert "time_limit_s = 3600.5 s" in error["msg"] and "ceiling of 3600 s" in error["msg"]
    assert api.queued_messages() == []


@pytest.mark.parametrize(
    ("value", "quoted"),
    [
        (-1, "greater than or equal to 0, got -1"),
        ("10", "a valid number, got '10'"),
        (3600.5, "less than or equal to 3600, got 3600.5"),
    ],
)
def test_a_grace_that_is_no_number_of_seconds_is_422_naming_it(
    api: Api, value: Any, quoted: str
) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, params={"time_limit_grace_s": value})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", "time_limit_grace_s"]
    assert quoted in error["msg"]
    assert api.queued_messages() == []
    asked = api.submit("search", scenario_id, params={"time_limit_s": 60, "time_limit_grace_s": 0})
    assert asked.status_code == 202, asked.text
    assert api.get(f"/jobs/{asked.json()['id']}").json()["params"]["time_limit_grace_s"] == 0


@pytest.mark.parametrize(
    ("job_type", "fields", "loc", "fragment"),
    [
        ("search", {"seed": "x"}, ["body", "seed"], "a valid integer, got 'x'"),
        ("search", {"params": {"timesteps": -1}}, ["body", "params", "timesteps"], "got -1"),
        ("train", {"params": {"sequence": "x"}}, ["body", "params", "sequence"], "'x'"),
        ("train", {}, ["body", "params"], "Field required"),
        ("sweep", {"seed": 1.5, "params": {"classifier_id": "0" * 32}}, ["body", "seed"], "1.5"),
        (
            "sweep",
            {"params": {"classifier_id": "0" * 32, "n_test": "x"}},
            ["body", "params", "n_test"],
            "x",
        ),
    ],
)
def test_a_job_field_refused_is_located_where_the_client_sent_it(
    api: Api, job_type: str, fields: dict[str, Any], loc: list[str], fragment: str
) -> None:
    """Pydantic located a job's fields under the union's tag, ``["body", "search",
    "seed"]``, a key the client never sent."""
    scenario_id = api.create_scenario()["id"]
    response = api.submit(job_type, scenario_id, **fields)
    assert response.status_code == 422, response.text
    errors = response.json()["detail"]
    assert [error["loc"] for error in errors] == [loc], errors
    assert fragment in errors[0]["msg"]
    # An unknown type is refused at the type, as before.
    response = api.post("/jobs", json={"type": "serch", "scenario_id": scenario_id})
    assert response.status_code == 422 and response.json()["detail"][0]["loc"] == ["body"]
    assert api.queued_messages() == []


@pytest.mark.parametrize(
    ("value", "quoted"),
    [
        (0, "greater than or equal to 1, got 0"),
        (-5, "greater than or equal to 1, got -5"),
        ("60", "a valid number, got '60'"),
        (True, "a valid number, got True"),
    ],
)
def test_a_time_limit_that_is_no_positive_number_is_422_naming_it(
    api: Api, value: Any, quoted: str
) -> None:
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, params={"time_limit_s": value})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"][-1] == "time_limit_s" and error["msg"].endswith(quoted)
    assert api.queued_messages() == []


@pytest.mark.parametrize("job_type", ["search", "sweep", "train"])
def test_a_time_limit_under_a_second_is_422_naming_it_and_the_floor(
    api: Api, classifier: InertiaClassifier, job_type: str
) -> None:
    """1e-9 s was queued: a training then failed on it, a sweep "succeeded" with no
    point, a search ran one sequence. Less than 1 s is no budget for any job's work,
    and most likely milliseconds meant as seconds; 1 s is taken."""
    scenario_id = api.create_scenario()["id"]
    params: dict[str, Any] = {}
    if job_type == "sweep":
        params["classifier_id"] = api.insert_classifier(scenario_id, classifier)
    if job_type == "train":
        params["sequence"] = GOOD_SEQUENCE
    for value in (1e-9, 0.5, 0.999):
        response = api.submit(job_type, scenario_id, params={**params, "time_limit_s": value})
        assert response.status_code == 422, response.text
        (error,) = response.json()["detail"]
        assert error["loc"] == ["body", "params", "time_limit_s"]
        assert error["msg"].endswith(f"greater than or equal to 1, got {value!r}"), error
    assert api.queued_messages() == []
    response = api.submit(job_type, scenario_id, params={**params, "time_limit_s": 1})
    assert response.status_code == 202, response.text
    assert response.json()["params"]["time_limit_s"] == 1
    schema = api.get("/openapi.json").json()["components"]["schemas"]
    limit = schema[f"{job_type.capitalize()}Params"]["properties"]["time_limit_s"]
    assert {"type": "number", "minimum": 1} in limit["anyOf"]
    assert "at least 1" in limit["description"]


def test_a_train_job_takes_a_time_limit_of_its_own_and_fails_past_it(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A training stops at its next checkpoint past its limit, so a train job takes
    ``time_limit_s`` as a search or sweep does (it was a 422: the limit could not stop a
    training part-way). Its limit is part of its configuration, as a search's is."""
    from worker.runner import execute_job

    scenario_id = api.create_scenario()["id"]
    params: dict[str, Any] = {
        "sequence": GOOD_SEQUENCE,
        "kind": "nearest-centroid",
        "metric": "euclidean",
        "n_realisations": 3,
        "time_limit_s": 1,
    }
    submitted = api.submit("train", scenario_id, params=params)
    assert submitted.status_code == 202, submitted.text
    job = submitted.json()
    assert job["params"]["time_limit_s"] == 1 and job["stopped"] is None
    assert job["config_hash"] == config_hash("train", scenario_id, job["params"], job["seed"])
    # The same training without the limit is other work: a job of its own.
    unlimited = api.submit("train", scenario_id, params={**params, "time_limit_s": None})
    assert unlimited.status_code == 202 and unlimited.json()["id"] != job["id"]
    # Asked for no limit, its parameters are those of a train job stored before train
    # jobs took one (no time_limit_s), and so is its identity: such a job is reused by an
    # identical submission, and a rerun may name it.
    stored = unlimited.json()["params"]
    assert "time_limit_s" not in stored and stored == {
        k: v for k, v in job["params"].items() if k != "time_limit_s"
    }
    assert unlimited.json()["config_hash"] == config_hash(
        "train", scenario_id, stored, unlimited.json()["seed"]
    )
    before = {k: v for k, v in params.items() if k != "time_limit_s"}
    rerun = api.submit(
        "train", scenario_id, params=before, rerun=True, rerun_of=unlimited.json()["id"]
    )
    assert rerun.status_code == 202, rerun.text

    # The job's clock reads its limit from the claim on: spent at the first checkpoint,
    # on any machine.
    job_clock(monkeypatch, after_claim=1.0)
    assert execute_job(job["id"], settings=api.settings, worker_name="tests") == "failed"
    failed = api.get(f"/jobs/{job['id']}").json()
    assert failed["error"] == "JobTimeLimitExceeded: the job exceeded its time limit of 1 s"
    assert failed["result"] is None
    # A field says why, for a client to read rather than match the error's words; a
    # list (which leaves the result out) says it too.
    assert failed["stopped"] == "time_limit"
    listed = api.get("/jobs", params={"status": "failed"}).json()["items"]
    assert [(item["id"], item["stopped"]) for item in listed] == [(job["id"], "time_limit")]
    assert api.get("/classifiers").json()["items"] == []
    # The list finds the jobs their limit stopped (the two jobs without a limit are
    # queued beside it), and names a reason it does not know.
    assert len(api.get("/jobs").json()["items"]) == 3
    stopped = api.get("/jobs", params={"stopped": "time_limit"}).json()
    assert [item["id"] for item in stopped["items"]] == [job["id"]] and stopped["total"] == 1
    unknown = api.get("/jobs", params={"stopped": "cancelled"})
    assert unknown.status_code == 422, unknown.text
    assert unknown.json()["detail"][0]["loc"] == ["query", "stopped"]
    assert "'time_limit'" in unknown.text and "cancelled" in unknown.text


def test_jobs_whose_sequences_no_gyro_measures_are_refused_at_submission(
    api: Api, classifier: InertiaClassifier
) -> None:
    """The plan's rule at submission: a sphere of 0.019 kg m² is left at 105 rad/s by one
    full-duty step once the lag has emptied. A search on it (its hand-designed baseline
    past the ceiling) and a training on that step were queued, to rank or classify rates
    no gyro measures; a sweep on thrusters 1000 times the classifier's too. Each is a 422
    naming the candidate and the rate, and nothing is queued."""
    candidates = Scenario.paper().model_dump(mode="json")["inertia_candidates"]
    candidates[0]["inertia_kg_m2"] = (0.019 * np.eye(3)).tolist()
    tiny = api.create_scenario(inertia_candidates=candidates)["id"]
    torque = Scenario.paper().model_dump(mode="json")["thrusters"]["torque_matrix_nm"]
    strong = api.create_scenario(
        thrusters={"torque_matrix_nm": [[1000 * v for v in row] for row in torque]}
    )["id"]
    classifier_id = api.insert_classifier(api.create_scenario()["id"], classifier)
    for job_type, scenario_id, params, loc in (
        ("search", tiny, {"method": "random", "sequence_length": 1}, ["body", "scenario_id"]),
        (
            "train",
            tiny,
            {"sequence": [[4, 4, 4, 0, 0, 0]]},
            ["body", "params", "sequence"],
        ),
        (
            "sweep",
            strong,
            {"classifier_id": classifier_id},
            ["body", "params", "classifier_id"],
        ),
    ):
        response = api.submit(job_type, scenario_id, params=params)
        assert response.status_code == 422, (job_type, response.text)
        (error,) = response.json()["detail"]
        assert error["loc"] == loc
        assert "beyond any attitude gyro's range" in error["msg"]
        if scenario_id == tiny:
            assert "candidate 'none ejected' to 105 rad/s (6,031 deg/s)" in error["msg"]
    assert (
        "its hand-designed baseline of 1 steps"
        in api.submit("search", tiny, params={"method": "random", "sequence_length": 1}).json()[
            "detail"
        ][0]["msg"]
    )
    assert api.queued_messages() == []


@pytest.mark.parametrize(
    ("constraints", "loc", "fragment"),
    [
        (
            {"max_final_rate_deg_s": -1},
            ["constraints", "max_final_rate_deg_s"],
            "constraint max_final_rate_deg_s must be a finite number >= 0, got -1.0",
        ),
        (
            {"max_impulse_nms": 20, "warp": 1},
            ["constraints", "warp"],
            "unknown constraint 'warp'; known: [",
        ),
        (
            {"max_final_rate_rad_s": 0.5, "max_final_rate_deg_s": 1},
            ["constraints"],
            "constraints max_final_rate_rad_s = 0.5 and max_final_rate_deg_s = 1 bound the "
            "same rate",
        ),
    ],
)
def test_a_bad_constraint_is_refused_at_its_own_key(
    api: Api, constraints: dict[str, float], loc: list[str], fragment: str
) -> None:
    """A bound the core's rules refuse was located at ``params`` alone, away from the
    other constraint refusals (at ``params.constraints``); now at its key, and a rule
    between two bounds at ``constraints``."""
    scenario_id = api.create_scenario()["id"]
    response = api.submit("search", scenario_id, params={"constraints": constraints})
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == ["body", "params", *loc]
    assert error["msg"].startswith(fragment) and error["type"] == "value_error"
    assert api.queued_messages() == []


def test_a_rate_bound_below_the_initial_rate_spread_is_422_naming_both(api: Api) -> None:
    # Accepted before, it ran to "no sequence met the constraints": the spread of the rate
    # at the start alone leaves a mean of 0.2286 deg/s, whatever the sequence.
    paper = Scenario.model_validate(api.create_scenario()["document"])
    uncertainty = {**paper.uncertainty.model_dump(), "initial_rate_sigma_rad_s": 0.0025}
    scenario_id = api.create_scenario(name="spread", uncertainty=uncertainty)["id"]
    params = {"method": "nsga2", "constraints": {"max_final_rate_deg_s": 0.2}}
    response = api.submit("search", scenario_id, params=params)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"][-1] == "constraints"
    assert "max_final_rate_deg_s = 0.2 deg/s" in error["msg"]
    assert "0.2286 deg/s for initial_rate_sigma_rad_s = 0.0025" in error["msg"]
    assert api.queued_messages() == []
    params = {"method": "nsga2", "constraints": {"max_final_rate_deg_s": 0.25}}
    assert api.submit("search", scenario_id, params=params).status_code == 202


def test_a_commanded_residual_bound_below_the_initial_rate_spread_is_accepted(api: Api) -> None:
    """The commanded residual is predicted from rest: |ω(0)| is not in it, so a bound
    below the floor a final-rate bound is refused under (0.2286 deg/s here) is met by a
    sequence that brakes, and accepted, in both units and on the mean or the worst
    candidate. Before, each name was a 422 "unknown constraint"."""
    paper = Scenario.model_validate(api.create_scenario()["document"])
    uncertainty = {**paper.uncertainty.model_dump(), "initial_rate_sigma_rad_s": 0.0025}
    scenario_id = api.create_scenario(name="spread", uncertainty=uncertainty)["id"]
    for name, bound in (
        ("max_commanded_residual_rate_deg_s", 0.2),
        ("max_commanded_residual_rate_rad_s", 0.0035),
        ("max_commanded_residual_rate_max_deg_s", 0.2),
        ("max_commanded_residual_rate_max_rad_s", 0.0035),
    ):
        for method in ("nsga2", "ppo"):
            params = {"method": method, "constraints": {name: bound}}
            response = api.submit("search", scenario_id, params=params)
            assert response.status_code == 202, response.text
            job = api.get(f"/jobs/{response.json()['id']}").json()
            assert job["params"]["constraints"] == {name: bound}


@pytest.mark.parametrize("method", ["random", "nsga2"])
def test_a_search_of_one_realisation_per_candidate_is_refused(api: Api, method: str) -> None:
    """One realisation per candidate makes every clustering perfect (one series per
    cluster): a random search with ``n_realisations = 1`` ran and reported its best F1
    and its fresh F1 as 1.000 (min 1.000) while its sequence's accuracy at the design
    noise was 0.32, barely above chance (0.2 for 5 candidates); an NSGA-II search's fresh
    F1 read 1.000 beside an accuracy of 0.72. The job list sorts such a search first by
    fresh F1. It is refused naming n_realisations, as a training below its kind's least
    is (helper-174's review)."""
    scenario_id = api.create_scenario()["id"]
    params = {"method": method, "sequence_length": 2, "n_realisations": 1}
    if method == "random":
        params["timesteps"] = 64
    response = api.submit("search", scenario_id, params=params)
    assert response.status_code == 422, response.text
    assert "n_realisations" in json.dumps(response.json()["detail"])
    assert api.queued_messages() == []
