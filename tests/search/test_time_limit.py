"""A search's time limit (every method) and what a cancel skips, on an injected clock: no
test sleeps or times anything."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

import pytest

from inertia_id import InputError, Scenario
from inertia_id.deadline import check_grace
from inertia_id.physics.simulate import Simulator
from inertia_id.pipelines import SearchRequest, search_with_baselines
from inertia_id.search import (
    OperatorSettings,
    ScorerSettings,
    cem_search,
    exhaustive_search,
    pareto_search,
    ppo_search,
    random_search,
)
from inertia_id.search.loop import Deadline, check_time_limit, time_limit_grace_s

SETTINGS = ScorerSettings(n_realisations=4)


def ticking() -> Callable[[], float]:
    """A monotonic clock one second further on at every reading: a search reads it once
    per check of its limit, so a limit of N s is spent at the N-th check."""
    return itertools.count().__next__  # type: ignore[return-value]


@pytest.mark.parametrize("value", [0, -1.0, math.nan, math.inf, True, "60"])
def test_a_time_limit_that_is_no_positive_number_is_refused_naming_it(value: Any) -> None:
    with pytest.raises(InputError, match=rf"time_limit_s must be .* got {value!r}"):
        check_time_limit(value)
    with pytest.raises(InputError, match="time_limit_s"):
        SearchRequest(method="random", time_limit_s=value).options()


def test_a_deadline_expires_on_its_clock() -> None:
    now = [100.0]
    deadline = Deadline(2.5, lambda: now[0])
    now[0] = 102.4
    assert not deadline.expired()
    now[0] = 102.5
    assert deadline.expired()
    assert not Deadline(None, lambda: now[0]).expired()


def test_exhaustive_search_stops_at_its_time_limit_with_its_best_rescored(tiny: Scenario) -> None:
    result = exhaustive_search(
        tiny, sequence_length=2, settings=SETTINGS, n_fresh_draws=2, time_limit_s=4,
        clock=ticking(),
    )  # fmt: skip
    assert result.stopped == "time_limit"
    # Checked before every sequence from the second on: 4 s before the fifth.
    assert result.episodes == 4 < result.space_size
    assert result.best.sequence is not None and len(result.fresh.f1) == 2
    assert result.settings["time_limit_s"] == 4.0


def test_random_search_stops_at_its_time_limit(tiny: Scenario) -> None:
    result = random_search(
        tiny, sequence_length=2, total_timesteps=10_000, settings=SETTINGS, n_fresh_draws=1,
        time_limit_s=3, clock=ticking(),
    )  # fmt: skip
    assert (result.stopped, result.episodes) == ("time_limit", 3)
    assert len(result.fresh.f1) == 1


def test_cem_stops_at_its_time_limit_with_its_best_rescored(tiny: Scenario) -> None:
    result = cem_search(
        tiny, sequence_length=2, total_timesteps=10_000, population=8, settings=SETTINGS,
        n_fresh_draws=1, patience_episodes=None, time_limit_s=11, clock=ticking(),
    )  # fmt: skip
    assert result.stopped == "time_limit"
    assert result.episodes == 11  # within its second iteration
    assert result.best is not None and len(result.fresh.f1) == 1


def test_a_time_limit_spent_before_the_first_sequence_still_plays_one(tiny: Scenario) -> None:
    # A search stopped by its limit ends with a best: a limit spent at once plays one.
    result = random_search(
        tiny, sequence_length=2, total_timesteps=10_000, settings=SETTINGS, n_fresh_draws=1,
        time_limit_s=1e-9, clock=ticking(),
    )  # fmt: skip
    assert (result.stopped, result.episodes) == ("time_limit", 1)


def test_ppo_stops_at_its_time_limit_at_the_step(tiny: Scenario) -> None:
    result = ppo_search(
        tiny, sequence_length=2, total_timesteps=320, settings=SETTINGS,
        ppo_params={"n_steps": 32, "batch_size": 16, "n_epochs": 2}, n_fresh_draws=1,
        time_limit_s=4, clock=ticking(),
    )  # fmt: skip
    assert result.stopped == "time_limit"
    # Read every step once the first episode (2 steps) has ended: 4 s at step 5.
    assert result.timesteps == 5 and len(result.fresh.f1) == 1


def _nsga2(paper: Scenario, *, population: int = 8, **options: Any):
    return pareto_search(
        paper,
        sequence_length=2,
        seed=1,
        operator=OperatorSettings(n_realisations=4),
        nsga2_params={"population": population, "generations": 4, "polish_iterations": 0},
        fresh_realisations=6,
        fresh_test_series=20,
        n_fresh_draws=2,
        **options,
    )


def test_nsga2_stops_at_its_time_limit_with_a_front_on_fresh_draws(paper: Scenario) -> None:
    result = _nsga2(paper, time_limit_s=2, clock=ticking())
    assert result.stopped == "time_limit"
    assert len(result.curve) == 2  # read after every generation: 2 s after the second
    front = result.front
    assert front is not None and front["members"] and front["candidates_rescored"] >= 1
    # The front is re-scored on the fresh draw; its accuracy measurement is skipped.
    assert front["accuracy_source"] == "predicted" and front["measurement_stopped"]
    assert result.best.sequence == front["members"][0]["sequence"]
    assert len(result.fresh.f1) == 2  # the best re-scored as usual


def test_a_cancelled_nsga2_stops_within_a_generation_and_skips_the_front(
    paper: Scenario, stop_after: Callable[[int], Callable[[], bool]]
) -> None:
    # 40 a generation, checked after every 16 scored: the second check cancels.
    result = _nsga2(paper, population=40, should_stop=stop_after(1))
    assert result.stopped == "cancelled"
    assert result.episodes == 32 and result.curve == []
    assert result.front is None and result.fresh.f1 == []
    assert len(result.best.sequence) == 2


def test_a_cancel_skips_the_rescore_a_time_limit_keeps_it(
    tiny: Scenario, stop_after: Callable[[int], Callable[[], bool]]
) -> None:
    options = {"sequence_length": 2, "settings": SETTINGS, "n_fresh_draws": 2}
    cancelled = exhaustive_search(tiny, should_stop=stop_after(3), **options)
    assert cancelled.stopped == "cancelled" and cancelled.episodes == 3
    assert cancelled.fresh.f1 == [] and math.isnan(cancelled.fresh.f1_mean)
    assert "not re-scored" in cancelled.summary()
    timed = exhaustive_search(tiny, time_limit_s=3, clock=ticking(), **options)
    assert timed.stopped == "time_limit" and len(timed.fresh.f1) == 2


def test_a_cancelled_search_skips_its_front_and_baselines(
    paper: Scenario, stop_after: Callable[[int], Callable[[], bool]]
) -> None:
    request = SearchRequest(method="random", sequence_length=3, timesteps=60, n_realisations=4)
    outcome = search_with_baselines(paper, request, seed=0, should_stop=stop_after(2))
    result = outcome.result
    assert result.stopped == "cancelled" and result.front is None and result.fresh.f1 == []
    scored = [entry for entry in outcome.baselines.values() if "fresh_f1" in entry]
    assert scored == []
    assert {"unavailable": "not scored: the search was cancelled"} in outcome.baselines.values()
    assert outcome.to_dict()["best"]["sequence"] == result.best.sequence


def test_a_search_past_its_time_limit_rescores_while_its_grace_lasts(paper: Scenario) -> None:
    request = SearchRequest(
        method="random",
        sequence_length=3,
        timesteps=60,
        n_realisations=4,
        fresh_test_series=20,
        time_limit_s=3,
    )
    # One second a reading: the limit is spent at 3 s, its grace (10 s) at 13 s.
    outcome = search_with_baselines(paper, request, seed=0, clock=ticking())
    result = outcome.result
    assert result.stopped == "time_limit" and result.settings["time_limit_grace_s"] == 10.0
    # Taking the cancelling firings off the best found reads the clock once first; a
    # draw clusters 3 prefixes, a reading before each: 2 of the 5 draws fit.
    assert result.firings_taken_off is not None
    assert (len(result.fresh.f1), result.fresh.draws_asked) == (2, 5)
    assert "2 fresh draws of 5 asked, the re-score stopped (time_limit)" in result.summary()
    # The front of the best alone, always; its accuracy measurement skipped.
    assert result.front is not None and result.front["accuracy_source"] == "predicted"
    assert [m["sequence"] for m in result.front["members"]] == [result.best.sequence]
    spent = "not scored: the time limit (3 s) and its grace (10 s) were spent"
    assert {"unavailable": spent} in outcome.baselines.values()
    assert not [entry for entry in outcome.baselines.values() if "fresh_f1" in entry]


class WorkClock:
    """A monotonic clock that moves only with the work: ``step_s`` seconds per simulated
    step of a batch (every :meth:`Simulator.advance`, the search's and the re-score's
    alike), so how far past its limit a search ends counts the work it did after it."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch, step_s: float = 1.0) -> None:
        self.now = 0.0
        advance = Simulator.advance

        def timed(simulator: Simulator, *args: Any, **kwargs: Any) -> Any:
            self.now += step_s
            return advance(simulator, *args, **kwargs)

        monkeypatch.setattr(Simulator, "advance", timed)

    def __call__(self) -> float:
        return self.now


