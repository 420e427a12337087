"""What every search method shares: the environment and tracker, the episode loop, the
learning curve, and the result.

A method creates a :class:`SearchRun`, plays sequences in it (its own way: random
draws, an enumeration, a sampling distribution, a policy), and calls
:meth:`SearchRun.finish`, which re-scores the best sequence on fresh draws and builds
the :class:`~inertia_id.search.records.SearchResult`. The options every method takes
beside its own (:class:`RunOptions`) go to the run unread, so each is declared, given
its default and documented once, on :class:`SearchRun`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import replace
from typing import Any, TypedDict

import numpy as np

from ..checks import check_seed, is_integer
from ..deadline import (
    GRACE_ASKED_MAX_S,
    GRACE_FRACTION,
    GRACE_MAX_S,
    GRACE_MIN_S,
    Deadline,
    check_time_limit,
    time_limit_grace_s,
)
from ..errors import InputError
from ..physics.scenario import Scenario
from .env import SequenceSearchEnv
from .firings import OpposedFirings
from .records import (
    EpisodeRecord,
    SearchProgress,
    SearchResult,
    SearchTracker,
    evaluate_sequence,
    fresh_seed,
    space_size,
)
from .scorer import ScorerSettings

__all__ = [
    "CANCELLED",
    "GRACE_ASKED_MAX_S",
    "GRACE_FRACTION",
    "GRACE_MAX_S",
    "GRACE_MIN_S",
    "TIME_LIMIT",
    "Deadline",
    "RunOptions",
    "SearchRun",
    "check_budget",
    "check_time_limit",
    "overrides",
    "report_point",
    "time_limit_grace_s",
]

#: Why a search stopped when ``should_stop`` said so: the result is abandoned, so the
#: best sequence is not re-scored (:meth:`SearchRun.finish`).
CANCELLED = "cancelled"
#: Why a search stopped when its time budget was spent: the best so far, re-scored as
#: after any other stop.
TIME_LIMIT = "time_limit"


def check_budget(name: str, value: int, sequence_length: int) -> None:
    """A step budget must hold one whole sequence at least."""
    if not is_integer(value, minimum=sequence_length):
        raise InputError(
            f"{name} must be an integer of at least one sequence ({sequence_length} steps), "
            f"got {value!r}"
        )


def overrides(
    params: dict[str, Any] | None, defaults: dict[str, Any], refusal: str
) -> dict[str, Any]:
    """``defaults`` updated with ``params``, a method's settings; a name the defaults do
    not hold is refused with ``refusal``, formatted with the ``unknown`` names and the
    ``known`` ones."""
    params = dict(params or {})
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise InputError(refusal.format(unknown=unknown, known=sorted(defaults)))
    return {**defaults, **params}


def report_point(
    tracker: SearchTracker,
    total_timesteps: int,
    progress: Callable[[SearchProgress], None] | None,
) -> None:
    """Close a learning-curve point and tell ``progress``."""
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


class RunOptions(TypedDict, total=False):
    """The keyword options every environment search (ppo, cem, exhaustive, random) takes
    beside its own budget and settings; see :class:`SearchRun` for each and its default."""

    fuel_weight: float
    seed: int
    settings: ScorerSettings | None
    constraints: dict[str, float] | None
    constraint_penalty: float
    n_fresh_draws: int
    progress: Callable[[SearchProgress], None] | None
    should_stop: Callable[[], bool] | None
    time_limit_s: float | None
    time_limit_grace_s: float | None
    clock: Callable[[], float]


class SearchRun:
    """One search from start to result: its environment, tracker and clock.

    :param patience_episodes: stop once the best F1 is 1 and nothing better came for
        this many episodes; None = never.
    :param fuel_weight: reward cost per N m s of commanded impulse.
    :param seed: seeds the environment's noise (and the method's own draws): the same
        seed gives the same learning curve.
    :param settings: how sequences are scored; None: the defaults.
    :param constraints: bounds on the sequence's physical figures (the constrained
        variant; the paper's reward is unchanged without them).
    :param constraint_penalty: the reward's cost per unit of summed relative violation.
    :param n_fresh_draws: fresh noise draws the best sequence is re-scored on.
    :param progress: called with every learning-curve point.
    :param should_stop: polled before every sequence (by PPO, every step); True cancels
        the search: its best sequence is kept but not re-scored (``fresh`` holds no
        draw), as nobody waits for the result.
    :param time_limit_s: the search's time budget in seconds (None: none), checked where
        ``should_stop`` is, from the first whole sequence on: once spent the search
        stops, "time_limit", and its best so far is re-scored as after any other stop,
        but only while the limit's grace lasts (:func:`time_limit_grace_s`): the fresh
        draws completed by then are kept (``fresh.draws_asked`` says how many were
        asked for), whatever stopped the search.
    :param time_limit_grace_s: that grace in seconds (>= 0 and <= 3600); None: the
        default rule.
    :param clock: monotonic seconds for ``time_limit_s``.
    """

    def __init__(
        self,
        scenario: Scenario,
        sequence_length: int,
        patience_episodes: int | None = None,
        *,
        fuel_weight: float = 0.0,
        seed: int = 0,
        settings: ScorerSettings | None = None,
        constraints: dict[str, float] | None = None,
        constraint_penalty: float = 0.0,
        n_fresh_draws: int = 5,
        progress: Callable[[SearchProgress], None] | None = None,
        should_stop: Callable[[], bool] | None = None,
        time_limit_s: float | None = None,
        time_limit_grace_s: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.started = time.perf_counter()
        self.seed = check_seed(seed)
        self.n_fresh_draws = n_fresh_draws
        self.progress = progress
        self.should_stop = should_stop
        self.deadline = Deadline(time_limit_s, clock, time_limit_grace_s)
        self.env = SequenceSearchEnv(
            scenario,
            sequence_length=sequence_length,
            fuel_weight=fuel_weight,
            seed=seed,
            settings=settings,
            constraints=constraints,
            constraint_penalty=constraint_penalty,
        )
        self.tracker = SearchTracker(fuel_weight=fuel_weight, patience_episodes=patience_episodes)
        #: Why :meth:`play_each` last stopped; None while sequences remain.
        self.stopped: str | None = None

    def play(self, sequence: np.ndarray) -> EpisodeRecord:
        """One whole sequence as one episode; its record."""
        self.env.reset()
        for row in sequence:
            _, reward, terminated, _, info = self.env.step(row)
            self.tracker.on_step(reward, terminated, info)
        assert self.tracker.last is not None  # the last step of an episode terminates it
        return self.tracker.last

    def rescore_stop(self) -> bool:
        """Whether the re-score after the search must stop now: a cancel, or the time
        limit's grace spent."""
        if self.should_stop is not None and self.should_stop():
            return True
        return self.deadline.grace_spent()

    def interrupted(self) -> str | None:
        """Why the search must stop now: "cancelled" when ``should_stop`` says so,
        "time_limit" once the time budget is spent, else None. A cancel wins: its result
        is abandoned."""
        if self.should_stop is not None and self.should_stop():
            return CANCELLED
        # Not before one whole sequence: a search stopped by its limit ends with a best.
        if self.tracker.best is not None and self.deadline.expired():
            return TIME_LIMIT
        return None

    def play_each(
        self, sequences: Iterable[np.ndarray], *, total_timesteps: int
    ) -> Iterator[tuple[np.ndarray, EpisodeRecord]]:
        """Play sequences until the budget, the target, a cancel or the time limit,
        yielding each sequence played with its record.

        Afterwards :attr:`stopped` says why it stopped: "budget", "cancelled",
        "time_limit", "target", or None when ``sequences`` ran out.
        """
        self.stopped = None
        length = self.env.sequence_length
        for sequence in sequences:
            if self.tracker.timesteps + length > total_timesteps:
                self.stopped = "budget"
                return
            interrupted = self.interrupted()
            if interrupted is not None:
                self.stopped = interrupted
                return
            yield sequence, self.play(sequence)
            if self.tracker.reached_target():
                self.stopped = "target"
                return

    def run_episodes(
        self, sequences: Iterable[np.ndarray], *, total_timesteps: int, report_every: int
    ) -> str:
        """Play sequences until the budget, the target, a cancel or the time limit; a
        curve point every ``report_every`` steps and at the end.

        Returns why it stopped: "budget", "target", "cancelled", "time_limit" or
        "exhausted".
        """
        next_report = report_every
        for _ in self.play_each(sequences, total_timesteps=total_timesteps):
            if self.tracker.timesteps >= next_report:
                next_report += report_every
                self.report(total_timesteps)
        self.close_curve(total_timesteps)
        return self.stopped or "exhausted"

    def report(self, total_timesteps: int) -> None:
        """Close a learning-curve point and tell :attr:`progress`."""
        report_point(self.tracker, total_timesteps, self.progress)

    def close_curve(self, total_timesteps: int) -> None:
        """A last curve point, unless the last one already holds every step."""
        curve = self.tracker.curve
        if not curve or curve[-1].timesteps != self.tracker.timesteps:
            self.report(total_timesteps)

    def finish(
        self,
        method: str,
        *,
        stopped: str,
        settings: dict[str, Any],
        policy_path: str | None = None,
    ) -> SearchResult:
        """Re-score the best sequence on fresh draws and assemble the result; a
        cancelled search's best is not re-scored (``fresh`` holds no draw), and the
        re-score stops at a cancel or once the time limit's grace is spent
        (:meth:`rescore_stop`).

        :param settings: the method's own parameters; the length, fuel weight, seed and
            scorer are added.
        """
        env, tracker = self.env, self.tracker
        if tracker.best is None:
            budget = (
                f"time limit {self.deadline.time_limit_s:g} s"
                if stopped == TIME_LIMIT
                else f"budget {settings.get('timesteps')} steps"
            )
            raise InputError(
                f"the search ended before one complete sequence ({budget}, sequences of "
                f"{env.sequence_length})"
            )
        best, taken_off = tracker.best, None
        if stopped != CANCELLED:
            best, taken_off = self._without_cancelling(best)
            self._check_fires(best, stopped)
        # A cancelled result is abandoned: a re-score (minutes at 200 realisations and
        # L = 20) would only delay the cancel.
        fresh = evaluate_sequence(
            env.scenario,
            best.sequence,
            env.settings,
            seed=fresh_seed(self.seed),
            n_draws=0 if stopped == CANCELLED else self.n_fresh_draws,
            should_stop=self.rescore_stop,
        )
        return SearchResult(
            method=method,
            best=best,
            fresh=fresh,
            curve=list(tracker.curve),
            timesteps=tracker.timesteps,
            episodes=tracker.episodes,
            wall_time_s=time.perf_counter() - self.started,
            stopped=stopped,
            space_size=space_size(env.scenario, env.sequence_length),
            settings={
                "sequence_length": env.sequence_length,
                "fuel_weight": env.fuel_weight,
                "seed": self.seed,
                "constraints": dict(env.constraints),
                "constraint_penalty": env.constraint_penalty,
                "time_limit_s": self.deadline.time_limit_s,
                "time_limit_grace_s": self.deadline.grace_s,
                **settings,
                "scorer": env.settings.as_dict(),
            },
            policy_path=policy_path,
            cache_hits=env.scorer.hits,
            cache_misses=env.scorer.misses,
            firings_taken_off=taken_off,
        )

    def _check_fires(self, best: EpisodeRecord, stopped: str) -> None:
        """Refuse a best sequence that applies no torque, as NSGA-II does (its front of
        the all-off sequence alone): nothing commanded tells the candidates apart, so no
        classifier can be trained on it (``train`` refuses it). Before, every tie went to
        the all-off sequence, whose residual rate is the smallest: exhaustive search of
        one step on four tetrahedral thrusters (separability 0.000 for all 81 sequences)
        returned ``[[0, 0, 0, 0]]`` as its best and said nothing.

        :raises InputError: saying why no sequence that fires came first.
        """
        try:
            self.env.scenario.check_fires(best.sequence)
        except InputError:
            pass
        else:
            return
        env = self.env
        what = {"f1": "F1"}.get(env.settings.objective, env.settings.objective)
        if env.constraints and best.constraint_violation <= 0.0:
            why = (
                f"no sequence that fires met the constraints {dict(env.constraints)} "
                f"among the {self.tracker.episodes} tried, only one that applies no torque"
            )
            advice = "loosen the constraints or search longer"
        else:
            why = (
                f"no sequence that fires scored above one that applies no torque "
                f"({what} {best.f1:.3f}) "
                + (
                    f"in all {self.tracker.episodes} sequences of the space"
                    if stopped == "exhausted"
                    else f"among the {self.tracker.episodes} tried (stopped: {stopped})"
                )
            )
            advice = (
                "a longer sequence, less noise, or the objective f1"
                + (
                    " or a smaller separability_margin"
                    if env.settings.objective == "separability"
                    else ""
                )
                + " may separate them"
            )
        shown = repr(best.sequence)
        if len(shown) > 200:  # an error names the sequence without echoing all of it
            shown = f"{shown[:200]}... ({len(shown)} characters)"
        raise InputError(
            f"the best sequence found, {shown}, applies no torque: {why}, "
            f"so nothing commanded tells the candidates apart and no classifier can be "
            f"trained on it; {advice}"
        )

    def _without_cancelling(
        self, best: EpisodeRecord
    ) -> tuple[EpisodeRecord, dict[str, Any] | None]:
        """The best sequence with what its steps' firings cancel among themselves taken
        off (:class:`~inertia_id.search.firings.OpposedFirings`), scored on the search's
        draw, and what was taken off; ``best`` and None when nothing cancels.

        CEM, random and exhaustive search and PPO sample levels thruster by thruster, so
        their best sequence fired opposing thrusters together (paper preset, separability,
        L = 3, 300 steps, seeds 0-2: all three CEM and all three random bests, up to 23.5
        N m s). Taking it off here, after the search, leaves the search itself as it was
        (PPO's reward as the paper states it, the learning curve, the steps counted): the
        reduced sequence gives every step the same net torque for less on-time, so it is
        the same manoeuvre with less propellant and less duty jitter. It is kept unless
        it breaks the constraints by more than the sequence found; its own scores on the
        search's draw are reported, the sequence found and its scores beside them.
        """
        found = np.asarray(best.sequence, dtype=int)
        reduced = OpposedFirings(self.env.scenario)(found)
        if np.array_equal(reduced, found) or self.rescore_stop():
            return best, None
        # Played apart from the tracker: the search's counts and curve stay the search's.
        scratch = SearchTracker(fuel_weight=self.env.fuel_weight)
        self.env.reset()
        for row in reduced:
            _, reward, terminated, _, info = self.env.step(row)
            scratch.on_step(reward, terminated, info)
        record = scratch.last
        assert record is not None  # the last step of an episode terminates it
        if round(record.constraint_violation, 12) > round(best.constraint_violation, 12):
            return best, None
        scenario = self.env.scenario
        taken_off = {
            "sequence_found": [list(row) for row in best.sequence],
            "score_found": best.f1,
            "impulse_found_nms": best.fuel_nms,
            "impulse_saved_nms": best.fuel_nms - record.fuel_nms,
            "on_time_saved_s": float(
                scenario.on_time_s(found).sum() - scenario.on_time_s(reduced).sum()
            ),
            "steps": [int(k) + 1 for k in np.flatnonzero((reduced != found).any(axis=1))],
        }
        return replace(record, episode=best.episode), taken_off
