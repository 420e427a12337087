"""The dashboard's whole workflow in headless Chromium against a running service + worker.

The tests run in file order and share what they made (scenario, search, classifier) in
``made``: create a scenario from the preset, see a bad one refused field by field, run
a small PPO search and watch its curve grow, train and sweep, identify telemetry,
compare searches, cancel a job. Each saves screenshots of its pages.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from dashboard_support import API_KEY, Dashboard

from inertia_id import Scenario, simulate

GOOD = [[4, 4, 4, 0, 0, 0]] * 4
TERMINAL = ("succeeded", "failed", "cancelled")
made: dict[str, Any] = {}


def _needs(*names: str) -> None:
    missing = [n for n in names if n not in made]
    if missing:
        pytest.fail(f"an earlier step did not make {missing}")


def _hash_id(dashboard: Dashboard, prefix: str) -> str:
    """The id in the page's ``#/<prefix>/<id>`` route, once the page has navigated there."""
    dashboard.page.wait_for_url(f"**/#/{prefix}/*")
    return str(dashboard.page.url.split(f"#/{prefix}/")[1].split("?")[0])


def _trace_points(dashboard: Dashboard, plot_id: str, trace: int = 0) -> int:
    return int(
        dashboard.page.evaluate(
            "([id, i]) => { const d = document.getElementById(id); "
            "return d && d.data && d.data[i] ? d.data[i].x.length : 0 }",
            [plot_id, trace],
        )
    )


def _telemetry_csv(path: Path, scenario: Scenario, candidate: int, seed: int) -> Path:
    result = simulate(scenario, GOOD, 1, np.random.default_rng(seed))
    omega = result.omega_measured[candidate, 0]
    times = scenario.sample_times(len(GOOD))
    rows = ["time_s,wx,wy,wz"] + [
        f"{t:.6f},{w[0]:.9f},{w[1]:.9f},{w[2]:.9f}" for t, w in zip(times, omega, strict=True)
    ]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_without_the_key_a_write_says_to_enter_it_then_the_key_is_kept(
    dashboard: Dashboard,
) -> None:
    dashboard.open("#/scenarios/new")
    dashboard.console.expect(r"status of 401")
    dashboard.page.click("#create-preset")
    error = dashboard.page.wait_for_selector("#preset-form + div .message.error")
    assert "API key" in error.inner_text()
    dashboard.page.fill("#api-key", API_KEY)
    dashboard.page.click("#api-key-form button")
    assert dashboard.page.inner_text("#api-key-state") == "saved"
    dashboard.page.reload()
    dashboard.page.wait_for_selector("#page h1")
    assert dashboard.page.inner_text("#api-key-state") == "saved"


def test_create_a_scenario_from_the_preset_shows_its_principal_moments(
    dashboard: Dashboard,
) -> None:
    dashboard.open("#/scenarios/new")
    dashboard.page.fill("#preset-name", "paper, from the browser")
    dashboard.page.click("#create-preset")
    made["scenario"] = _hash_id(dashboard, "scenarios")
    dashboard.page.wait_for_selector("#candidate-table")
    rows = dashboard.page.locator("#candidate-table tbody tr")
    assert rows.count() == 5
    first = rows.nth(0).inner_text()
    # I0 = diag(100, 60, 90): principal moments ascending.
    assert "none ejected" in first and "60.00, 90.00, 100.00" in first
    assert _trace_points(dashboard, "moments-plot") == 5
    assert "paper, from the browser" in dashboard.page.inner_text("h1")
    dashboard.screenshot("scenario")