#: What may run past a limit and its grace, in simulated steps at L = 2 (WorkClock): the
#: sequence under way when the limit was read (NSGA-II: 16 sequences, 4 steps), the
#: front's first member and its baselines (always re-scored: NSGA-II, 12 steps), then
#: the piece under way when the grace ran out (a prefix, 2 steps; 16 front members, 6).
PAST_THE_GRACE_S = 24.0

METHODS: dict[str, Callable[..., Any]] = {
    "exhaustive": lambda scenario, **options: exhaustive_search(scenario, **options),
    "random": lambda scenario, **options: random_search(
        scenario, total_timesteps=10_000, **options
    ),
    "cem": lambda scenario, **options: cem_search(
        scenario, total_timesteps=10_000, population=8, patience_episodes=None, **options
    ),
    "ppo": lambda scenario, **options: ppo_search(
        scenario,
        total_timesteps=10_000,
        ppo_params={"n_steps": 32, "batch_size": 16, "n_epochs": 1},
        patience_episodes=None,
        **options,
    ),
    "nsga2": lambda scenario, settings, **options: pareto_search(
        scenario,
        operator=OperatorSettings(n_realisations=4),
        nsga2_params={"population": 40, "generations": 100, "polish_iterations": 0},
        fresh_realisations=6,
        fresh_test_series=20,
        **options,
    ),
}


