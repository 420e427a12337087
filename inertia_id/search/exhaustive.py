"""Exhaustive search: every sequence of a small space, in prefix order."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from typing import Unpack

import numpy as np

from ..checks import is_integer
from ..errors import InputError
from ..physics.scenario import Scenario
from .loop import RunOptions, SearchRun
from .records import SearchResult, space_size

__all__ = ["exhaustive_search"]


def _magnitude(size: int) -> str:
    """``size`` as 5.96e+16, or as 10^N where a float cannot hold it."""
    try:
        return f"{size:.4g}"
    except OverflowError:
        return f"about 10^{len(str(size)) - 1}"


def exhaustive_search(
    scenario: Scenario,
    *,
    sequence_length: int = 2,
    max_sequences: int = 100_000,
    report_every: int = 2048,
    **options: Unpack[RunOptions],
) -> SearchResult:
    """Score every sequence of length L and return the best.

    The space holds (M^N)^L sequences; a space larger than ``max_sequences`` is refused
    before any work, with its size. Sequences are visited in lexicographic order, so a
    prefix shared by consecutive sequences is simulated and clustered once (the
    environment caches it).

    :param max_sequences: the budget: the largest space this call will enumerate.
    :param options: fuel weight, seed, scorer settings, constraints, fresh draws and
        the progress and cancel hooks and the time limit: see
        :class:`~inertia_id.search.loop.SearchRun`.
    """
    size = space_size(scenario, sequence_length)
    if not is_integer(max_sequences, minimum=1, numpy=False):
        raise InputError(f"max_sequences must be a positive integer, got {max_sequences!r}")
    m, n = scenario.n_levels, scenario.n_thrusters
    if size > max_sequences:
        raise InputError(
            f"the space holds ({m}^{n})^{sequence_length} = {_magnitude(size)} sequences, more "
            f"than the budget of {max_sequences} for exhaustive search; shorten the sequence, use "
            f"fewer levels or thrusters, raise the budget, or use random or PPO search"
        )
    run = SearchRun(scenario, sequence_length, **options)
    rows = [np.asarray(r) for r in itertools.product(range(m), repeat=n)]

    def sequences() -> Iterator[np.ndarray]:
        for combo in itertools.product(range(len(rows)), repeat=sequence_length):
            yield np.stack([rows[i] for i in combo])

    stopped = run.run_episodes(
        sequences(), total_timesteps=size * sequence_length, report_every=report_every
    )
    return run.finish("exhaustive", stopped=stopped, settings={"max_sequences": max_sequences})
