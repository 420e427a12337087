"""Cross-entropy-method search: a sampling distribution that narrows onto good sequences.

Each of the L x N entries of a sequence (the level of thruster j at step i) gets its own
categorical distribution over the M levels, uniform at first. Every iteration draws a
population of sequences from these distributions, plays each in the sequence-search
environment (so it is scored exactly as PPO's and random search's episodes are, on the
same noise draw, through the same prefix cache), keeps the best fraction (the elites)
and moves every distribution towards the elites' level frequencies. Good levels become
likely in a few iterations; sequences drawn again are answered from the cache, so a
narrowing population costs less and less.

The elites are ranked as the search's best is: by the full sequence's score, then by
the smaller final rate plus ``fuel_weight`` x fuel. Once the distributions have all but
collapsed onto one sequence (a draw differs from it with probability below
:data:`CONVERGED`), further iterations would only replay it: the search stops there,
"converged".
"""

from __future__ import annotations

import math
from typing import Any, Unpack

import numpy as np

from ..checks import is_integer
from ..errors import InputError
from ..physics.scenario import Scenario
from .loop import RunOptions, SearchRun, check_budget
from .records import SearchResult

__all__ = ["CEM_DEFAULTS", "CONVERGED", "cem_search", "check_cem_params"]

#: The cross-entropy method's defaults.
CEM_DEFAULTS: dict[str, Any] = {"population": 64, "elite_fraction": 0.125, "smoothing": 0.7}
#: Stop once a draw differs from the most likely sequence with less than this probability.
CONVERGED = 1e-3


def check_cem_params(population: Any, elite_fraction: Any, smoothing: Any) -> int:
    """Refuse parameters the method cannot use, quoting them; return the elite count."""
    if not is_integer(population, minimum=2, maximum=1_000_000):
        raise InputError(f"population must be an integer in 2..1000000, got {population!r}")
    for name, value in (("elite_fraction", elite_fraction), ("smoothing", smoothing)):
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not (math.isfinite(value) and 0 < value <= 1)
        ):
            raise InputError(f"{name} must be a number in (0, 1], got {value!r}")
    return max(1, math.ceil(elite_fraction * population))


def _sample(rng: np.random.Generator, probabilities: np.ndarray, count: int) -> np.ndarray:
    """``count`` sequences (count, L, N), each entry drawn from its own categorical."""
    cumulative = np.cumsum(probabilities, axis=-1)
    draws = rng.random((count, *probabilities.shape[:-1], 1))
    levels = (draws >= cumulative).sum(axis=-1)
    # Rounding can leave the last cumulative value a hair below 1.
    return np.minimum(levels, probabilities.shape[-1] - 1)


def cem_search(
    scenario: Scenario,
    *,
    sequence_length: int = 4,
    total_timesteps: int = 20_480,
    population: int = CEM_DEFAULTS["population"],
    elite_fraction: float = CEM_DEFAULTS["elite_fraction"],
    smoothing: float = CEM_DEFAULTS["smoothing"],
    patience_episodes: int | None = 500,
    **options: Unpack[RunOptions],
) -> SearchResult:
    """Search with the cross-entropy method and return the best sequence it met.

    A curve point (mean episode reward, mean and best F1 of the iteration's sequences)
    is added after every iteration and ``progress`` called with it; ``should_stop`` is
    polled before every sequence.

    :param total_timesteps: environment steps (sequence_length per sequence played,
        replayed ones included); an iteration the budget cuts short is not learnt from.
    :param population: sequences drawn per iteration.
    :param elite_fraction: share of each population the distributions move towards
        (at least one sequence).
    :param smoothing: how far the distributions move per iteration, in (0, 1]: 1 puts
        them at the elites' frequencies (a level absent from the elites is never drawn
        again), smaller keeps some of the previous iteration's spread.
    :param patience_episodes: stop once the best F1 is 1 and nothing better (smaller
        final rate plus fuel cost) came for this many sequences; None = no such stop.
    :param options: fuel weight, seed (of the noise and of the sampling), scorer
        settings, constraints, fresh draws, the progress and cancel hooks and the time
        limit: see :class:`~inertia_id.search.loop.SearchRun`.
    """
    check_budget("total_timesteps", total_timesteps, sequence_length)
    n_elite = check_cem_params(population, elite_fraction, smoothing)
    run = SearchRun(scenario, sequence_length, patience_episodes, **options)
    tracker = run.tracker
    # A stream of its own: random search draws from child 1 of the same seed sequence.
    rng = np.random.default_rng(np.random.SeedSequence(run.seed).spawn(3)[2])
    m = scenario.n_levels
    probabilities = np.full((sequence_length, scenario.n_thrusters, m), 1.0 / m)
    stopped: str | None = None
    while stopped is None:
        draws = _sample(rng, probabilities, population)
        ranked = [
            (tracker.rank(record), sequence)
            for sequence, record in run.play_each(draws, total_timesteps=total_timesteps)
        ]
        stopped = run.stopped
        if ranked:
            run.report(total_timesteps)
        if stopped is None:
            # A stable sort: among equals, the first drawn is the elite.
            ranked.sort(key=lambda pair: pair[0], reverse=True)
            elites = np.stack([sequence for _, sequence in ranked[:n_elite]])
            frequencies = (elites[..., None] == np.arange(m)).mean(axis=0)
            probabilities = (1.0 - smoothing) * probabilities + smoothing * frequencies
            if 1.0 - np.prod(probabilities.max(axis=-1)) < CONVERGED:
                stopped = "converged"
    return run.finish(
        "cem",
        stopped=stopped,
        settings={
            "timesteps": total_timesteps,
            "patience_episodes": patience_episodes,
            "cem": {
                "population": population,
                "elite_fraction": elite_fraction,
                "smoothing": smoothing,
            },
        },
    )
