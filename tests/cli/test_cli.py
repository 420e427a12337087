"""The inertia-id command line: the workflow a user runs, and clean errors."""

from __future__ import annotations

import itertools
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from cli_support import run_cli, run_cli_json
from click.testing import CliRunner

import inertia_id
from inertia_id import InertiaClassifier
from inertia_id.cli import main, parse_sequence
from inertia_id.deadline import Deadline
from inertia_id.wording import significant


@pytest.fixture()
def runner() -> CliRunner:
    return CliRunner()


def test_train_simulate_identify_round_trip(tmp_path: Path) -> None:
    classifier = tmp_path / "c.json"
    telemetry = tmp_path / "t.csv"
    trained = run_cli(["train", "--metric", "euclidean", "-n", "10", "--out", str(classifier)])
    assert json.loads(trained.stdout)["f1"] == 1.0
    assert InertiaClassifier.load(classifier).metric == "euclidean"
    run_cli(
        [
            "simulate",
            "-n",
            "1",
            "--seed",
            "7",
            "--candidate",
            "payload 3 ejected",
            "--telemetry",
            str(telemetry),
        ]
    )
    assert telemetry.read_text().startswith("time_s,")
    identified = run_cli(
        ["identify", "--classifier", str(classifier), "--telemetry", str(telemetry)]
    )
    verdict = json.loads(identified.stdout)
    assert verdict["candidate"] == "payload 3 ejected"
    assert verdict["matches_none"] is False


def run_paper(out: Path, *options: str) -> dict[str, Any]:
    """``inertia-id paper`` with a small euclidean training into ``out``; its summary."""
    run_cli(["paper", "--metric", "euclidean", "-n", "10", *options, "--out-dir", str(out)])
    summary: dict[str, Any] = json.loads((out / "summary.json").read_text())
    return summary


