"""Identification of simulated telemetry, as JSON and as a CSV upload; bad telemetry."""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cli_support import run_cli

from app.classifier_cache import ClassifierCache
from inertia_id import InertiaClassifier, Scenario, SimulationResult, simulate
from inertia_id.evaluation.telemetry import same_sequence_start

from .support import GOOD_SEQUENCE, Api


@pytest.fixture(scope="module")
def flight(paper: Scenario) -> SimulationResult:
    """One fresh noisy response per candidate, never seen in training."""
    return simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(7))


def telemetry(flight: SimulationResult, k: int) -> dict[str, Any]:
    return {
        "time_s": flight.time_s.tolist(),
        "omega_rad_s": flight.omega_measured[k, 0].tolist(),
    }


def csv_text(time_s: Any, omega: Any) -> str:
    rows = ["time_s,wx,wy,wz"]
    rows += [",".join(repr(float(v)) for v in (t, *w)) for t, w in zip(time_s, omega, strict=True)]
    return "\n".join(rows) + "\n"


@pytest.fixture
def classifier_id(api: Api, classifier: InertiaClassifier) -> str:
    return api.insert_classifier(api.create_scenario()["id"], classifier)


@pytest.mark.parametrize("k", [0, 3])
def test_json_identifies_the_candidate(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario, k: int
) -> None:
    response = api.post(
        "/identify", json={"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
    )
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["classifier_id"] == classifier_id
    assert result["candidate_index"] == k
    assert result["candidate"] == paper.candidate_names[k]
    assert result["inertia_kg_m2"] == paper.inertia_candidates[k].inertia_kg_m2
    assert set(result["distances"]) == set(paper.candidate_names)
    nearest = min(result["distances"].values())
    assert result["distances"][paper.candidate_names[k]] == nearest
    assert result["margin"] > 0
    assert result["matches_none"] is False
    assert result["verdict"] == paper.candidate_names[k]


def test_csv_upload_identifies_the_candidate(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    k = 2
    text = csv_text(flight.time_s, flight.omega_measured[k, 0])
    response = api.post(
        "/identify",
        data={"classifier_id": classifier_id},
        files={"file": ("telemetry.csv", text.encode(), "text/csv")},
    )
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["candidate"] == paper.candidate_names[k]
    assert result["matches_none"] is False
    as_json = api.post(
        "/identify", json={"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
    ).json()
    assert result["distances"] == pytest.approx(as_json["distances"])


def test_an_averaging_gyro_is_said_in_the_json_or_the_form(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """``averaged``: each rate the mean over the interval before its stamp. JSON and CSV
    say it the same way, and anything but true or false is refused by name."""
    means = flight.omega_measured[1, 0].reshape(4, 20, 3).mean(axis=1)
    stamps = [1.0, 2.0, 3.0, 4.0]
    body = {"time_s": stamps, "omega_rad_s": means.tolist(), "averaged": True}
    as_json = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": body})
    assert as_json.status_code == 200, as_json.text
    text = csv_text(np.array(stamps), means)
    form = api.post(
        "/identify",
        data={"classifier_id": classifier_id, "averaged": "true"},
        files={"file": ("t.csv", text)},
    )
    assert form.status_code == 200, form.text
    assert form.json()["distances"] == pytest.approx(as_json.json()["distances"])
    assert form.json()["candidate"] == as_json.json()["candidate"]
    read_at_stamps = api.post(
        "/identify", data={"classifier_id": classifier_id}, files={"file": ("t.csv", text)}
    )
    assert read_at_stamps.json()["distances"] != pytest.approx(as_json.json()["distances"])
    bad = api.post(
        "/identify",
        data={"classifier_id": classifier_id, "averaged": "yes"},
        files={"file": ("t.csv", text)},
    )
    assert bad.status_code == 422 and "averaged must be true or false, got 'yes'" in bad.text


def test_classifier_is_cached(api: Api, classifier_id: str, flight: SimulationResult) -> None:
    # The verdict process keeps the classifier; the API remembers only its checksum.
    verdicts = api.app.state.verdicts
    assert verdicts is not None
    for k in (0, 1):
        body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
        assert api.post("/identify", json=body).status_code == 200
    assert verdicts.loads() == 1
    cache: ClassifierCache = api.app.state.classifier_cache
    assert cache.stored_of(classifier_id) is not None and len(cache) == 0


def test_a_verdict_names_the_classifier_that_judged_as_the_cli_s_does(
    api: Api, classifier: InertiaClassifier, flight: SimulationResult, tmp_path: Path
) -> None:
    """The API's verdict named only ``classifier_id``: a verdict a flight team keeps could
    not tell which stored classifier judged (its checksum, the training job). It names
    ``classifier`` too, with the fields the CLI's verdict on the downloaded file names
    (sha256 and provenance, created_at in UTC with its zone) and the kind, and the schema
    documents them."""
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier, with_job=True)
    stored = api.get(f"/classifiers/{classifier_id}").json()
    job_id = stored["job_id"]
    assert job_id is not None
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, 0)}
    verdict = api.post("/identify", json=body).json()
    assert verdict["classifier"] == {
        "sha256": stored["sha256"],
        "kind": stored["kind"],
        "provenance": {
            "classifier_id": classifier_id,
            "job_id": job_id,
            "scenario_id": scenario_id,
            "created_at": stored["created_at"],
        },
    }
    assert datetime.fromisoformat(
        verdict["classifier"]["provenance"]["created_at"]
    ).utcoffset() == (timedelta(0))
    # The second request is answered from the remembered look-up: the same names.
    assert api.post("/identify", json=body).json()["classifier"] == verdict["classifier"]
    document = tmp_path / "classifier.json"
    document.write_bytes(api.get(f"/classifiers/{classifier_id}/download").content)
    series = tmp_path / "t.csv"
    series.write_text(csv_text(flight.time_s, flight.omega_measured[0, 0]))
    cli = run_cli(["identify", "--classifier", str(document), "--telemetry", str(series)])
    named = json.loads(cli.stdout)["classifier"]
    assert named["sha256"] == verdict["classifier"]["sha256"]
    assert named["provenance"] == verdict["classifier"]["provenance"]
    schema = api.get("/openapi.json").json()["components"]["schemas"]
    for name in ("IdentifyResult", "PartialIdentifyResult"):
        assert name in schema and "classifier" in schema[name]["required"], name
    fields = schema["JudgingClassifier"]["properties"]
    assert all(fields[key].get("description") for key in ("sha256", "kind")), fields
    provenance = schema["ClassifierProvenance"]["properties"]
    assert "UTC" in provenance["created_at"]["description"]


def test_the_verdict_process_answers_as_the_compute_threads(
    api: Api,
    make_api: Callable[..., Api],
    classifier_id: str,
    flight: SimulationResult,
) -> None:
    """Identify and the partial posterior computed in the verdict process (as shipped)
    and, with it off, on the API's compute threads: the same answers."""
    threads = make_api(api.settings.model_copy(update={"verdict_process": "off"}), api.key)
    assert api.app.state.verdicts is not None and threads.app.state.verdicts is None
    for k in (1, 4):
        body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
        for path in ("/identify", "/identify/partial"):
            there = api.post(path, json=body)
            here = threads.post(path, json=body)
            # (This classifier kind has no partial posterior: the same 422 from both.)
            expected = 200 if path == "/identify" else 422
            assert there.status_code == here.status_code == expected, (there.text, here.text)
            assert there.json() == here.json()
    unknown = {"classifier_id": "0" * 32, "telemetry": telemetry(flight, 0)}
    assert api.post("/identify", json=unknown).status_code == 404
    assert threads.post("/identify", json=unknown).status_code == 404


def test_a_killed_verdict_process_costs_one_503_and_is_replaced(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, 2)}
    assert api.post("/identify", json=body).status_code == 200
    verdicts = api.app.state.verdicts
    first = verdicts.pid()
    os.kill(first, signal.SIGKILL)
    deadline = time.monotonic() + 60
    codes = []
    while time.monotonic() < deadline:
        answer = api.post("/identify", json=body)
        codes.append(answer.status_code)
        if answer.status_code == 200:
            break
        assert answer.status_code == 503, answer.text
        assert int(answer.headers["Retry-After"]) >= 1
        assert "restarting" in answer.json()["detail"]
        time.sleep(0.2)
    assert codes[0] == 503 and codes[-1] == 200 and codes.count(503) <= 2, codes
    assert verdicts.restarts == 1 and verdicts.pid() != first
    assert answer.json()["candidate_index"] == 2


