"""A Pareto front of sequences an operator can fly: NSGA-II (pymoo) on the operator's
objectives, every member re-scored on fresh draws, the baselines beside it.

:func:`pareto_search` runs pymoo's NSGA-II over the L x N level indices (integer
variables: simulated binary crossover and polynomial mutation on the real line, rounded
back to levels, pymoo's recipe for integer problems; duplicates eliminated). Each
generation's population is scored at once by an
:class:`~inertia_id.search.operator.OperatorScorer` on one noise draw (common random
numbers), on the objectives and constraints of its
:class:`~inertia_id.search.operator.OperatorSettings`; the constraints are pymoo's
inequality constraints (feasible first, then by violation). The first population holds
the baselines (:mod:`inertia_id.physics.sequences`) and the all-off sequence beside
random ones, so the search starts from what an engineer would try. After the
generations a polish (:func:`_polish`) walks from the best sequences and the baselines
by local moves that NSGA-II's per-level operators rarely make: a firing moved in time
keeps its impulse, so a sequence that ends at rest stays near rest while its timing
changes.

Every sequence evaluated is kept; the non-dominated, feasible ones on the search's draw
are re-scored with an independent seed (:func:`build_front`): the residual and peak
rates on a fresh draw with more realisations, and the accuracy *measured*, not
predicted: the noise model's Bayes classifier tested on fresh series at each design
condition (the search ranks by a prediction that is off by up to a point near
saturation and by more lower down, and picks the sequences it flatters; the measurement
is what catches them). The stored front is what
is feasible and non-dominated *on those fresh scores*, each member with a stable index
(0 = the most accurate; a sequence that applies no torque comes after every one that
fires and dominates none of them: its accuracy is the noise's, :func:`_front_mask`).
The baselines are scored on the same draws, and a baseline that dominates a member is
flagged, on the member and on the baseline.

Member 0 is the most accurate *on those series*: among dozens of members a point or two
apart, its figure there is biased up on average (a selection effect of about a point at
L = 8 on the paper preset). So it is measured once more, on five times as many series
independent of that choice (``confirmation`` in the stored front): the figure to quote
for the front's best. The baselines that could dominate it (no worse on every other
objective) are measured on the same series, and whether one dominates member 0 is judged
there, pair by pair, rather than against its flattered figure.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..checks import check_seed, is_integer
from ..errors import InputError
from ..physics.scenario import Scenario
from ..physics.sequences import BASELINES
from .firings import OpposedFirings
from .loop import CANCELLED, TIME_LIMIT, Deadline, overrides
from .objectives import (
    CONSTRAINTS,
    FRONT_FLIGHTS,
    SequenceScores,
    check_per_flight_realisations,
)
from .operator import MAX_TEST_SERIES, OperatorScorer, OperatorSettings
from .records import (
    CurvePoint,
    EpisodeRecord,
    SearchProgress,
    SearchResult,
    evaluate_sequence,
    fresh_seed,
    space_size,
)
from .scorer import ScorerSettings

__all__ = [
    "NSGA2_DEFAULTS",
    "Front",
    "build_front",
    "check_nsga2_params",
    "check_test_series",
    "dominates",
    "non_dominated",
    "pareto_search",
    "scored_baselines",
]

#: NSGA-II's defaults: population size, generations, SBX and polynomial-mutation
#: distribution indices (larger: children nearer their parents) and the crossover
#: probability (the mutation probability per variable is 1 / (L N)); then the polish:
#: rounds of local moves (a population of neighbours a round) from each of
#: ``polish_starts`` sequences (0 rounds: none).
NSGA2_DEFAULTS: dict[str, Any] = {
    "population": 64,
    "generations": 30,
    "crossover_eta": 15.0,
    "mutation_eta": 20.0,
    "crossover_prob": 0.9,
    "polish_iterations": 30,
    "polish_starts": 4,
}
#: Members re-scored on fresh draws at most (the non-dominated set on the search's draw
#: is thinned evenly along the accuracy beyond this).
MAX_FRONT_CANDIDATES = 60
#: Member 0's confirmation measures this many times the front's test series.
CONFIRMATION_FACTOR = 5
#: One NSGA-II evaluation (a sequence predicted by the noise model and its rates
#: simulated) costs about as much as measuring this many test series of the same length
#: (the 2-core machine, paper preset: 64 at L = 4, 84 at L = 8, 101 at L = 16). It
#: sizes the front's measurement in the progress a search reports, so the bar does not
#: sit at 100 % while the front is measured.
SERIES_PER_EVALUATION = 80
#: Sequences a generation scores between two checks of a cancel or the time limit: a
#: generation of 64 at 200 realisations and L = 20 takes about 30 s on one core, a
#: quarter of it about 8 s (as fast a sequence: the scorer's results do not depend on
#: how the population is cut).
STOP_CHECK_SEQUENCES = 16


class _Interrupted(Exception):
    """A cancel or the time limit heard while a generation was scored."""


def check_nsga2_params(params: dict[str, Any] | None) -> dict[str, Any]:
    """NSGA-II's defaults updated with ``params``, each checked; unknown names refused."""
    merged = overrides(params, NSGA2_DEFAULTS, "unknown NSGA-II settings {unknown}; known: {known}")
    minimum = {"population": 4, "generations": 1, "polish_iterations": 0, "polish_starts": 1}
    for name in ("population", "generations", "polish_iterations", "polish_starts"):
        value = merged[name]
        if not is_integer(value, minimum=minimum[name], maximum=10_000):
            raise InputError(
                f"NSGA-II {name} must be an integer in {minimum[name]}..10000, got {value!r}"
            )
    for name in ("crossover_eta", "mutation_eta"):
        value = merged[name]
        if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value <= 1000:
            raise InputError(f"NSGA-II {name} must be a number in (0, 1000], got {value!r}")
    prob = merged["crossover_prob"]
    if isinstance(prob, bool) or not isinstance(prob, int | float) or not 0 <= prob <= 1:
        raise InputError(f"NSGA-II crossover_prob must be in [0, 1], got {prob!r}")
    return merged


def check_test_series(value: Any) -> int:
    """A front's test series per candidate and condition: 0 (keep the prediction) to
    :data:`~inertia_id.search.operator.MAX_TEST_SERIES`."""
    if not is_integer(value, minimum=0, maximum=MAX_TEST_SERIES):
        raise InputError(f"test_series must be an integer in 0..{MAX_TEST_SERIES}, got {value!r}")
    return int(value)


