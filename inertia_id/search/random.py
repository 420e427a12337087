"""Random search: the honest baseline a learned search must beat."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Unpack

import numpy as np

from ..physics.scenario import Scenario
from .loop import RunOptions, SearchRun, check_budget
from .records import SearchResult

__all__ = ["random_search"]


def random_search(
    scenario: Scenario,
    *,
    sequence_length: int = 4,
    total_timesteps: int = 20_480,
    patience_episodes: int | None = None,
    report_every: int = 2048,
    **options: Unpack[RunOptions],
) -> SearchResult:
    """Try uniformly random sequences in the environment until the step budget.

    Sequences are scored exactly as PPO's episodes are (same environment, same noise
    draw for the same seed), so the two compare at an equal number of environment steps.

    :param total_timesteps: environment steps (sequence_length per sequence).
    :param report_every: environment steps between learning-curve points (2048 = one
        PPO rollout at the paper's n_steps).
    :param options: fuel weight, seed, scorer settings, constraints, fresh draws and
        the progress and cancel hooks and the time limit: see
        :class:`~inertia_id.search.loop.SearchRun`.
    """
    check_budget("total_timesteps", total_timesteps, sequence_length)
    run = SearchRun(scenario, sequence_length, patience_episodes, **options)
    rng = np.random.default_rng(np.random.SeedSequence(run.seed).spawn(2)[1])

    def sequences() -> Iterator[np.ndarray]:
        while True:
            yield rng.integers(0, scenario.n_levels, (sequence_length, scenario.n_thrusters))

    stopped = run.run_episodes(
        sequences(), total_timesteps=total_timesteps, report_every=report_every
    )
    return run.finish("random", stopped=stopped, settings={"timesteps": total_timesteps})
