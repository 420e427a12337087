"""What every search reports, how the best sequence is tracked, and its honest re-scoring.

PPO, CEM, exhaustive and random search all drive
:class:`~inertia_id.search.env.SequenceSearchEnv` (the episode loop is
:mod:`inertia_id.search.loop`) and return a :class:`SearchResult` of the same shape:
the best sequence with the score the search saw, the same sequence re-scored on fresh
realisations with an independent seed (the search's own score comes from one noise draw
and is optimistic), and the learning curve.

"F1" in a record or curve point is the search objective's score: the clustering F1, or
the separability score of a search with ``objective="separability"``. The fresh
re-scoring always reports the clustering F1 (what users compare), and the separability
score too when the search used it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ..checks import MAX_SEED, finite_or_none
from ..physics.scenario import Scenario
from .scorer import PrefixScorer, ScorerSettings

__all__ = [
    "CurvePoint",
    "EpisodeRecord",
    "FreshEvaluation",
    "SearchProgress",
    "SearchResult",
    "SearchTracker",
    "evaluate_sequence",
    "fresh_seed",
    "space_size",
]


def space_size(scenario: Scenario, sequence_length: int) -> int:
    """Number of distinct sequences, (M^N)^L."""
    return int(scenario.n_levels ** (scenario.n_thrusters * sequence_length))


def fresh_seed(seed: int) -> int:
    """A seed independent of ``seed`` (a spawned child of its seed sequence), 0 to
    :data:`~inertia_id.checks.MAX_SEED`: a result stores it and the dashboard shows it, so
    it stays an exact number in JavaScript (below 2**53) and a seed the command line and
    the service take back (``--seed``)."""
    child = np.random.SeedSequence(seed).spawn(1)[0]
    # MAX_SEED is 2**31 - 1: its low 31 bits.
    return int(child.generate_state(1, np.uint32)[0]) & MAX_SEED


@dataclass(frozen=True)
class EpisodeRecord:
    """One complete sequence a search tried.

    :param sequence: (L, N) level indices.
    :param f1: the objective's score of the full sequence on the search's noise draw
        (clustering F1, or the separability score).
    :param final_rate_rad_s: mean |ω| when the last command ends, rad/s, the paper's
        reward (NSGA-II, which does not measure it: the residual rate below).
    :param fuel_nms: commanded angular impulse, N m s.
    :param episode_return: the environment's summed reward.
    :param episode: 1-based episode number in the search.
    :param constraint_violation: summed relative violation of the search's constraints
        (0 when they hold or there are none).
    :param residual_rate_rad_s: the residual rate once the actuation lag has delivered
        the torque still in it, mean over candidates (each the larger of its mean and
        the plan's prediction), rad/s: the same figure for every method, as a front's
        ``final_rate_rad_s``. NaN in records stored before it.
    """

    sequence: list[list[int]]
    f1: float
    final_rate_rad_s: float
    fuel_nms: float
    episode_return: float
    episode: int
    constraint_violation: float = 0.0
    residual_rate_rad_s: float = float("nan")


@dataclass(frozen=True)
class CurvePoint:
    """The learning curve at one report (every rollout, or every ``report_every`` steps).

    :param timesteps: environment steps so far.
    :param episodes: complete episodes so far.
    :param mean_episode_reward: mean return of the episodes finished since the last point.
    :param mean_f1: mean full-sequence F1 (objective's score) of those episodes.
    :param best_f1: best full-sequence F1 (objective's score) so far.
    :param best_residual_rate_rad_s: the residual rate of the best sequence so far on
        the search's draw (:attr:`EpisodeRecord.residual_rate_rad_s`), rad/s: once the
        lag has delivered the torque still in it, mean over candidates, for every method.
    :param best_feasible: whether that best sequence meets the search's constraints
        (always, without constraints). The best so far is the most accurate feasible
        sequence, and the most accurate of all while none is feasible: this says which.
    """

    timesteps: int
    episodes: int
    mean_episode_reward: float
    mean_f1: float
    best_f1: float
    best_residual_rate_rad_s: float
    best_feasible: bool = True


@dataclass(frozen=True)
class SearchProgress:
    """Passed to a search's ``progress`` callback at every curve point, and while a
    search works between points (the front's measurement after NSGA-II's generations
    and polish rounds, each of which is a point): then ``new_point`` is False and
    ``point`` repeats the last curve point.

    :param phase: what the search is doing: ``"search"``, or ``"measuring the front"``
        (the fresh measurement of the front's accuracy after the last curve point).
    :param fraction_done: the fraction of the whole job done, where the steps alone
        do not tell it (NSGA-II counts the front's measurement in); None: the steps'.
    """

    timesteps: int
    total_timesteps: int
    episodes: int
    point: CurvePoint
    best: EpisodeRecord | None
    new_point: bool = True
    phase: str = "search"
    fraction_done: float | None = None

    @property
    def fraction(self) -> float:
        if self.fraction_done is not None:
            return min(1.0, max(0.0, self.fraction_done))
        return min(1.0, self.timesteps / max(self.total_timesteps, 1))


@dataclass(frozen=True)
class FreshEvaluation:
    """The best sequence re-scored on fresh noise draws.

    :param seed: the independent seed the draws came from.
    :param f1: clustering F1 on each draw, whatever the search's objective.
    :param final_rate_rad_s: mean final rate on each draw, rad/s.
    :param separability: the separability score on each draw, when the search's
        objective was "separability"; else None.
    :param draws_asked: the draws asked for; more than ``f1`` holds when the re-score
        was stopped (a time limit's grace spent, :func:`evaluate_sequence`); None: as
        many as ``f1`` holds (results stored before it).
    """

    seed: int
    f1: list[float]
    final_rate_rad_s: list[float]
    separability: list[float] | None = None
    draws_asked: int | None = None

    @property
    def f1_mean(self) -> float:
        """NaN (null in JSON) without draws: a cancelled search is not re-scored."""
        return float(np.mean(self.f1)) if self.f1 else float("nan")

    @property
    def f1_min(self) -> float:
        return float(np.min(self.f1)) if self.f1 else float("nan")


def evaluate_sequence(
    scenario: Scenario,
    sequence: Any,
    settings: ScorerSettings,
    *,
    seed: int,
    n_draws: int = 5,
    should_stop: Callable[[], bool] | None = None,
) -> FreshEvaluation:
    """Score ``sequence`` on ``n_draws`` independent noise draws derived from ``seed``.

    The clustering F1 is always computed (with ``settings``' clustering options); with
    the objective "separability" the separability score is computed on the same draws.

    :param should_stop: polled before each prefix of each draw is clustered (a draw of
        200 realisations at L = 20 clusters 20 prefixes, about 2 s each); True ends the
        re-score there: the draws completed are kept, the one under way is dropped, and
        ``draws_asked`` says how many were asked for.
    """
    rows = scenario.check_sequence(sequence)
    seeds = np.random.SeedSequence(seed).generate_state(n_draws, np.uint32)
    clustering = settings if settings.objective == "f1" else replace(settings, objective="f1")
    f1: list[float] = []
    rate: list[float] = []
    separability: list[float] = []

    def evaluation() -> FreshEvaluation:
        return FreshEvaluation(
            seed=seed,
            f1=f1,
            final_rate_rad_s=rate,
            separability=separability if settings.objective != "f1" else None,
            draws_asked=n_draws,
        )

    for draw_seed in seeds:
        scorer = PrefixScorer(scenario, len(rows), clustering, seed=int(draw_seed))
        # Prefix by prefix, so that a stop is heard within one clustering: the score is
        # the same (each prefix extends its cached parent, as one call would).
        for end in range(1, len(rows) + 1):
            if should_stop is not None and should_stop():
                return evaluation()
            score = scorer.score(rows[:end])
        f1.append(score.f1)
        rate.append(score.final_rate_rad_s)
        if settings.objective != "f1":
            other = PrefixScorer(scenario, len(rows), settings, seed=int(draw_seed))
            separability.append(other.score(rows).f1)
    return evaluation()


class SearchTracker:
    """Follows a search episode by episode: the best sequence and the learning curve.

    The best sequence has the highest F1; among equals, the smallest final rate plus
    ``fuel_weight`` times its fuel.

    :param fuel_weight: the environment's fuel weight, for the tie-break.
    :param patience_episodes: stop once the best F1 is 1 and no better sequence (smaller
        final rate and fuel cost) has turned up for this many episodes; None = never.
    """

    def __init__(self, *, fuel_weight: float = 0.0, patience_episodes: int | None = None) -> None:
        self.fuel_weight = fuel_weight
        self.patience_episodes = patience_episodes
        self.best: EpisodeRecord | None = None
        #: The episode finished last.
        self.last: EpisodeRecord | None = None
        self.best_episode = 0
        self.episodes = 0
        self.timesteps = 0
        self.curve: list[CurvePoint] = []
        self._returns: list[float] = []
        self._f1s: list[float] = []
        self._violations: list[float] = []
        self._running_return = 0.0

    def rank(self, record: EpisodeRecord) -> tuple[float, float, float]:
        """The order of sequences, larger is better: meeting the constraints (the smaller
        violation), then F1, then minus the cost."""
        cost = record.final_rate_rad_s + self.fuel_weight * record.fuel_nms
        return (-round(record.constraint_violation, 12), round(record.f1, 12), -cost)

    def on_step(self, reward: float, done: bool, info: dict[str, Any]) -> bool:
        """Account for one environment step; True when this step found a new best."""
        self.timesteps += 1
        self._running_return += reward
        if not done:
            return False
        self.episodes += 1
        record = EpisodeRecord(
            sequence=[list(row) for row in info["sequence"]],
            f1=float(info["f1"]),
            final_rate_rad_s=float(info["final_rate_rad_s"]),
            fuel_nms=float(info["fuel_nms"]),
            episode_return=self._running_return,
            episode=self.episodes,
            constraint_violation=float(info.get("constraint_violation", 0.0)),
            residual_rate_rad_s=float(info["residual_rate_rad_s"]),
        )
        self._violations.append(record.constraint_violation)
        self.last = record
        self._returns.append(self._running_return)
        self._f1s.append(record.f1)
        self._running_return = 0.0
        if self.best is None or self.rank(record) > self.rank(self.best):
            self.best = record
            self.best_episode = self.episodes
            return True
        return False

    def mean_violation(self) -> float:
        """Mean constraint violation of the episodes finished since the last curve point."""
        return float(np.mean(self._violations)) if self._violations else 0.0

    def reached_target(self) -> bool:
        """Best F1 is 1 and it has not improved for ``patience_episodes`` episodes."""
        return (
            self.patience_episodes is not None
            and self.best is not None
            and self.best.f1 >= 1.0
            and self.best.constraint_violation <= 0.0
            and self.episodes - self.best_episode >= self.patience_episodes
        )

    def add_point(self) -> CurvePoint:
        """Close a curve point over the episodes finished since the last one."""
        previous = self.curve[-1] if self.curve else None
        point = CurvePoint(
            timesteps=self.timesteps,
            episodes=self.episodes,
            mean_episode_reward=float(np.mean(self._returns))
            if self._returns
            else (previous.mean_episode_reward if previous else float("nan")),
            mean_f1=float(np.mean(self._f1s))
            if self._f1s
            else (previous.mean_f1 if previous else float("nan")),
            best_f1=self.best.f1 if self.best else float("nan"),
            best_residual_rate_rad_s=self.best.residual_rate_rad_s if self.best else float("nan"),
            best_feasible=self.best is None or self.best.constraint_violation <= 0.0,
        )
        self.curve.append(point)
        self._returns, self._f1s, self._violations = [], [], []
        return point


#: What a search's ``best.f1`` and its curve's ``mean_f1``/``best_f1`` hold, by the name
#: the exports give their columns (the stored key says f1 whatever the objective).
SCORE_NAMES = {
    "f1": "the clustering F1 on the search's draw",
    "separability": "the separability score on the search's draw (not an F1)",
    "predicted_accuracy_design_noise": "the noise model's predicted accuracy at the design "
    "noise (NSGA-II; no draw produced it)",
}


def score_name(method: Any, objective: Any) -> str:
    """The name (a key of :data:`SCORE_NAMES`) of what a search of ``method`` with the
    scorer ``objective`` ranks by: NSGA-II's prediction, else the objective's score."""
    if method == "nsga2":
        return "predicted_accuracy_design_noise"
    return "f1" if objective in (None, "f1") else "separability"


@dataclass
class SearchResult:
    """The outcome of a search, the same shape for every method.

    :param method: "ppo", "cem", "exhaustive", "random" or "nsga2".
    :param best: the best sequence and the scores the search saw for it.
    :param fresh: the best sequence re-scored on fresh draws (independent seed).
    :param curve: the learning curve.
    :param timesteps: environment steps taken.
    :param episodes: sequences tried.
    :param wall_time_s: wall-clock time of the search, s.
    :param stopped: "budget", "target" (F1 = 1 and no improvement for the patience),
        "cancelled" (``fresh`` then holds no draw), "time_limit" (the search's time
        budget was spent: the best so far, re-scored while the limit's grace lasted,
        ``fresh.draws_asked`` saying what it did not reach), "exhausted" (every sequence
        tried) or "converged" (CEM's sampling distribution collapsed onto one sequence).
    :param space_size: number of distinct sequences, (M^N)^L.
    :param settings: the search's parameters, as given.
    :param policy_path: where PPO saved its policy, if it did.
    :param cache_hits: environment steps whose prefix score came from the cache.
    :param cache_misses: environment steps that simulated and clustered a new prefix.
    """

    method: str
    best: EpisodeRecord
    fresh: FreshEvaluation
    curve: list[CurvePoint]
    timesteps: int
    episodes: int
    wall_time_s: float
    stopped: str
    space_size: int
    settings: dict[str, Any] = field(default_factory=dict)
    policy_path: str | None = None
    cache_hits: int = 0
    cache_misses: int = 0
    #: The front on fresh draws with the baselines beside it (:class:`~inertia_id.
    #: search.pareto.Front` as a dict): a Pareto search's front, or for the other
    #: methods a front of their best sequence alone (added by the pipeline).
    front: dict[str, Any] | None = None
    #: What the best sequence found fired for no torque and was taken off it after the
    #: search (:meth:`~inertia_id.search.loop.SearchRun.finish`): the sequence found, its
    #: F1 and impulse, the impulse and on-time saved and the steps changed; None when
    #: nothing cancelled (and for NSGA-II, which never scores such a sequence).
    firings_taken_off: dict[str, Any] | None = None

    @property
    def best_sequence(self) -> np.ndarray:
        return np.asarray(self.best.sequence, dtype=int)

    @property
    def objective(self) -> str:
        """What ``best.f1`` and the curve's F1 measure: "f1" or "separability"."""
        return str(self.settings.get("scorer", {}).get("objective", "f1"))

    @property
    def score_name(self) -> str:
        """What ``best.f1`` holds (:func:`score_name`), stated in :meth:`to_dict` as
        ``best.score_name`` with its meaning beside it."""
        return score_name(self.method, self.objective)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        # The key says f1 whatever the search ranked by (kept for the clients that read
        # it); the document says what it holds.
        out["best"]["score_name"] = self.score_name
        out["best"]["score_meaning"] = SCORE_NAMES[self.score_name]
        out["fresh"]["f1_mean"] = self.fresh.f1_mean
        out["fresh"]["f1_min"] = self.fresh.f1_min
        return out

    def to_json(self) -> str:
        """The result as JSON (NaN, e.g. a curve point before any episode, as null)."""
        return json.dumps(finite_or_none(self.to_dict()), allow_nan=False)

    def summary(self) -> str:
        b = self.best
        if self.method == "nsga2":
            # NSGA-II ranks by the noise model's prediction, which no draw produced; the
            # fresh figure beside it is the clustering F1, another metric.
            seen = f"predicted accuracy {b.f1:.3f} at the design noise, clustering F1 "
        elif self.objective == "f1":
            seen = f"F1 {b.f1:.3f} on the search's draw, "
        else:
            seen = f"separability {b.f1:.3f} on the search's draw, F1 "
        # Two rates, each named for what it is: the residual once the lag is empty (the
        # same figure for every method, as the front's) and |ω| when the last command
        # ends, on the fresh draws (what the paper's last-step term reads).
        residual = b.residual_rate_rad_s
        settled = (
            f"residual rate {residual:.4f} rad/s ({math.degrees(residual):.3f} deg/s) once the "
            "lag is empty | "
            if math.isfinite(residual)
            else ""
        )
        asked = self.fresh.draws_asked
        cut = (
            f" of {asked} asked, the re-score stopped ({self.stopped})"
            if asked is not None and asked > len(self.fresh.f1)
            else ""
        )
        if self.fresh.f1:
            end = float(np.mean(self.fresh.final_rate_rad_s))
            fresh = (
                f"{self.fresh.f1_mean:.3f} mean on {len(self.fresh.f1)} fresh draws{cut} "
                f"(min {self.fresh.f1_min:.3f}) | {settled}|ω| at the last step's end "
                f"{end:.4f} rad/s ({math.degrees(end):.3f} deg/s), fresh mean | "
            )
        else:
            fresh = f"not re-scored on fresh draws ({self.stopped}) | {settled}"
        broken = (
            " | breaks the constraints on the search's draw (summed relative violation "
            f"{b.constraint_violation:.3g}): no sequence tried met them, this one least"
            if self.settings.get("constraints") and b.constraint_violation > 0
            else ""
        )
        taken = self.firings_taken_off
        reduced = (
            f" | firings that cancelled taken off step{'s' if len(taken['steps']) > 1 else ''} "
            f"{', '.join(map(str, taken['steps']))} of the sequence found "
            f"{taken['sequence_found']} (the same torque, "
            f"{taken['impulse_saved_nms']:.2f} N m s less; it scored "
            f"{taken['score_found']:.3f} on the search's draw, whose one score varies: "
            "the fresh draws are the figure to compare)"
            if taken
            else ""
        )
        return (
            f"{self.method}: best sequence {b.sequence} | {seen}{fresh}"
            f"impulse {b.fuel_nms:.2f} N m s | {self.timesteps} env steps, {self.episodes} "
            f"episodes, {self.wall_time_s:.1f} s, stopped: {self.stopped}{broken}{reduced}"
        )
