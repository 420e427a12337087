"""The hand-designed baselines scored on the draws a search's best sequence was."""

from __future__ import annotations

from inertia_id import Scenario
from inertia_id.physics.sequences import hand_designed
from inertia_id.search import ScorerSettings, evaluate_sequence
from inertia_id.search.baselines import compare_with_baselines


def test_baselines_are_scored_on_the_given_fresh_draws(paper: Scenario) -> None:

    settings = ScorerSettings(n_realisations=8, metric="euclidean")
    compared = compare_with_baselines(paper, 3, settings, seed=11, n_draws=2)
    assert list(compared) == [
        "hand-designed",
        "axis-in-turn",
        "fire-then-brake",
        "fire-coast-brake",
    ]
    same = evaluate_sequence(paper, hand_designed(paper, 3), settings, seed=11, n_draws=2)
    assert compared["hand-designed"]["fresh_f1"] == same.f1
    assert compared["hand-designed"]["fuel_nms"] == 18.0  # 3 thrusters x 2 N m x 3 s
    assert compared["axis-in-turn"]["fuel_nms"] == 6.0


def test_a_cancelled_search_scores_no_further_baseline(paper: Scenario) -> None:
    """A cancel came while the baselines were scored: each took a fresh evaluation, and
    the job went on for minutes before it said cancelled."""
    settings = ScorerSettings(n_realisations=8, metric="euclidean")
    asked: list[int] = []

    def stop_after_first() -> bool:
        # Asked before each baseline and before each of its 4 prefixes is clustered.
        asked.append(1)
        return len(asked) > 5

    compared = compare_with_baselines(
        paper, 4, settings, seed=11, n_draws=1, should_stop=stop_after_first
    )
    assert "fresh_f1" in compared["hand-designed"]
    cancelled = {"unavailable": "not scored: the search was cancelled"}
    assert [compared[n] for n in ("axis-in-turn", "fire-then-brake", "fire-coast-brake")] == [
        cancelled
    ] * 3


def test_a_stop_heard_within_a_baseline_leaves_it_unscored(paper: Scenario) -> None:
    """Stopped between two prefixes: the baseline is on the best's draws, or not at all."""
    settings = ScorerSettings(n_realisations=8, metric="euclidean")
    asked: list[int] = []

    def stop_within_the_first() -> bool:
        asked.append(1)
        return len(asked) > 3

    compared = compare_with_baselines(
        paper, 4, settings, seed=11, n_draws=1, should_stop=stop_within_the_first
    )
    assert compared["hand-designed"] == {"unavailable": "not scored: the search was cancelled"}
