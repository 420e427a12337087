"""POST /identify: the start search asked for, the hint of a start near the stated one,
the inputs echoed, and a large upload parsed off the event loop."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest

from inertia_id import InertiaClassifier, Scenario, simulate

from .support import GOOD_SEQUENCE, Api


@pytest.fixture(scope="module")
def quiet_around(paper: Scenario) -> dict[str, list[Any]]:
    """Candidate 1 with 2 s of quiet before the sequence and 2 s after, at 20 Hz."""
    quiet = [[0] * paper.n_thrusters]
    result = simulate(paper, quiet * 2 + GOOD_SEQUENCE + quiet * 2, 1, np.random.default_rng(8))
    return {
        "time_s": (result.time_s - 2.0).tolist(),
        "omega_rad_s": result.omega_measured[1, 0].tolist(),
    }


def csv_of(series: dict[str, list[Any]]) -> str:
    rows = ["time_s,wx,wy,wz"]
    rows += [
        ",".join(repr(float(v)) for v in (t, *w))
        for t, w in zip(series["time_s"], series["omega_rad_s"], strict=True)
    ]
    return "\n".join(rows) + "\n"


@pytest.fixture
def classifier_id(api: Api, classifier: InertiaClassifier) -> str:
    return api.insert_classifier(api.create_scenario()["id"], classifier)


def test_the_start_search_as_json_and_form_and_its_refusals(
    api: Api, classifier_id: str, quiet_around: dict[str, list[Any]], paper: Scenario
) -> None:
    truth = paper.candidate_names[1]
    late = {**quiet_around, "sequence_start": 0.3}  # stated 6 samples after the true start
    body = {"classifier_id": classifier_id, "telemetry": late}
    plain = api.post("/identify", json=body)
    assert plain.status_code == 200, plain.text
    # The verdict is the stated start's; its text says a start 0.3 s earlier matches.
    assert plain.json()["status"] == "matches-none"
    assert plain.json()["start_hint_candidate"] == truth
    assert plain.json()["start_hint_shift_s"] == pytest.approx(-0.3, abs=0.051)
    assert "estimate_start_within_s" in plain.json()["verdict"]
    searched = api.post("/identify", json={**body, "estimate_start_within_s": 0.5})
    assert searched.status_code == 200, searched.text
    found = searched.json()
    assert (found["status"], found["candidate"]) == ("identified", truth)
    # Within a grid period: the grid's best start is a period late (-0.25 s; the stated
    # start is 0.3 s late, so 6 of the 40 samples in this pass's 2 s before it are the
    # sequence's), and its score and its neighbours' bracket no minimum, so it is kept,
    # not refined (README *Start below the grid period*).
    assert found["sequence_start_shift_s"] == pytest.approx(-0.3, abs=0.051)
    assert isinstance(found["sequence_start_refined"], bool)
    assert found["estimate_start_within_s"] == 0.5
    assert found["sequence_start"] == pytest.approx(0.3 + found["sequence_start_shift_s"])
    form = api.post(
        "/identify",
        data={
            "classifier_id": classifier_id,
            "sequence_start": "0.3",
            "estimate_start_within_s": "0.5",
        },
        files={"file": ("t.csv", csv_of(quiet_around))},
    )
    assert form.status_code == 200, form.text
    assert form.json()["sequence_start_shift_s"] == found["sequence_start_shift_s"]
    assert form.json()["candidate"] == truth
    for bad in ("-1", "1000", "soon"):
        refused = api.post(
            "/identify",
            data={"classifier_id": classifier_id, "estimate_start_within_s": bad},
            files={"file": ("t.csv", csv_of(quiet_around))},
        )
        assert refused.status_code == 422, refused.text
        assert (
            f"estimate_start_within_s must be a number of seconds in [0, 100], got '{bad}'"
            in refused.text
        )
    for bad_number in (-1, 1000):
        refused = api.post("/identify", json={**body, "estimate_start_within_s": bad_number})
        assert refused.status_code == 422 and "estimate_start_within_s" in refused.text
    partial = api.post("/identify/partial", json={**body, "estimate_start_within_s": 0.5})
    assert partial.status_code == 422 and "POST /identify only, got 0.5" in partial.text


def test_the_verdict_and_its_csv_echo_the_start_and_the_span(
    api: Api, classifier_id: str, quiet_around: dict[str, list[Any]]
) -> None:
    telemetry = {
        "time_s": [810000000.0 + t for t in quiet_around["time_s"]],
        "omega_rad_s": quiet_around["omega_rad_s"],
    }
    body = {"classifier_id": classifier_id, "telemetry": telemetry, "sequence_start": 810000000.0}
    verdict = api.post("/identify", json=body).json()
    assert verdict["sequence_start"] == 810000000.0
    assert verdict["telemetry_first_stamp"] == telemetry["time_s"][0]
    assert verdict["telemetry_last_stamp"] == telemetry["time_s"][-1]
    assert verdict["telemetry_samples"] == len(telemetry["time_s"]) == 160
    assert verdict["telemetry_span_s"] == pytest.approx([-1.95, 6.0])
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    assert "# sequence_start: 810000000.0\n" in table.text
    assert f"# telemetry_first_stamp: {telemetry['time_s'][0]!r}\n" in table.text
    assert "# telemetry_samples: 160\n" in table.text
    assert "# sequence_start_shift_s: 0.0\n" in table.text


def test_a_slow_parse_leaves_the_event_loop_to_other_requests(
    api: Api,
    classifier_id: str,
    quiet_around: dict[str, list[Any]],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """While one upload is parsed, /health is answered: on the event loop the parse made
    every request wait (a 78,000-row CSV held /health 3-6 s)."""
    import app.api.identify as api_identify

    parsing, release, parsed = threading.Event(), threading.Event(), threading.Event()
    real_parse = api_identify.parse_telemetry

    def slow_parse(*args: Any, **kwargs: Any) -> Any:
        parsing.set()
        # Waits for the test to release it; the limit only ends a test that failed.
        release.wait(timeout=15)
        parsed.set()
        return real_parse(*args, **kwargs)

    monkeypatch.setattr(api_identify, "parse_telemetry", slow_parse)
    answers: list[Any] = []
    upload = threading.Thread(
        target=lambda: answers.append(
            api.post(
                "/identify",
                data={"classifier_id": classifier_id},
                files={"file": ("t.csv", csv_of(quiet_around))},
            )
        )
    )
    upload.start()
    try:
        assert parsing.wait(timeout=15)
        health = api.client.get("/health")
        answered_while_parsing = not parsed.is_set()
    finally:
        release.set()
        upload.join()
    assert health.status_code in (200, 503)
    assert answered_while_parsing
    assert answers[0].status_code == 200, answers[0].text


def test_a_start_search_on_a_whole_series_kind_says_in_words_it_is_unrefined(
    api: Api, classifier_id: str, quiet_around: dict[str, list[Any]], paper: Scenario
) -> None:
    """A clustering classifier keeps the grid start its distance favours: the answer
    said so only by ``sequence_start_refined: false`` (the CLI warned in words); it says
    it in ``sequence_start_note``, in the JSON and the CSV, and a likelihood kind, which
    refines the start, has no note."""
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    body = {
        "classifier_id": classifier_id,
        "telemetry": {**quiet_around, "sequence_start": 0.3},
        "estimate_start_within_s": 0.5,
    }
    found = api.post("/identify", json=body).json()
    assert found["sequence_start_refined"] is False
    shift = f"{found['sequence_start_shift_s']:+.6g}"
    assert found["sequence_start_note"] == (
        f"the 'clustering' kind compares whole series: the start taken ({shift} s) is the "
        "0.05 s grid's that its distance favours, not refined below the grid period, and "
        "may lie a period or two off the true one (README's example: 0.25 s for a 0.2 s "
        "late start); the likelihood kinds (marginal-likelihood, the default, or "
        "likelihood) refine it"
    )
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    assert f"# sequence_start_note: {found['sequence_start_note']}\n" in table.text
    schema = api.get("/openapi.json").json()["components"]["schemas"]["IdentifyResult"]
    assert "sequence_start_note" in schema["properties"]
    assert (
        api.post("/identify", json={**body, "estimate_start_within_s": None}).json()[
            "sequence_start_note"
        ]
        is None
    )
    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    likelihood_id = api.insert_classifier(api.create_scenario()["id"], model)
    refined = api.post("/identify", json={**body, "classifier_id": likelihood_id}).json()
    assert refined["estimate_start_within_s"] == 0.5
    assert refined["sequence_start_note"] is None


def test_a_csv_in_deg_s_without_its_unit_is_hinted_at(
    api: Api, classifier_id: str, quiet_around: dict[str, list[Any]], paper: Scenario
) -> None:
    """A flight team's gyro export in deg/s, uploaded with no header (so read as rad/s),
    is a verdict of no candidate that says which one the rates match in deg/s, in the
    JSON and in the CSV; labelled wx_deg_s it is identified."""
    truth = paper.candidate_names[1]
    in_degrees = {
        "time_s": quiet_around["time_s"],
        "omega_rad_s": np.degrees(quiet_around["omega_rad_s"]).tolist(),
    }
    text = csv_of(in_degrees).split("\n", 1)[1]  # no header: rad/s
    form = {"classifier_id": classifier_id, "sequence_start": "0"}
    wrong = api.post("/identify", data=form, files={"file": ("pass.csv", text)})
    assert wrong.status_code == 200, wrong.text
    verdict = wrong.json()
    assert verdict["status"] != "identified" and verdict["matches_none"]
    assert (verdict["unit_hint_candidate"], verdict["unit_hint_rates_unit"]) == (truth, "deg/s")
    assert "if its rates are in deg/s" in verdict["verdict"]
    table = api.post("/identify?format=csv", data=form, files={"file": ("pass.csv", text)})
    assert table.status_code == 200, table.text
    assert f"# unit_hint: the telemetry matches {truth!r}" in table.text
    labelled = api.post(
        "/identify",
        data=form,
        files={"file": ("pass.csv", "time_s,wx_deg_s,wy_deg_s,wz_deg_s\n" + text)},
    )
    assert labelled.status_code == 200, labelled.text
    assert (labelled.json()["status"], labelled.json()["candidate"]) == ("identified", truth)
    assert labelled.json()["unit_hint"] is None


def test_a_start_search_that_misses_the_start_says_so(
    api: Api, classifier_id: str, quiet_around: dict[str, list[Any]]
) -> None:
    """The start stated 1.5 s before the thrusters fired, searched within ±1 s: the answer
    says its start lies at the window's edge with a better one beyond, and how wide to
    search, in its JSON and its CSV notes (nothing said so before); the status stays."""
    body = {
        "classifier_id": classifier_id,
        "telemetry": {**quiet_around, "sequence_start": -1.5},
        "estimate_start_within_s": 1.0,
    }
    response = api.post("/identify", json=body)
    assert response.status_code == 200, response.text
    verdict = response.json()
    assert verdict["sequence_start_shift_s"] == pytest.approx(1.0)
    assert verdict["start_window_better_shift_s"] > 1.0
    assert "lies at the edge of the ±1 s searched" in verdict["start_window_hint"]
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    notes = dict(
        line[2:].split(": ", 1) for line in table.text.splitlines() if line.startswith("# ")
    )
    assert notes["start_window_hint"] == verdict["start_window_hint"]
    wider = verdict["start_window_hint"].split("window to ±")[1].split(" s")[0]
    found = api.post("/identify", json={**body, "estimate_start_within_s": float(wider)})
    assert found.status_code == 200, found.text
    assert found.json()["start_window_hint"] is None
    assert found.json()["sequence_start_shift_s"] == pytest.approx(1.5, abs=0.051)