def test_paper_writes_results_and_report(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    summary = run_paper(
        out, "--search", "none", "--multiples", "1,8", "--n-test", "50", "--seed", "7"
    )
    for name in ("classifier.json", "sweep.json", "scenario.json", "summary.json", "report.html"):
        assert (out / name).is_file(), name
    assert summary["training_f1"] == 1.0
    assert set(summary["accuracy"]["process"]) == {"1", "8"}
    report = (out / "report.html").read_text()
    assert "Accuracy vs noise" in report
    # A rate in deg/s beside rad/s, as the dashboard gives it (rad/s alone before).
    shown = re.search(r"mean final rate \|ω\|</th><td>(\S+) rad/s \((\S+) deg/s\)", report)
    assert shown is not None
    assert float(shown[2]) == pytest.approx(math.degrees(float(shown[1])), rel=1e-3)
    # The seed, as summary.json gives it, and the version that wrote the report: the
    # report alone did not say how to make the run again.
    assert summary["seed"] == 7
    assert "<tr><th>seed</th><td>7</td></tr>" in report
    assert f"<tr><th>inertia-id version</th><td>{inertia_id.__version__}</td></tr>" in report
    assert summary["sequence"] == [[4, 4, 4, 0, 0, 0]] * 4
    assert summary["sequence_from"] == "given"


def test_paper_uses_the_searched_sequence(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    searching = ["--search", "random", "--length", "2", "--timesteps", "40"]
    searching += ["--search-realisations", "5"]
    summary = run_paper(out, *searching, "--multiples", "1", "--n-test", "20")
    search = json.loads((out / "search.json").read_text())
    assert summary["sequence"] == search["best"]["sequence"]
    assert len(summary["sequence"]) == 2
    assert summary["sequence_from"] == "random search"
    assert summary["search_timesteps"] == search["timesteps"] <= 40
    assert "learning curve" in (out / "report.html").read_text()


def _random_search(out: Path, timesteps: int, realisations: int, *extra: str) -> tuple[Any, Any]:
    """``inertia-id search --method random --length 2`` with ``extra`` options."""
    return run_cli_json(
        [
            "search",
            "--method",
            "random",
            "--length",
            "2",
            "--timesteps",
            str(timesteps),
            "--search-realisations",
            str(realisations),
            *extra,
        ],
        out,
    )


def test_search_writes_the_best_sequence(tmp_path: Path) -> None:
    doc, result = _random_search(tmp_path / "search.json", 24, 4, "--seed", "3")
    assert doc["method"] == "random"
    assert doc["timesteps"] == 24 and doc["episodes"] == 12
    assert len(doc["fresh"]["f1"]) == 5
    assert doc["settings"]["scorer"]["n_realisations"] == 4
    assert json.loads(result.stdout.strip().splitlines()[-1]) == doc["best"]["sequence"]
    assert doc["scenario"]["name"] == "paper"  # what `plan --search` plans on


def _seeds(document: Any, path: str = "") -> list[tuple[str, Any]]:
    """Every value under a key that names a seed (``seed``, ``fresh_seed``), with its path."""
    if isinstance(document, dict):
        return [
            found
            for key, value in document.items()
            for found in (
                [(f"{path}.{key}", value)]
                if key.endswith("seed")
                else _seeds(value, f"{path}.{key}")
            )
        ]
    if isinstance(document, list):
        return [found for i, item in enumerate(document) for found in _seeds(item, f"{path}[{i}]")]
    return []


def test_every_seed_a_search_result_stores_is_one_seed_takes_back(tmp_path: Path) -> None:
    """The fresh draws' seed (``fresh.seed``, ``front.fresh_seed``, the confirmation's)
    was a 63-bit number: above 2**53 a JavaScript client (the dashboard's JSON.parse)
    reads another number, and ``--seed`` (0 to 2**31 - 1, the service's) refused it.
    Every seed stored is now one the command line takes back, and this document holds no
    integer JavaScript rounds (``space_size``, (M^N)^L, passes 2**53 from L = 4 on the
    paper preset: a count, not a number to type back)."""
    args = ["search", "--method", "nsga2", "--length", "2", "--nsga2", "population=8"]
    args += ["--nsga2", "generations=2", "--search-realisations", "4", "--seed", "5"]
    args += ["--fresh-realisations", "4", "--fresh-test-series", "2"]
    doc, _ = run_cli_json(args, tmp_path / "s.json")
    seeds = dict(_seeds(doc))
    assert {".fresh.seed", ".front.fresh_seed", ".front.confirmation.seed"} <= set(seeds)
    for path, seed in seeds.items():
        telemetry = tmp_path / "t.csv"
        taken = CliRunner().invoke(
            main, ["simulate", "-n", "1", "--seed", str(seed), "--telemetry", str(telemetry)]
        )
        assert taken.exit_code == 0, (path, seed, taken.output)
    assert max(abs(n) for n in _integers(doc)) < 2**53


def _integers(document: Any) -> list[int]:
    if isinstance(document, dict):
        return [n for value in document.values() for n in _integers(value)]
    if isinstance(document, list):
        return [n for item in document for n in _integers(item)]
    return [document] if isinstance(document, int) and not isinstance(document, bool) else []


def test_a_best_sequence_that_breaks_a_bound_is_flagged_in_the_listing(tmp_path: Path) -> None:
    """A searcher other than NSGA-II keeps its best sequence even when it breaks a
    constraint; the listing says so beside the figure it breaks."""
    # Above the 6.7e-4 rad/s the disturbance alone leaves (below it the search is refused).
    bound = ["--constraint", "max_final_rate_p95_rad_s=0.001", "--constraint-penalty", "1"]
    doc, result = _random_search(tmp_path / "s.json", 8, 10, "--fresh-test-series", "0", *bound)
    member = doc["front"]["members"][0]
    assert member["feasible"] is False
    assert member["scores"]["final_rate_p95_rad_s"] > 0.001
    line = next(x for x in result.output.splitlines() if x.strip().startswith("#0 "))
    assert "BREAKS A CONSTRAINT" in line and ">= 95 % of flights under" in line
    # The peak rate in rad/s beside deg/s, as the residual rate; the impulse to three
    # significant digits (a 0.45 N m s member read 0.5).
    scores = member["scores"]
    assert (
        f"peak {scores['peak_rate_rad_s']:.4f} rad/s ({scores['peak_rate_deg_s']:.2f} deg/s)"
        in line
    )
    assert f"{scores['impulse_nms']:.3g} N m s" in line


def test_the_search_listing_gives_the_commanded_residual_beside_the_total(tmp_path: Path) -> None:
    # On a scenario that draws an initial rate the residual carries its floor; the part
    # the commands leave is listed beside it, rad/s and deg/s, mean and worst candidate.
    doc, result = _random_search(
        tmp_path / "s.json", 8, 10, "--preset", "paper-in-orbit", "--fresh-test-series", "0"
    )
    scores = doc["front"]["members"][0]["scores"]
    line = next(x for x in result.output.splitlines() if x.strip().startswith("#0 "))
    # Three significant digits, as the dashboard: at :.4f a braking member's 5.8e-5 rad/s
    # read "0.0001 rad/s (0.00 deg/s)", and members of 9.6e-5, 5.8e-5 and 0 rad/s alike.
    assert (
        f"commanded (from rest) {significant(scores['commanded_residual_rate_rad_s'])} rad/s "
        f"({significant(scores['commanded_residual_rate_deg_s'])} deg/s), worst "
        f"{significant(scores['commanded_residual_rate_max_rad_s'])}"
    ) in line
    assert scores["commanded_residual_rate_max_rad_s"] <= scores["final_rate_max_rad_s"]


def test_a_search_bounds_the_commanded_residual_in_deg_s(tmp_path: Path) -> None:
    """``--constraint max_commanded_residual_rate_max_deg_s=0.2`` on paper-in-orbit: the
    bound is on the part the commands leave (from rest), not the total with |ω(0)| (a
    final-rate bound of 0.2 deg/s is refused there). The front's member and baselines
    are judged on it: fire-then-brake meets it, the hand-designed sequence (spinning at
    about 5 deg/s) does not. Before, the name was refused as unknown."""
    bound = ["--constraint", "max_commanded_residual_rate_max_deg_s=0.2"]
    doc, result = _random_search(
        tmp_path / "s.json", 8, 4, "--preset", "paper-in-orbit", "--fresh-test-series", "0", *bound
    )
    front = doc["front"]
    assert front["constraints"] == {"max_commanded_residual_rate_max_deg_s": 0.2}
    for entry in [*front["members"], *front["baselines"].values()]:
        if "scores" in entry:
            commanded = entry["scores"]["commanded_residual_rate_max_deg_s"]
            assert entry["feasible"] is (commanded <= 0.2)
    assert front["baselines"]["fire-then-brake"]["feasible"] is True
    assert front["baselines"]["hand-designed"]["feasible"] is False
    member = front["members"][0]
    line = next(x for x in result.output.splitlines() if x.strip().startswith("#0 "))
    assert ("BREAKS A CONSTRAINT" in line) is (member["feasible"] is False)


def test_the_search_listing_tells_braking_members_commanded_residuals_apart(
    tmp_path: Path,
) -> None:
    """Held to a 0.2 deg/s commanded residual on paper-in-orbit, every member brakes, and
    the listing's commanded figure is what tells them apart. At :.4f rad/s (:.2f deg/s)
    members leaving 2.5e-5 and 1.9e-5 rad/s read "0.0000 rad/s (0.00 deg/s)" as the
    all-off member does, and 1.9e-4 rad/s "0.0002 rad/s (0.01 deg/s)", 0.0002 rad/s
    being 0.011 deg/s; the dashboard gives three significant digits. So does the CLI."""
    args = ["search", "--preset", "paper-in-orbit", "--method", "nsga2", "--length", "2"]
    args += ["--nsga2", "population=8", "--nsga2", "generations=2", "--seed", "4"]
    args += ["--search-realisations", "6", "--fresh-realisations", "4"]
    args += ["--fresh-test-series", "2"]
    args += ["--constraint", "max_commanded_residual_rate_max_deg_s=0.2"]
    doc, result = run_cli_json(args, tmp_path / "s.json")
    lines = {
        int(x.split()[0][1:]): x for x in result.output.splitlines() if re.match(r"\s+#\d+ ", x)
    }
    members = doc["front"]["members"]
    assert sorted(lines) == [m["index"] for m in members]
    small = 0
    for member in members:
        scores = member["scores"]
        commanded = scores["commanded_residual_rate_rad_s"]
        small += 0 < commanded < 1e-3
        assert (
            f"commanded (from rest) {significant(commanded)} rad/s "
            f"({significant(scores['commanded_residual_rate_deg_s'])} deg/s), worst "
            f"{significant(scores['commanded_residual_rate_max_rad_s'])};"
        ) in lines[member["index"]]
    assert small > 0, members


def _search_document(sequence: list[list[int]], scenario: dict[str, Any]) -> dict[str, Any]:
    """The parts of a search JSON that ``plan --search`` reads."""
    member = {"index": 0, "sequence": sequence}
    return {"best": {"sequence": sequence}, "front": {"members": [member]}, "scenario": scenario}


def test_a_plan_csv_says_where_its_sequence_comes_from_and_when_it_was_written(
    tmp_path: Path,
) -> None:
    """A plan of ``--sequence`` began with the plan's own lines: nothing said which file
    the sequence came from or when the plan was written, which every job CSV now says.
    Now the sequence file (JSON: ``source``) when there is one, then ``exported_at`` (UTC,
    ``Z``); ``pandas.read_csv(path, comment="#")`` still reads the table whole."""
    import io
    from datetime import UTC, datetime

    import pandas

    sequence = tmp_path / "sequence.json"
    sequence.write_text("[[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]", encoding="utf-8")
    out = tmp_path / "p.csv"
    for given, source in [
        (str(sequence), {"sequence_file": str(sequence.resolve())}),
        ("4,4,4,0,0,0;0,0,0,4,4,4", {}),
    ]:
        before = datetime.now(UTC)
        run_cli(["plan", "--sequence", given, "--out", str(out)])
        after = datetime.now(UTC)
        text = out.read_text(encoding="utf-8")
        lines = [line for line in text.splitlines() if line.startswith("# ")]
        named = [f"# {key}: {json.dumps(value)}" for key, value in source.items()]
        assert lines[: len(named)] == named
        name, stamp = lines[len(named)][2:].split(": ", 1)
        assert name == "exported_at" and stamp.endswith("Z"), lines
        assert before <= datetime.fromisoformat(stamp) <= after
        assert lines[len(named) + 1].startswith("# scenario: ")
        table = pandas.read_csv(io.StringIO(text), comment="#")
        assert list(table["step"]) == [1, 2]
        before = datetime.now(UTC)
        plan, _ = run_cli_json(["plan", "--sequence", given], tmp_path / "p.json")
        after = datetime.now(UTC)
        assert plan.get("source", {}) == source
        # The JSON says when it was written too, as the service's plan JSON does.
        assert plan["exported_at"].endswith("Z")
        assert before <= datetime.fromisoformat(plan["exported_at"]) <= after


def test_plan_of_a_search_uses_the_scenario_searched(runner: CliRunner, tmp_path: Path) -> None:
    from inertia_id import preset

    paper = preset("paper")
    weak = preset("paper", name="weak", thrusters={"nominal_torque_nm": 1.0})
    search = tmp_path / "search.json"
    search.write_text(json.dumps(_search_document([[4, 0, 0, 0, 0, 0]], weak.model_dump())))
    plan, _ = run_cli_json(["plan", "--search", str(search), "--member", "0"], tmp_path / "p.json")
    assert plan["scenario"] == "weak"
    # It says where it came from, as the API's plan does (its job and member).
    assert plan["source"] == {"search": str(search.resolve()), "member": 0}
    run_cli(["plan", "--search", str(search), "--out", str(tmp_path / "p.csv")])
    notes = (tmp_path / "p.csv").read_text().splitlines()[:4]
    assert notes[:2] == [f"# search: {json.dumps(str(search.resolve()))}", "# member: best"]
    # Not a job's search: no job lines, the export time after the source.
    assert notes[2].startswith("# exported_at: ") and notes[2].endswith("Z")
    assert notes[3].startswith("# scenario: ")
    assert plan["steps"][0]["torque_nm"][0] == pytest.approx(paper.torque_matrix[0, 0] / 2)
    # A scenario named beside it must be the searched one.
    refused = runner.invoke(main, ["plan", "--search", str(search), "--preset", "paper"])
    assert refused.exit_code != 0 and "searched on scenario 'weak'" in refused.output
    # A search JSON that records none is planned on the named scenario, with a warning.
    old = _search_document([[4, 0, 0, 0, 0, 0]], weak.model_dump())
    del old["scenario"]
    search.write_text(json.dumps(old))
    plan, result = run_cli_json(["plan", "--search", str(search)], tmp_path / "p.json")
    assert plan["scenario"] == "paper" and "does not record the scenario" in result.output
    # The same scenario under another name is the same spacecraft.
    renamed = tmp_path / "renamed.json"
    renamed.write_text(weak.model_copy(update={"name": "weak, renamed"}).model_dump_json())
    search.write_text(json.dumps(_search_document([[4, 0, 0, 0, 0, 0]], weak.model_dump())))
    run_cli(["plan", "--search", str(search), "--scenario", str(renamed), "--out", "-"])
    # A job as the service downloads it: the search is its result; the scenario is the job's.
    job = {"id": "j1", "type": "search", "scenario_id": "s1", "result": old}
    search.write_text(json.dumps(job))
    plan, result = run_cli_json(["plan", "--search", str(search)], tmp_path / "p.json")
    assert plan["sequence"] == [[4, 0, 0, 0, 0, 0]]
    assert "job j1 of scenario s1" in result.output and "GET /jobs/{id}/plan" in result.output
    # The service's searches record their scenario in the result, as the CLI's do.
    search.write_text(
        json.dumps({**job, "result": _search_document([[4, 0, 0, 0, 0, 0]], weak.model_dump())})
    )
    plan, result = run_cli_json(["plan", "--search", str(search)], tmp_path / "p.json")
    assert plan["scenario"] == "weak" and "warning" not in result.output
    search.write_text(json.dumps({**job, "type": "train"}))
    refused = runner.invoke(main, ["plan", "--search", str(search)])
    assert refused.exit_code != 0 and "is a train job, not a search" in refused.output
    # A recorded scenario that is no scenario: one line naming what is wrong.
    broken = _search_document([[4, 0, 0, 0, 0, 0]], {**weak.model_dump(), "timing": 3})
    search.write_text(json.dumps(broken))
    refused = runner.invoke(main, ["plan", "--search", str(search)])
    assert refused.exit_code != 0 and "recorded scenario is not valid: timing" in refused.output
    assert len(refused.output.strip().splitlines()) == 1


def test_plan_flies_the_sequence_when_asked(runner: CliRunner, tmp_path: Path) -> None:
    sequence = "4,4,4,0,0,0;4,4,4,0,0,0;0,0,0,4,4,4;0,0,0,4,4,4"
    plan, result = run_cli_json(
        ["plan", "--sequence", sequence, "--flights", "50", "--seed", "2"], tmp_path / "p.json"
    )
    assert plan["flights"]["flights_per_candidate"] == 50 and plan["flights"]["seed"] == 2
    bound = plan["flights"]["residual_rate_p95_bound_max_rad_s"]
    assert f"at least 95 % of flights end under {bound:.4f} rad/s" in result.output
    p95 = plan["flights"]["residual_rate_p95_max_rad_s"]
    assert f"the 95th percentile of these flights {p95:.4f}" in result.output
    peak = plan["flights"]["peak_rate_p95_bound_max_rad_s"]
    assert f"peak rate: at least 95 % of flights under {peak:.4f} rad/s" in result.output
    refused = runner.invoke(main, ["plan", "--sequence", sequence, "--flights", "1"])
    assert refused.exit_code != 0
    assert "flights must be 0 (none) or an integer in 2..100000, got 1" in refused.output


def test_plan_names_the_commanded_residual_beside_the_initial_rate_floor(tmp_path: Path) -> None:
    # paper-in-orbit draws an initial rate (σ 0.005 rad/s an axis): every flight keeps
    # |ω(0)|, 0.0080 rad/s on average, which the plan's prediction from rest leaves out;
    # the plan said "largest residual rate 0.0004 rad/s" with no word of either.
    sequence = "4,4,4,0,0,0;0,0,0,4,4,4"
    plan, result = run_cli_json(
        ["plan", "--preset", "paper-in-orbit", "--sequence", sequence, "--flights", "60"],
        tmp_path / "p.json",
    )
    commanded = plan["commanded_residual_rate_max_rad_s"]
    assert commanded < 0.001 and commanded == plan["residual_rate_max_rad_s"]
    floor = plan["initial_rate_floor"]
    assert floor["mean_rad_s"] == pytest.approx(0.0079788, rel=1e-4)
    # To three significant digits, as the dashboard: at :.4f it read "0.0004 rad/s (0.020
    # deg/s)" for 0.000356 rad/s, 12 % off, and 0.0004 rad/s is 0.023 deg/s.
    assert (
        f"largest residual rate {significant(commanded)} rad/s "
        f"({significant(plan['commanded_residual_rate_max_deg_s'])} deg/s)"
    ) in result.output
    shown = re.search(r"largest residual rate ([\d.]+) rad/s \(([\d.]+) deg/s\)", result.output)
    assert shown is not None, result.output
    rad_s, deg_s = float(shown[1]), float(shown[2])
    assert rad_s == pytest.approx(commanded, rel=5e-3)
    assert rad_s * 180 / math.pi == pytest.approx(deg_s, rel=5e-3)
    assert "commanded (from rest: commanded_residual_rate_max)" in result.output
    assert f"{floor['mean_rad_s']:.4f} rad/s ({floor['mean_deg_s']:.3f} deg/s) on average" in (
        result.output
    )
    # The flights carry the floor: their mean residual is about it, the commands' part not.
    for candidate in plan["candidates"]:
        assert candidate["commanded_residual_rate_rad_s"] < 0.1 * floor["mean_rad_s"]
        assert candidate["flights"]["residual_rate_mean_rad_s"] > 0.7 * floor["mean_rad_s"]
    out = tmp_path / "p.csv"
    run_cli(["plan", "--preset", "paper-in-orbit", "--sequence", sequence, "--out", str(out)])
    text = out.read_text()
    assert "# initial_rate_floor: initial_rate_sigma_rad_s 0.005; mean_rad_s 0.00797885" in text
    assert ", commanded_residual_rate_rad_s " in text and ", commanded_residual_rate_deg_s " in text


@pytest.mark.parametrize(
    ("content", "message"),
    [("{bad", "is not a search JSON"), ("[1, 2]", "it holds a list")],
)
def test_plan_refuses_a_file_that_is_no_search(
    runner: CliRunner, tmp_path: Path, content: str, message: str
) -> None:
    search = tmp_path / "search.json"
    search.write_text(content)
    result = runner.invoke(main, ["plan", "--search", str(search)])
    assert result.exit_code != 0 and message in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["simulate", "--sequence", "9,0,0,0,0,0"], "level index 9 is outside 0..4"),
        (["simulate", "--sequence", "4,4"], "got shape (1, 2)"),
        (["plan", "--sequence", "4,4,4,0,0,0;;0,0,0,4,4,4"], "step 2 is empty"),
        (
            ["search", "--constraint", "max_impulse_nms=9", "--constraint", "max_impulse_nms=90"],
            "--constraint max_impulse_nms is given twice",
        ),
        (
            ["search", "--method", "nsga2", "--constraint", "min_accuracy=1.5"],
            "min_accuracy is a fraction in [0, 1], got 1.5",
        ),
        (["train", "--sequence", "a,b"], "sequence 'a,b' is not rows of level indices"),
        (["simulate", "--candidate", "nobody", "--telemetry", "x.csv"], "'nobody'"),
        (["sweep", "--classifier", "missing.json"], "does not exist"),
        (["search", "--method", "exhaustive"], "(5^6)^4 = 5.96e+16 sequences"),
        (["search", "--ppo", "n_step=8"], "unknown PPO parameters ['n_step']"),
        (["search", "--ppo", "ent_coef=-1"], "ent_coef must be >= 0, got -1"),
        (["search", "--ppo", "gamma"], "--ppo takes NAME=VALUE"),
        (["search", "--radius", "-2"], "--radius must be an integer >= 0 or 'none', got '-2'"),
        (["search", "--method", "random", "--ppo", "gamma=0.9"], "--ppo applies to --method"),
        (
            ["plan", "--sequence", "[[4,4,4,0,0,true]]"],
            "integer level indices, got [[4, 4, 4, 0, 0, True",
        ),
        (["search", "--method", "nsga2", "--design-noise", ""], "pairs, got ''"),
        (["search", "--method", "nsga2", "--design-noise", " ; "], "pairs, got ' ; '"),
    ],
)
def test_bad_input_is_one_line_error(
    runner: CliRunner,
    args: list[str],
    message: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(main, args)
    assert result.exit_code != 0
    assert message in result.output
    assert "Traceback" not in result.output


def test_tampered_classifier_is_refused(runner: CliRunner, tmp_path: Path) -> None:
    classifier = tmp_path / "c.json"
    assert (
        runner.invoke(
            main, ["train", "--metric", "euclidean", "-n", "4", "--out", str(classifier)]
        ).exit_code
        == 0
    )
    doc = json.loads(classifier.read_text())
    doc["classifier"]["scale"] *= 2
    classifier.write_text(json.dumps(doc))
    result = runner.invoke(main, ["sweep", "--classifier", str(classifier)])
    assert result.exit_code == 1
    assert "checksum mismatch" in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--multiples", "1,1e6"], "at most 1000 (beyond it the simulated rates"),
        (["--multiples", "1e300"], "got [1e+300]"),
        (["--ceiling-realisations", "2"], "must be 0 (no ceiling) or at least 3, got 2"),
    ],
)
def test_a_sweep_beyond_its_bounds_is_refused_before_any_work(
    runner: CliRunner, tmp_path: Path, args: list[str], message: str
) -> None:
    classifier = tmp_path / "c.json"
    trained = runner.invoke(
        main, ["train", "--metric", "euclidean", "-n", "4", "--out", str(classifier)]
    )
    assert trained.exit_code == 0, trained.output
    out = tmp_path / "sweep.json"
    result = runner.invoke(
        main, ["sweep", "--classifier", str(classifier), "--out", str(out), *args]
    )
    assert result.exit_code != 0 and message in result.output, result.output
    assert "Traceback" not in result.output and not out.exists()


