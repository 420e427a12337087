"""The command line and the worker give the same numbers for the same inputs and seed.

Both call the same pipelines (:mod:`inertia_id.pipelines`) with the same seeding; here
the worker runs its real handler through the job runner on a real database, and the
CLI runs in-process, from the same scenario, params and seed.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from cli_support import run_cli, run_cli_json
from scenario_support import GOOD_SEQUENCE

from inertia_id.deadline import time_limit_grace_s
from service.store import ClassifierRow
from worker.runner import execute_job

if TYPE_CHECKING:
    from conftest import Store

WORKER = "parity@host"
GOOD_TEXT = ";".join(",".join(map(str, row)) for row in GOOD_SEQUENCE)


def run_job(store: Store, job_type: str, params: dict[str, Any], seed: int) -> dict[str, Any]:
    job_id = store.add_job(job_type, params, seed=seed)
    assert execute_job(job_id, settings=store.settings, worker_name=WORKER) == "succeeded", (
        store.job(job_id).error
    )
    result = store.job(job_id).result
    assert result is not None
    return result


@pytest.mark.parametrize(
    ("cli", "params"),
    [
        (["--metric", "euclidean"], {"metric": "euclidean"}),
        ([], {}),  # no kind, no metric: the default kind, on both sides
    ],
)
def test_train_gives_the_same_classifier(
    store: Store, tmp_path: Path, cli: list[str], params: dict[str, Any]
) -> None:
    cli_document, _ = run_cli_json(
        ["train", "--sequence", GOOD_TEXT, "-n", "6", "--seed", "4", *cli],
        tmp_path / "classifier.json",
    )
    result = run_job(
        store, "train", {"sequence": GOOD_SEQUENCE, "n_realisations": 6, **params}, seed=4
    )
    with store.db.session() as session:
        row = session.get(ClassifierRow, result["classifier_id"])
        assert row is not None
        document = row.document
    assert json.loads(document) == cli_document


def test_sweep_gives_the_same_points(store: Store, tmp_path: Path) -> None:
    classifier = tmp_path / "classifier.json"
    run_cli(
        [
            "train",
            "--metric",
            "euclidean",
            "--sequence",
            GOOD_TEXT,
            "-n",
            "6",
            "--seed",
            "1",
            "--out",
            str(classifier),
        ]
    )
    trained = run_job(
        store,
        "train",
        {"sequence": GOOD_SEQUENCE, "metric": "euclidean", "n_realisations": 6},
        seed=1,
    )
    cli, _ = run_cli_json(
        [
            "sweep",
            "--classifier",
            str(classifier),
            "--multiples",
            "1,6",
            "--noise",
            "process",
            "--noise",
            "thrust_scale",
            "--others",
            "least-squares,1nn:euclidean",
            "--limit-realisations",
            "3",
            "--n-train",
            "4",
            "--n-test",
            "20",
            "--seed",
            "7",
        ],
        tmp_path / "sweep.json",
    )
    params = {
        "classifier_id": trained["classifier_id"],
        "multiples": [1.0, 6.0],
        "noises": ["process", "thrust_scale"],
        "others": ["least-squares", "1nn:euclidean"],
        "limit_realisations": 3,
        "n_train": 4,
        "n_test": 20,
    }
    swept = run_job(store, "sweep", params, seed=7)
    assert swept == cli
    # Both swept the bodies off the candidates too: one default, the pipeline's.
    assert (
        cli["inertia"]["points"]
        and cli["limit"]
        and set(cli["others"])
        == {
            "least-squares",
            "1nn:euclidean",
        }
    )


def test_a_small_search_finds_the_same_sequence(store: Store, tmp_path: Path) -> None:
    cli, _ = run_cli_json(
        [
            "search",
            "--method",
            "random",
            "--length",
            "2",
            "--timesteps",
            "8",
            "--search-realisations",
            "3",
            "--search-metric",
            "euclidean",
            "--seed",
            "5",
        ],
        tmp_path / "search.json",
    )
    params = {
        "method": "random",
        "sequence_length": 2,
        "timesteps": 8,
        "n_realisations": 3,
        "metric": "euclidean",
    }
    found = run_job(store, "search", params, seed=5)
    for side in (found, cli):
        side.pop("wall_time_s")
    # A job runs under the service's ceiling on run time; the command line has none.
    assert found["settings"].pop("time_limit_s") == store.settings.job_time_limit_s
    assert cli["settings"].pop("time_limit_s") is None
    grace = found["settings"].pop("time_limit_grace_s")
    assert grace == time_limit_grace_s(store.settings.job_time_limit_s)
    assert cli["settings"].pop("time_limit_grace_s") is None
    assert found == cli
    from inertia_id.physics.sequences import BASELINES

    assert set(cli["baselines"]) == set(BASELINES)