def dominates(a: np.ndarray, b: np.ndarray) -> bool:
    """``a`` dominates ``b`` (both minimised): no worse in every objective, better in one."""
    return bool(np.all(a <= b) and np.any(a < b))


def non_dominated(objectives: np.ndarray) -> np.ndarray:
    """Mask of the rows no other row dominates, (P,) for (P, M) objectives to minimise.

    Identical rows do not dominate each other: both stay.
    """
    f = np.asarray(objectives, dtype=float)
    no_worse = np.all(f[:, None, :] <= f[None, :, :], axis=-1)  # [i, j]: i <= j everywhere
    better = np.any(f[:, None, :] < f[None, :, :], axis=-1)
    dominated = np.any(no_worse & better, axis=0)
    return np.asarray(~dominated)


@dataclass
class Front:
    """The front as stored with a search: members on fresh scores, the baselines beside.

    :param members: each a dict with ``index`` (stable, 0 = most accurate; those that
        fire first), ``fires``
        (False: it applies no torque, a classifier cannot be trained on it), ``sequence``,
        ``scores`` (fresh: the rates on a fresh draw, the accuracy measured on fresh test
        series when ``test_series`` > 0, the prediction kept beside), ``search_scores``
        (what the search saw, when known),
        ``feasible`` and ``dominated_by`` (the baselines that dominate it).
    :param baselines: by name: ``sequence``, ``scores`` (same fresh draw), ``feasible``,
        ``dominates`` (indices of the members it dominates); or ``unavailable`` (why).
    :param confirmation: member 0's accuracy measured again on
        :func:`confirmation_series` series per candidate and condition, independent of
        those that ranked it first (:func:`_confirmed`), with the baselines that could
        dominate it (no worse on every other objective) on the same series
        (``baselines``, each with ``dominates_member_0``: member 0's ``dominated_by`` is
        judged there); None when only one sequence was measured (nothing was chosen),
        when the accuracy is predicted, or when the measurement was stopped.
    :param stopped: ``should_stop`` ended the measurement or the confirmation (the front
        then says what it holds; a search reports why: "cancelled" or "time_limit").
    :param not_rescored: the candidates left out once the re-score was stopped (a time
        limit's grace spent), in the search's order: each ``sequence`` and its
        ``search_scores`` (the search's draw only); the front is judged without them.
    """

    settings: OperatorSettings
    fresh_seed: int
    fresh_realisations: int
    members: list[dict[str, Any]] = field(default_factory=list)
    baselines: dict[str, dict[str, Any]] = field(default_factory=dict)
    candidates: int = 0
    test_series: int = 0
    confirmation: dict[str, Any] | None = None
    stopped: bool = False
    not_rescored: list[dict[str, Any]] = field(default_factory=list)

    @property
    def dominated_by_baseline(self) -> bool:
        return any(member["dominated_by"] for member in self.members)

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.settings.as_dict(),
            "fresh_seed": self.fresh_seed,
            "fresh_realisations": self.fresh_realisations,
            "fresh_test_series": self.test_series,
            "accuracy_source": "measured" if self.test_series else "predicted",
            "candidates_rescored": self.candidates,
            "members": self.members,
            "baselines": self.baselines,
            "dominated_by_baseline": self.dominated_by_baseline,
            "confirmation": self.confirmation,
            "measurement_stopped": self.stopped,
            "not_rescored": self.not_rescored,
        }


def scored_baselines(
    scenario: Scenario, length: int, scorer: OperatorScorer
) -> dict[str, tuple[np.ndarray, SequenceScores] | str]:
    """Every baseline of ``length`` steps scored by ``scorer``; a baseline the geometry
    or the length does not allow is the reason it is missing."""
    made: dict[str, np.ndarray] = {}
    out: dict[str, tuple[np.ndarray, SequenceScores] | str] = {}
    for name, make in BASELINES.items():
        try:
            made[name] = make(scenario, length)
        except InputError as exc:
            out[name] = str(exc)
    if made:
        scores = scorer.score(np.stack(list(made.values())))
        for (name, sequence), score in zip(made.items(), scores, strict=True):
            out[name] = (sequence, score)
    return {name: out[name] for name in BASELINES}


def _measured(
    scorer: OperatorScorer,
    sequences: np.ndarray,
    scores: list[SequenceScores],
    test_series: int,
    seed: int,
    should_stop: Callable[[], bool] | None,
    progress: Callable[[float], None] | None = None,
) -> list[SequenceScores] | None:
    """``scores`` with the accuracy measured on ``test_series`` fresh series per
    candidate and condition (the prediction kept beside); as they are for 0; None when
    stopped."""
    if not test_series:
        return scores
    measured = scorer.measured_accuracy(
        sequences, test_series, seed=seed, should_stop=should_stop, progress=progress
    )
    if measured is None:
        return None
    fractions, per_condition = measured
    out = []
    for score, row in zip(scores, fractions, strict=True):
        # From the counts, so that an export reads 0.695, not 0.6950000000000001.
        correct = np.rint(row * per_condition)
        out.append(
            replace(
                score,
                accuracy=float(correct.sum() / (per_condition * len(row))),
                accuracy_by_noise=[float(c / per_condition) for c in correct],
                predicted_accuracy_by_noise=list(score.accuracy_by_noise),
                accuracy_bound=None,
            )
        )
    return out


def flights_seed(seed: int) -> int:
    """The seed of a front's per-flight draw: another stream than the fresh draw's and the
    confirmation's."""
    return int(np.random.SeedSequence([int(seed), 3]).generate_state(1)[0])


def confirmation_series(test_series: int) -> int:
    """Series per candidate and condition on which member 0 is measured again: five
    times the front's (one sequence, so cheap; its interval about half as wide), at most
    :data:`~inertia_id.search.operator.MAX_TEST_SERIES`."""
    return min(MAX_TEST_SERIES, CONFIRMATION_FACTOR * int(test_series))


def confirmation_rows(test_series: int) -> float:
    """What the confirmation costs, in rows of the front's measurement (for progress)."""
    return confirmation_series(test_series) / test_series if test_series else 0.0