def test_a_verdict_past_its_time_kills_the_verdict_process_with_a_503(
    api: Api, make_api: Callable[..., Api], classifier_id: str, flight: SimulationResult
) -> None:
    """A hung verdict process would hold its requests for good: past the timeout it is
    killed and the request answered 503 (here the timeout is shorter than any verdict)."""
    hasty = make_api(api.settings.model_copy(update={"verdict_timeout_s": 0.001}), api.key)
    verdicts = hasty.app.state.verdicts
    first = verdicts.pid()
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, 0)}
    answer = hasty.post("/identify", json=body)
    assert answer.status_code == 503, answer.text
    assert "took over 0.001 s" in answer.json()["detail"]
    assert int(answer.headers["Retry-After"]) >= 1
    assert verdicts.restarts == 1  # replaced at once, not on the next request
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and os.path.exists(f"/proc/{first}/stat"):
        try:
            with open(f"/proc/{first}/stat") as stat:
                if stat.read().rpartition(")")[2].split()[0] == "Z":
                    break
        except FileNotFoundError:
            break  # reaped between the check and the read: gone, as wanted
        time.sleep(0.1)
    else:
        assert not os.path.exists(f"/proc/{first}/stat"), "the hung child is still running"
    # The service's own timeout still answers verdicts.
    assert api.post("/identify", json=body).status_code == 200


def test_cache_evicts_the_least_recently_used() -> None:
    cache = ClassifierCache(2)
    loads: list[str] = []

    def loader(name: str) -> Any:
        def load() -> Any:
            loads.append(name)
            return name

        return load

    for name in ("a", "b", "a", "c", "a", "b"):
        cache.get((name, ""), loader(name))
    # a, b loaded; a hit; c evicts b; a hit; b reloaded (evicting c).
    assert loads == ["a", "b", "c", "b"]
    assert ("a", "") in cache and ("b", "") in cache and ("c", "") not in cache


@pytest.mark.parametrize(
    ("time_token", "omega_token", "fragment"),
    [
        ("NaN", "0.0", "time_s[1] = nan is not finite"),
        ("0.1", "Infinity", "omega_rad_s[1][2] = inf is not finite"),
        ("0.1", "-Infinity", "omega_rad_s[1][2] = -inf is not finite"),
        ("0.1", "NaN", "omega_rad_s[1][2] = nan is not finite"),
    ],
)
def test_non_finite_telemetry_is_422(
    api: Api, classifier_id: str, time_token: str, omega_token: str, fragment: str
) -> None:
    body = (
        f'{{"classifier_id": "{classifier_id}", "telemetry": {{"time_s": [0.05, {time_token}, '
        f'0.15], "omega_rad_s": [[0, 0, 0], [0, 0, {omega_token}], [0, 0, 0]]}}}}'
    )
    response = api.post_raw_json("/identify", body)
    assert response.status_code == 422, response.text
    assert fragment in " | ".join(e["msg"] for e in response.json()["detail"])


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        pytest.param(
            "time_s,wx,wy,wz\n0.05,0,0,0\n0.10,0,nan,0\n0.15,0,0,0\n",
            "omega_rad_s[1][1] = nan is not finite",
            id="non-finite",
        ),
        # A lone carriage return makes Python's csv module raise csv.Error (found by fuzzing).
        pytest.param(
            "time_s,wx,wy,wz\n0.05,0,0\r,0\n0.10,0,0,0\n", "not valid CSV", id="malformed"
        ),
        pytest.param(
            "time_s,wx,wy\n0.05,0,0\n0.10,0,0\n", "has 3 columns, expected 4", id="3-columns"
        ),
        # float() reads 1_0 as 10 and full-width digits as digits: no one writes them.
        pytest.param(
            "time_s,wx,wy,wz\n0.05,0,0,0\n0.10,0,1_0e-3,0\n0.15,0,0,0\n",
            "CSV data row 2 is not numeric: '1_0e-3' is not a decimal number",
            id="underscore",
        ),
        pytest.param(
            "time_s,wx,wy,wz\n0.05,0,0,0\n1_0,0,0,0\n0.15,0,0,0\n",
            "CSV data row 2: time '1_0' is neither seconds nor",
            id="underscore-time",
        ),
        pytest.param(
            "time_s,wx,wy,wz\n0.05,0,0,0\n0.10,\uff11e-3,0,0\n0.15,0,0,0\n",
            "'\uff11e-3' is not a decimal number",
            id="full-width",
        ),
    ],
)
def test_bad_csv_is_422(api: Api, classifier_id: str, text: str, fragment: str) -> None:
    response = api.post(
        "/identify", data={"classifier_id": classifier_id}, files={"file": ("t.csv", text)}
    )
    assert response.status_code == 422
    assert fragment in response.json()["detail"][0]["msg"]