def test_a_bad_scenario_shows_the_servers_message_next_to_the_field(
    dashboard: Dashboard,
) -> None:
    dashboard.open("#/scenarios/new")
    dashboard.console.expect(r"status of 422")
    page = dashboard.page
    page.wait_for_selector("#scenario-form")
    page.fill("#candidate-rows tr:nth-child(2) .cand-Izz", "500")
    page.fill("#levels", "0, 0.5")
    page.fill("#noise-gyro_noise_sigma_rad_s", "-0.001")
    page.click("#create-scenario")
    candidate_error = page.wait_for_selector("#candidate-rows tr.field-error")
    assert "triangle inequality" in candidate_error.inner_text()
    # The message sits under the offending candidate's row.
    assert (
        page.evaluate(
            "() => document.querySelector('#candidate-rows tr.field-error')"
            ".previousElementSibling.querySelector('.cand-Izz').value"
        )
        == "500"
    )
    assert "0 and 1" in page.inner_text("#levels + .field-error")
    gyro_error = page.locator("#noise-gyro_noise_sigma_rad_s + .field-error")
    assert "-0.001" in gyro_error.inner_text()
    assert page.url.endswith("#/scenarios/new")
    dashboard.screenshot("scenario-validation")


def test_a_search_curve_gains_points_while_ppo_runs(dashboard: Dashboard) -> None:
    _needs("scenario")
    page = dashboard.page
    metric_requests: list[str] = []
    page.on("request", lambda r: metric_requests.append(r.url) if "/metrics" in r.url else None)
    dashboard.open(f"#/jobs?scenario={made['scenario']}&type=search")
    page.fill("#search-timesteps", "1280")
    page.fill("#search-n_realisations", "10")
    page.fill("#search-ppo", '{"n_steps": 128, "batch_size": 64}')
    page.click("#submit-job")
    made["search"] = job_id = _hash_id(dashboard, "jobs")
    page.evaluate("() => { window.__notReloaded = true }")

    page.wait_for_function(
        "() => Number(document.querySelector('#curve-points')?.dataset.points || 0) >= 1",
        timeout=180_000,
    )
    first = int(page.get_attribute("#curve-points", "data-points") or 0)
    assert dashboard.service.job(job_id)["status"] == "running"
    page.wait_for_function(
        f"() => Number(document.querySelector('#curve-points').dataset.points) > {first}",
        timeout=120_000,
    )
    assert page.evaluate("() => window.__notReloaded") is True
    assert _trace_points(dashboard, "reward-plot") > first
    # Later polls ask only for points after the last one held.
    assert any("after=" in url for url in metric_requests[1:]), metric_requests

    page.wait_for_selector("#best-sequence", timeout=180_000)
    job = dashboard.service.job(job_id)
    assert job["status"] == "succeeded", job
    assert page.inner_text("#best-sequence") == str(job["result"]["best"]["sequence"]).replace(
        " ", ""
    )
    curve = job["result"]["curve"]
    assert _trace_points(dashboard, "reward-plot") == len(curve)
    page.wait_for_function(
        "() => document.getElementById('response-plot')?.data?.length === 45"
    )  # 5 candidates x 3 axes x (mean + two band edges)
    assert _trace_points(dashboard, "sequence-plot") == 4
    # The hand-designed baselines, scored on the same fresh draws as the best sequence.
    rows = page.locator("#baseline-table tbody tr")
    available = [n for n, b in job["result"]["baselines"].items() if "unavailable" not in b]
    assert rows.count() == 1 + len(available)
    assert "hand-designed" in rows.nth(1).inner_text()
    assert job["result"]["baselines"]["hand-designed"]["fuel_nms"] == 24.0
    dashboard.screenshot("search")


def test_the_job_list_updates_without_reload_and_training_shows_the_classifier(
    dashboard: Dashboard,
) -> None:
    _needs("scenario")
    page = dashboard.page
    dashboard.open(f"#/jobs?scenario={made['scenario']}&type=train")
    assert page.input_value("#train-sequence") == str(GOOD).replace(" ", "")
    page.click("#submit-job")
    job_id = _hash_id(dashboard, "jobs")
    page.evaluate("() => { window.__notReloaded = true }")
    page.evaluate("() => { location.hash = '#/jobs' }")
    row = f"#job-rows tr[data-job-id='{job_id}']"
    page.wait_for_selector(row)
    page.wait_for_selector(f"{row}[data-status='succeeded']", timeout=180_000)
    assert page.evaluate("() => window.__notReloaded") is True
    assert "100 %" in page.inner_text(f"{row} .progress")
    dashboard.screenshot("jobs")

    page.click(f"{row} a[href='#/jobs/{job_id}']")
    page.wait_for_selector("#classifier-f1")
    job = dashboard.service.job(job_id)
    made["classifier"] = job["result"]["classifier_id"]
    assert page.inner_text("#classifier-f1") == f"{job['result']['f1']:.3f}"
    page.wait_for_function(
        "() => document.getElementById('classifier-fuel').textContent.includes('N m s')"
    )
    # Three thrusters at 2 N m, full duty, 4 s: 24 N m s.
    assert page.inner_text("#classifier-fuel") == "24.0 N m s"