def _confirmed(
    scorer: OperatorScorer,
    sequence: np.ndarray,
    test_series: int,
    seed: int,
    should_stop: Callable[[], bool] | None,
    progress: Callable[[float], None] | None = None,
    rivals: dict[str, np.ndarray] | None = None,
) -> dict[str, Any] | None:
    """Member 0's accuracy on ``test_series`` series per candidate and condition drawn
    from ``seed``, independent of the series that ranked it first, and each of
    ``rivals`` (baselines by name) on the same series; None when stopped.

    The front orders its members by their measured accuracy, so the first is the best
    of every sequence measured on those series, and its figure there is biased up on
    average (by about a point at L = 8 on the paper preset, 43 members a point or two
    apart; any one draw can go either way). These series played no part in the choice,
    so their figure is not biased, and a baseline measured on them is compared with it
    pair by pair. (Measured together or alone, member 0's figure is the same: every
    sequence of one call is tested on the same series.)
    """
    from ..evaluation.sweep import wilson_interval

    rivals = rivals or {}
    measured = scorer.measured_accuracy(
        np.stack([sequence, *rivals.values()]),
        test_series,
        seed=seed,
        should_stop=should_stop,
        progress=progress,
    )
    if measured is None:
        return None
    fractions, per_condition = measured

    def figures(row: np.ndarray) -> dict[str, Any]:
        correct = np.rint(row * per_condition).astype(int)
        return {
            "accuracy": float(correct.sum() / (per_condition * len(correct))),
            "accuracy_by_noise": [float(c / per_condition) for c in correct],
            "interval_by_noise": [list(wilson_interval(int(c), per_condition)) for c in correct],
        }

    return {
        "member": 0,
        "seed": int(seed),
        "test_series": int(test_series),
        "series_per_condition": int(per_condition),
        **figures(fractions[0]),
        "baselines": {name: figures(row) for name, row in zip(rivals, fractions[1:], strict=True)},
    }


def _rivals(
    sequence: np.ndarray,
    member: SequenceScores,
    baselines: dict[str, Any],
    objectives: tuple[str, ...],
) -> dict[str, np.ndarray]:
    """The baselines that could dominate member 0 (``sequence``, ``member``) once its
    accuracy is measured again: no worse on every other objective (on those, the front's
    fresh draw decides; a baseline worse on one of them dominates it on no series), and
    not the same sequence."""
    if "accuracy" not in objectives:
        return {}
    others = [i for i, name in enumerate(objectives) if name != "accuracy"]
    mine = member.objective_vector(objectives)[others]
    return {
        name: entry[0]
        for name, entry in baselines.items()
        if not isinstance(entry, str)
        and not np.array_equal(entry[0], sequence)
        and np.all(entry[1].objective_vector(objectives)[others] <= mine)
    }


def _rejudge_member_0(front: Front) -> None:
    """Member 0's ``dominated_by`` (and each baseline's ``dominates``) on the
    confirmation's series, where neither was chosen: on the front's own series member 0
    is flattered, and a baseline that dominates it could pass unflagged."""
    confirmation, objectives = front.confirmation, front.settings.objectives
    assert confirmation is not None
    member = SequenceScores.from_dict(front.members[0]["scores"])
    mine = replace(member, accuracy=confirmation["accuracy"]).objective_vector(objectives)
    for name, figures in confirmation["baselines"].items():
        stored = SequenceScores.from_dict(front.baselines[name]["scores"])
        score = replace(stored, accuracy=figures["accuracy"])
        figures["dominates_member_0"] = dominates(score.objective_vector(objectives), mine)
        flagged = [i for i in front.baselines[name]["dominates"] if i != 0]
        front.baselines[name]["dominates"] = [0] * figures["dominates_member_0"] + flagged
    front.members[0]["dominated_by"] = [
        name for name, entry in front.baselines.items() if 0 in entry.get("dominates", ())
    ]


def _feasible(score: SequenceScores, constraints: dict[str, float], series: int) -> bool:
    """The constraints on fresh scores; a measured accuracy meets ``min_accuracy`` unless
    its Wilson interval lies wholly below it (a measurement on ``series`` series carries
    sampling error the prediction the search constrained did not)."""
    if score.predicted_accuracy_by_noise is None or "min_accuracy" not in constraints:
        return score.feasible(constraints)
    from ..evaluation.sweep import wilson_interval

    _, upper = wilson_interval(round(score.accuracy * series), series)
    return replace(score, accuracy=upper).feasible(constraints)


def _fires(scenario: Scenario, row: np.ndarray) -> bool:
    """Whether the sequence applies torque at some step. The all-off sequence is a
    legitimate member (the end of the front that spends nothing and keeps the body at
    rest; its measured accuracy is the noise's, :func:`_front_mask`) but no classifier
    can be trained on it: marked, so the dashboard and ``train`` can say why
    (:meth:`Scenario.check_fires`)."""
    try:
        scenario.check_fires(row)
    except InputError:
        return False
    return True


def _front_mask(vectors: np.ndarray, eligible: np.ndarray, fires: np.ndarray) -> np.ndarray:
    """The eligible rows of a front: those no eligible row dominates, except that a
    sequence that applies no torque dominates none that fires.

    Its measured accuracy comes from the noise alone (the disturbance's random walk
    scales with I⁻¹: the noise model's classifier reads 0.216-0.218 off the all-off
    sequence at the default design noise, K = 5, on 10,000 series a condition) and no
    classifier is trained on it (:meth:`Scenario.check_fires`). Where firing adds less
    than the sampling error (one 0.1 N m thruster at L = 1: 0.2195-0.2233 at full duty),
    the measurement on 1,000 series a condition ranked it first by luck: it was member 0
    and the search's ``best`` on 7 of 20 seeds, mostly as the front's only member. It
    stays the zero-torque end of the front (least impulse).
    """
    keep = np.zeros(len(vectors), bool)
    firing = np.flatnonzero(eligible & fires)
    if len(firing):
        keep[firing[non_dominated(vectors[firing])]] = True
    every = np.flatnonzero(eligible)
    for i in np.flatnonzero(eligible & ~fires):
        keep[i] = not any(dominates(vectors[j], vectors[i]) for j in every)
    return keep