def test_wrong_column_count_is_422(api: Api, classifier_id: str) -> None:
    """The JSON form; the CSV form is test_bad_csv_is_422[3-columns]."""
    body = {
        "classifier_id": classifier_id,
        "telemetry": {"time_s": [0.05, 0.1], "omega_rad_s": [[0, 0, 0], [0, 0]]},
    }
    response = api.post("/identify", json=body)
    assert response.status_code == 422
    assert "omega_rad_s row 1 has 2 columns, expected 3" in response.json()["detail"][0]["msg"]


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ({"time_s": [0.1, 0.1, 0.2]}, "time stamps must increase strictly"),
        ({"time_s": [0.1]}, "at least 2 samples"),
        ({"time_s": [0.05, 0.1, 0.15, 0.2]}, "4 time stamps but 3 omega rows"),
        ({"time_s": [0.05, 0.10, 0.15]}, "telemetry spans 0.05 s to 0.15 s"),
    ],
)
def test_bad_telemetry_is_422(
    api: Api, classifier_id: str, change: dict[str, Any], fragment: str
) -> None:
    series = {"time_s": [0.05, 0.10, 0.15], "omega_rad_s": [[0, 0, 0]] * 3, **change}
    response = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": series})
    assert response.status_code == 422, response.text
    assert fragment in " | ".join(e["msg"] for e in response.json()["detail"])


def test_unknown_classifier_is_404(api: Api, flight: SimulationResult) -> None:
    missing = "0123456789abcdef0123456789abcdef"
    response = api.post(
        "/identify", json={"classifier_id": missing, "telemetry": telemetry(flight, 0)}
    )
    assert response.status_code == 404
    text = csv_text(flight.time_s, flight.omega_measured[0, 0])
    response = api.post(
        "/identify", data={"classifier_id": missing}, files={"file": ("t.csv", text)}
    )
    assert response.status_code == 404


def test_malformed_requests(api: Api, classifier_id: str) -> None:
    not_json = api.post_raw_json("/identify", b"{not json")
    assert not_json.status_code == 422
    assert "not valid JSON" in not_json.json()["detail"][0]["msg"]
    plain = api.client.post(
        "/identify", content=b"hello", headers={**api.auth, "content-type": "text/plain"}
    )
    assert plain.status_code == 415
    no_file = api.post("/identify", data={"classifier_id": classifier_id}, files={"x": ("a", "")})
    assert no_file.status_code == 422
    assert "file" in no_file.json()["detail"][0]["msg"]


