"""The episode loop every search shares, and how a search's result is assembled.

:func:`run_episodes` plays whole sequences in the environment until the budget, the
target or a cancel; :func:`report_point` closes a learning-curve point and tells the
caller; :func:`finish` re-scores the best sequence on fresh draws and builds the
:class:`~inertia_id.search.records.SearchResult`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from ..errors import InputError
from .env import SequenceSearchEnv
from .records import (
    SearchProgress,
    SearchResult,
    SearchTracker,
    evaluate_sequence,
    fresh_seed,
    space_size,
)

__all__ = ["finish", "report_point", "run_episodes"]


def run_episodes(
    env: SequenceSearchEnv,
    sequences: Iterable[np.ndarray],
    tracker: SearchTracker,
    *,
    total_timesteps: int,
    report_every: int,
    progress: Callable[[SearchProgress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> str:
    """Play whole sequences in ``env`` until the budget, the target or a cancel.

    Returns why it stopped: "budget", "target", "cancelled" or "exhausted".
    """
    length = env.sequence_length
    next_report = report_every
    stopped = "exhausted"
    for sequence in sequences:
        if tracker.timesteps + length > total_timesteps:
            stopped = "budget"
            break
        if should_stop is not None and should_stop():
            stopped = "cancelled"
            break
        env.reset()
        for row in sequence:
            _, reward, terminated, _, info = env.step(row)
            tracker.on_step(reward, terminated, info)
        if tracker.timesteps >= next_report:
            next_report += report_every
            report_point(tracker, total_timesteps, progress)
        if tracker.reached_target():
            stopped = "target"
            break
    if not tracker.curve or tracker.curve[-1].timesteps != tracker.timesteps:
        report_point(tracker, total_timesteps, progress)
    return stopped


def report_point(
    tracker: SearchTracker,
    total_timesteps: int,
    progress: Callable[[SearchProgress], None] | None,
) -> None:
    point = tracker.add_point()
    if progress is not None:
        progress(
            SearchProgress(
                timesteps=tracker.timesteps,
                total_timesteps=total_timesteps,
                episodes=tracker.episodes,
                point=point,
                best=tracker.best,
            )
        )


def finish(
    method: str,
    env: SequenceSearchEnv,
    tracker: SearchTracker,
    *,
    seed: int,
    started: float,
    stopped: str,
    settings: dict[str, Any],
    n_fresh_draws: int = 5,
    policy_path: str | None = None,
) -> SearchResult:
    """Re-score the best sequence on fresh draws and assemble the result."""
    if tracker.best is None:
        raise InputError(
            f"the search ended before one complete sequence (budget {settings.get('timesteps')} "
            f"steps, sequences of {env.sequence_length})"
        )
    fresh = evaluate_sequence(
        env.scenario,
        tracker.best.sequence,
        env.settings,
        seed=fresh_seed(seed),
        n_draws=n_fresh_draws,
    )
    return SearchResult(
        method=method,
        best=tracker.best,
        fresh=fresh,
        curve=list(tracker.curve),
        timesteps=tracker.timesteps,
        episodes=tracker.episodes,
        wall_time_s=time.perf_counter() - started,
        stopped=stopped,
        space_size=space_size(env.scenario, env.sequence_length),
        settings=settings,
        policy_path=policy_path,
        cache_hits=env.scorer.hits,
        cache_misses=env.scorer.misses,
    )