def build_front(
    scenario: Scenario,
    sequences: Sequence[Any],
    settings: OperatorSettings,
    *,
    seed: int,
    fresh_realisations: int = 40,
    search_scores: Sequence[SequenceScores] | None = None,
    keep_infeasible: bool = False,
    test_series: int = 200,
    should_stop: Callable[[], bool] | None = None,
    progress: Callable[[float], None] | None = None,
    rescore_stop: Callable[[], bool] | None = None,
) -> Front:
    """Re-score ``sequences`` on a fresh draw and keep the non-dominated (and, unless
    ``keep_infeasible``, feasible) ones; score the baselines on the same draw and flag
    those that dominate a member.

    :param seed: the fresh draw's seed (pass one independent of the search's).
    :param search_scores: each sequence's scores on the search's draw, stored beside.
    :param keep_infeasible: keep members that break a constraint (marked
        ``feasible: false``): for the single best sequence of a search that did not
        optimise the constraints.
    :param test_series: fresh test series per candidate and design condition on which
        each sequence's accuracy is measured (:meth:`OperatorScorer.measured_accuracy`,
        every sequence and baseline on the same series); 0 keeps the prediction.
    :param should_stop: polled while the accuracy is measured; True keeps the predictions
        (the front then says its accuracy is predicted).
    :param progress: called while the accuracy is measured, with the fraction done.
    :param rescore_stop: polled before every :data:`STOP_CHECK_SEQUENCES` sequences are
        re-scored, after the first sequence and the baselines (always re-scored: a front
        needs a member); True leaves the rest out of the front (``not_rescored``), so
        put the sequences in the order they matter.

    When more than one sequence was measured and the front keeps a member, member 0 is
    measured again on :func:`confirmation_series` series from a seed independent of
    ``seed`` (``confirmation``): it was chosen as the best of them.
    """
    settings = settings.check(scenario)
    check_test_series(test_series)
    rows = [scenario.check_sequence(s) for s in sequences]
    if not rows:
        raise InputError("a front needs at least one sequence")
    length = len(rows[0])
    scorer = OperatorScorer(
        scenario,
        length,
        OperatorSettings(
            objectives=settings.objectives,
            design_noise=settings.design_noise,
            constraints=settings.constraints,
            n_realisations=fresh_realisations,
        ),
        seed=seed,
    )
    baselines = scored_baselines(scenario, length, scorer)
    available = {name: scored for name, scored in baselines.items() if not isinstance(scored, str)}
    # The per-flight figure from flights of their own: the scorer's 40 realisations bound
    # it only through a model of the residual's distribution, which lopsided noise
    # breaks; FRONT_FLIGHTS flights bound it without one (per_flight_bound).
    figures = (
        list(
            scorer.per_flight_figures(
                np.stack([sequence for sequence, _ in available.values()]),
                FRONT_FLIGHTS,
                seed=flights_seed(seed),
            )
        )
        if available
        else []
    )
    # The sequences a chunk at a time, the first alone: each scored and flown on the
    # same draw whatever the cut, so a stop changes what is re-scored, not its scores.
    predicted: list[SequenceScores] = []
    flown: list[np.ndarray] = []
    for first in (0, *range(1, len(rows), STOP_CHECK_SEQUENCES)):
        if first and rescore_stop is not None and rescore_stop():
            break
        chunk = np.stack(rows[first : first + (STOP_CHECK_SEQUENCES if first else 1)])
        predicted += scorer.score(chunk)
        flown += list(scorer.per_flight_figures(chunk, FRONT_FLIGHTS, seed=flights_seed(seed)))
    left_out = [
        {
            "sequence": rows[i].tolist(),
            "search_scores": None if search_scores is None else search_scores[i].as_dict(),
        }
        for i in range(len(predicted), len(rows))
    ]
    rows = rows[: len(predicted)]
    predicted += [score for _, score in available.values()]
    figures = flown + figures
    # The members and the baselines measured on the same series, in one pass; then,
    # maybe, member 0 again (one row more).
    everything = [*rows, *(sequence for sequence, _ in available.values())]
    confirming = bool(test_series) and len(rows) > 1
    extra = confirmation_rows(test_series) if confirming else 0.0
    share = len(everything) / (len(everything) + extra)
    measured = _measured(
        scorer,
        np.stack(everything),
        predicted,
        test_series,
        seed,
        should_stop,
        None if progress is None else (lambda done: progress(done * share)),
    )
    stopped = measured is None
    if stopped:
        test_series = 0  # stopped: the predictions stand, and the front says so
    scored = predicted if measured is None else measured
    scored = [
        replace(
            score,
            final_rate_p95_rad_s=max(float(residual), score.final_rate_max_rad_s),
            peak_rate_p95_rad_s=max(float(peak), score.peak_rate_rad_s),
        )
        for score, (residual, peak) in zip(scored, figures, strict=True)
    ]
    fresh = scored[: len(rows)]
    for (name, (sequence, _)), score in zip(available.items(), scored[len(rows) :], strict=True):
        baselines[name] = (sequence, score)
    series = len(settings.design_noise) * scenario.n_candidates * test_series
    constraints = dict(settings.constraints)
    vectors = np.stack([s.objective_vector(settings.objectives) for s in fresh])
    feasible = np.array([_feasible(s, constraints, series) for s in fresh])
    eligible = np.ones(len(rows), bool) if keep_infeasible else feasible
    fires = np.array([_fires(scenario, row) for row in rows])
    keep = _front_mask(vectors, eligible, fires)
    # One member per distinct sequence; those that fire first, the most accurate first.
    order = sorted(
        (int(i) for i in np.flatnonzero(keep)),
        key=lambda i: (not fires[i], -fresh[i].ranking_accuracy, fresh[i].impulse_nms),
    )
    seen: set[bytes] = set()
    chosen: list[int] = []
    for i in order:
        key = rows[i].tobytes()
        if key not in seen:
            seen.add(key)
            chosen.append(int(i))
    front = Front(
        settings,
        int(seed),
        int(fresh_realisations),
        candidates=len(rows),
        test_series=int(test_series),
        stopped=stopped,
        not_rescored=left_out,
    )
    for index, i in enumerate(chosen):
        front.members.append(
            {
                "index": index,
                "sequence": rows[i].tolist(),
                "scores": fresh[i].as_dict(),
                "search_scores": None if search_scores is None else search_scores[i].as_dict(),
                "feasible": bool(feasible[i]),
                "dominated_by": [],
                "fires": bool(fires[i]),
            }
        )
    for name, entry in baselines.items():
        if isinstance(entry, str):
            front.baselines[name] = {"unavailable": entry}
            continue
        sequence, score = entry
        vector = score.objective_vector(settings.objectives)
        allowed = _feasible(score, constraints, series)
        # Constrained domination: a baseline the constraints rule out cannot be flown in a
        # member's place, so it dominates none (the dashboard raised "hand-designed
        # dominates member 0" beside its own row's "breaks a constraint").
        beaten = [
            member["index"]
            for member, i in zip(front.members, chosen, strict=True)
            if allowed and dominates(vector, vectors[i])
        ]
        for index in beaten:
            front.members[index]["dominated_by"].append(name)
        front.baselines[name] = {
            "sequence": sequence.tolist(),
            "scores": score.as_dict(),
            "feasible": allowed,
            "dominates": beaten,
            "fires": _fires(scenario, sequence),
        }
    if test_series and len(rows) > 1 and chosen:
        best = chosen[0]
        front.confirmation = _confirmed(
            scorer,
            rows[best],
            confirmation_series(test_series),
            fresh_seed(seed),
            should_stop,
            None if progress is None else (lambda done: progress(share + done * (1 - share))),
            rivals=_rivals(
                rows[best],
                fresh[best],
                {
                    name: entry
                    for name, entry in baselines.items()
                    if front.baselines[name].get("feasible")
                },
                settings.objectives,
            ),
        )
        front.stopped = front.confirmation is None
        if front.confirmation is not None:
            _rejudge_member_0(front)
    elif progress is not None and test_series:
        progress(1.0)  # no confirmation to make: the measurement is done
    return front


