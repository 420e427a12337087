"""Cross-entropy-method search: reproducible, finds the brute-force best, stops when told."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from typing import Any

import pytest

from inertia_id import Scenario
from inertia_id.search import (
    SEARCH_METHODS,
    ScorerSettings,
    SearchProgress,
    SearchResult,
    cem_search,
    exhaustive_search,
    random_search,
    search,
)

SETTINGS = ScorerSettings(n_realisations=4)
SEPARABILITY = ScorerSettings(n_realisations=4, objective="separability")


def run(tiny: Scenario, **options: Any) -> SearchResult:
    defaults: dict[str, Any] = {
        "sequence_length": 2,
        "total_timesteps": 160,
        "population": 16,
        "seed": 0,
        "settings": SETTINGS,
        "patience_episodes": None,
        "n_fresh_draws": 1,
    }
    return cem_search(tiny, **{**defaults, **options})


def test_same_seed_same_search_and_another_seed_another(tiny: Scenario) -> None:
    first, again = run(tiny, seed=4), run(tiny, seed=4)
    assert again.curve == first.curve
    assert again.best == first.best
    assert again.fresh == first.fresh
    assert run(tiny, seed=5).curve != first.curve


@pytest.mark.parametrize("settings", [SETTINGS, SEPARABILITY], ids=["f1", "separability"])
def test_finds_the_exhaustive_best_of_a_small_space(
    tiny: Scenario, settings: ScorerSettings
) -> None:
    # Same seed, same noise draw: the scores CEM sees are the exhaustive search's.
    best = exhaustive_search(tiny, sequence_length=2, seed=3, settings=settings, n_fresh_draws=1)
    found = run(tiny, seed=3, settings=settings, total_timesteps=2_000, elite_fraction=0.25)
    assert found.best.f1 == best.best.f1
    assert found.best.final_rate_rad_s == best.best.final_rate_rad_s
    assert found.best.sequence == best.best.sequence
    # It learnt: its first, uniformly drawn iteration missed the best, and its last
    # iteration's sequences score better on average.
    assert found.curve[0].best_f1 < best.best.f1
    assert found.curve[-1].mean_f1 > found.curve[0].mean_f1
    assert found.stopped in ("converged", "budget")


def test_one_curve_point_and_progress_report_per_iteration(tiny: Scenario) -> None:
    reports: list[SearchProgress] = []
    result = run(tiny, total_timesteps=100, progress=reports.append)
    # 16 sequences of 2 steps per iteration; the budget cuts the 4th iteration at 2 of 16.
    assert [p.timesteps for p in result.curve] == [32, 64, 96, 100]
    assert [p.episodes for p in result.curve] == [16, 32, 48, 50]
    assert [r.point for r in reports] == result.curve
    assert [r.fraction for r in reports] == pytest.approx([0.32, 0.64, 0.96, 1.0])
    assert [p.best_f1 for p in result.curve] == sorted(p.best_f1 for p in result.curve)
    assert result.stopped == "budget"
    assert (result.timesteps, result.episodes) == (100, 50)


def test_cancel_is_checked_before_each_sequence(
    tiny: Scenario, stop_after: Callable[[int], Any]
) -> None:
    should_stop = stop_after(5)
    result = run(tiny, should_stop=should_stop)
    assert result.stopped == "cancelled"
    assert (result.episodes, result.timesteps) == (5, 10)
    assert result.curve[-1].timesteps == 10


def test_stops_at_the_target(tiny_quiet: Scenario) -> None:
    result = run(
        tiny_quiet, total_timesteps=2_000, patience_episodes=20,
        settings=ScorerSettings(n_realisations=3),
    )  # fmt: skip
    assert result.stopped == "target"
    assert result.best.f1 == 1.0
    assert result.episodes == result.best.episode + 20


def test_stops_once_the_distribution_has_collapsed(tiny: Scenario) -> None:
    # Moving all the way to a single elite leaves one sequence to draw.
    result = run(tiny, total_timesteps=1_000, smoothing=1.0, elite_fraction=0.01)
    assert result.stopped == "converged"
    assert result.episodes == 16 and len(result.curve) == 1


def test_result_json_round_trips_with_the_shape_of_every_search(tiny: Scenario) -> None:
    result = search("cem", tiny, sequence_length=2, total_timesteps=64, population=8,
                    settings=SEPARABILITY, n_fresh_draws=2)  # fmt: skip
    assert "cem" in SEARCH_METHODS
    assert result.method == "cem"
    data = json.loads(result.to_json())
    baseline = json.loads(
        random_search(tiny, sequence_length=2, total_timesteps=8, settings=SETTINGS,
                      n_fresh_draws=1).to_json()
    )  # fmt: skip
    assert data.keys() == baseline.keys()
    assert data["best"].keys() == baseline["best"].keys()
    assert data["curve"][0].keys() == baseline["curve"][0].keys()
    assert data["best"]["sequence"] == result.best.sequence
    assert data["settings"]["cem"] == {"population": 8, "elite_fraction": 0.125, "smoothing": 0.7}
    assert data["settings"]["scorer"]["objective"] == "separability"
    # best.f1 holds the objective's score whatever its name; the document says which.
    assert data["best"]["score_name"] == "separability"
    assert "not an F1" in data["best"]["score_meaning"]
    assert baseline["best"]["score_name"] == "f1"
    # The fresh draws report the clustering F1 and, for this objective, the separability.
    assert len(data["fresh"]["f1"]) == 2 and len(data["fresh"]["separability"]) == 2
    assert baseline["fresh"]["separability"] is None
    assert data["fresh"]["f1_mean"] == pytest.approx(result.fresh.f1_mean)
    assert "separability" in result.summary()


@pytest.mark.parametrize(
    ("options", "quoted"),
    [
        ({"population": 1}, "population must be an integer in 2..1000000, got 1"),
        ({"population": 8.0}, "8.0"),
        ({"elite_fraction": 0.0}, "elite_fraction must be a number in (0, 1], got 0.0"),
        ({"smoothing": 1.5}, "smoothing must be a number in (0, 1], got 1.5"),
        ({"smoothing": float("nan")}, "nan"),
        ({"total_timesteps": 1}, "got 1"),
    ],
)
def test_bad_parameters_are_refused(tiny: Scenario, options: dict[str, Any], quoted: str) -> None:
    with pytest.raises(ValueError, match=re.escape(quoted)):
        run(tiny, **options)