def test_a_sweep_draws_both_accuracy_curves_with_intervals_and_a_confusion_matrix(
    dashboard: Dashboard,
) -> None:
    _needs("classifier")
    page = dashboard.page
    dashboard.open(f"#/classifiers/{made['classifier']}")
    page.click("#run-sweep")
    page.wait_for_selector("#sweep-multiples")
    assert page.input_value("#sweep-classifier") == made["classifier"]
    page.fill("#sweep-multiples", "1, 4, 8")
    page.fill("#sweep-n_test", "50")
    page.click("#submit-job")
    sweep_id = _hash_id(dashboard, "jobs")
    page.wait_for_selector("#confusion-plot", timeout=180_000)
    result = dashboard.service.job(sweep_id)["result"]
    for noise in ("process", "measurement"):
        plot = f"accuracy-{noise}"
        assert _trace_points(dashboard, plot) == 3
        drawn = page.evaluate(
            "id => { const t = document.getElementById(id).data[0]; "
            "return {y: t.y, plus: t.error_y.array, minus: t.error_y.arrayminus} }",
            plot,
        )
        points = [p for p in result["points"] if p["noise"] == noise]
        assert drawn["y"] == pytest.approx([p["accuracy"] for p in points])
        assert [y + e for y, e in zip(drawn["y"], drawn["plus"], strict=True)] == pytest.approx(
            [p["ci_high"] for p in points]
        )
        # The limit and least squares, scored on the same series, drawn beside it.
        limit = page.evaluate(
            "id => document.getElementById(id).data.find(t => t.name.startsWith('limit')).y",
            plot,
        )
        assert limit == pytest.approx(
            [p["accuracy"] for p in result["limit"] if p["noise"] == noise]
        )
    page.wait_for_function("() => document.getElementById('inertia-plot')?.data?.length === 2")
    flagged = page.evaluate("() => document.getElementById('inertia-plot').data[0].y")
    scaled = [p for p in result["inertia"]["points"] if p["body"] == "scaled"]
    assert flagged == pytest.approx([p["matches_none_rate"] for p in scaled])
    page.select_option("#confusion-noise", "process")
    page.select_option("#confusion-multiple", "8")
    eighth = next(p for p in result["points"] if p["noise"] == "process" and p["multiple"] == 8)
    page.wait_for_function(
        "() => document.getElementById('confusion-plot').layout.title.text.includes('×8')"
    )
    shown = page.evaluate("() => document.getElementById('confusion-plot').data[0].text")
    assert shown == [[str(v) for v in row] for row in eighth["confusion"]]
    dashboard.screenshot("sweep")

    dashboard.open(f"#/classifiers/{made['classifier']}")
    page.wait_for_selector("#confusion-plot")
    assert _trace_points(dashboard, "accuracy-measurement") == 3
    dashboard.screenshot("classifier")