class _Archive:
    """Every sequence evaluated, with its scores on the search's draw."""

    def __init__(self) -> None:
        self.scores: dict[bytes, tuple[np.ndarray, SequenceScores]] = {}

    def add(self, rows: np.ndarray, scores: list[SequenceScores]) -> None:
        for row, score in zip(rows, scores, strict=True):
            self.scores.setdefault(row.tobytes(), (row, score))


def _baseline_rows(scenario: Scenario, length: int) -> list[np.ndarray]:
    """The baselines the geometry and the length allow."""
    rows = []
    for make in BASELINES.values():
        try:
            rows.append(make(scenario, length))
        except InputError:
            continue
    return rows


def _initial_population(
    scenario: Scenario, length: int, size: int, rng: np.random.Generator
) -> np.ndarray:
    seeded = _baseline_rows(scenario, length)
    seeded.append(np.zeros((length, scenario.n_thrusters), dtype=int))
    # Random sequences, most entries off: a uniformly random level on every thruster
    # fires opposing thrusters almost always.
    count = max(size - len(seeded), 0)
    levels = rng.integers(1, scenario.n_levels, (count, length, scenario.n_thrusters))
    on = rng.random((count, length, scenario.n_thrusters)) < 0.3
    population = OpposedFirings(scenario)(np.concatenate([np.stack(seeded)[:size], levels * on]))
    return population.reshape(len(population), -1)


def opposing_thrusters(torque_matrix: np.ndarray) -> np.ndarray:
    """For each thruster, the one whose torque is most nearly opposite (cosine below
    -0.5), or -1: what brakes what it fires, for any geometry."""
    directions = torque_matrix / np.maximum(np.linalg.norm(torque_matrix, axis=0), 1e-300)
    cosines = directions.T @ directions
    best = cosines.argmin(axis=1)
    return np.where(cosines[np.arange(len(best)), best] < -0.5, best, -1)