def test_a_cold_classifier_is_loaded_once_however_many_ask_at_once() -> None:
    import threading
    import time as clock

    from app.classifier_cache import ClassifierCache

    cache = ClassifierCache(4)
    loads: list[int] = []

    def slow_load() -> Any:
        loads.append(1)
        clock.sleep(0.2)  # a 2 MB document being parsed while the others ask
        return object()

    barrier = threading.Barrier(8)
    got: list[Any] = []

    def ask() -> None:
        barrier.wait()
        got.append(cache.get(("c1", "sha"), slow_load))

    threads = [threading.Thread(target=ask) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(loads) == 1 and cache.loads == 1
    assert len({id(model) for model in got}) == 1


def test_a_classifiers_checksum_is_remembered_for_a_while_only() -> None:
    from app.classifier_cache import ClassifierCache, StoredClassifier

    now = [0.0]
    cache = ClassifierCache(4, checksum_ttl_s=30.0, clock=lambda: now[0])
    assert cache.stored_of("c1") is None
    stored = StoredClassifier("c1", "abc", "clustering", None, "s1", datetime(2026, 1, 1))
    cache.remember_stored(stored)
    now[0] = 29.0
    assert cache.stored_of("c1") == stored
    now[0] = 31.0
    assert cache.stored_of("c1") is None


MISSION_START_S = 810_000_000.0


def test_mission_clock_and_iso_stamps_with_a_sequence_start(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    k = 1
    mission = {
        "time_s": (flight.time_s + MISSION_START_S).tolist(),
        "omega_rad_s": flight.omega_measured[k, 0].tolist(),
    }
    plain = api.post(
        "/identify", json={"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
    ).json()
    for body, query in (
        ({"telemetry": {**mission, "sequence_start": MISSION_START_S}}, ""),
        ({"telemetry": mission, "sequence_start": MISSION_START_S}, ""),
        ({"telemetry": mission}, f"?sequence_start={MISSION_START_S:.0f}"),
        ({"telemetry": mission, "sequence_start": MISSION_START_S}, "?sequence_start=810000000"),
        (
            {"telemetry": {**mission, "sequence_start": MISSION_START_S}},
            "?sequence_start=810000000.0",
        ),
    ):
        response = api.post(f"/identify{query}", json={"classifier_id": classifier_id, **body})
        assert response.status_code == 200, response.text
        assert response.json()["distances"] == pytest.approx(plain["distances"], rel=1e-6)
    stamps = [f"2025-03-01T12:00:{t:09.6f}Z" for t in flight.time_s]
    rows = ["time_utc,wx,wy,wz"] + [
        f"{s},{w[0]!r},{w[1]!r},{w[2]!r}"
        for s, w in zip(stamps, flight.omega_measured[k, 0].tolist(), strict=True)
    ]
    response = api.post(
        "/identify?sequence_start=2025-03-01T12:00:00Z",
        data={"classifier_id": classifier_id},
        files={"file": ("t.csv", "\n".join(rows))},
    )
    assert response.status_code == 200, response.text
    assert response.json()["candidate"] == paper.candidate_names[k]
    # The start as a form field beside the file (it was dropped silently), not twice;
    # a field the API does not read is refused by name.
    upload = {"file": ("t.csv", "\n".join(rows))}
    field = {"classifier_id": classifier_id, "sequence_start": "2025-03-01T12:00:00Z"}
    response = api.post("/identify", data=field, files=upload)
    assert response.status_code == 200, response.text
    assert response.json()["candidate"] == paper.candidate_names[k]
    twice = api.post("/identify?sequence_start=2025-03-01T12:00:00Z", data=field, files=upload)
    assert twice.status_code == 422 and "given both as a form field and in" in twice.text
    bad = api.post("/identify", data={**field, "sequence_start": "noon"}, files=upload)
    assert bad.status_code == 422 and bad.json()["detail"][0]["loc"] == ["body", "sequence_start"]
    unknown = api.post("/identify", data={**field, "units": "deg/s"}, files=upload)
    assert unknown.status_code == 422
    assert "unknown form field 'units'" in unknown.json()["detail"][0]["msg"]


def test_a_start_given_twice_must_name_the_same_moment(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """A start in the query, the body and the telemetry (or a JSON file and the form field
    beside it) that name different moments is refused, naming both: the query's used to
    win silently, reading the pass from a start its sender may not have meant."""
    mission = {
        "time_s": (flight.time_s + MISSION_START_S).tolist(),
        "omega_rad_s": flight.omega_measured[1, 0].tolist(),
    }
    cases = (
        ({"telemetry": mission, "sequence_start": 5.0}, "?sequence_start=810000000", "query"),
        (
            {"telemetry": {**mission, "sequence_start": 5.0}},
            "?sequence_start=810000000",
            "query",
        ),
        ({"telemetry": {**mission, "sequence_start": 5.0}, "sequence_start": 810e6}, "", "body"),
    )
    for body, query, where in cases:
        for path in ("/identify", "/identify/partial"):
            response = api.post(f"{path}{query}", json={"classifier_id": classifier_id, **body})
            assert response.status_code == 422, (path, body.keys(), response.text)
            detail = response.json()["detail"][0]
            assert detail["loc"][0] == where, detail
            assert "5.0" in detail["msg"] and "810000000" in detail["msg"], detail
            assert "give the start once" in detail["msg"], detail
    document = json.dumps({**mission, "sequence_start": 5.0})
    upload = {"file": ("t.json", document)}
    field = {"classifier_id": classifier_id, "sequence_start": "810000000"}
    response = api.post("/identify", data=field, files=upload)
    assert response.status_code == 422, response.text
    assert "give the start once" in response.text and "5.0" in response.text


def test_same_sequence_start_compares_moments() -> None:
    assert same_sequence_start(5, "5.0")
    assert same_sequence_start("2025-03-01T12:00:00Z", "2025-03-01t13:00:00+01:00")
    assert not same_sequence_start("2025-03-01T12:00:00Z", "2025-03-01T12:00:01Z")
    assert not same_sequence_start(5.0, "2025-03-01T12:00:00Z")
    assert not same_sequence_start("noon", "noon")


def test_a_missing_or_bad_sequence_start_is_422(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    mission = {
        "time_s": (flight.time_s + MISSION_START_S).tolist(),
        "omega_rad_s": flight.omega_measured[0, 0].tolist(),
    }
    missing = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": mission})
    assert missing.status_code == 422
    assert (
        "sequence_start is required: the first time stamp time_s[0] = 810000000.05"
        in (missing.json()["detail"][0]["msg"])
    )
    bad = api.post(
        "/identify?sequence_start=tomorrow",
        json={"classifier_id": classifier_id, "telemetry": mission},
    )
    assert bad.status_code == 422
    detail = bad.json()["detail"][0]
    assert detail["loc"] == ["query", "sequence_start"]
    assert "sequence_start = 'tomorrow' is not an ISO-8601 UTC time stamp" in detail["msg"]
    # float() reads 8_1e8 as 8.1e8: refused by name, not taken.
    underscore = api.post(
        "/identify?sequence_start=8_1e8",
        json={"classifier_id": classifier_id, "telemetry": mission},
    )
    assert underscore.status_code == 422
    detail = underscore.json()["detail"][0]
    assert detail["loc"] == ["query", "sequence_start"]
    assert "sequence_start = '8_1e8' is not a decimal number" in detail["msg"]
    text = csv_text(flight.time_s, flight.omega_measured[0, 0])
    form = api.post(
        "/identify",
        data={"classifier_id": classifier_id, "pre_start_window_s": "1_0"},
        files={"file": ("t.csv", text)},
    )
    assert form.status_code == 422
    assert form.json()["detail"][0]["msg"] == (
        "pre_start_window_s must be a number of seconds in [0, 3600], got '1_0'"
    )
    late = api.post(
        "/identify",
        json={"classifier_id": classifier_id, "telemetry": mission, "sequence_start": 8.1e8 + 1},
    )
    assert late.status_code == 422
    assert "a gap of 1 s before the end of the sequence" in late.json()["detail"][0]["msg"]


@pytest.mark.parametrize("repeated", ["confidence", "classifier_id", "file", "sequence_start"])
def test_a_form_field_given_twice_is_422_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult, repeated: str
) -> None:
    """Starlette's form keeps the last of repeated values: a verdict at a confidence, on
    a classifier or from a file other than the first one sent, without a word."""
    text = csv_text(flight.time_s, flight.omega_measured[1, 0])
    fields = {"classifier_id": classifier_id, "confidence": "0.9", "sequence_start": "0"}
    data: list[tuple[str, str]] = list(fields.items())
    files = [("file", ("first.csv", text))]
    if repeated == "file":
        files.append(("file", ("second.csv", text)))
    else:
        data.append((repeated, "0.5" if repeated == "confidence" else fields[repeated]))
    for path in ("/identify", "/identify/partial"):
        response = api.client.post(
            path,
            headers=api.auth,
            files=[*((name, (None, value)) for name, value in data), *files],
        )
        assert response.status_code == 422, response.text
        detail = response.json()["detail"][0]
        assert detail["loc"] == ["body", repeated]
        assert detail["msg"].startswith(f"form field {repeated!r} is given 2 times")
    once = api.post("/identify", data=fields, files=files[:1])
    assert once.status_code == 200, once.text


def test_the_verdict_carries_its_posterior_and_confidence(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, 1), "confidence": 0.9}
    response = api.post("/identify", json=body)
    assert response.status_code == 200, response.text
    result = response.json()
    assert result["status"] == "identified" and result["required_confidence"] == 0.9
    assert sum(result["posterior"].values()) + result["p_none"] == pytest.approx(1.0)
    assert result["confidence"] == max(result["posterior"].values()) >= 0.9
    bad = api.post("/identify", json={**body, "confidence": 1.5})
    assert bad.status_code == 422 and "confidence" in bad.text


def test_partial_telemetry_and_the_calibration_report(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    partial = {
        "time_s": flight.time_s[:30].tolist(),
        "omega_rad_s": flight.omega_measured[0, 0][:30].tolist(),
    }
    # The clustering has no Gaussian model of a leading block: the caller is told so.
    response = api.post(
        "/identify/partial", json={"classifier_id": classifier_id, "telemetry": partial}
    )
    assert response.status_code == 422 and "partial series" in response.text
    report = api.get(f"/classifiers/{classifier_id}/calibration")
    assert report.status_code == 200, report.text
    assert report.json()["temperature"] >= 1.0 and "ece" in report.json()
    assert api.get("/classifiers/nope/calibration").status_code == 404


def test_partial_telemetry_of_a_likelihood_classifier(
    api: Api, flight: SimulationResult, paper: Scenario
) -> None:
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(3), grid=AXES_GRID)
    found = api.insert_classifier(api.create_scenario()["id"], model)
    partial = {
        "time_s": flight.time_s[:60].tolist(),
        "omega_rad_s": flight.omega_measured[2, 0][:60].tolist(),
    }
    response = api.post("/identify/partial", json={"classifier_id": found, "telemetry": partial})
    assert response.status_code == 200, response.text
    result = response.json()
    assert len(result["time_s"]) == 60 and result["covers_s"] == pytest.approx(3.0)
    assert sum(result["current"].values()) + result["current_p_none"] == pytest.approx(1.0)
    if result["decided"]:
        assert result["candidate"] == paper.candidate_names[2]


@pytest.mark.parametrize(
    ("where", "start", "quoted"),
    [
        ("body", "true", ", got True"),
        ("body", "NaN", ", got nan"),
        ("body", "[1]", ""),
        ("body", '{"at": 1}', ""),
        # (NaN in the telemetry is a number, refused once there as not finite.)
        ("telemetry", "true", ", got True"),
        ("telemetry", "[1]", ""),
        ("telemetry", '{"at": 1}', ""),
    ],
)
def test_a_start_that_is_no_number_or_string_is_one_422_where_it_was_sent(
    api: Api, classifier_id: str, where: str, start: str, quoted: str
) -> None:
    """Pydantic refused each member of ``float | str`` at a key of its own, ``["body",
    "sequence_start", "float"]`` and ``[..., "str"]``, keys no client sent; a start beside
    the telemetry was refused a third time inside it, at ``["body", "telemetry",
    "sequence_start", ...]``. One error now, where the start was sent, naming both forms."""
    samples = '"time_s": [0, 1, 2], "omega_rad_s": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]'
    if where == "body":
        body = f'{{"classifier_id": "{classifier_id}", "sequence_start": {start}, '
        body += f'"telemetry": {{{samples}}}}}'
        loc = ["body", "sequence_start"]
    else:
        body = f'{{"classifier_id": "{classifier_id}", '
        body += f'"telemetry": {{{samples}, "sequence_start": {start}}}}}'
        loc = ["body", "telemetry", "sequence_start"]
    response = api.post_raw_json("/identify", body)
    assert response.status_code == 422, response.text
    (error,) = response.json()["detail"]
    assert error["loc"] == loc
    assert error["msg"].startswith("Input should be a ") and " or a valid string" in error["msg"]
    assert error["msg"].endswith(quoted)


def test_a_stamp_that_is_no_number_or_string_is_one_422_at_that_stamp(
    api: Api, classifier_id: str
) -> None:
    """``time_s[1] = true`` was refused at ``["body", "telemetry", "time_s", 1, "float"]``
    and ``[..., "str"]``."""
    body = f'{{"classifier_id": "{classifier_id}", "telemetry": {{"time_s": [0, true, 2], '
    body += '"omega_rad_s": [[0, 0, 0], [0, 0, 0], [0, 0, 0]]}}'
    for route in ("/identify", "/identify/partial"):
        response = api.post_raw_json(route, body)
        assert response.status_code == 422, response.text
        assert response.json()["detail"] == [
            {
                "loc": ["body", "telemetry", "time_s", 1],
                "msg": "Input should be a valid number or a valid string, got True",
                "type": "float_type",
            }
        ]


def test_telemetry_before_the_start_is_used_unless_asked_not_to(api: Api, paper: Scenario) -> None:
    # The default classifier measures the rate plus bias before the start (JSON body and
    # form field pre_start_window_s; 0 ignores that part); a bad window is a 422 that
    # quotes it, through the verdict process as through the compute threads.
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    found = api.insert_classifier(api.create_scenario()["id"], model)
    flown = [[0] * paper.n_thrusters] * 4 + GOOD_SEQUENCE
    result = simulate(paper, flown, 1, np.random.default_rng(5))
    series = {
        "time_s": (result.time_s - 4.0).tolist(),
        "omega_rad_s": result.omega_measured[1, 0].tolist(),
    }
    body = {"classifier_id": found, "telemetry": series}
    used = api.post("/identify", json=body)
    assert used.status_code == 200, used.text
    assert used.json()["pre_start_samples"] == 79  # -3.95 s to -0.05 s at 20 Hz
    # The paper preset has no gyro bias: the offset is the body's rate at the start.
    error = np.asarray(used.json()["initial_offset_rad_s"]) - result.omega_true[1, 0, 79]
    assert np.all(np.abs(error) < 4 * np.asarray(used.json()["initial_offset_std_rad_s"]))
    np.testing.assert_allclose(
        used.json()["initial_offset_deg_s"],
        np.degrees(used.json()["initial_offset_rad_s"]),
        rtol=1e-12,
    )
    ignored = api.post("/identify", json={**body, "pre_start_window_s": 0})
    assert ignored.status_code == 200, ignored.text
    assert ignored.json()["pre_start_samples"] == 0
    assert ignored.json()["initial_offset_rad_s"] is None
    partial = api.post("/identify/partial", json={**body, "pre_start_window_s": 2})
    assert partial.status_code == 200, partial.text
    form = api.post(
        "/identify",
        data={"classifier_id": found, "pre_start_window_s": "2"},
        files={"file": ("t.csv", csv_text(series["time_s"], series["omega_rad_s"]))},
    )
    assert form.status_code == 200, form.text
    assert form.json()["pre_start_samples"] == 40  # -2.00 s to -0.05 s
    for bad in (-1, 1e9):
        refused = api.post("/identify", json={**body, "pre_start_window_s": bad})
        assert refused.status_code == 422 and "pre_start_window_s" in refused.text
    refused = api.post(
        "/identify",
        data={"classifier_id": found, "pre_start_window_s": "soon"},
        files={"file": ("t.csv", csv_text(series["time_s"], series["omega_rad_s"]))},
    )
    assert refused.status_code == 422 and "'soon'" in refused.text


@pytest.mark.parametrize(("row", "value"), [(40, 1e200), (120, 1e154), (120, -101.0)])
def test_a_corrupted_sample_is_refused_by_name(
    api: Api, paper: Scenario, row: int, value: float
) -> None:
    """A rate beyond any gyro's range (a corrupted word in a downlink) is a 422 naming the
    sample, before the start or in the sequence; one within it gets a verdict. A 1e200
    spike was a 500 (the least-squares SVD did not converge), 1e154 a 422 blaming the
    server's own posterior."""
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    found = api.insert_classifier(api.create_scenario()["id"], model)
    flown = [[0] * paper.n_thrusters] * 4 + GOOD_SEQUENCE
    result = simulate(paper, flown, 1, np.random.default_rng(5))
    omega = result.omega_measured[1, 0].copy()
    times = (result.time_s - 4.0).tolist()
    omega[row, 1] = value
    body = {"classifier_id": found, "telemetry": {"time_s": times, "omega_rad_s": omega.tolist()}}
    refused = api.post("/identify", json=body)
    assert refused.status_code == 422, refused.text
    message = refused.json()["detail"][0]["msg"]
    assert f"omega_rad_s[{row}][1] = {value!r} rad/s is beyond any attitude gyro's range" in message
    form = api.post(
        "/identify",
        data={"classifier_id": found},
        files={"file": ("t.csv", csv_text(times, omega))},
    )
    assert form.status_code == 422 and f"omega_rad_s[{row}][1]" in form.text
    omega[row, 1] = 99.0 * np.sign(value)  # within range: judged, whatever the verdict
    body["telemetry"]["omega_rad_s"] = omega.tolist()
    judged = api.post("/identify", json=body)
    assert judged.status_code == 200, judged.text
    assert judged.json()["status"] in {"matches-none", "not-this-sequence"}


def _digits_body(found: str) -> str:
    return f'{{"classifier_id": "{found}", "telemetry": {{"time_s": [{"9" * 5000}, 1]}}}}'


@pytest.mark.parametrize(
    ("case", "fragment"),
    [
        ("start past year 9999 in UTC", "lies outside the years 1 to 9999 in UTC"),
        ("start before year 1 in UTC", "lies outside the years 1 to 9999 in UTC"),
        ("stamps a billion seconds apart", "s from the sequence start (0.0); at most 1e+08 s"),
        ("stamps near 1e300", "from the sequence start"),
        ("stamps in milliseconds", "Are the stamps in seconds (not milliseconds)"),
        ("stamps in nanoseconds", "are the stamps in seconds (not milli- or nanoseconds)"),
        ("no sample within the sequence", "0 sample(s) within the sequence"),
        ("an integer of 5,000 digits", "request body is not acceptable JSON"),
        ("arrays nested 100,000 deep", "request body is not acceptable JSON"),
        ("a misspelt sequence_start", "unknown key(s) 'sequence_strat'"),
        ("a rate given as true", "Input should be a valid number"),
    ],
)
def test_telemetry_a_client_got_wrong_is_a_422_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult, case: str, fragment: str
) -> None:
    """Each of these was a 500 (a datetime overflow, a 298 GiB allocation, a negative
    bincount, an unparsed integer, a RecursionError) or, for stamps in the wrong unit, a
    confident "matches none" from one sample in the sequence."""
    found = classifier_id
    times, omega = flight.time_s, flight.omega_measured[2, 0]
    telemetry: dict[str, Any] = {"time_s": times.tolist(), "omega_rad_s": omega.tolist()}
    if case.startswith("start"):
        late = case == "start past year 9999 in UTC"
        start = "9999-12-31T23:59:59-05:00" if late else "0001-01-01T00:00:00+05:00"
        telemetry = {
            "time_utc": [f"2026-01-01T00:00:{i:02d}Z" for i in range(2)],
            "omega_rad_s": omega[:2].tolist(),
            "sequence_start": start,
        }
    elif case == "stamps a billion seconds apart":
        telemetry = {**telemetry, "time_s": (np.arange(len(times)) * 1e9).tolist()}
        telemetry["sequence_start"] = 0.0
    elif case == "stamps near 1e300":
        telemetry = {**telemetry, "time_s": (1e300 * np.arange(1, len(times) + 1)).tolist()}
        telemetry["sequence_start"] = 1e300
    elif case == "stamps in milliseconds":
        telemetry = {**telemetry, "time_s": (times * 1e3).tolist()}
    elif case == "stamps in nanoseconds":
        telemetry = {**telemetry, "time_s": (times * 1e9).tolist(), "sequence_start": 0.0}
    elif case == "no sample within the sequence":
        telemetry = {**telemetry, "time_s": (times * 50 + 4.0).tolist()}
    elif case == "a misspelt sequence_start":
        telemetry = {**telemetry, "time_s": (times + 4.0).tolist(), "sequence_strat": 4.0}
    elif case == "a rate given as true":
        telemetry["omega_rad_s"][3][1] = True
    if case.startswith("an integer"):
        refused = api.post_raw_json("/identify", _digits_body(found))
    elif case.startswith("arrays"):
        refused = api.post_raw_json("/identify", "[" * 100_000 + "]" * 100_000)
    else:
        refused = api.post("/identify", json={"classifier_id": found, "telemetry": telemetry})
    assert refused.status_code == 422, refused.text
    assert fragment in refused.json()["detail"][0]["msg"], refused.text
    if case == "a rate given as true":
        assert refused.json()["detail"][0]["loc"][-3:] == ["omega_rad_s", 3, 1], refused.text


def test_a_pass_with_a_dropout_is_judged_and_its_gap_reported(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    """A 10 Hz pass that lost 0.5 s (more than 4 periods): the default kind judges it on
    the samples present and says so in JSON and CSV; a whole-series kind refuses it with
    a 422 that names the gap and the kind that can judge it."""
    import json as jsonlib

    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    found = api.insert_classifier(api.create_scenario()["id"], model)
    t = flight.time_s[1::2]
    keep = (t <= 1.5 + 1e-9) | (t >= 2.0 - 1e-9)
    series = {
        "time_s": t[keep].tolist(),
        "omega_rad_s": flight.omega_measured[2, 0][1::2][keep].tolist(),
    }
    body = {"classifier_id": found, "telemetry": series}
    response = api.post("/identify", json=body)
    assert response.status_code == 200, response.text
    verdict = response.json()
    assert verdict["candidate"] == paper.candidate_names[2]
    assert verdict["telemetry_gaps"] == [
        {"from_s": pytest.approx(1.5), "to_s": pytest.approx(2.0), "length_s": pytest.approx(0.5)}
    ]
    assert verdict["sequence_covered_fraction"] == pytest.approx(71 / 80)
    # 36 samples, each at its own grid time: the values judged, not the span.
    assert verdict["sequence_measured_fraction"] == pytest.approx(36 / 80)
    # The posterior so far judges across the same gap, and its answer says so.
    partial = api.post("/identify/partial", json=body)
    assert partial.status_code == 200, partial.text
    assert partial.json()["telemetry_gaps"] == verdict["telemetry_gaps"]
    assert partial.json()["sequence_covered_fraction"] == pytest.approx(71 / 80)
    assert partial.json()["sequence_measured_fraction"] == pytest.approx(36 / 80)
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    notes = dict(
        line[2:].split(": ", 1) for line in table.text.splitlines() if line.startswith("# ")
    )
    assert float(notes["sequence_covered_fraction"]) == pytest.approx(71 / 80)
    assert float(notes["sequence_measured_fraction"]) == pytest.approx(36 / 80)
    assert jsonlib.loads(notes["telemetry_gaps"]) == verdict["telemetry_gaps"]
    refused = api.post("/identify", json={**body, "classifier_id": classifier_id})
    assert refused.status_code == 422, refused.text
    assert "no sample from 1.5 s to 2 s" in refused.text
    assert "a likelihood kind (marginal-likelihood, the default, or likelihood)" in refused.text


@pytest.mark.parametrize("field", ["confidence", "pre_start_window_s", "estimate_start_within_s"])
def test_an_empty_numeric_form_field_is_422_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult, field: str
) -> None:
    """``confidence=`` took the default without a word, while an empty query number
    (``?limit=``) is a 422: a field sent empty is refused, one left out is the default."""
    text = csv_text(flight.time_s, flight.omega_measured[1, 0])
    files = [("file", ("flight.csv", text))]
    fields = {"classifier_id": classifier_id, "sequence_start": "0"}
    paths = (
        ["/identify"] if field == "estimate_start_within_s" else ["/identify", "/identify/partial"]
    )
    for path in paths:
        response = api.post(path, data={**fields, field: ""}, files=files)
        assert response.status_code == 422, response.text
        detail = response.json()["detail"][0]
        assert detail["loc"] == ["body", field]
        assert detail["msg"] == f"{field} is empty; leave the field out for the default"
    assert api.post("/identify", data=fields, files=files).status_code == 200


@pytest.mark.parametrize(
    ("field", "why"),
    [
        ("sequence_start", "leave the field out for the default"),
        ("averaged", "leave the field out for the default"),
        ("classifier_id", "it is required"),
        ("file", "it is required"),
    ],
)
def test_an_empty_text_form_field_is_422_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult, field: str, why: str
) -> None:
    """``sequence_start=`` and ``averaged=`` meant "not given" without a word, as the
    numeric fields did: a client that meant to send a value learns it did not."""
    text = csv_text(flight.time_s, flight.omega_measured[1, 0])
    files = [("file", ("flight.csv", text))]
    fields = {"classifier_id": classifier_id, "sequence_start": "0", "averaged": "false"}
    for path in ["/identify", "/identify/partial"]:
        if field == "file":
            # A text field named file (a part with no filename), not an upload.
            response = api.post(path, data=fields, files=[("file", (None, ""))])
        else:
            response = api.post(path, data={**fields, field: ""}, files=files)
        assert response.status_code == 422, response.text
        detail = response.json()["detail"][0]
        assert detail["loc"] == ["body", field]
        assert detail["msg"] == f"{field} is empty; {why}"
    assert api.post("/identify", data=fields, files=files).status_code == 200
    # Left out, a field is the default.
    left_out = {k: v for k, v in fields.items() if k not in ("sequence_start", "averaged")}
    assert api.post("/identify", data=left_out, files=files).status_code == 200


def test_the_multipart_schema_declares_text_fields_non_empty(api: Api) -> None:
    body = api.get("/openapi.json").json()["paths"]["/identify"]["post"]["requestBody"]
    properties = body["content"]["multipart/form-data"]["schema"]["properties"]
    assert properties["sequence_start"]["minLength"] == 1
    assert properties["classifier_id"]["minLength"] == 1


def test_the_off_candidates_rule_in_the_partial_answer_and_the_csv(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    """The verdict's off-candidates factor and whether it withheld the name are in its
    CSV, as notes appended after the units (none before them moves); the posterior over
    time carries the factor after every sample (null before the first measured one, here
    10 Hz telemetry on the 20 Hz grid), at the last sample and at the decision."""
    from inertia_id.classifiers.marginal import AXES_GRID, train_marginal

    model = train_marginal(paper, GOOD_SEQUENCE, 10, np.random.default_rng(4), grid=AXES_GRID)
    found = api.insert_classifier(api.create_scenario()["id"], model)
    series = {
        "time_s": flight.time_s[1::2].tolist(),
        "omega_rad_s": flight.omega_measured[2, 0][1::2].tolist(),
    }
    body = {"classifier_id": found, "telemetry": series}
    verdict = api.post("/identify", json=body).json()
    assert verdict["off_candidates_log_bayes"] is not None
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    lines = [line[2:].split(": ", 1) for line in table.text.splitlines() if line.startswith("# ")]
    names = [name for name, _ in lines]
    assert names[-3:] == ["units", "fits_off_candidates", "off_candidates_log_bayes"]
    assert names[:3] == ["classifier_id", "status", "verdict"]
    notes = dict(lines)
    assert notes["fits_off_candidates"] == str(verdict["fits_off_candidates"])
    assert float(notes["off_candidates_log_bayes"]) == verdict["off_candidates_log_bayes"]
    partial = api.post("/identify/partial", json=body)
    assert partial.status_code == 200, partial.text
    online = partial.json()
    assert online["classifier"] == verdict["classifier"]
    assert online["classifier"]["provenance"]["classifier_id"] == found
    factors = online["off_candidates_log_bayes"]
    assert len(factors) == len(online["time_s"])
    assert factors[0] is None and all(f is not None for f in factors[1:])
    assert factors[-1] == pytest.approx(verdict["off_candidates_log_bayes"], abs=1e-6)
    assert online["current_off_candidates_log_bayes"] == factors[-1]
    assert online["fits_off_candidates"] is False and online["withheld_time_s"] is None
    assert online["decided"] and online["candidate"] == paper.candidate_names[2]
    at = online["time_s"].index(online["decision_time_s"])
    assert online["decision_off_candidates_log_bayes"] == factors[at] < 0.0


def test_the_partial_schema_says_a_decision_stands_beside_the_flag(api: Api) -> None:
    """/identify/partial keeps a decision taken earlier where the data since fit another
    body better (``fits_off_candidates``): its OpenAPI document says so at the decision's
    own fields, where a client reading ``decided`` and ``candidate`` looks, not only in
    the flag's (the candidate field had no description at all)."""
    schema = api.get("/openapi.json").json()["components"]["schemas"]["PartialIdentifyResult"]
    fields = schema["properties"]
    assert "fits_off_candidates" in fields["decided"]["description"]
    assert "stands" in fields["decided"]["description"]
    assert "fits_off_candidates" in fields["candidate"]["description"]
    assert "not a confirmed identification" in fields["candidate"]["description"]
    assert "disowned" in fields["fits_off_candidates"]["description"]


def test_a_kind_without_the_off_candidates_test_says_so_in_every_answer(
    api: Api, paper: Scenario
) -> None:
    """A ``likelihood`` classifier cannot test for bodies off the candidates: its verdict,
    its CSV and its posterior over time answered ``fits_off_candidates`` false, as though
    the test had passed. Now null, with ``off_candidates_note`` saying why (in the CSV a
    note after the others, so that none moves)."""
    from inertia_id import train_classifier

    model = train_classifier(paper, GOOD_SEQUENCE, 20, np.random.default_rng(0), kind="likelihood")
    found = api.insert_classifier(api.create_scenario()["id"], model)
    flown = simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(21))
    series = {"time_s": flown.time_s.tolist(), "omega_rad_s": flown.omega_measured[1, 0].tolist()}
    body = {"classifier_id": found, "telemetry": series}
    response = api.post("/identify", json=body)
    assert response.status_code == 200, response.text
    verdict = response.json()
    assert verdict["status"] == "identified"
    assert verdict["fits_off_candidates"] is None and verdict["off_candidates_log_bayes"] is None
    note = verdict["off_candidates_note"]
    assert note.startswith("this classifier cannot test for bodies off the candidates")
    assert "likelihood kind" in note
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    lines = [line[2:].split(": ", 1) for line in table.text.splitlines() if line.startswith("# ")]
    names = [name for name, _ in lines]
    assert names[-4:] == [
        "units",
        "fits_off_candidates",
        "off_candidates_log_bayes",
        "off_candidates_note",
    ]
    assert dict(lines)["off_candidates_note"] == note
    partial = api.post("/identify/partial", json=body)
    assert partial.status_code == 200, partial.text
    online = partial.json()
    assert online["fits_off_candidates"] is None and online["off_candidates_log_bayes"] is None
    assert online["off_candidates_note"] == note
    schema = api.get("/openapi.json").json()["components"]["schemas"]
    for name in ("IdentifyResult", "PartialIdentifyResult"):
        assert "off_candidates_note" in schema[name]["properties"], name


def test_a_thruster_pulse_before_the_start_is_named_in_the_answer(
    api: Api, classifier_id: str, paper: Scenario
) -> None:
    """One thruster fired for 1 s, 4 s before the stated start: the answer says when the
    rates changed there and by how much (the status is the verdict's own), and the CSV
    export's notes say it too. Before, nothing in it named the step."""
    quiet = [[0] * paper.n_thrusters]
    sequence = quiet * 8 + GOOD_SEQUENCE
    sequence[4] = [4, 0, 0, 0, 0, 0]
    flown = simulate(paper, sequence, 1, np.random.default_rng(12))
    series = {
        "time_s": (flown.time_s - 8.0).tolist(),
        "omega_rad_s": flown.omega_measured[1, 0].tolist(),
    }
    body = {"classifier_id": classifier_id, "telemetry": {**series, "sequence_start": 0.0}}
    response = api.post("/identify", json=body)
    assert response.status_code == 200, response.text
    verdict = response.json()
    assert verdict["pre_start_activity_hint"] is not None
    assert "before the sequence start" in verdict["pre_start_activity_hint"]
    assert -4.5 <= verdict["pre_start_activity_at_s"] <= -3.5
    assert verdict["pre_start_activity_sigmas"] > 8.0
    assert len(verdict["pre_start_activity_step_deg_s"]) == 3
    table = api.post("/identify?format=csv", json=body)
    assert table.status_code == 200, table.text
    notes = dict(
        line[2:].split(": ", 1) for line in table.text.splitlines() if line.startswith("# ")
    )
    assert notes["pre_start_activity_hint"] == verdict["pre_start_activity_hint"]
    # The same pass without the pulse: no hint.
    calm = simulate(paper, quiet * 8 + GOOD_SEQUENCE, 1, np.random.default_rng(12))
    still = {"time_s": series["time_s"], "omega_rad_s": calm.omega_measured[1, 0].tolist()}
    quiet_answer = api.post(
        "/identify",
        json={"classifier_id": classifier_id, "telemetry": {**still, "sequence_start": 0.0}},
    )
    assert quiet_answer.status_code == 200, quiet_answer.text
    assert quiet_answer.json()["pre_start_activity_hint"] is None


def test_json_telemetry_in_deg_s_is_identified_as_in_rad_s(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    """``omega_deg_s`` states deg/s as a CSV header's ``wx_deg_s`` does: the same verdict
    as the rates in rad/s, and documented in OpenAPI. Before, the key was refused as
    unknown (422), and deg/s sent as omega_rad_s was judged 57 times too fast."""
    k = 3
    series = telemetry(flight, k)
    degrees = {
        "time_s": series["time_s"],
        "omega_deg_s": np.degrees(series["omega_rad_s"]).tolist(),
    }
    in_radians = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": series})
    in_degrees = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": degrees})
    assert in_degrees.status_code == 200, in_degrees.text
    assert in_degrees.json()["candidate"] == paper.candidate_names[k]
    assert in_degrees.json()["posterior"] == pytest.approx(in_radians.json()["posterior"])
    both = {**degrees, "omega_rad_s": series["omega_rad_s"]}
    refused = api.post("/identify", json={"classifier_id": classifier_id, "telemetry": both})
    assert refused.status_code == 422 and "not both" in refused.text
    schema = api.get("/openapi.json").json()["components"]["schemas"]["Telemetry"]
    assert "deg/s" in schema["properties"]["omega_deg_s"]["description"]
    assert "omega_rad_s" not in schema.get("required", [])