@pytest.mark.parametrize("method", METHODS)
def test_a_search_ends_within_its_time_limit_and_grace(
    method: str, paper: Scenario, tiny: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = WorkClock(monkeypatch)
    # 20 fresh draws of 2 prefixes, 2 simulated steps each (the draw's and the plan's):
    # 80 s of re-score, far more than the grace (10 s).
    result = METHODS[method](
        tiny if method == "exhaustive" else paper, sequence_length=2, settings=SETTINGS,
        n_fresh_draws=20, seed=0, time_limit_s=30, clock=clock,
    )  # fmt: skip
    assert result.stopped == "time_limit"
    assert result.settings["time_limit_grace_s"] == 10.0
    assert clock() <= 30 + 10 + PAST_THE_GRACE_S
    # The result says what the grace did not reach.
    draws = len(result.fresh.f1)
    assert result.fresh.draws_asked == 20 and draws < 20
    summary = result.summary()
    if draws:
        assert f"{draws} fresh draws of 20 asked, the re-score stopped (time_limit)" in summary
    else:
        assert "not re-scored on fresh draws (time_limit)" in summary


def test_nsga2_past_its_grace_lists_the_front_candidates_not_rescored(
    paper: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    clock = WorkClock(monkeypatch)
    result = METHODS["nsga2"](
        paper, settings=SETTINGS, sequence_length=2, seed=0, time_limit_s=30, clock=clock
    )
    front = result.front
    assert result.stopped == "time_limit" and front is not None
    left_out = front["not_rescored"]
    # The most accurate on the search's draw first: member 0 always re-scored, more
    # 16 at a time while the grace lasted, the rest listed with the search's scores only.
    assert front["candidates_rescored"] >= 1 and left_out
    assert all(entry["search_scores"]["accuracy"] is not None for entry in left_out)
    members = {str(m["sequence"]) for m in front["members"]}
    assert not members & {str(entry["sequence"]) for entry in left_out}
    assert front["accuracy_source"] == "predicted" and front["measurement_stopped"]
    # The best is member 0; its clustering F1 draws came after the front, past the grace.
    assert result.best.sequence == front["members"][0]["sequence"]
    assert result.fresh.f1 == [] and result.fresh.draws_asked == 5
    assert "not re-scored on fresh draws (time_limit)" in result.summary()


@pytest.mark.parametrize("method", METHODS)
def test_a_grace_of_zero_stops_the_rescore_at_the_limit(
    method: str, paper: Scenario, tiny: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A flight team with a hard window asks for no grace: the search ends at its limit
    with nothing re-scored but what always is (NSGA-II: the front's first member and the
    baselines on the fresh draw), and the result says so."""
    clock = WorkClock(monkeypatch)
    result = METHODS[method](
        tiny if method == "exhaustive" else paper, sequence_length=2, settings=SETTINGS,
        n_fresh_draws=5, seed=0, time_limit_s=30, time_limit_grace_s=0, clock=clock,
    )  # fmt: skip
    assert result.stopped == "time_limit"
    assert result.settings["time_limit_grace_s"] == 0.0
    assert (result.fresh.f1, result.fresh.draws_asked) == ([], 5)
    if method == "nsga2":
        assert result.front is not None and result.front["not_rescored"]
    # It ends within its limit and the piece under way: no grace.
    assert clock() <= 30 + PAST_THE_GRACE_S


@pytest.mark.parametrize("value", [-1.0, math.nan, math.inf, True, "10", 3600.5, 60000])
def test_a_grace_that_is_no_number_of_seconds_is_refused_naming_it(value: Any) -> None:
    with pytest.raises(InputError, match=rf"time_limit_grace_s must be .* got {value!r}"):
        check_grace(value)
    with pytest.raises(InputError, match="time_limit_grace_s"):
        SearchRequest(method="random", time_limit_s=60, time_limit_grace_s=value).options()
    assert time_limit_grace_s(60, 0) == 0.0 and time_limit_grace_s(60, 120) == 120.0
    assert time_limit_grace_s(None, 5) is None
    # An hour at most, asked for (the default rule stops at 300 s).
    assert time_limit_grace_s(60, 3600) == 3600.0


def test_a_grace_over_its_bound_is_refused_with_the_bound() -> None:
    with pytest.raises(InputError, match=r"<= 3600 .* got 3601"):
        check_grace(3601)
    with pytest.raises(InputError, match=r"<= 3600 .* got 3601"):
        Deadline(60, grace_s=3601)


def test_without_a_time_limit_nothing_is_cut(tiny: Scenario) -> None:
    result = random_search(
        tiny, sequence_length=2, total_timesteps=40, settings=SETTINGS, n_fresh_draws=3,
    )  # fmt: skip
    assert result.settings["time_limit_grace_s"] is None
    assert (len(result.fresh.f1), result.fresh.draws_asked) == (3, 3)
    assert "asked" not in result.summary()


def test_the_grace_is_a_tenth_of_the_limit_at_least_ten_seconds_at_most_five_minutes() -> None:
    assert time_limit_grace_s(None) is None
    assert time_limit_grace_s(60) == 10.0
    assert time_limit_grace_s(2000) == 200.0
    assert time_limit_grace_s(3600) == 300.0
    # The 6 h job ceiling: 300 s, not 36 min.
    assert time_limit_grace_s(6 * 3600) == 300.0
    now = [0.0]
    deadline = Deadline(200, lambda: now[0])
    now[0] = 219.9
    assert deadline.expired() and not deadline.grace_spent()
    now[0] = 220.0
    assert deadline.grace_spent()