def test_a_sweep_document_names_the_seed_that_runs_it_again(tmp_path: Path) -> None:
    """The seed a sweep.json records as its own is one ``--seed`` takes, and it gives the
    same document. Its ``seed`` is the test series' stream derived from ``--seed``: for
    ``--seed 2`` 2,240,297,063, which ``--seed`` refused (past 2**31 - 1); a smaller one
    would have run other draws. The document did not record ``--seed`` at all."""
    classifier = tmp_path / "c.json"
    run_cli(["train", "--metric", "euclidean", "-n", "4", "--out", str(classifier)])
    sweep = ["sweep", "--classifier", str(classifier), "--multiples", "1,6", "--n-test", "10"]
    sweep += ["--others", "none", "--ceiling-realisations", "0"]
    first, _ = run_cli_json([*sweep, "--seed", "2"], tmp_path / "first.json")
    assert first["seed"] == 2_240_297_063  # the derived stream, kept as it was
    again, _ = run_cli_json([*sweep, "--seed", str(first["run_seed"])], tmp_path / "again.json")
    assert again == first
    other, _ = run_cli_json([*sweep, "--seed", "3"], tmp_path / "other.json")
    assert other["run_seed"] == 3 and other["inertia"] != first["inertia"]


def test_a_sweep_says_when_its_test_series_do_not_spread_evenly(tmp_path: Path) -> None:
    """--n-test 9 over 5 candidates drew 5 series a point, 1 a candidate, without a word."""
    classifier = tmp_path / "c.json"
    run_cli(["train", "--metric", "euclidean", "-n", "4", "--out", str(classifier)])
    sweep = ["sweep", "--classifier", str(classifier), "--multiples", "1", "--others", "none"]
    sweep += ["--ceiling-realisations", "0", "--no-inertia"]
    document, result = run_cli_json([*sweep, "--n-test", "9"], tmp_path / "nine.json")
    assert [p["n_series"] for p in document["points"]] == [5, 5]
    assert "warning: --n-test 9 over 5 candidates draws 1 series a candidate, 5 a point" in (
        result.stderr
    )
    _, even = run_cli_json([*sweep, "--n-test", "10"], tmp_path / "ten.json")
    assert "warning" not in even.stderr


