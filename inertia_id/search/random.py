"""Random search: the honest baseline a learned search must beat."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from ..physics.scenario import Scenario
from .loop import SearchRun, check_budget
from .records import SearchProgress, SearchResult
from .scorer import ScorerSettings

__all__ = ["random_search"]


def random_search(
    scenario: Scenario,
    *,
    sequence_length: int = 4,
    total_timesteps: int = 20_480,
    fuel_weight: float = 0.0,
    seed: int = 0,
    settings: ScorerSettings | None = None,
    constraints: dict[str, float] | None = None,
    constraint_penalty: float = 0.0,
    patience_episodes: int | None = None,
    report_every: int = 2048,
    n_fresh_draws: int = 5,
    progress: Callable[[SearchProgress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> SearchResult:
    """Try uniformly random sequences in the environment until the step budget.

    Sequences are scored exactly as PPO's episodes are (same environment, same noise
    draw for the same seed), so the two compare at an equal number of environment steps.

    :param total_timesteps: environment steps (sequence_length per sequence).
    :param report_every: environment steps between learning-curve points (2048 = one
        PPO rollout at the paper's n_steps).
    """
    check_budget("total_timesteps", total_timesteps, sequence_length)
    run = SearchRun(
        scenario,
        sequence_length,
        fuel_weight,
        seed,
        settings,
        patience_episodes,
        constraints=constraints,
        constraint_penalty=constraint_penalty,
    )
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])

    def sequences() -> Iterator[np.ndarray]:
        while True:
            yield rng.integers(0, scenario.n_levels, (sequence_length, scenario.n_thrusters))

    stopped = run.run_episodes(
        sequences(),
        total_timesteps=total_timesteps,
        report_every=report_every,
        progress=progress,
        should_stop=should_stop,
    )
    return run.finish(
        "random",
        stopped=stopped,
        settings={"timesteps": total_timesteps},
        n_fresh_draws=n_fresh_draws,
    )