def _neighbours(
    current: np.ndarray,
    count: int,
    n_levels: int,
    opposing: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """``count`` sequences one local move away from ``current`` (L, N): a firing moved to
    the step before or after (or to any step), a level one up or down, two steps
    swapped, or a firing and its brake added or taken away together (the same level
    change on a thruster at one step and on its opposing thruster at a later one).
    Moves in time keep each thruster's impulse, and a paired change keeps the momentum
    balance where the two thrusters' torques are equal and opposite and the levels
    evenly spaced (as usual; elsewhere it comes near), so a sequence that ends at rest
    stays near rest while its timing and its impulse change, which the crossover and
    mutation of NSGA-II, acting on one level at a time, rarely achieve.

    :param opposing: each thruster's opposing one, or -1 (:func:`opposing_thrusters`).
    """
    length, n_thr = current.shape
    firing = np.argwhere(current > 0)
    paired = np.flatnonzero(opposing >= 0)
    out = np.repeat(current[None], count, axis=0)
    for child in out:
        move = rng.integers(5)
        step, thruster = int(rng.integers(length)), int(rng.integers(n_thr))
        if move < 2 and len(firing):
            step, thruster = (int(i) for i in firing[rng.integers(len(firing))])
        if move == 0 and length > 1:
            other = step + 1 if step == 0 else step - 1 if step == length - 1 else step
            other = other if other != step else step + int(rng.choice((-1, 1)))
            child[[step, other], thruster] = child[[other, step], thruster]
        elif move == 1 and length > 1:
            other = int((step + rng.integers(1, length)) % length)
            child[[step, other], thruster] = child[[other, step], thruster]
        elif move == 3 and length > 1:
            other = int((step + rng.integers(1, length)) % length)
            child[[step, other]] = child[[other, step]]
        elif move == 4 and length > 1 and len(paired):
            fire = int(paired[rng.integers(len(paired))])
            first, later = sorted(rng.choice(length, 2, replace=False))
            brake = opposing[fire]
            low, high = child[first, fire], child[later, brake]
            if rng.random() < 0.5:  # add: as much as both have room for
                change = min(int(rng.integers(1, n_levels)), n_levels - 1 - max(low, high))
            else:  # take away: as much as both have
                change = -min(int(rng.integers(1, n_levels)), min(low, high))
            child[first, fire] += change
            child[later, brake] += change
        else:
            level = child[step, thruster] + rng.choice((-1, 1))
            child[step, thruster] = np.clip(level, 0, n_levels - 1)
    return out


def _rank_key(score: SequenceScores, constraints: dict[str, float]) -> tuple[float, float]:
    """Feasible first (the summed relative violation), then the most accurate."""
    violation = float(np.sum(np.maximum(score.violations(constraints), 0.0)))
    return violation, -score.ranking_accuracy


def _polish(
    scorer: OperatorScorer,
    archive: _Archive,
    starts: list[np.ndarray],
    constraints: dict[str, float],
    *,
    iterations: int,
    batch: int,
    rng: np.random.Generator,
    after_round: Callable[[list[SequenceScores]], bool] | None = None,
    after_start: Callable[[], None] | None = None,
    interrupted: Callable[[], bool] | None = None,
) -> bool:
    """Steepest-ascent local search (a memetic step after NSGA-II) from each start:
    each round scores ``batch`` neighbours and moves to the best if it ranks above the
    current sequence (:func:`_rank_key`), else stops there. Every sequence scored goes
    into the archive, so the front gains whatever non-dominated ones it met.

    :param after_round: called after every round with the round's scores (a point of
        the learning curve); True ends the polish there, and the function returns False;
        ``after_start`` after each start's climb.
    :param interrupted: polled between :data:`STOP_CHECK_SEQUENCES` sequences of a
        round (a round of 64 at 200 realisations and L = 20 takes about 30 s); True
        ends the polish there, what was scored kept in the archive, and the function
        returns False."""
    n_levels = scorer.scenario.n_levels
    opposing = opposing_thrusters(scorer.scenario.torque_matrix)
    opposed = OpposedFirings(scorer.scenario)
    for start in starts:
        current = np.asarray(start)
        best = _rank_key(scorer.score(current[None])[0], constraints)
        for _ in range(iterations):
            moved = opposed(_neighbours(current, batch, n_levels, opposing, rng))
            rows = np.unique(moved, axis=0)
            rows = rows[(rows != current).any(axis=(1, 2))]
            if not len(rows):
                break
            scores: list[SequenceScores] = []
            for first in range(0, len(rows), STOP_CHECK_SEQUENCES):
                if scores and interrupted is not None and interrupted():
                    return False
                chunk = rows[first : first + STOP_CHECK_SEQUENCES]
                scores += scorer.score(chunk)
                archive.add(chunk, scores[first:])
            if after_round is not None and after_round(scores):
                return False
            keys = [_rank_key(score, constraints) for score in scores]
            chosen = min(range(len(rows)), key=keys.__getitem__)
            if keys[chosen] >= best:
                break
            current, best = rows[chosen], keys[chosen]
        if after_start is not None:
            after_start()
    return True


@dataclass
class _Bar:
    """The fraction of an NSGA-II job done, for its progress bar.

    The job is the generations, the polish and the front's measurement, in evaluations.
    The polish stops a start where no neighbour ranks higher, usually after a few
    rounds (on the paper preset about 3 of the 30 allowed), so its remaining work is
    estimated from the starts climbed so far rather than counted at its maximum; the
    measurement is counted from the start (at the largest front until the front is
    known). The fraction reported never goes back.
    """

    population: int
    generations: int
    polish_starts: int
    measured_series: int
    generations_done: int = 0
    starts_done: int = 0
    #: Rows measured: the front's candidates, the baselines and member 0's confirmation.
    front_rows: float = MAX_FRONT_CANDIDATES + len(BASELINES) + CONFIRMATION_FACTOR
    _evaluations_at_polish: int | None = None
    _last: float = 0.0

    #: Rounds a polish start is expected to climb before any start has finished.
    PRIOR_ROUNDS = 3

    def start_done(self) -> None:
        self.starts_done += 1

    def fraction(self, evaluations: int, measured: float) -> float:
        if self.generations_done >= self.generations and self._evaluations_at_polish is None:
            self._evaluations_at_polish = evaluations
        polished = evaluations - (self._evaluations_at_polish or evaluations)
        per_start = (
            polished / self.starts_done if self.starts_done else self.PRIOR_ROUNDS * self.population
        )
        if measured:
            polish_left = 0.0
        else:
            polish_left = max(0.0, per_start * self.polish_starts - polished)
        generations_left = max(0, self.generations - self.generations_done) * self.population
        measurement = self.front_rows * self.measured_series / SERIES_PER_EVALUATION
        done = evaluations + measured * measurement
        whole = evaluations + generations_left + polish_left + measurement
        self._last = max(self._last, done / whole if whole else 1.0)
        return self._last


def _nearest(entries: list[tuple[Any, SequenceScores]], constraints: dict[str, float]) -> str:
    """Each constraint's best figure among the sequences evaluated, in its unit, and how
    many of them met it: why none met them all (one bound no sequence came near, or
    bounds each met by other sequences)."""
    words = []
    for name, bound in constraints.items():
        figure, sense, factor = CONSTRAINTS[name]
        values = np.array([score.figure(figure) for _, score in entries]) / factor
        values = values[np.isfinite(values)]
        met = int(np.count_nonzero(values <= bound if sense == "max" else values >= bound))
        best = (values.min() if sense == "max" else values.max()) if values.size else np.nan
        words.append(
            f"{name} = {bound:g}: best {best:.4g}, met by {met} of {len(entries)} sequences"
        )
    return "; ".join(words)


def pareto_search(
    scenario: Scenario,
    *,
    sequence_length: int = 4,
    seed: int = 0,
    operator: OperatorSettings | None = None,
    nsga2_params: dict[str, Any] | None = None,
    fresh_realisations: int = 40,
    fresh_test_series: int = 200,
    settings: ScorerSettings | None = None,
    n_fresh_draws: int = 5,
    progress: Callable[[SearchProgress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    time_limit_s: float | None = None,
    time_limit_grace_s: float | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> SearchResult:
    """NSGA-II over the operator's objectives; the front re-scored on fresh draws.

    :param operator: objectives, design noise, constraints and realisations per score.
    :param nsga2_params: overrides of :data:`NSGA2_DEFAULTS`.
    :param fresh_realisations: realisations per candidate of the fresh re-scoring.
    :param fresh_test_series: test series per candidate and design condition on which
        each member's accuracy is measured (0: the prediction is kept).
    :param settings: how the best member's clustering F1 is measured on
        ``n_fresh_draws`` fresh draws (the figure every search reports).
    :param progress: called after every generation and every polish round (each a
        point of ``curve``, so that the curve ends at the evaluations reported), and
        while the front is measured.
    :param should_stop: polled after every generation and every polish round, and while
        the front is measured; True ends the search there, "cancelled": nobody waits for
        the result, so no front is built (the best is the most accurate feasible
        sequence on the search's draw) and it is not re-scored.
    :param time_limit_s: the search's time budget in seconds (None: none), checked where
        ``should_stop`` is: once spent the search stops, "time_limit"; the front's
        accuracy stays predicted (the measurement, minutes at 200 realisations and
        L = 20, is skipped, and the front says so). The re-score on fresh draws goes on
        only while the limit's grace lasts (:func:`~inertia_id.search.loop.
        time_limit_grace_s`), in order of need: the front's candidates by accuracy on
        the search's draw, 16 at a time after the first (those left out are listed in
        ``not_rescored``), then the best's fresh draws (those completed kept).
    :param time_limit_grace_s: that grace in seconds (>= 0 and <= 3600); None: the
        default rule.
    :param clock: monotonic seconds for ``time_limit_s``.
    :param seed: seeds the noise draw and NSGA-II: the same seed, the same front.
    """
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.problem import Problem
    from pymoo.core.repair import Repair
    from pymoo.operators.crossover.sbx import SBX
    from pymoo.operators.mutation.pm import PM
    from pymoo.operators.repair.rounding import RoundingRepair

    started = time.perf_counter()
    deadline = Deadline(time_limit_s, clock, time_limit_grace_s)
    if not is_integer(sequence_length, minimum=1, maximum=50):
        raise InputError(f"sequence_length must be an integer in 1..50, got {sequence_length!r}")
    seed = check_seed(seed)
    params = check_nsga2_params(nsga2_params)
    check_test_series(fresh_test_series)
    checked = (operator or OperatorSettings()).check(scenario, sequence_length)
    check_per_flight_realisations(dict(checked.constraints), checked.n_realisations)
    scorer = OperatorScorer(scenario, sequence_length, checked, seed=seed)
    constraints = dict(checked.constraints)
    n, m = scenario.n_thrusters, scenario.n_levels
    n_var = sequence_length * n
    archive = _Archive()

    class _Sequences(Problem):
        def __init__(self) -> None:
            super().__init__(
                n_var=n_var,
                n_obj=len(checked.objectives),
                n_ieq_constr=len(constraints),
                xl=0,
                xu=m - 1,
                vtype=int,
            )

        def _evaluate(self, x: np.ndarray, out: dict[str, Any], *args: Any, **kwargs: Any) -> None:
            rows = np.rint(x).astype(int).clip(0, m - 1).reshape(len(x), sequence_length, n)
            scores: list[SequenceScores] = []
            for start in range(0, len(rows), STOP_CHECK_SEQUENCES):
                if scores and interrupted():
                    raise _Interrupted
                chunk = rows[start : start + STOP_CHECK_SEQUENCES]
                scores += scorer.score(chunk)
                archive.add(chunk, scores[start:])
            out["F"] = np.stack([s.objective_vector(checked.objectives) for s in scores])
            if constraints:
                out["G"] = np.stack([s.violations(constraints) for s in scores])

    opposed = OpposedFirings(scenario)

    class _NoOpposedFirings(Repair):
        """pymoo's hook for offspring (and the first population): each one's opposed
        firings cancelled (:class:`OpposedFirings`)."""

        def _do(self, problem: Any, X: np.ndarray, **kwargs: Any) -> np.ndarray:
            rows = np.rint(X).astype(int).clip(0, m - 1).reshape(len(X), sequence_length, n)
            return opposed(rows).reshape(len(X), -1)

    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(4)[3])
    algorithm = NSGA2(
        repair=_NoOpposedFirings(),
        pop_size=params["population"],
        sampling=_initial_population(scenario, sequence_length, params["population"], rng),
        crossover=SBX(
            prob=params["crossover_prob"],
            eta=params["crossover_eta"],
            vtype=float,
            repair=RoundingRepair(),
        ),
        mutation=PM(prob=1.0, eta=params["mutation_eta"], vtype=float, repair=RoundingRepair()),
        eliminate_duplicates=True,
    )
    algorithm.setup(_Sequences(), termination=("n_gen", params["generations"]), seed=seed)
    # The polish climbs the accuracy: only worth its evaluations when accuracy is asked.
    polish_starts: list[np.ndarray] = []
    if params["polish_iterations"] > 0 and "accuracy" in checked.objectives:
        polish_starts = _baseline_rows(scenario, sequence_length)
    rounds = params["polish_iterations"] * (params["polish_starts"] + len(polish_starts))
    # At most: the polish stops early where no neighbour ranks higher.
    budget = (
        params["population"] * (params["generations"] + rounds) + params["polish_starts"]
    ) * sequence_length
    curve: list[CurvePoint] = []

    bar = _Bar(
        population=params["population"],
        generations=params["generations"],
        polish_starts=params["polish_starts"] + len(polish_starts) if polish_starts else 0,
        measured_series=len(checked.design_noise) * scenario.n_candidates * fresh_test_series,
    )

    #: Why the search was told to stop, once it was: "cancelled" or "time_limit".
    halted: list[str] = []

    def interrupted() -> bool:
        """Whether to stop now (a cancel or the time limit); the first reason is kept."""
        if not halted:
            if should_stop is not None and should_stop():
                halted.append(CANCELLED)
            elif deadline.expired():
                halted.append(TIME_LIMIT)
        return bool(halted)

    def rescore_stop() -> bool:
        """Whether the re-score after the search must stop: a cancel, or the time
        limit's grace spent (whatever stopped the search)."""
        return (should_stop is not None and should_stop()) or deadline.grace_spent()

    def report(
        point: CurvePoint, *, new_point: bool = True, phase: str = "search", measured: float = 0.0
    ) -> bool:
        if progress is not None:
            progress(
                SearchProgress(
                    timesteps=scorer.evaluations * sequence_length,
                    total_timesteps=max(budget, scorer.evaluations * sequence_length),
                    episodes=scorer.evaluations,
                    point=point,
                    best=None,
                    new_point=new_point,
                    phase=phase,
                    fraction_done=bar.fraction(scorer.evaluations, measured),
                )
            )
        return interrupted()

    def measuring(done: float) -> None:
        bar.front_rows = (
            len(candidates) + len(BASELINES) + confirmation_rows(fresh_test_series)
            if len(candidates) > 1
            else 1 + len(BASELINES)
        )
        report(curve[-1], new_point=False, phase="measuring the front", measured=done)

    #: The most accurate feasible sequence scored so far (of all, while none is feasible).
    best_so_far: list[SequenceScores] = []

    def curve_point(scored: list[SequenceScores]) -> CurvePoint:
        """A point of the learning curve at the evaluations so far: the most accurate
        feasible sequence so far, as :class:`CurvePoint` says of every method, and the
        mean accuracy of ``scored`` (a generation's population, or a polish round's
        neighbours). The best of ``scored`` alone dipped: a polish round's neighbours
        are each a step off the sequence climbed, most of them less accurate."""
        best_so_far[:] = [
            max(
                [*best_so_far, *scored],
                key=lambda s: (s.feasible(constraints), s.ranking_accuracy),
            )
        ]
        top = best_so_far[0]
        return CurvePoint(
            timesteps=scorer.evaluations * sequence_length,
            episodes=scorer.evaluations,
            mean_episode_reward=float("nan"),
            mean_f1=float(np.mean([s.accuracy for s in scored])),
            best_f1=top.accuracy,
            best_residual_rate_rad_s=top.final_rate_rad_s,
            best_feasible=top.feasible(constraints),
        )

    def polish_round(scored: list[SequenceScores]) -> bool:
        # Every polish round is a point too, so that the curve ends at the evaluations
        # the job reports: a job of 3 generations of 16 at L = 4 drew its curve to 192
        # steps while it reported 736, the polish's 544 off the curve and unsaid.
        curve.append(curve_point(scored))
        return report(curve[-1])

    stopped = "budget"
    while algorithm.has_next():
        try:
            algorithm.next()
        except _Interrupted:
            stopped = halted[0]  # part of a generation scored: kept in the archive
            break
        population = [
            archive.scores[np.rint(x).astype(int).reshape(sequence_length, n).tobytes()][1]
            for x in algorithm.pop.get("X")
        ]
        point = curve_point(population)
        curve.append(point)
        bar.generations_done += 1
        if report(point):
            stopped = halted[0]
            break
    if stopped == "budget" and polish_starts:
        ranked = sorted(archive.scores.values(), key=lambda e: _rank_key(e[1], constraints))
        starts = [row for row, _ in ranked[: params["polish_starts"]]] + polish_starts
        if not _polish(
            scorer,
            archive,
            starts,
            constraints,
            iterations=params["polish_iterations"],
            batch=params["population"],
            rng=rng,
            after_round=polish_round,
            after_start=bar.start_done,
            interrupted=interrupted,
        ):
            stopped = halted[0]
    entries = list(archive.scores.values())
    vectors = np.stack([s.objective_vector(checked.objectives) for _, s in entries])
    allowed = np.array([s.feasible(constraints) for _, s in entries])
    if not allowed.any():
        raise InputError(
            f"no sequence met the constraints {constraints} in {scorer.evaluations} evaluations "
            f"({_nearest(entries, constraints)}); loosen them or search longer"
        )
    if not any(_fires(scenario, entries[i][0]) for i in np.flatnonzero(allowed)):
        # Only sequences that apply no torque (the all-off one) met them: a front of it
        # alone came back as the search's best, which no classifier can be trained on
        # (three thrusters on one side of the body, L = 4, a 0.01 deg/s commanded
        # residual: nothing that fires can stop about +z).
        firing = [entry for entry in entries if _fires(scenario, entry[0])]
        raise InputError(
            f"no sequence that fires met the constraints {constraints} in "
            f"{scorer.evaluations} evaluations, only the all-off sequence (no torque: "
            "nothing to train a classifier on)"
            + (f" ({_nearest(firing, constraints)})" if firing else "")
            + "; loosen them or search longer"
        )
    candidates = np.flatnonzero(allowed)[non_dominated(vectors[allowed])]
    candidates = candidates[
        np.argsort([-entries[i][1].ranking_accuracy for i in candidates], kind="stable")
    ]
    if len(candidates) > MAX_FRONT_CANDIDATES:
        candidates = candidates[
            np.unique(np.linspace(0, len(candidates) - 1, MAX_FRONT_CANDIDATES).round().astype(int))
        ]
    front = None
    if stopped == CANCELLED:
        # Nobody waits for a cancelled result: the front's re-scoring would only delay
        # the cancel. The best is the most accurate non-dominated feasible sequence on
        # the search's draw.
        best_sequence = entries[candidates[0]][0]
    else:
        front = build_front(
            scenario,
            [entries[i][0] for i in candidates],
            checked,
            seed=fresh_seed(seed),
            fresh_realisations=fresh_realisations,
            search_scores=[entries[i][1] for i in candidates],
            test_series=fresh_test_series,
            should_stop=interrupted,
            progress=measuring if curve else None,
            rescore_stop=rescore_stop,
        )
        if front.stopped:
            # Told to stop while the front was measured (the reason, when it came
            # through ``interrupted``).
            stopped = halted[0] if halted else CANCELLED
        if not front.members:
            cut = (
                f" (the {front.candidates} re-scored before the time limit's grace of "
                f"{deadline.grace_s:g} s was spent)"
                if front.not_rescored
                else ""
            )
            raise InputError(
                f"no sequence of the front met the constraints {constraints} on the fresh "
                f"draw{cut}; loosen them or search longer"
            )
        best_sequence = np.asarray(front.members[0]["sequence"])
    seen = archive.scores[best_sequence.tobytes()][1]
    best = EpisodeRecord(
        sequence=best_sequence.tolist(),
        f1=seen.accuracy,
        final_rate_rad_s=seen.final_rate_rad_s,
        residual_rate_rad_s=seen.final_rate_rad_s,
        fuel_nms=seen.impulse_nms,
        episode_return=float("nan"),
        episode=0,
    )
    clustering = settings or ScorerSettings()
    fresh = evaluate_sequence(
        scenario,
        best_sequence,
        clustering,
        seed=fresh_seed(seed),
        n_draws=0 if stopped == CANCELLED else n_fresh_draws,
        should_stop=rescore_stop,
    )
    return SearchResult(
        method="nsga2",
        best=best,
        fresh=fresh,
        curve=curve,
        timesteps=scorer.evaluations * sequence_length,
        episodes=scorer.evaluations,
        wall_time_s=time.perf_counter() - started,
        stopped=stopped,
        space_size=space_size(scenario, sequence_length),
        settings={
            "sequence_length": sequence_length,
            "seed": seed,
            "nsga2": params,
            "operator": checked.as_dict(),
            "fresh_realisations": fresh_realisations,
            "fresh_test_series": int(fresh_test_series),
            "time_limit_s": deadline.time_limit_s,
            "time_limit_grace_s": deadline.grace_s,
            "scorer": clustering.as_dict(),
        },
        front=None if front is None else front.to_dict(),
    )
