"""The use cases the command line and the service share, with their defaults and one
seeding scheme.

Each use case takes a request (a frozen dataclass whose field names are the job
parameters the service stores, and whose defaults are *the* defaults, for the CLI's
options and the service's jobs alike) and a seed:

- :func:`search_with_baselines`: search for a sequence, then score the hand-designed
  baselines on the very fresh draws the best sequence was re-scored on;
- :func:`train_for_sequence`: train a classifier of any kind (the kind is
  :func:`~inertia_id.classifiers.registry.resolve_kind`'s);
- :func:`train_others`: the classifiers a sweep draws beside the main one;
- :func:`sweep_with_limit`: the noise sweep with the others, the ceiling and the bodies
  off the candidates;
- :func:`run_paper`: the paper's pipeline (search, train, sweep, report).

Seeding, the same whoever calls:

- training: every draw (and a seed the kind needs) from ``np.random.default_rng(seed)``;
- sweep: ``SeedSequence(seed).spawn(3)``: the first trains the others, the second seeds
  the test draws (and, through them, the ceiling's), the third the bodies off the
  candidates;
- search: ``seed`` seeds the search; its fresh re-scoring, and so the baselines, use a
  seed spawned from it;
- paper: the search takes ``seed``; of ``SeedSequence(seed).spawn(3)`` the first trains
  the classifier, the sweep takes ``seed`` itself (so the classifier and the others it is
  compared with train on the same draws), the third draws the report's responses.

Importing this module is quick: the core is imported by the use cases when they run.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from .errors import InputError

if TYPE_CHECKING:
    from .classifiers.registry import CandidateClassifier
    from .evaluation.sweep import InertiaSweepResult, SweepResult
    from .physics.scenario import Scenario
    from .search import OperatorSettings, ScorerSettings, SearchProgress, SearchResult

__all__ = [
    "PAPER_SEQUENCE",
    "PaperOutcome",
    "SearchOutcome",
    "SearchRequest",
    "SweepOutcome",
    "SweepRequest",
    "TrainRequest",
    "Trained",
    "check_search",
    "check_search_scenario",
    "check_sweep_scenario",
    "run_paper",
    "search_with_baselines",
    "sweep_with_limit",
    "train_for_sequence",
    "train_others",
]

#: The hand-designed excitation of the paper preset (the positive-axis thrusters at full
#: duty every step): what the paper pipeline uses without a search.
PAPER_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4


class _Request:
    """A request built from stored job parameters: names it knows, defaults for the rest."""

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> Self:
        fields = dataclasses.fields(cls)  # type: ignore[arg-type]
        required = [
            f.name
            for f in fields
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        ]
        missing = [name for name in required if name not in params]
        if missing:
            raise InputError(f"the job's params lack {missing}")
        names = {f.name for f in fields}
        return cls(**{name: value for name, value in params.items() if name in names})

    @classmethod
    def default(cls, name: str) -> Any:
        """The default of one field: what a CLI option shows and falls back to."""
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.name == name:
                if f.default_factory is not dataclasses.MISSING:
                    return f.default_factory()
                return f.default
        raise KeyError(name)


# Search, then the baselines on the same fresh draws.


@dataclass(frozen=True)
class SearchRequest(_Request):
    """What to search for and how (the job's ``params``).

    :param method: "ppo", "cem", "exhaustive" or "random".
    :param sequence_length: steps L of the sequence.
    :param timesteps: environment-step budget (ppo, cem, random).
    :param max_sequences: exhaustive search refuses larger spaces.
    :param n_realisations: realisations per candidate in each environment step.
    :param objective: "f1" (the clustering F1, the paper's) or "separability".
    :param metric: clustering metric that scores sequences.
    :param sakoe_chiba_radius: DTW band half-width in samples; None: unconstrained.
    :param fuel_weight: reward cost per N m s of commanded impulse.
    :param patience_episodes: stop once F1 = 1 and nothing better came for this many
        episodes (ppo, cem, random); None: never.
    :param ppo: overrides of the paper's PPO hyperparameters (method ppo only).
    :param cem: overrides of the cross-entropy method's settings (method cem only).
    :param nsga2: overrides of NSGA-II's settings (method nsga2 only).
    :param objectives: what the front trades off (method nsga2), and what every
        search's front (its best sequence beside the baselines) is judged on.
    :param design_noise: (process multiple, measurement multiple) conditions at which
        the accuracy objective is predicted (and the front's accuracy measured).
    :param constraints: bounds by name (``max_final_rate_deg_s``, ``max_impulse_nms``,
        ...): NSGA-II's constraints; the other methods rank and (ppo) penalise by them.
    :param constraint_penalty: reward cost per unit of summed relative violation (the
        constrained variant of the paper's reward; ppo, cem, random, exhaustive).
    :param lagrangian_lr: ppo: update the penalty by dual ascent after every rollout.
    :param fresh_realisations: realisations per candidate when the front is re-scored.
    :param fresh_test_series: test series per candidate and design condition on which
        each front member's accuracy is measured; 0 keeps the prediction.
    :param time_limit_s: the search's time budget in seconds (every method); None: none.
        Once spent the search stops, ``stopped`` "time_limit", and the front's accuracy
        measurement is skipped; the re-score on fresh draws (the best, the front, the
        baselines, in that order of need) goes on only while the limit's grace lasts
        (``settings.time_limit_grace_s``: 10 % of the limit, at least 10 s, at most
        300 s), and the
        result says what it did not reach.
    :param time_limit_grace_s: that grace in seconds (>= 0 and <= 3600; 0 stops the
        re-score at the limit, after what is always re-scored); None: the default rule.
    """

    method: str = "ppo"
    sequence_length: int = 4
    timesteps: int = 20_480
    max_sequences: int = 100_000
    n_realisations: int = 20
    objective: str = "f1"
    metric: str = "dtw"
    sakoe_chiba_radius: int | None = 2
    fuel_weight: float = 0.0
    patience_episodes: int | None = 500
    ppo: Mapping[str, Any] = field(default_factory=dict)
    cem: Mapping[str, Any] = field(default_factory=dict)
    nsga2: Mapping[str, Any] = field(default_factory=dict)
    objectives: Sequence[str] = ("accuracy", "final_rate", "impulse")
    design_noise: Sequence[Sequence[float]] = ((6.0, 1.0), (1.0, 6.0))
    constraints: Mapping[str, float] = field(default_factory=dict)
    constraint_penalty: float = 0.0
    lagrangian_lr: float = 0.0
    fresh_realisations: int = 40
    fresh_test_series: int = 200
    time_limit_s: float | None = None
    time_limit_grace_s: float | None = None

    def operator(self) -> OperatorSettings:
        """What the front is judged on: objectives, design noise, constraints."""
        from .search import OperatorSettings

        return OperatorSettings(
            objectives=tuple(self.objectives),
            design_noise=tuple((float(p), float(q)) for p, q in self.design_noise),
            constraints=dict(self.constraints),
            n_realisations=self.n_realisations,
        )

    def scorer(self) -> ScorerSettings:
        """How the search scores sequences."""
        from .search import ScorerSettings

        return ScorerSettings(
            n_realisations=self.n_realisations,
            metric=self.metric,
            sakoe_chiba_radius=self.sakoe_chiba_radius,
            objective=self.objective,
        )

    def _check_unused_settings(self) -> None:
        """Refuse a setting, away from its default, that the method never reads, as the
        CLI refuses its option: NSGA-II has no reward (``fuel_weight``,
        ``constraint_penalty``) and spends no step budget (``timesteps``,
        ``patience_episodes``: its budget is ``nsga2`` population and generations), and
        the exhaustive search scores every sequence. A job had taken ``"timesteps": 100``
        for nsga2 (202), run its 30 generations and dropped the budget without a word.

        :raises InputError: naming the setting, its value and the methods that read it.
        """
        if self.method == "nsga2":
            for name in ("fuel_weight", "constraint_penalty"):
                value = getattr(self, name)
                if value:
                    raise InputError(
                        f"{name} = {value:g} weighs the reward of method ppo, cem, random or "
                        "exhaustive; nsga2 has none: it trades impulse off as an objectives "
                        "entry and keeps every constraint as a constraint"
                    )
        if self.method in ("nsga2", "exhaustive"):
            for name in ("timesteps", "patience_episodes"):
                value = getattr(self, name)
                if value != self.default(name):
                    budget = (
                        "its budget is nsga2 population and generations"
                        if self.method == "nsga2"
                        else "it scores every sequence"
                    )
                    raise InputError(
                        f"{name} = {value} applies to method ppo, cem or random, not "
                        f"{self.method!r} ({budget}); leave it out"
                    )

    def options(self) -> dict[str, Any]:
        """The method's own keyword arguments (besides the scenario, seed and scorer)."""
        # Each method's own settings are named after it.
        for method, own in (("ppo", self.ppo), ("cem", self.cem), ("nsga2", self.nsga2)):
            if own and self.method != method:
                raise InputError(
                    f"{method} settings apply to method {method} only, not {self.method!r}"
                )
        if self.lagrangian_lr and self.method != "ppo":
            raise InputError(f"lagrangian_lr applies to method ppo only, not {self.method!r}")
        self._check_unused_settings()
        from .deadline import check_grace
        from .search.loop import check_time_limit

        time_limit_s = check_time_limit(self.time_limit_s)
        grace_s = check_grace(self.time_limit_grace_s)
        if self.method == "nsga2":
            return {
                "time_limit_s": time_limit_s,
                "time_limit_grace_s": grace_s,
                "sequence_length": self.sequence_length,
                "operator": self.operator(),
                "nsga2_params": dict(self.nsga2),
                "fresh_realisations": self.fresh_realisations,
                "fresh_test_series": self.fresh_test_series,
            }
        options: dict[str, Any] = {
            "time_limit_s": time_limit_s,
            "time_limit_grace_s": grace_s,
            "sequence_length": self.sequence_length,
            "fuel_weight": self.fuel_weight,
            "constraints": dict(self.constraints) or None,
            "constraint_penalty": self.constraint_penalty,
        }
        if self.method == "exhaustive":
            options["max_sequences"] = self.max_sequences
        else:
            options["total_timesteps"] = self.timesteps
            options["patience_episodes"] = self.patience_episodes
        if self.method == "ppo":
            options["ppo_params"] = dict(self.ppo)
            options["lagrangian_lr"] = self.lagrangian_lr
        if self.method == "cem":
            from .search import CEM_DEFAULTS

            # Only the CEM's own settings: any other name would reach the search as a
            # keyword (a TypeError), or override the length, budget or seed given.
            unknown = sorted(set(self.cem) - set(CEM_DEFAULTS))
            if unknown:
                raise InputError(f"unknown CEM setting(s) {unknown}; known: {sorted(CEM_DEFAULTS)}")
            options.update(self.cem)
        return options


@dataclass(frozen=True)
class SearchOutcome:
    """A search's result and the baselines scored on its fresh draws."""

    result: SearchResult
    baselines: dict[str, dict[str, Any]]
    scenario: Scenario | None = None

    def to_dict(self) -> dict[str, Any]:
        """The result as JSON data (NaN as null), with ``"baselines"`` and the
        ``"scenario"`` searched, so that a plan of the result (``inertia-id plan
        --search``) is of the same spacecraft, wherever the result is read."""
        document = {**json.loads(self.result.to_json()), "baselines": self.baselines}
        if self.scenario is not None:
            document["scenario"] = self.scenario.model_dump(mode="json")
        return document


def search_with_baselines(
    scenario: Scenario,
    request: SearchRequest,
    *,
    seed: int,
    policy_path: str | None = None,
    progress: Callable[[SearchProgress], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
    clock: Callable[[], float] = time.monotonic,
    checked: bool = False,
) -> SearchOutcome:
    """Search for the sequence that best separates the candidates, then score the
    hand-designed baselines on the same fresh draws as the best sequence.

    Every result carries a front (``result.front``): NSGA-II's, or for the other
    methods the best sequence alone, re-scored on the operator's objectives beside the
    baselines on the same fresh draw, so that a baseline that dominates it is flagged.

    :param policy_path: where a PPO search saves its policy (ignored by the others).
    :param progress: called at every learning-curve point.
    :param should_stop: polled every environment step; True cancels the search. A
        cancelled search's result is abandoned: its best is kept, but neither re-scored
        nor judged on a front, and the baselines are not scored (each ``unavailable``).
    :param clock: monotonic seconds for ``request.time_limit_s``. The limit covers the
        search and the front's accuracy measurement; the re-score on fresh draws (the
        best's draws, the front's first member and baselines, the baselines' draws) goes
        on while the limit's grace lasts, each piece checked before it starts: what is
        left out says so (``fresh.draws_asked``, the front's ``not_rescored``, a
        baseline ``unavailable``).
    :param checked: the caller ran :func:`check_search` on this scenario and request
        already (the CLI, before its first progress line): its checks are not run again.
        They cost a nominal simulation of the baseline, which the CLI's search and the
        paper pipeline ran twice.
    """
    from .search import search
    from .search.baselines import STOPPED, compare_with_baselines

    if not checked:
        check_search_scenario(
            scenario, request.sequence_length, request.constraints, request.design_noise
        )
    from .search.loop import CANCELLED, TIME_LIMIT, Deadline

    settings = request.scorer()
    options = request.options()
    deadline = Deadline(request.time_limit_s, clock, request.time_limit_grace_s)
    if request.method == "ppo":
        options["policy_path"] = policy_path
    found = search(
        request.method,
        scenario,
        seed=seed,
        settings=settings,
        progress=progress,
        should_stop=should_stop,
        clock=clock,
        **options,
    )
    stopped = {"why": found.stopped}

    def after_search_stop() -> bool:
        """The work after the search (the front's measurement, the baselines) stops on a
        cancel, or once the time limit is spent, whenever that comes."""
        if stopped["why"] != CANCELLED and should_stop is not None and should_stop():
            stopped["why"] = CANCELLED
        elif stopped["why"] not in (CANCELLED, TIME_LIMIT) and deadline.expired():
            stopped["why"] = TIME_LIMIT
        return stopped["why"] in (CANCELLED, TIME_LIMIT)

    def rescore_stop() -> bool:
        """The baselines' re-score stops on a cancel, or once the time limit's grace is
        spent, whenever that comes."""
        if stopped["why"] != CANCELLED and should_stop is not None and should_stop():
            stopped["why"] = CANCELLED
        return stopped["why"] == CANCELLED or deadline.grace_spent()

    if found.front is None and found.stopped != CANCELLED:
        from .search import build_front

        front = build_front(
            scenario,
            [found.best.sequence],
            request.operator(),
            seed=found.fresh.seed,
            fresh_realisations=request.fresh_realisations,
            test_series=request.fresh_test_series,
            keep_infeasible=True,
            should_stop=after_search_stop,
        )
        found.front = front.to_dict()
    baselines = compare_with_baselines(
        scenario,
        len(found.best.sequence),
        settings,
        seed=found.fresh.seed,
        n_draws=len(found.fresh.f1),
        should_stop=rescore_stop,
    )
    if stopped["why"] == CANCELLED:
        # A cancel heard after the search (while the front was measured): the job
        # was abandoned all the same.
        found.stopped = CANCELLED
    else:
        for entry in baselines.values():
            if entry.get("unavailable") == STOPPED:
                entry["unavailable"] = (
                    f"not scored: the time limit ({deadline.time_limit_s:g} s) and its "
                    f"grace ({deadline.grace_s:g} s) were spent"
                )
    return SearchOutcome(found, baselines, scenario)


def check_search(scenario: Scenario, request: SearchRequest) -> None:
    """Everything a search on ``scenario`` refuses that can be told before it starts: the
    operator's settings on the scenario (constraints, a propellant bound or objective, a
    duration bound every sequence breaks, design noise) and
    :func:`check_search_scenario` (a rate bound below the initial-rate floor, a gyro
    range the baseline passes). The API's submission runs the same checks; the CLI runs
    them before its first progress line, which the refusal followed before.

    :raises InputError: naming the setting and its value.
    """
    from .search.objectives import check_per_flight_realisations

    checked = request.operator().check(scenario, request.sequence_length)
    # A per-flight bound on too few realisations: refused inside the search before, after
    # the CLI's "searching" line and its bar's first frame.
    check_per_flight_realisations(dict(checked.constraints), checked.n_realisations)
    check_search_scenario(
        scenario, request.sequence_length, request.constraints, checked.design_noise
    )


def check_search_scenario(
    scenario: Scenario,
    sequence_length: int,
    constraints: Mapping[str, float] | None = None,
    design_noise: Sequence[Sequence[float]] = (),
) -> None:
    """Refuse a search on a scenario whose hand-designed sequence of ``sequence_length``
    steps (full duty on the principal diagonal: the baseline every search is scored
    against) passes any attitude gyro's range
    (:func:`~inertia_id.physics.simulate.check_nominal_gyro_range`). At 100 rad/s (5,730
    deg/s) that is a scenario in the wrong units, not a spacecraft: a search on it would
    rank responses no gyro measures, and its baselines' figures would be of rates no
    flight shows. Refused before the search rather than flagged after it, at the cost of
    one nominal run.

    Also refuse a rate bound among ``constraints`` below what the scenario's initial-rate
    spread alone leaves (:func:`~inertia_id.search.objectives.check_rate_floor`): no
    sequence meets it, and the search would end saying only that none did.

    And refuse one holding two candidates of the same tensor
    (:meth:`~inertia_id.physics.scenario.Scenario.check_distinguishable`), which no
    sequence tells apart.

    And refuse one whose rates overflow to inf or nan on that baseline at 1x (what every
    search scores at) or at any ``design_noise`` condition (process multiple, measurement
    multiple: what the front's accuracy is measured at)
    (:func:`~inertia_id.physics.simulable.check_simulable`, up to 256 seeded realisations
    a candidate): such a search was accepted and failed at run time.

    :raises InputError: a rate bound below the initial-rate floor, naming both; two
        candidates of one tensor, naming them.
    :raises ~inertia_id.physics.simulate.RatesBeyondGyro: naming the scenario, the
        baseline and, in :func:`~inertia_id.physics.simulate.check_gyro_range`'s words,
        the candidate, its rate and the ceiling.
    :raises ~inertia_id.physics.simulable.NoiseOverflow: naming the noise figure, its
        value, the multiple and the step by which the rates overflow.
    """
    from .physics.sequences import hand_designed
    from .physics.simulable import NoiseOverflow, check_conditions
    from .physics.simulate import RatesBeyondGyro, check_nominal_gyro_range
    from .search.objectives import check_constraints, check_design_noise, check_rate_floor

    check_rate_floor(check_constraints(dict(constraints or {})), scenario, sequence_length)
    # Two candidates of one tensor cap every sequence's accuracy at (K-1)/K: the search
    # ran its whole budget to that and said nothing of why.
    scenario.check_distinguishable()
    baseline = hand_designed(scenario, sequence_length)
    try:
        check_nominal_gyro_range(scenario, baseline)
    except RatesBeyondGyro as exc:
        raise RatesBeyondGyro(
            f"no search on scenario {scenario.name!r}: its hand-designed baseline of "
            f"{sequence_length} steps, what every search is scored against, leaves the "
            f"gyro's range: {exc}"
        ) from None
    # The measurement multiple scales the gyro's noise and bias, which never reach the
    # rates: the process multiple alone can overflow them.
    pairs = check_design_noise(design_noise) if len(design_noise) else ()
    process = sorted({p for p, _q in pairs} - {1.0})
    try:
        check_conditions(
            scenario,
            baseline,
            [{"disturbance_torque_sigma_nm": p} for p in process],
            sequence_name=f"the hand-designed baseline of scenario {scenario.name!r}",
        )
    except NoiseOverflow as exc:
        at = "at 1x" if exc.multiple == 1.0 else "at its design noise"
        raise exc.said_of(f"no search on scenario {scenario.name!r} {at}") from None


# Training.


@dataclass(frozen=True)
class TrainRequest(_Request):
    """A classifier to train for a sequence (the job's ``params``).

    :param sequence: (L, N) level indices.
    :param kind: the classifier kind; None: :data:`~inertia_id.classifiers.registry.
        DEFAULT_KIND`, or the paper's clustering when a metric is given.
    :param metric: for the kinds that take one; None: the kind's first.
    :param n_realisations: training realisations per candidate; None: the kind's default.
    :param sakoe_chiba_radius: DTW band half-width for the kinds with a metric; None:
        unconstrained.
    :param n_init: the clustering's k-means initialisations; None: its default.
    """

    sequence: Any
    kind: str | None = None
    metric: str | None = None
    n_realisations: int | None = None
    sakoe_chiba_radius: int | None = None
    n_init: int | None = None

    def resolved(self) -> tuple[str, int, dict[str, Any]]:
        """The kind, the realisations and the classifier options meant, checked."""
        from .classifiers.registry import kind_class, resolve_kind

        kind = resolve_kind(self.kind, self.metric)
        cls = kind_class(kind)
        options: dict[str, Any] = {}
        if cls.METRICS:
            options["metric"] = self.metric or cls.METRICS[0]
            if self.sakoe_chiba_radius is not None:
                if options["metric"] != "dtw":
                    # The band only constrains dtw: with another metric it was dropped
                    # without a word and the classifier trained unconstrained.
                    raise InputError(
                        f"a DTW band (sakoe_chiba_radius {self.sakoe_chiba_radius!r}) applies "
                        f"to metric 'dtw' only, not {options['metric']!r}"
                    )
                options["sakoe_chiba_radius"] = self.sakoe_chiba_radius
        elif self.metric is not None:
            raise InputError(f"the {kind!r} classifier takes no metric, got {self.metric!r}")
        elif self.sakoe_chiba_radius is not None:
            raise InputError(
                f"the {kind!r} classifier takes no DTW band, got {self.sakoe_chiba_radius!r}"
            )
        if self.n_init is not None:
            options["n_init"] = self.n_init
        n = cls.DEFAULT_REALISATIONS if self.n_realisations is None else self.n_realisations
        return kind, n, options


@dataclass(frozen=True)
class Trained:
    """A trained classifier, with the kind and realisations it was trained as."""

    model: CandidateClassifier
    kind: str
    n_realisations: int
    #: What the training found doubtful but did not refuse (a response far below the
    #: gyro noise: :func:`~inertia_id.physics.simulate.weak_response_warning`).
    warnings: tuple[str, ...] = ()

    def summary(self) -> dict[str, Any]:
        """What a training reports: scores, confusion, candidates, sequence, kind."""
        return {
            "kind": self.kind,
            "metric": self.model.metric,
            "f1": float(self.model.f1_),
            "accuracy": float(self.model.accuracy_),
            "confusion": np.asarray(self.model.confusion_).tolist(),
            "candidate_names": list(self.model.candidate_names_),
            "sequence": np.asarray(self.model.sequence_).tolist(),
            "n_realisations": self.n_realisations,
            "warnings": list(self.warnings),
        }


def train_for_sequence(
    scenario: Scenario,
    request: TrainRequest,
    *,
    seed: int | np.random.SeedSequence,
    should_stop: Callable[[], bool] | None = None,
) -> Trained:
    """Train the classifier a request names, on draws from ``default_rng(seed)``.

    :param should_stop: asked at the training's checkpoints (after each simulation,
        between the pieces of a kind's fit: the folds of a covariance's shrinkage, the
        default kind's noise conditions, a DTW barycentre; before and after a library fit
        with no hook of its own, tslearn's k-means; in the calibration). True stops the
        training there: :class:`~inertia_id.stopping.TrainingStopped` is raised and
        nothing half-trained is returned.
    """
    from .classifiers.registry import train_classifier
    from .physics.simulable import check_simulable
    from .physics.simulate import check_nominal_gyro_range, weak_response_warning

    kind, n_realisations, options = request.resolved()
    # A classifier of responses no gyro measures classifies no telemetry.
    run = check_nominal_gyro_range(scenario, request.sequence)
    # Nor is one trained where the scenario's own noise overflows the rates: refused
    # before the first draw (it failed in the middle of the training's simulation).
    check_simulable(scenario, request.sequence, sequence_name="the training's sequence")
    # One of responses far below the gyro noise classifies noise: said, not refused.
    weak = weak_response_warning(scenario, request.sequence, run)
    rng = np.random.default_rng(seed)
    model = train_classifier(
        scenario,
        request.sequence,
        n_realisations,
        rng,
        kind=kind,
        should_stop=should_stop,
        **options,
    )
    return Trained(model, kind, n_realisations, () if weak is None else (weak,))


def train_others(
    scenario: Scenario,
    sequence: Any,
    specs: Sequence[str],
    n_train: int,
    rng: np.random.Generator,
    should_stop: Callable[[], bool] | None = None,
) -> dict[str, CandidateClassifier]:
    """Classifiers by spec (``"least-squares"``, ``"1nn:euclidean"``), trained at 1x on
    ``n_train`` realisations per candidate, one after another from ``rng``.

    :param should_stop: asked before each classifier and at its training's checkpoints;
        True stops there and returns those trained before it (a sweep stopped then
        measures no point: its poll between points says stop too)."""
    from .classifiers.registry import parse_spec, train_classifier
    from .stopping import TrainingStopped

    others = {}
    for spec in specs:
        if should_stop is not None and should_stop():
            break
        kind, options = parse_spec(spec)
        try:
            others[spec] = train_classifier(
                scenario, sequence, n_train, rng, kind=kind, should_stop=should_stop, **options
            )
        except TrainingStopped:
            break
    return others


# The noise sweep.


@dataclass(frozen=True)
class SweepRequest(_Request):
    """A sweep of a trained classifier (the job's ``params``).

    :param multiples: noise multiples to visit, each at most
        :data:`~inertia_id.evaluation.sweep.MAX_MULTIPLE` (1000); None: 1 to 8.
    :param noises: sources of error to scale in turn; None: process and measurement.
    :param others: classifiers trained at 1x and scored on the same test series, as
        specs.
    :param ceiling_realisations: the ceiling (per-candidate Gaussians fitted at each
        point's noise, :mod:`inertia_id.evaluation.ceiling`) on this many realisations per
        candidate; 0 leaves it out, else at least 3.
    :param limit_realisations: deprecated name of ``ceiling_realisations``; when given
        it wins.
    :param n_train: training realisations per candidate for ``others``.
    :param inertia: also ask how often bodies off the candidates "match none".
    :param n_test: test series per point.
    """

    multiples: Sequence[float] | None = None
    noises: Sequence[str] | None = None
    others: Sequence[str] = ("least-squares",)
    ceiling_realisations: int = 2000
    limit_realisations: int | None = None
    n_train: int = 20
    inertia: bool = True
    n_test: int = 200


@dataclass(frozen=True)
class SweepOutcome:
    """A sweep, and the bodies off the candidates when they were asked for."""

    sweep: SweepResult
    inertia: InertiaSweepResult | None
    others: tuple[str, ...]
    #: The seed the sweep was run with (``inertia-id sweep --seed``, a sweep job's
    #: ``seed``): with the same classifier and options it gives the same numbers.
    #: ``sweep.seed`` and ``inertia.seed`` are streams derived from it, 0 to 2**32 - 1,
    #: which reproduce their own draws through :func:`~inertia_id.evaluation.sweep.
    #: run_sweep` and :func:`~inertia_id.evaluation.sweep.run_inertia_sweep` but not the
    #: sweep through ``--seed``. None: not known (an outcome built by hand).
    run_seed: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """The sweep as JSON data: ``"run_seed"`` first when known, and ``"inertia"``
        when it was run."""
        document = self.sweep.model_dump(mode="json")
        if self.run_seed is not None:
            document = {"run_seed": self.run_seed, **document}
        if self.inertia is not None:
            document["inertia"] = self.inertia.model_dump(mode="json")
        return document


def check_sweep_scenario(named: Scenario, trained: Scenario | None, sequence: Any) -> Scenario:
    """The scenario a sweep simulates: the one named, if the classifier can classify it.

    Its candidates (names and tensors) must be the classifier's, and the classifier's
    sequence must drive it on the same sample grid; its noise, thrust and everything else
    may differ: that is what the sweep then measures.
    """
    from .evaluation.sweep import check_classifier_scenario
    from .physics.simulate import check_nominal_gyro_range

    check_classifier_scenario(named, trained)
    try:
        named.check_sequence(sequence)
    except InputError as exc:
        raise InputError(
            f"the classifier's sequence does not drive scenario {named.name!r}: {exc}"
        ) from None
    # Its noise may be scaled up, but its nominal response must be one a gyro measures.
    check_nominal_gyro_range(named, sequence)
    return named


def sweep_with_limit(
    classifier: CandidateClassifier,
    request: SweepRequest,
    *,
    seed: int,
    scenario: Scenario | None = None,
    progress: Callable[[float], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> SweepOutcome:
    """Accuracy of ``classifier`` as each source of error grows, with the others, the
    ceiling and (``request.inertia``) the bodies off the candidates.

    :param scenario: the scenario to sweep; default the classifier's. One with other
        candidates or another sample grid is refused (:func:`check_sweep_scenario`).
    :param progress: called with the fraction done (the bodies take the last fifth).
    :param should_stop: asked before each classifier of ``request.others`` is trained
        and at its training's checkpoints, then between points; True stops with the
        points done (none, when it comes before the first) and skips the bodies.
    """
    from .checks import check_seed
    from .evaluation.sweep import (
        DEFAULT_MULTIPLES,
        DEFAULT_NOISES,
        check_ceiling_realisations,
        check_multiples,
        check_sweep_simulable,
        run_inertia_sweep,
        run_sweep,
    )

    # Refused before the others are trained, as run_sweep would refuse them after.
    if request.multiples is not None:
        check_multiples(request.multiples)
    if request.limit_realisations is not None:
        check_ceiling_realisations(request.limit_realisations, "limit_realisations")
    else:
        check_ceiling_realisations(request.ceiling_realisations)
    sequence = classifier.sequence_
    if classifier.scenario_ is None or sequence is None:
        raise InputError("the classifier does not carry its scenario and sequence")
    scenario = check_sweep_scenario(
        classifier.scenario_ if scenario is None else scenario, classifier.scenario_, sequence
    )
    # Refused before the others are trained, as run_sweep would refuse it after.
    check_sweep_simulable(
        scenario,
        sequence,
        DEFAULT_NOISES if request.noises is None else request.noises,
        DEFAULT_MULTIPLES if request.multiples is None else request.multiples,
    )
    streams = np.random.SeedSequence(check_seed(seed)).spawn(3)
    others = train_others(
        scenario,
        sequence,
        request.others,
        request.n_train,
        np.random.default_rng(streams[0]),
        should_stop=should_stop,
    )
    share = 0.8 if request.inertia else 1.0
    options: dict[str, Any] = {}
    if request.multiples is not None:
        options["multiples"] = request.multiples
    if request.noises is not None:
        options["noises"] = request.noises
    sweep = run_sweep(
        classifier,
        others=others,
        scenario=scenario,
        sequence=sequence,
        ceiling_realisations=request.limit_realisations
        if request.limit_realisations is not None
        else request.ceiling_realisations,
        n_test=request.n_test,
        seed=int(streams[1].generate_state(1)[0]),
        progress=None if progress is None else (lambda fraction: progress(share * fraction)),
        should_stop=should_stop,
        **options,
    )
    inertia = None
    if request.inertia and not (should_stop is not None and should_stop()):
        inertia = run_inertia_sweep(
            classifier,
            scenario=scenario,
            seed=int(streams[2].generate_state(1)[0]),
            progress=None
            if progress is None
            else (lambda fraction: progress(share + (1 - share) * fraction)),
            should_stop=should_stop,
        )
    return SweepOutcome(sweep, inertia, tuple(others), run_seed=int(seed))


# The paper.


@dataclass(frozen=True)
class PaperOutcome:
    """What the paper pipeline wrote, and its summary."""

    out_dir: Path
    summary: dict[str, Any]
    sweep: SweepResult


def run_paper(
    out_dir: str | Path,
    *,
    sequence: Any = None,
    search: SearchRequest | None = None,
    metric: str = "dtw",
    n_realisations: int = 20,
    multiples: Sequence[float] | None = None,
    n_test: int = 200,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
    search_progress: Callable[[SearchProgress], None] | None = None,
    sweep_progress: Callable[[float], None] | None = None,
) -> PaperOutcome:
    """The paper's pipeline on its preset: search, train, sweep, report.

    Writes ``search.json`` (with the baselines) and ``policy.zip`` when it searched,
    ``classifier.json``, ``sweep.json``, ``report.html``, ``scenario.json`` and
    ``summary.json`` to ``out_dir``.

    :param sequence: the sequence to use; None: search for one with ``search``, or, when
        that is None too, the hand-designed :data:`PAPER_SEQUENCE`.
    :param search: the search to run when no sequence is given.
    :param metric: the paper's clustering metric.
    :param n_realisations: training realisations per candidate (the paper's 20); the
        least-squares reference trains on as many.
    :param log: told each stage as it starts.
    """
    from .evaluation.report import write_report
    from .evaluation.sweep import DEFAULT_NOISES, check_multiples
    from .files import write_whole
    from .physics.scenario import Scenario
    from .physics.simulate import simulate

    if multiples is not None:
        check_multiples(multiples)  # before the search and the training, not after
    say = log or (lambda _message: None)
    scenario = Scenario.paper()
    if sequence is None and search is not None:
        check_search(scenario, search)  # before the folder and the first stage's line
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    seeds = np.random.SeedSequence(seed).spawn(3)
    started = time.perf_counter()
    searched = None
    if sequence is not None:
        steps = scenario.check_sequence(sequence)
    elif search is None:
        steps = scenario.check_sequence(PAPER_SEQUENCE)
    else:
        say("[0/3] searching for the sequence")
        policy = str(out / "policy.zip") if search.method == "ppo" else None
        found = search_with_baselines(
            scenario,
            search,
            seed=seed,
            policy_path=policy,
            progress=search_progress,
            checked=True,  # above, before the folder
        )
        write_whole(out / "search.json", json.dumps(found.to_dict()))
        searched = found.result
        steps = searched.best_sequence
    say(
        f"[1/3] training {metric} classifier ({scenario.n_candidates} candidates x "
        f"{n_realisations} realisations, {len(steps)} steps)"
    )
    trained = train_for_sequence(
        scenario,
        TrainRequest(steps, metric=metric, n_realisations=n_realisations),
        seed=seeds[0],
    )
    model = trained.model
    model.save(out / "classifier.json")
    say(f"      training F1 {model.f1_:.3f}, accuracy {model.accuracy_:.3f}")
    say("[2/3] accuracy vs noise")
    swept = sweep_with_limit(
        model,
        SweepRequest(multiples=multiples, n_train=n_realisations, inertia=False, n_test=n_test),
        seed=seed,
        progress=sweep_progress,
    )
    sweep = swept.sweep
    write_whole(out / "sweep.json", json.dumps(swept.to_dict(), indent=2))
    say("[3/3] report")
    result = simulate(scenario, steps, n_realisations, np.random.default_rng(seeds[2]))
    write_report(
        out / "report.html",
        scenario=scenario,
        sequence=steps,
        result=result,
        classifier=model,
        sweep=sweep,
        search=searched,
        seed=seed,
    )
    write_whole(out / "scenario.json", scenario.model_dump_json(indent=2))

    def by_multiple(points: Any, noise: str) -> dict[str, float]:
        return {f"{p.multiple:g}": p.accuracy for p in points if p.noise == noise}

    summary = {
        "sequence": np.asarray(steps).tolist(),
        "sequence_from": "given" if searched is None else f"{searched.method} search",
        "search_f1": None if searched is None else searched.best.f1,
        "search_fresh_f1_mean": None if searched is None else searched.fresh.f1_mean,
        "search_timesteps": None if searched is None else searched.timesteps,
        "metric": metric,
        "seed": seed,
        "training_f1": model.f1_,
        "training_accuracy": model.accuracy_,
        "impulse_nms": result.impulse_nms,
        "mean_final_rate_rad_s": result.mean_final_rate_rad_s,
        "accuracy": {noise: by_multiple(sweep.points, noise) for noise in DEFAULT_NOISES},
        "accuracy_others": {
            label: {noise: by_multiple(points, noise) for noise in DEFAULT_NOISES}
            for label, points in {**sweep.others, "ceiling": sweep.ceiling}.items()
        },
        "wall_time_s": time.perf_counter() - started,
    }
    write_whole(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return PaperOutcome(out, summary, sweep)