def test_the_paper_pipeline_refuses_large_multiples_before_it_trains(
    runner: CliRunner, tmp_path: Path
) -> None:
    out = tmp_path / "paper"
    result = runner.invoke(main, ["paper", "--multiples", "1,5000", "--out-dir", str(out)])
    assert result.exit_code != 0 and "got [5000.0] in [1.0, 5000.0]" in result.output
    assert not (out / "classifier.json").exists()


def test_parse_sequence_forms(tmp_path: Path) -> None:
    rows = [[4, 4, 4, 0, 0, 0], [0, 0, 0, 1, 2, 3]]
    assert parse_sequence("4,4,4,0,0,0;0,0,0,1,2,3") == rows
    assert parse_sequence("4,4,4,0,0,0;0,0,0,1,2,3;") == rows
    assert parse_sequence(json.dumps(rows)) == rows
    path = tmp_path / "seq.json"
    path.write_text(json.dumps(rows))
    assert parse_sequence(str(path)) == rows


def test_any_kind_trains_and_a_sweep_scores_others_beside_it(
    runner: CliRunner, tmp_path: Path
) -> None:
    classifier = tmp_path / "lik.json"
    sequence = "4,0,0,0,0,0;0,4,0,0,0,0;0,0,4,0,0,0;4,4,0,0,0,0;0,4,4,0,0,0;4,0,4,0,0,0"
    run_cli(
        [
            "train",
            "--kind",
            "likelihood",
            "--sequence",
            sequence,
            "-n",
            "10",
            "--out",
            str(classifier),
        ]
    )
    refused = runner.invoke(main, ["train", "--kind", "likelihood", "--metric", "dtw"])
    assert refused.exit_code != 0 and "takes no --metric" in refused.output
    document, _ = run_cli_json(
        [
            "sweep",
            "--classifier",
            str(classifier),
            "--multiples",
            "1,8",
            "--noise",
            "thrust_scale",
            "--others",
            "least-squares,1nn:euclidean",
            "--n-test",
            "50",
            "--inertia",
        ],
        tmp_path / "sweep.json",
    )
    assert [p["value"] for p in document["points"]] == [0.02, 0.16]
    assert set(document["others"]) == {"least-squares", "1nn:euclidean"}
    assert document["inertia"]["points"][0]["body"] == "scaled"
    telemetry = tmp_path / "t.csv"
    runner.invoke(
        main,
        [
            "simulate",
            "-n",
            "1",
            "--sequence",
            sequence,
            "--candidate",
            "3",
            "--telemetry",
            str(telemetry),
        ],
    )
    identified = runner.invoke(
        main, ["identify", "--classifier", str(classifier), "--telemetry", str(telemetry)]
    )
    verdict = json.loads(identified.stdout)
    assert verdict["candidate"] == "payload 2 ejected"
    # Axis by axis and in pairs, the sequence excites the diagonal: least squares from
    # the same telemetry lands near the true tensor.
    estimated = verdict["estimated_inertia_kg_m2"]
    assert [estimated[i][i] for i in range(3)] == pytest.approx([94.83, 52.12, 77.29], rel=0.05)


def test_train_without_a_kind_gives_the_marginal_likelihood_and_a_metric_the_clustering(
    runner: CliRunner, tmp_path: Path
) -> None:
    from inertia_id import MarginalLikelihoodClassifier, load_classifier

    default = tmp_path / "default.json"
    trained = run_cli(["train", "-n", "10", "--out", str(default)])
    assert isinstance(load_classifier(default), MarginalLikelihoodClassifier)
    assert "marginal-likelihood" in trained.stderr and "x 10 realisations" in trained.stderr
    clustering = tmp_path / "clustering.json"
    runner.invoke(main, ["train", "--metric", "euclidean", "-n", "5", "--out", str(clustering)])
    assert isinstance(load_classifier(clustering), InertiaClassifier)