def test_identify_telemetry_files_verdict_distances_and_matches_none(
    dashboard: Dashboard, tmp_path: Path
) -> None:
    _needs("classifier")
    page = dashboard.page
    paper = Scenario.paper()
    matching = _telemetry_csv(tmp_path / "payload3.csv", paper, candidate=3, seed=11)
    dashboard.open(f"#/identify?classifier={made['classifier']}")
    page.set_input_files("#telemetry-file", str(matching))
    page.wait_for_function("() => document.getElementById('telemetry-text').value.length > 100")
    page.click("#identify-submit")
    verdict = page.wait_for_selector("#verdict")
    assert "payload 3 ejected" in verdict.inner_text()
    assert "match" in (verdict.get_attribute("class") or "")
    # The physics baseline's estimate from the same telemetry, with its caveat: the
    # hand-designed sequence fires one torque direction and excites little of the tensor.
    estimate = page.inner_text("#ls-estimate")
    assert "principal moments" in estimate and "hardly excites" in estimate
    assert _trace_points(dashboard, "distance-plot") == 5
    page.wait_for_function("() => document.getElementById('overlay-plot')?.data?.length === 12")
    dashboard.screenshot("identify")

    # A body 50 % heavier than every candidate: the answer is "matches none".
    base = paper.inertia_candidates[0]
    heavier = (1.5 * np.asarray(base.inertia_kg_m2)).tolist()
    heavy = paper.model_copy(
        update={
            "inertia_candidates": [
                base.model_copy(update={"name": "heavy", "inertia_kg_m2": heavier})
            ]
        }
    )
    unknown = _telemetry_csv(tmp_path / "heavy.csv", heavy, candidate=0, seed=12)
    page.set_input_files("#telemetry-file", str(unknown))
    page.wait_for_function(
        "text => document.getElementById('telemetry-text').value === text",
        arg=unknown.read_text(encoding="utf-8"),
    )
    page.click("#identify-submit")
    page.wait_for_selector("#verdict.none")
    assert "Matches none" in page.inner_text("#verdict")
    page.wait_for_function("() => document.getElementById('overlay-plot')?.data?.length === 12")
    dashboard.screenshot("identify-matches-none")

    # Pasted JSON works as a file does.
    rows = [line.split(",") for line in matching.read_text(encoding="utf-8").split()[1:]]
    document = {
        "time_s": [float(r[0]) for r in rows],
        "omega_rad_s": [[float(v) for v in r[1:]] for r in rows],
    }
    page.fill("#telemetry-text", json.dumps(document))
    page.click("#identify-submit")
    page.wait_for_selector("#verdict.match")
    assert "payload 3 ejected" in page.inner_text("#verdict")

    dashboard.console.expect(r"status of 422")
    page.fill("#telemetry-text", "time_s,wx,wy,wz\n0.05,1,2\n")
    page.click("#identify-submit")
    error = page.wait_for_selector("#telemetry-text + .field-error")
    assert "3 columns" in error.inner_text() and "expected 4" in error.inner_text()


def test_compare_overlays_searches_and_a_job_can_be_cancelled(dashboard: Dashboard) -> None:
    _needs("scenario", "search")
    page = dashboard.page
    dashboard.open(f"#/compare?jobs={made['search']}")
    page.wait_for_function("() => document.getElementById('compare-reward').data[0].x.length > 1")
    dashboard.screenshot("compare")

    dashboard.open(f"#/jobs?scenario={made['scenario']}&type=search")
    page.fill("#search-timesteps", "200000")
    page.fill("#search-seed", "1")
    page.click("#submit-job")
    job_id = _hash_id(dashboard, "jobs")
    page.wait_for_selector("#job-header .badge.status-running", timeout=120_000)
    page.click("#cancel-job")
    page.wait_for_selector("#job-header .badge.status-cancelled", timeout=120_000)
    assert dashboard.service.job(job_id)["status"] == "cancelled"


@pytest.mark.parametrize("route", ["#/scenarios", "#/jobs", "#/classifiers", "#/identify"])
def test_pages_fit_a_laptop_screen(dashboard: Dashboard, route: str) -> None:
    dashboard.page.set_viewport_size({"width": 1366, "height": 768})
    dashboard.open(route)
    dashboard.page.wait_for_load_state("networkidle")
    overflow = dashboard.page.evaluate(
        "() => document.documentElement.scrollWidth - window.innerWidth"
    )
    assert overflow <= 0, f"{route} is {overflow} px wider than a 1366 px screen"