@pytest.fixture(scope="module")
def small_classifier(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("classifier") / "c.json"
    run_cli(["train", "--metric", "euclidean", "-n", "10", "--out", str(path)])
    return path


def _simulate_telemetry(path: Path, candidate: str, *extra: str) -> None:
    args = ["simulate", "-n", "1", "--seed", "11", "--candidate", candidate]
    run_cli([*args, "--telemetry", str(path), *extra])


def test_identify_many_files_with_a_mission_clock(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    """A folder and a file in one call: a JSON line each, a bad file named, exit code 1."""
    folder = tmp_path / "downlink"
    folder.mkdir()
    start = "810000000"
    _simulate_telemetry(folder / "a.csv", "2", "--sample-rate", "200", "--time-offset", start)
    _simulate_telemetry(folder / "b.csv", "4", "--sample-rate", "10", "--time-offset", start)
    assert (folder / "a.csv").read_text().splitlines()[1].startswith("810000000.005,")
    (folder / "notes.txt").write_text("not telemetry")  # not .csv or .json: skipped
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,wx,wy,wz\n810000000.1,0,0,0\n810000000.1,0,0,0\n")
    result = runner.invoke(
        main,
        [
            "identify",
            "--classifier",
            str(small_classifier),
            "--sequence-start",
            start,
            str(folder),
            "--telemetry",
            str(bad),
        ],
    )
    assert result.exit_code == 1
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert [line["path"] for line in lines] == [
        str(bad),
        str(folder / "a.csv"),
        str(folder / "b.csv"),
    ]
    assert "time stamps must increase strictly: time_s[0] = 810000000.1" in lines[0]["error"]
    assert (lines[1]["candidate"], lines[1]["matches_none"]) == ("payload 1 ejected", False)
    assert (lines[2]["candidate"], lines[2]["matches_none"]) == ("payload 3 ejected", False)
    assert "1 of 3 telemetry files failed" in result.stderr
    # All good: exit code 0. Without the start the mission clock is refused, by name.
    run_cli(
        ["identify", "--classifier", str(small_classifier), "--sequence-start", start, str(folder)]
    )
    alone = runner.invoke(
        main,
        ["identify", "--classifier", str(small_classifier), "--telemetry", str(folder / "a.csv")],
    )
    assert alone.exit_code == 1
    assert (
        "sequence_start is required: the first time stamp time_s[0] = 810000000.005" in alone.output
    )


def test_identify_iso_stamps_and_an_estimated_start(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(telemetry, "3", "--time-offset", "2025-03-01T12:00:00Z")
    assert telemetry.read_text().startswith(
        "time_utc,wx_rad_s,wy_rad_s,wz_rad_s\n2025-03-01T12:00:00.050000Z,"
    )
    base = ["identify", "--classifier", str(small_classifier), str(telemetry)]
    result = run_cli([*base, "--sequence-start", "2025-03-01T12:00:00Z"])
    assert json.loads(result.stdout)["candidate"] == "payload 2 ejected"
    # The operator's start is 0.2 s early; searching ±0.3 s finds the true one.
    early = run_cli(
        [*base, "--sequence-start", "2025-03-01T11:59:59.8Z", "--estimate-start-within", "0.3"]
    )
    verdict = json.loads(early.stdout)
    # Within a grid period: the start taken (0.25 s) is the latest the telemetry lets
    # the search try, with no later neighbour to bracket a minimum, so it is not refined
    # below the grid (README *Start below the grid period*; checked below).
    assert verdict["sequence_start_shift_s"] == pytest.approx(0.2, abs=0.051)
    assert verdict["candidate"] == "payload 2 ejected"
    # The telemetry ends 0.2 s after the sequence: no earlier start than about 0.2 s
    # late could be tried, and a narrower window than asked for is said, not kept quiet.
    low, high = verdict["sequence_start_shifts_tried_s"]
    assert low > 0.1 and high <= 0.3 and low <= verdict["sequence_start_shift_s"] <= high
    assert verdict["sequence_start_refined"] is (verdict["sequence_start_shift_s"] < high)
    assert "could be tried, not ±0.3 s" in early.stderr
    # A window the telemetry covers to within a grid period: nothing to say.
    near = [*base, "--sequence-start", "2025-03-01T12:00:00Z", "--estimate-start-within", "0.05"]
    assert "could be tried" not in run_cli(near).stderr
    wrong = runner.invoke(main, [*base, "--sequence-start", "noon"])
    assert wrong.exit_code != 0
    assert "--sequence-start = 'noon' is not an ISO-8601 UTC time stamp" in wrong.output
    # A window beyond use is one line naming it, not a 298 GiB allocation's traceback.
    wide = runner.invoke(
        main, [*base, "--sequence-start", "2025-03-01T12:00:00Z", "--estimate-start-within", "1e9"]
    )
    assert wide.exit_code != 0
    assert "the start window ±1e+09 s at a 0.05 s step is 4e+10 start times" in wide.output
    assert len(wide.output.strip().splitlines()) == 1
    # A corrupted sample is refused by name, not judged into NaN and printed as invalid JSON.
    lines = telemetry.read_text().splitlines()
    stamp, *_ = lines[40].split(",")
    lines[40] = f"{stamp},0.0,1e200,0.0"
    telemetry.write_text("\n".join(lines) + "\n")
    spike = runner.invoke(main, [*base, "--sequence-start", "2025-03-01T12:00:00Z"])
    assert spike.exit_code != 0
    # Named by its index in the series and by its CSV row (counted from 1) as written.
    assert (
        "omega_rad_s[39][1] = 1e+200 rad/s (CSV data row 40, written '1e200') is beyond any "
        "attitude gyro's range" in spike.output
    )


def test_a_start_search_with_a_kind_that_compares_whole_series_says_it_is_not_refined(
    tmp_path: Path, small_classifier: Path
) -> None:
    """README's ISO example searched the start with the clustering kind and took 0.25 s
    for a 0.2 s late start, with nothing but ``sequence_start_refined: false`` to say
    that the kind takes a grid start its distance favours; the CLI now says it."""
    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(
        telemetry, "2", "--pre-start", "1", "--time-offset", "2025-03-01T12:00:00.2Z"
    )
    base = ["identify", "--classifier", str(small_classifier), str(telemetry)]
    search = [*base, "--sequence-start", "2025-03-01T12:00:00Z", "--estimate-start-within", "0.5"]
    result = run_cli(search)
    verdict = json.loads(result.stdout)
    assert verdict["sequence_start_refined"] is False
    taken = f"{verdict['sequence_start_shift_s']:+.6g} s"
    assert (
        f"the 'clustering' kind compares whole series: the start taken ({taken}) is the "
        "0.05 s grid's that its distance favours, not refined below the grid period"
        in result.stderr
    )
    assert "the likelihood kinds (marginal-likelihood, the default" in result.stderr
    # The JSON says it as the API's does, word for word.
    assert f"warning: {telemetry}: {verdict['sequence_start_note']}" in result.stderr
    # Without a search nothing is said.
    plain = run_cli([*base, "--sequence-start", "2025-03-01T12:00:00Z"])
    assert "not refined" not in plain.stderr


@pytest.mark.parametrize(
    ("named", "counted"), [(1, "1 identified verdict"), (2, "2 identified verdicts")]
)
def test_the_untested_warning_counts_its_verdicts_in_agreement(
    capsys: pytest.CaptureFixture[str], named: int, counted: str
) -> None:
    """A run of three verdicts, ``named`` of them identified by a kind that cannot test for
    bodies off the candidates, warned "(1 identified verdicts)" for one."""
    from inertia_id.cli.classify import _warn_untested

    note = "this classifier cannot test for bodies off the candidates"
    verdicts = [{"status": "identified", "off_candidates_note": note}] * named
    verdicts += [{"status": "ambiguous", "off_candidates_note": note}] * (3 - named)
    _warn_untested(verdicts)
    assert capsys.readouterr().err == f"warning ({counted}): {note}\n"


def test_json_output_is_strict_json(tmp_path: Path) -> None:
    """NaN and Infinity are not JSON: they are written as null."""
    from inertia_id.cli.options import write_json

    path = tmp_path / "out.json"
    write_json(path, {"a": float("nan"), "b": [1.0, float("inf")], "c": (2, -float("inf"))})
    assert json.loads(path.read_text(), parse_constant=pytest.fail) == {
        "a": None,
        "b": [1.0, None],
        "c": [2, None],
    }


def test_simulate_with_basilisk_writes_telemetry_identify_reads(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    from inertia_id.physics.engines import basilisk_available

    telemetry = tmp_path / "k.csv"
    args = [
        "simulate",
        "--engine",
        "basilisk",
        "--seed",
        "3",
        "--candidate",
        "5",
        "--sample-rate",
        "50",
        "--telemetry",
        str(telemetry),
    ]
    result = runner.invoke(main, args)
    if not basilisk_available():
        assert result.exit_code == 1
        assert "Basilisk is not available" in result.output
        return
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["series_shape"] == [200, 3]
    verdict = run_cli(["identify", "--classifier", str(small_classifier), str(telemetry)])
    assert json.loads(verdict.stdout)["candidate"] == "payload 4 ejected"
    refused = runner.invoke(main, ["simulate", "--engine", "basilisk"])
    assert refused.exit_code == 1 and "give --telemetry" in refused.output


def test_telemetry_from_before_the_start_is_written_and_used(
    runner: CliRunner, tmp_path: Path
) -> None:
    # simulate --pre-start writes 10 s of drift before the sequence; identify measures the
    # rate plus bias there unless --pre-start-window 0; a span that is no whole number of
    # steps is refused by value.
    classifier = tmp_path / "orbit.json"
    run_cli(["train", "--preset", "paper-in-orbit", "-n", "20", "--out", str(classifier)])
    telemetry = tmp_path / "t.csv"
    args = ["--preset", "paper-in-orbit", "--sample-rate", "1", "--pre-start", "10"]
    _simulate_telemetry(telemetry, "3", *args, "--time-offset", "810000000")
    stamps = [line.split(",")[0] for line in telemetry.read_text().splitlines()[1:]]
    assert stamps[0] == "809999991" and "810000000" in stamps and stamps[-1] == "810000004"
    base = ["identify", "--classifier", str(classifier), "--sequence-start", "810000000"]
    verdict = json.loads(run_cli([*base, str(telemetry)]).stdout)
    assert verdict["pre_start_samples"] == 9 and len(verdict["initial_offset_rad_s"]) == 3
    ignored = run_cli([*base, "--pre-start-window", "0", str(telemetry)])
    assert json.loads(ignored.stdout)["pre_start_samples"] == 0
    assert verdict["pre_start_activity_hint"] is None and "changed" not in ignored.stderr
    # The rates stepped by 0.02 rad/s about x 4.5 s before the start (a thruster pulse
    # there): the verdict says so in its JSON and beside it, whatever its status.
    header, *rows = telemetry.read_text().splitlines()
    stepped = [
        ",".join([t, repr(float(wx) + 0.02), *rest]) if float(t) > 809999995 else row
        for row in rows
        for t, wx, *rest in [row.split(",")]
    ]
    telemetry.write_text("\n".join([header, *stepped]) + "\n")
    pulsed = run_cli([*base, str(telemetry)])
    hint = json.loads(pulsed.stdout)["pre_start_activity_hint"]
    assert hint is not None and "before the sequence start" in hint
    assert f"warning: {telemetry}: {hint}" in pulsed.stderr
    assert -5.0 <= json.loads(pulsed.stdout)["pre_start_activity_at_s"] <= -4.0
    refused = runner.invoke(main, ["simulate", "--pre-start", "2.5", "--telemetry", "x.csv"])
    assert refused.exit_code == 1
    assert "--pre-start 2.5 s is not a whole number of the scenario's 1 s steps" in refused.output


def test_telemetry_stamps_from_a_start_with_an_offset_are_written_in_utc(tmp_path: Path) -> None:
    """The column is time_utc: a start given at +02:00 gave stamps at +02:00 under it."""
    telemetry = tmp_path / "t.csv"
    start = "2025-03-01T14:00:00+02:00"
    run_cli(["simulate", "-n", "1", "--time-offset", start, "--telemetry", str(telemetry)])
    lines = telemetry.read_text().splitlines()
    assert lines[0].startswith("time_utc,") and lines[1].startswith("2025-03-01T12:00:00.050000Z,")
    assert all(line.split(",")[0].endswith("Z") for line in lines[1:])


def test_identify_reads_gzip_telemetry_as_the_plain_file(
    tmp_path: Path, small_classifier: Path
) -> None:
    """pass.csv.gz and pass.json.gz (and gzip under a plain name, known by its magic
    bytes) give the plain file's verdict, alone and from a folder."""
    import gzip

    plain = tmp_path / "t.csv"
    _simulate_telemetry(plain, "4")
    text = plain.read_bytes()
    rows = [line.split(",") for line in text.decode().split()[1:]]
    document = {
        "time_s": [float(r[0]) for r in rows],
        "omega_rad_s": [[float(v) for v in r[1:]] for r in rows],
    }
    folder = tmp_path / "downlink"
    folder.mkdir()
    (folder / "a.csv.gz").write_bytes(gzip.compress(text))
    (folder / "b.json.gz").write_bytes(gzip.compress(json.dumps(document).encode()))
    (folder / "c.csv").write_bytes(gzip.compress(text))
    base = ["identify", "--classifier", str(small_classifier)]
    expected = json.loads(run_cli([*base, "--telemetry", str(plain)]).stdout)
    assert expected["candidate"] == "payload 3 ejected"
    for name in ("a.csv.gz", "b.json.gz", "c.csv"):
        verdict = json.loads(run_cli([*base, "--telemetry", str(folder / name)]).stdout)
        assert verdict == expected, name
    lines = [json.loads(line) for line in run_cli([*base, str(folder)]).stdout.splitlines()]
    assert [line.pop("path") for line in lines] == [
        str(folder / name) for name in ("a.csv.gz", "b.json.gz", "c.csv")
    ]
    assert lines == [expected] * 3


def test_identify_reads_telemetry_that_begins_with_a_byte_order_mark(
    tmp_path: Path, small_classifier: Path
) -> None:
    """A spreadsheet's "CSV UTF-8" export (and some ground tools' JSON) begins with a
    UTF-8 byte order mark: the CLI gives it the plain file's verdict, as the API does with
    the same upload. (It was refused: "CSV header column 1 is '\\ufefftime_s': not a
    time ...", and the JSON as not valid JSON.)"""
    plain = tmp_path / "t.csv"
    _simulate_telemetry(plain, "4")
    text = plain.read_text()
    rows = [line.split(",") for line in text.split()[1:]]
    document = json.dumps(
        {
            "time_s": [float(r[0]) for r in rows],
            "omega_rad_s": [[float(v) for v in r[1:]] for r in rows],
        }
    )
    marked_csv = tmp_path / "excel.csv"
    marked_csv.write_text(text, encoding="utf-8-sig")
    marked_json = tmp_path / "tool.json"
    marked_json.write_text(document, encoding="utf-8-sig")
    base = ["identify", "--classifier", str(small_classifier)]
    expected = json.loads(run_cli([*base, "--telemetry", str(plain)]).stdout)
    assert expected["candidate"] == "payload 3 ejected"
    for marked in (marked_csv, marked_json):
        assert marked.read_bytes().startswith(b"\xef\xbb\xbf")
        verdict = json.loads(run_cli([*base, "--telemetry", str(marked)]).stdout)
        assert verdict == expected, marked.name


def test_identify_reads_an_averaging_gyro_at_its_intervals_midpoints(
    tmp_path: Path, small_classifier: Path
) -> None:
    """--averaged-gyro: each rate the mean over the second before its stamp, read at the
    interval's midpoint (the same telemetry read at its stamps is another series)."""
    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(telemetry, "3")
    import numpy as np

    rows = np.loadtxt(telemetry, delimiter=",", skiprows=1)
    means = rows[:, 1:].reshape(4, 20, 3).mean(axis=1)
    lines = ["time_s,wx,wy,wz"] + [
        f"{k + 1}.0," + ",".join(f"{v:.10g}" for v in row) for k, row in enumerate(means)
    ]
    telemetry.write_text("\n".join(lines) + "\n")
    base = ["identify", "--classifier", str(small_classifier), str(telemetry)]
    averaged = json.loads(run_cli([*base, "--averaged-gyro"]).stdout)
    at_stamps = json.loads(run_cli(base).stdout)
    assert averaged["distances"] != pytest.approx(at_stamps["distances"])
    assert averaged["candidate"] == "payload 2 ejected"


def test_the_help_benchmark_times_every_command(monkeypatch: pytest.MonkeyPatch) -> None:
    """bench/cli_help.py kept its own list, which left out ``plan``."""
    import importlib
    import sys

    from inertia_id.cli import COMMANDS

    monkeypatch.syspath_prepend(str(Path(__file__).parents[2] / "bench"))
    monkeypatch.delitem(sys.modules, "cli_help", raising=False)
    assert set(importlib.import_module("cli_help").COMMANDS) == set(COMMANDS)


def test_identify_judges_a_dropout_with_the_default_kind_and_reports_it(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    """A 10 Hz pass that lost 0.5 s: the default kind's verdict lists the gap and the part
    covered; the Euclidean clustering refuses it naming the gap and the kind that can."""
    default = tmp_path / "default.json"
    run_cli(["train", "-n", "10", "--out", str(default)])
    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(telemetry, "3", "--sample-rate", "10")
    header, *rows = telemetry.read_text().splitlines()
    kept = [row for row in rows if not 1.5 + 1e-9 < float(row.split(",")[0]) < 2.0 - 1e-9]
    assert len(rows) - len(kept) == 4
    telemetry.write_text("\n".join([header, *kept]) + "\n")
    verdict = json.loads(run_cli(["identify", "--classifier", str(default), str(telemetry)]).stdout)
    assert verdict["candidate"] == "payload 2 ejected"
    assert verdict["telemetry_gaps"] == [
        {"from_s": pytest.approx(1.5), "to_s": pytest.approx(2.0), "length_s": pytest.approx(0.5)}
    ]
    assert verdict["sequence_covered_fraction"] == pytest.approx(71 / 80)
    refused = runner.invoke(
        main, ["identify", "--classifier", str(small_classifier), str(telemetry)]
    )
    assert refused.exit_code == 1
    assert "no sample from 1.5 s to 2 s" in refused.output
    assert "The 'clustering' classifier compares whole series" in refused.output


def _deadlines_on_a_ticking_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every Deadline made from now on reads a clock one second further on at every
    reading: no sleeps, and no dependence on the machine's speed."""
    ticks = itertools.count()
    init = Deadline.__init__

    def on_ticking_clock(
        self: Deadline, time_limit_s: Any, clock: Any = None, grace_s: Any = None
    ) -> None:
        init(self, time_limit_s, lambda: float(next(ticks)), grace_s)

    monkeypatch.setattr(Deadline, "__init__", on_ticking_clock)


def test_a_search_cut_at_its_time_limit_says_what_was_not_rescored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """NSGA-II with --time-limit 1 --time-limit-grace 0: the front's other candidates
    and the best's fresh draws are left out; the listing said nothing of either. The
    deadlines run on a clock one second further on at every reading (no sleeps, and no
    dependence on the machine's speed): the limit is spent at its first check."""
    _deadlines_on_a_ticking_clock(monkeypatch)
    args = ["search", "--method", "nsga2", "--length", "2", "--nsga2", "population=8"]
    args += ["--nsga2", "generations=2", "--search-realisations", "4"]
    args += ["--fresh-realisations", "4", "--fresh-test-series", "2"]
    doc, result = run_cli_json(
        [*args, "--time-limit", "1", "--time-limit-grace", "0"], tmp_path / "s.json"
    )
    left = len(doc["front"]["not_rescored"])
    assert left > 0 and doc["fresh"]["draws_asked"] > len(doc["fresh"]["f1"])
    why = "the time limit (1 s) was reached and no grace was asked for"
    assert f"+ {left} candidates not re-scored: {why}" in result.output
    done, asked = len(doc["fresh"]["f1"]), doc["fresh"]["draws_asked"]
    assert f"F1 is on {done} of the {asked} fresh draws asked: {why}" in result.output
    # No mean of no draws (it printed "F1 nan" with a RuntimeWarning).
    assert done > 0 or "found: no fresh draw was scored (stopped: time_limit)" in result.output
    assert "nan" not in result.output


def test_train_stops_at_its_time_limit_and_writes_nothing(
    runner: CliRunner, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``train --time-limit``, as ``search`` has (train had none). The deadline runs on a
    clock one second further on at every reading, so the limit is spent at the
    training's first checkpoint on any machine."""
    args = ["train", "--kind", "nearest-centroid", "--metric", "euclidean", "-n", "3"]
    roomy = tmp_path / "roomy.json"
    run_cli([*args, "--time-limit", "600", "--out", str(roomy)])
    assert json.loads(roomy.read_text())["format"] == "inertia-id/supervised-classifier"

    _deadlines_on_a_ticking_clock(monkeypatch)
    out = tmp_path / "c.json"
    result = runner.invoke(main, [*args, "--time-limit", "1", "--out", str(out)])
    assert result.exit_code == 1, result.output
    message = " ".join(result.output.split())
    assert "the training reached its time limit of 1 s (--time-limit)" in message
    assert f"stopped part-way; nothing written to {out}" in message
    assert "Traceback" not in result.output and not out.exists()


def test_identify_and_the_plan_number_a_candidate_alike(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    """identify named its candidate by ``candidate_index`` from 0 while plan tables number
    candidates from 1 (``# candidate_3 ...``, ``candidate_3_wx_rad_s``), and ``simulate
    --candidate 2`` flew the third. Now one convention: a candidate's number from 1 beside
    its name in identify's ``candidate_number``, the plan's JSON ``number`` and CSV, and
    ``simulate --candidate``; ``candidate_index`` keeps its meaning (from 0)."""
    telemetry = tmp_path / "t.csv"
    flown = runner.invoke(
        main,
        ["simulate", "-n", "1", "--seed", "11", "--candidate", "3", "--telemetry", str(telemetry)],
    )
    assert flown.exit_code == 0, flown.output
    assert "(candidate 3 'payload 2 ejected', realisation 0)" in flown.stderr
    verdict = json.loads(
        run_cli(["identify", "--classifier", str(small_classifier), str(telemetry)]).stdout
    )
    assert verdict["candidate"] == "payload 2 ejected"
    assert (verdict["candidate_number"], verdict["candidate_index"]) == (3, 2)
    plan, _ = run_cli_json(["plan", "--sequence", "4,4,4,0,0,0"], tmp_path / "p.json")
    numbered = {c["number"]: c["name"] for c in plan["candidates"]}
    assert numbered[verdict["candidate_number"]] == verdict["candidate"]
    run_cli(["plan", "--sequence", "4,4,4,0,0,0", "--out", str(tmp_path / "p.csv")])
    table = (tmp_path / "p.csv").read_text()
    assert f'# candidate_3 "{verdict["candidate"]}": residual_rate_rad_s' in table
    assert ",candidate_3_wx_rad_s," in table
    refused = runner.invoke(main, ["simulate", "--candidate", "0", "--telemetry", "x.csv"])
    assert refused.exit_code == 1
    assert (
        "numbered from 1" in refused.output and "the first is 1, 'none ejected'" in refused.output
    )


def test_train_and_plan_warn_when_the_response_is_far_below_the_gyro_noise(
    tmp_path: Path,
) -> None:
    # A reviewer's case: inertia typed in kg mm^2 as kg m^2 (1e6 too large) trained to F1
    # near chance and planned a peak rate of 1e-7 rad/s under a 1e-3 rad/s gyro without a
    # word. Warned, not refused: both still write their outputs.
    from inertia_id import preset

    paper = preset("paper")
    candidates = [
        {"name": c.name, "inertia_kg_m2": (np.asarray(c.inertia_kg_m2) * 1e6).tolist()}
        for c in paper.inertia_candidates
    ]
    scenario = tmp_path / "mm.json"
    scenario.write_text(preset("paper", name="mm", inertia_candidates=candidates).model_dump_json())
    sequence = "4,4,4,0,0,0;4,4,4,0,0,0"
    plan, planned = run_cli_json(
        ["plan", "--scenario", str(scenario), "--sequence", sequence], tmp_path / "p.json"
    )
    (warning,) = plan["warnings"]
    assert "predicted to peak at 1.02e-07 rad/s" in warning
    assert "below the gyro noise (0.001 rad/s, 0.0573 deg/s a sample) by 9.83e+03x" in warning
    assert "kg mm^2 typed as kg m^2" in warning
    assert f"warning: {warning}" in planned.stderr
    classifier = tmp_path / "c.json"
    options = ["--sequence", sequence, "--metric", "euclidean", "-n", "5"]
    trained = run_cli(["train", "--scenario", str(scenario), *options, "--out", str(classifier)])
    assert json.loads(trained.stdout)["warnings"] == [warning]
    assert f"warning: {warning}" in trained.stderr
    # The paper preset's own scenario warns of nothing.
    plan, planned = run_cli_json(["plan", "--sequence", sequence], tmp_path / "q.json")
    assert plan["warnings"] == [] and "warning" not in planned.stderr


def test_simulate_refuses_a_candidate_that_is_one_name_and_another_number(
    runner: CliRunner, tmp_path: Path
) -> None:
    """A name won over a number, so with the first candidate named "3", ``--candidate 3``
    flew the first and the third (number 3 in plan tables) could not be asked for by its
    number. Now that value is refused naming both readings, and ``--candidate-number``
    is a number only."""
    from inertia_id import preset

    document = preset("paper").model_dump(mode="json")
    document["inertia_candidates"][0]["name"] = "3"
    document["inertia_candidates"][4]["name"] = "5"  # the fifth: no other reading
    scenario = tmp_path / "s.json"
    scenario.write_text(json.dumps(document))
    telemetry = tmp_path / "t.csv"
    base = ["simulate", "-n", "1", "--scenario", str(scenario), "--telemetry", str(telemetry)]

    refused = runner.invoke(main, [*base, "--candidate", "3"])
    assert refused.exit_code == 1, refused.output
    assert (
        "--candidate '3' is both the name of candidate 1 and the number of candidate 3 "
        "('payload 2 ejected'): give --candidate-number 1 for the one named '3', or "
        "--candidate-number 3 for number 3"
    ) in refused.output
    assert not telemetry.exists()
    for asked, flown in (
        (["--candidate-number", "3"], "(candidate 3 'payload 2 ejected', realisation 0)"),
        (["--candidate-number", "1"], "(candidate 1 '3', realisation 0)"),
        (["--candidate", "5"], "(candidate 5 '5', realisation 0)"),
        (["--candidate", "payload 2 ejected"], "(candidate 3 'payload 2 ejected', realisation 0)"),
        ([], "(candidate 1 '3', realisation 0)"),
    ):
        result = runner.invoke(main, [*base, *asked])
        assert result.exit_code == 0, result.output
        assert flown in result.stderr, asked
    for asked, message in (
        (["--candidate", "3", "--candidate-number", "3"], "both name the candidate; give one"),
        (["--candidate-number", "6"], "--candidate-number 6: the scenario has 5 candidates"),
        (["--candidate-number", "0"], "0 is not in the range x>=1"),
    ):
        result = runner.invoke(main, [*base, *asked])
        assert result.exit_code in (1, 2) and message in result.output, result.output
    result = runner.invoke(main, ["simulate", "-n", "1", "--candidate-number", "2"])
    assert result.exit_code == 1
    assert "--candidate-number applies with --telemetry only" in result.output


def test_identify_says_when_the_kind_cannot_test_for_bodies_off_the_candidates(
    tmp_path: Path,
) -> None:
    """A ``likelihood`` classifier has no model of other bodies near the candidates: its
    verdict gave ``fits_off_candidates`` false, as though the test had passed, so a pass
    no candidate gives was named with full confidence and no warning. Now the flag is
    null, the note says why, and a name is followed by a warning on stderr."""
    classifier = tmp_path / "likelihood.json"
    run_cli(["train", "--kind", "likelihood", "-n", "10", "--out", str(classifier)])
    telemetry = tmp_path / "pass.csv"
    _simulate_telemetry(telemetry, "4")
    result = run_cli(["identify", "--classifier", str(classifier), "--telemetry", str(telemetry)])
    verdict = json.loads(result.stdout)
    assert verdict["status"] == "identified"
    assert verdict["fits_off_candidates"] is None
    assert verdict["off_candidates_log_bayes"] is None
    note = verdict["off_candidates_note"]
    assert note.startswith("this classifier cannot test for bodies off the candidates")
    assert "likelihood kind" in note
    assert result.stderr == f"warning: {note}\n"
    # Several files: one warning for the run, counting the names it concerns.
    folder = tmp_path / "downlink"
    folder.mkdir()
    for name in ("a.csv", "b.csv"):
        (folder / name).write_text(telemetry.read_text())
    many = run_cli(["identify", "--classifier", str(classifier), str(folder)])
    assert len(many.stdout.splitlines()) == 2
    assert many.stderr == f"warning (2 identified verdicts): {note}\n"


def test_the_search_bar_says_whether_its_best_met_the_constraints(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No sequence of 3 steps reaches 0.9 on 9 N m s (test_pareto's case): the bar named
    the best of all, 0.939, "best_accuracy" while it broke the constraints."""
    import tqdm

    shown: list[str] = []
    monkeypatch.setattr(
        tqdm.tqdm, "set_postfix", lambda self, figures=None, **kw: shown.extend(figures or kw)
    )
    args = ["search", "--method", "nsga2", "--length", "3", "--nsga2", "population=8"]
    args += ["--nsga2", "generations=2", "--search-realisations", "4"]
    args += ["--constraint", "min_accuracy=0.9", "--constraint", "max_impulse_nms=9"]
    result = CliRunner().invoke(main, [*args, "--out", str(tmp_path / "s.json")])
    assert "no sequence met the constraints" in result.output
    assert shown and set(shown) == {"best_accuracy_none_feasible_yet"}
    shown.clear()
    run_cli([*args[:-4], "--constraint", "max_impulse_nms=9", "--out", str(tmp_path / "t.json")])
    assert shown and set(shown) == {"best_accuracy_feasible"}


def test_plan_says_one_step_in_the_singular(tmp_path: Path) -> None:
    """It said 'wrote plan.json: 1 steps, ...'."""
    for sequence, said in [
        ("4,4,4,0,0,0", ": 1 step, "),
        ("4,4,4,0,0,0;0,0,0,4,4,4", ": 2 steps, "),
    ]:
        result = run_cli(["plan", "--sequence", sequence, "--out", str(tmp_path / "p.json")])
        assert said in result.output, result.output


def _seven_thrusters(tmp_path: Path) -> Path:
    """The paper preset with a seventh thruster that gives no torque (a zero column)."""
    from inertia_id import preset

    document = preset("paper").model_dump(mode="json")
    torque = np.zeros((3, 7))
    torque[:, :6] = [[2, -2, 0, 0, 0, 0], [0, 0, 2, -2, 0, 0], [0, 0, 0, 0, 2, -2]]
    document["thrusters"] = {"torque_matrix_nm": torque.tolist(), "n_levels": 5}
    path = tmp_path / "seven.json"
    path.write_text(json.dumps(document))
    return path


def test_scenario_warns_of_a_thruster_that_gives_no_torque(tmp_path: Path) -> None:
    """``inertia-id scenario`` validated a scenario with a thruster that gives no torque
    (a zero column of the torque matrix) without a word; it now warns on stderr, naming
    the thruster by its number, and still writes the scenario."""
    path = _seven_thrusters(tmp_path)
    written, result = run_cli_json(["scenario", "--scenario", str(path)], tmp_path / "out.json")
    said = "warning: thruster 7 gives no torque (column 7 of torque_matrix_nm is zero"
    assert result.stderr.count(said) == 1, result.stderr
    assert len(written["thrusters"]["torque_matrix_nm"][0]) == 7
    # The paper's own thrusters all give torque: nothing on stderr.
    assert run_cli(["scenario", "--preset", "paper"]).stderr == ""


def test_every_command_that_loads_a_scenario_warns_of_a_thruster_that_gives_no_torque(
    tmp_path: Path,
) -> None:
    """Only ``inertia-id scenario`` warned of a thruster that gives no torque; ``simulate``,
    ``plan`` (and ``train``, ``search``) loaded the same file without a word. Each warns
    once, on stderr: stdout still holds the JSON alone."""
    path = _seven_thrusters(tmp_path)
    said = "warning: thruster 7 gives no torque (column 7 of torque_matrix_nm is zero"
    simulated = run_cli(["simulate", "--scenario", str(path), "--sequence", "4,4,4,0,0,0,0"])
    assert simulated.stderr.count(said) == 1, simulated.stderr
    assert json.loads(simulated.stdout)["series_shape"][0] == 5
    planned = run_cli(
        [
            "plan",
            "--scenario",
            str(path),
            "--sequence",
            "0,0,4,0,0,0,0",
            "--out",
            str(tmp_path / "plan.json"),
        ]
    )
    assert planned.stderr.count(said) == 1, planned.stderr
    assert "warning: thruster" not in run_cli(["simulate", "--sequence", "4,4,4,0,0,0"]).stderr


def test_plan_of_a_search_warns_of_a_thruster_of_its_scenario_that_gives_no_torque(
    tmp_path: Path,
) -> None:
    """``plan --search`` without ``--scenario`` plans on the scenario the search
    recorded, read outside ``load_scenario``: its thruster that gives no torque was not
    warned of. Now it is, once, on stderr; named beside it too (still once)."""
    seven = _seven_thrusters(tmp_path)
    search = tmp_path / "search.json"
    document = _search_document([[4, 4, 4, 0, 0, 0, 0]], json.loads(seven.read_text()))
    search.write_text(json.dumps(document))
    said = "warning: thruster 7 gives no torque (column 7 of torque_matrix_nm is zero"
    for named in [[], ["--scenario", str(seven)]]:
        planned = run_cli(["plan", "--search", str(search), *named, "--out", "-"])
        assert planned.stderr.count(said) == 1, planned.stderr
        assert json.loads(planned.stdout)["sequence"] == [[4, 4, 4, 0, 0, 0, 0]]


def test_identify_reads_json_telemetry_in_deg_s(tmp_path: Path, small_classifier: Path) -> None:
    """A JSON file states deg/s with ``omega_deg_s``, as a CSV header does with
    ``wx_deg_s``: the same verdict as the file in rad/s. (JSON could not say it: the key
    was refused as unknown.)"""
    plain = tmp_path / "t.csv"
    _simulate_telemetry(plain, "4")
    rows = [line.split(",") for line in plain.read_text().split()[1:]]
    in_degrees = tmp_path / "t.json"
    in_degrees.write_text(
        json.dumps(
            {
                "time_s": [float(r[0]) for r in rows],
                "omega_deg_s": [[math.degrees(float(v)) for v in r[1:]] for r in rows],
            }
        )
    )
    base = ["identify", "--classifier", str(small_classifier)]
    expected = json.loads(run_cli([*base, str(plain)]).stdout)
    verdict = json.loads(run_cli([*base, str(in_degrees)]).stdout)
    assert verdict["candidate"] == expected["candidate"] == "payload 3 ejected"
    assert verdict["distances"] == pytest.approx(expected["distances"])


def test_a_start_search_that_misses_the_start_says_so_beside_the_json(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    """The start stated 1.5 s before the thrusters fired, searched within ±1 s: the start
    taken lies at the window's edge and a start beyond it fits better, said on stderr
    and in the JSON, with the window that reaches it (nothing said it before); a window
    that no start fits says how wide a search the telemetry allows."""
    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(telemetry, "3", "--pre-start", "10", "--time-offset", "810000000")
    base = ["identify", "--classifier", str(small_classifier), str(telemetry)]
    early = run_cli([*base, "--sequence-start", "809999998.5", "--estimate-start-within", "1"])
    verdict = json.loads(early.stdout)
    assert verdict["sequence_start_shift_s"] == pytest.approx(1.0)
    assert verdict["start_window_better_shift_s"] > 1.0
    assert f"warning: {telemetry}: {verdict['start_window_hint']}" in early.stderr
    assert "lies at the edge of the ±1 s searched" in early.stderr
    wider = verdict["start_window_hint"].split("window to ±")[1].split(" s")[0]
    found = run_cli([*base, "--sequence-start", "809999998.5", "--estimate-start-within", wider])
    assert json.loads(found.stdout)["start_window_hint"] is None
    assert json.loads(found.stdout)["sequence_start_shift_s"] == pytest.approx(1.5, abs=0.051)
    # No start within ±1 s of a start stated 20 s early: the refusal names the window to ask.
    lost = runner.invoke(
        main, [*base, "--sequence-start", "809999980", "--estimate-start-within", "1"]
    )
    assert lost.exit_code == 1
    assert "outside the window: check the stated start, or widen the window to ±" in lost.output


def test_identify_names_its_classifier_in_the_verdict(
    runner: CliRunner, tmp_path: Path, small_classifier: Path
) -> None:
    """The CLI's verdict named no classifier (the API's names its classifier_id; a hostile
    review): it names the file, the sha256 its document states and, for a file the
    service handed out, its provenance and classifier_id; in a batch, on every line. A
    provenance that is not an object of strings is refused by name."""
    from inertia_id.classifiers import documents

    telemetry = tmp_path / "t.csv"
    _simulate_telemetry(telemetry, "4")
    text = small_classifier.read_text()
    sha256 = json.loads(text)["sha256"]
    verdict = json.loads(
        run_cli(["identify", "--classifier", str(small_classifier), str(telemetry)]).stdout
    )
    assert verdict["classifier_id"] is None
    assert verdict["classifier"] == {
        "file": str(small_classifier),
        "sha256": sha256,
        "provenance": None,
    }
    assert verdict["candidate"] == "payload 3 ejected"

    provenance = {
        "classifier_id": "0123456789abcdef0123456789abcdef",
        "job_id": "fedcba9876543210fedcba9876543210",
        "scenario_id": "00112233445566778899aabbccddeeff",
        "created_at": "2026-12-07T17:52:39.123456Z",
    }
    downloaded = tmp_path / "classifier-0123.json"
    downloaded.write_bytes(bytes(documents.with_provenance(text, provenance)))
    folder = tmp_path / "downlink"
    folder.mkdir()
    (folder / "a.csv").write_text(telemetry.read_text())
    (folder / "b.csv").write_text(telemetry.read_text())
    lines = [
        json.loads(line)
        for line in run_cli(
            ["identify", "--classifier", str(downloaded), str(folder)]
        ).stdout.splitlines()
    ]
    assert len(lines) == 2
    for line in lines:
        assert line["classifier_id"] == provenance["classifier_id"]
        assert line["classifier"] == {
            "file": str(downloaded),
            "sha256": sha256,
            "provenance": provenance,
        }
        assert line["candidate"] == "payload 3 ejected"

    edited = json.loads(text)
    edited["provenance"] = ["not", "an", "object"]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(edited))
    refused = runner.invoke(main, ["identify", "--classifier", str(bad), str(telemetry)])
    assert refused.exit_code == 1
    assert "provenance must be a JSON object, got list" in refused.output
    assert "Traceback" not in refused.output
