"""Classifier accuracy as the noise grows beyond what it was trained at.

Train once at 1x noise, then classify fresh series simulated with one source of error
at a multiple of its 1x level and every other source at 1x. The sources
(:data:`NOISE_KINDS`):

- ``process``: the disturbance torque sigma;
- ``measurement``: the gyro noise sigma;
- ``jitter``: the thruster timing (duty) jitter sigma;
- ``thrust_scale``: each thruster's torque-scale error sigma. Torque and inertia enter
  Euler's equations as their ratio, so this is the confounder that matters most;
- ``gyro_bias``: the sigma of a constant gyro bias per realisation and axis.

A multiple scales the scenario's own 1x level; where that level is zero (the paper
preset has no thrust-scale error and no gyro bias) it scales :data:`REFERENCE_LEVELS`
instead, and every point records the absolute ``value`` it used.

Each point carries a Wilson 95 % interval, so a plot can show how much of a difference
is sampling error. ``others`` classifiers (least squares, the supervised classifiers)
and the ceiling (:mod:`inertia_id.evaluation.ceiling`) are scored on exactly the same
test series as the main one.

:func:`run_inertia_sweep` asks the other question a GNC engineer has: if the true
inertia is none of the candidates (between two of them, or all scaled), does the
classifier say "matches none"? It counts the verdict
:func:`~inertia_id.evaluation.identify.identify` gives each series (the same rule:
:func:`~inertia_id.evaluation.identify.verdicts`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

from ..checks import MAX_NOISE_MULTIPLE, check_seed, is_integer
from ..errors import InputError
from ..physics.scenario import AS_TRAINED, Scenario
from ..physics.simulate import SimulationOverflow, simulate
from .identify import DEFAULT_CONFIDENCE, STATUSES, _check_probability, verdicts

if TYPE_CHECKING:
    from ..classifiers.registry import CandidateClassifier

__all__ = [
    "DEFAULT_MULTIPLES",
    "DEFAULT_NOISES",
    "MAX_MULTIPLE",
    "NOISE_KINDS",
    "NOISE_LABELS",
    "NOISE_UNITS",
    "REFERENCE_LEVELS",
    "InertiaPoint",
    "InertiaSweepResult",
    "SweepPoint",
    "SweepResult",
    "body_series",
    "check_ceiling_realisations",
    "check_classifier_scenario",
    "check_multiples",
    "check_sweep_simulable",
    "noise_level",
    "run_inertia_sweep",
    "run_sweep",
    "wilson_interval",
]

#: Each source of error a sweep can scale, with the Uncertainty field it scales.
NOISE_FIELDS = {
    "process": "disturbance_torque_sigma_nm",
    "measurement": "gyro_noise_sigma_rad_s",
    "jitter": "duty_jitter_sigma",
    "thrust_scale": "thrust_scale_sigma",
    "gyro_bias": "gyro_bias_sigma_rad_s",
}
NOISE_KINDS = tuple(NOISE_FIELDS)
#: What a sweep visits unless told otherwise: the paper's two noises.
DEFAULT_NOISES = ("process", "measurement")
#: The noise multiples a sweep visits unless told otherwise.
DEFAULT_MULTIPLES: tuple[float, ...] = (1, 2, 3, 4, 5, 6, 7, 8)
#: The largest noise multiple a sweep visits. On the paper preset at 1000x of any source
#: the RK4 integration still agrees with one at a ten times finer step to 1e-5 (the rates
#: reach 8 rad/s at 1000x thrust-scale error); at 1e4x thrust-scale error it is 1.4 % off,
#: at 1e5x the rates overflow to inf and nan. Every classifier is at chance long before.
MAX_MULTIPLE = MAX_NOISE_MULTIPLE
#: Units of each source's absolute level.
#: What each source is, for a person reading a plot or a form.
NOISE_LABELS = {
    "process": "process noise (disturbance torque σ)",
    "measurement": "measurement noise (gyro noise σ)",
    "jitter": "duty jitter σ",
    "thrust_scale": "thrust-scale error σ",
    "gyro_bias": "gyro bias σ",
}
NOISE_UNITS = {
    "process": "N m",
    "measurement": "rad/s",
    "jitter": "fraction of full duty",
    "thrust_scale": "fraction of nominal torque",
    "gyro_bias": "rad/s",
}
#: The 1x level of a source the scenario leaves at zero: a 2 % thruster calibration
#: error; a gyro bias as large as the paper's gyro noise sigma.
REFERENCE_LEVELS = {"thrust_scale": 0.02, "gyro_bias": 1e-3}


def noise_level(scenario: Scenario, noise: str) -> float:
    """The 1x absolute level of ``noise``: the scenario's, else the reference level."""
    if noise not in NOISE_FIELDS:
        raise InputError(f"noise must be one of {list(NOISE_KINDS)}, got {noise!r}")
    own = float(getattr(scenario.uncertainty, NOISE_FIELDS[noise]))
    return own if own > 0 else REFERENCE_LEVELS.get(noise, 0.0)


def wilson_interval(successes: int, total: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (95 % by default).

    Unlike the normal approximation it stays inside [0, 1] and is honest at 100 %
    accuracy, where a classifier usually sits at low noise.
    """
    if total <= 0:
        return 0.0, 1.0
    p = successes / total
    denom = 1.0 + z**2 / total
    centre = (p + z**2 / (2 * total)) / denom
    half = z * math.sqrt(p * (1 - p) / total + z**2 / (4 * total**2)) / denom
    # At 0 % and 100 % the end is exactly 0 or 1; computed, it rounds to 1e-19 or to
    # 0.9999999999999999, which reads as "not quite certain" in a table.
    low = 0.0 if successes <= 0 else max(0.0, centre - half)
    high = 1.0 if successes >= total else min(1.0, centre + half)
    return low, high


class SweepPoint(BaseModel):
    """Accuracy at one noise multiple; ``value`` is the absolute level used.

    ``above_ceiling_interval``: whether ``accuracy`` lies above the upper end of the
    ceiling's Wilson interval at the same point (a check against that interval, not a
    paired test); None for the ceiling itself, without a ceiling, and in results stored
    before it was recorded.
    """

    noise: str
    multiple: float
    value: float = 0.0
    accuracy: float
    ci_low: float
    ci_high: float
    f1: float
    n_series: int
    confusion: list[list[int]]
    above_ceiling_interval: bool | None = None


class SweepResult(BaseModel):
    """Accuracy vs noise multiple, for each kind of noise swept (JSON-ready)."""

    candidate_names: list[str]
    sequence: list[list[int]]
    metric: str
    #: The seed of the test series (``run_sweep``'s). A sweep run through
    #: :func:`~inertia_id.pipelines.sweep_with_limit` (the CLI, a job) derives it from the
    #: seed it was given, which its document keeps as ``run_seed``: that one re-runs it.
    seed: int
    n_test_per_candidate: int
    points: list[SweepPoint]
    levels: dict[str, float] = {}
    units: dict[str, str] = {}
    others: dict[str, list[SweepPoint]] = {}
    #: The ceiling at every point (:mod:`inertia_id.evaluation.ceiling`), on the same
    #: test series; empty when it was not asked for.
    ceiling: list[SweepPoint] = []
    ceiling_realisations: int = 0
    #: Where each ceiling point's covariances came from ("sample" or "noise model",
    #: whichever classified the ceiling's validation draw better); empty in results
    #: stored before the choice existed.
    ceiling_covariance: list[str] = []
    #: Deprecated: the name of the reference line before it was a ceiling. New results
    #: repeat the ceiling here; results stored before hold the old pooled-covariance
    #: reference, which a classifier could beat (read ``ceiling`` instead).
    limit: list[SweepPoint] = []
    limit_realisations: int = 0

    def curve(self, noise: str, classifier: str | None = None) -> list[SweepPoint]:
        """The points of one noise, of the main classifier or of ``others[classifier]``."""
        points = self.points if classifier is None else self.others[classifier]
        return [p for p in points if p.noise == noise]


def check_multiples(multiples: Sequence[float]) -> list[float]:
    """The noise multiples a sweep visits, as floats: at least one, each finite, >= 0 and
    at most :data:`MAX_MULTIPLE`.

    :raises InputError: quoting the multiples that break the rule.
    """
    bad = [
        m
        for m in multiples
        if isinstance(m, bool)
        or not isinstance(m, int | float | np.integer | np.floating)
        or not (math.isfinite(m) and m >= 0)
    ]
    if bad or not multiples:
        raise InputError(f"noise multiples must be finite and >= 0, got {list(multiples)}")
    large = [float(m) for m in multiples if m > MAX_MULTIPLE]
    if large:
        raise InputError(
            f"noise multiples must be at most {MAX_MULTIPLE:g} (beyond it the simulated "
            f"rates lose accuracy and then overflow), got {large} in "
            f"{[float(m) for m in multiples]}"
        )
    values = [float(m) for m in multiples]
    repeated = sorted({m for m in values if values.count(m) > 1})
    if repeated:
        # Each multiple is one point of a curve: [1, 1] drew two points at 1x and its
        # confusion matrices were offered as "x1" twice, the second never told apart.
        raise InputError(
            f"noise multiples must each be given once, got {repeated} more than once in {values}"
        )
    return values


def check_ceiling_realisations(value: Any, name: str = "ceiling_realisations") -> int:
    """The ceiling's realisations per candidate: 0 (no ceiling) or an integer >= 3, what
    :func:`~inertia_id.evaluation.ceiling.fit_ceiling` needs for a per-candidate covariance.

    :raises InputError: quoting the value.
    """
    if not is_integer(value, minimum=0, numpy=False):
        raise InputError(f"{name} must be an integer >= 0, got {value!r}")
    if 0 < value < 3:
        raise InputError(f"{name} must be 0 (no ceiling) or at least 3, got {value}")
    return int(value)


def _mark_above_ceiling(points: list[SweepPoint], ceiling: SweepPoint) -> None:
    for point in points:
        point.above_ceiling_interval = point.accuracy > ceiling.ci_high


def _point(
    classifier: CandidateClassifier, X: np.ndarray, y: np.ndarray, **where: Any
) -> SweepPoint:
    scores = classifier.evaluate(X, y)
    correct = int(np.trace(scores["confusion"]))
    low, high = wilson_interval(correct, len(y))
    return SweepPoint(
        **where,
        accuracy=scores["accuracy"],
        ci_low=low,
        ci_high=high,
        f1=scores["f1"],
        n_series=len(y),
        confusion=np.asarray(scores["confusion"]).tolist(),
    )


def _point_from_predictions(
    predicted: np.ndarray, y: np.ndarray, n_candidates: int, **where: Any
) -> SweepPoint:
    """A point from labels predicted by a supervised rule (no cluster matching)."""
    confusion = np.zeros((n_candidates, n_candidates), dtype=int)
    np.add.at(confusion, (y, predicted), 1)
    correct = int(np.trace(confusion))
    low, high = wilson_interval(correct, len(y))
    precision = np.diag(confusion) / np.maximum(confusion.sum(axis=0), 1)
    recall = np.diag(confusion) / np.maximum(confusion.sum(axis=1), 1)
    f1 = np.where(
        precision + recall > 0, 2 * precision * recall / np.maximum(precision + recall, 1e-300), 0.0
    )
    return SweepPoint(
        **where,
        accuracy=correct / len(y),
        ci_low=low,
        ci_high=high,
        f1=float(f1.mean()),
        n_series=len(y),
        confusion=confusion.tolist(),
    )


def check_classifier_scenario(named: Scenario, trained: Scenario | None) -> None:
    """A scenario a classifier trained on ``trained`` can classify: the same candidates
    (names and tensors, in order: the classifier's labels are their indices) on the same
    sample grid; its noise, thrust and everything else may differ. Nothing to check
    without ``trained``.

    :raises InputError: naming both scenarios' candidates, or both grids.
    """
    if trained is None or named is trained:
        return
    mine = [(c.name, np.asarray(c.inertia_kg_m2).tolist()) for c in named.inertia_candidates]
    theirs = [(c.name, np.asarray(c.inertia_kg_m2).tolist()) for c in trained.inertia_candidates]
    if mine != theirs:
        raise InputError(
            f"scenario {named.name!r} has candidates {named.candidate_names}, not the "
            f"ones the classifier was trained on ({trained.candidate_names} of scenario "
            f"{trained.name!r}, with their tensors)"
        )
    grid = (named.timing.samples_per_step, named.timing.sample_rate_hz)
    if grid != (trained.timing.samples_per_step, trained.timing.sample_rate_hz):
        raise InputError(
            f"scenario {named.name!r} samples {grid[0]} times per step at {grid[1]:g} Hz; "
            f"the classifier was trained on {trained.timing.samples_per_step} at "
            f"{trained.timing.sample_rate_hz:g} Hz"
        )


def check_sweep_simulable(
    scenario: Scenario,
    sequence: Any,
    noises: Sequence[str] = DEFAULT_NOISES,
    multiples: Sequence[float] = DEFAULT_MULTIPLES,
) -> None:
    """Refuse a sweep whose simulations overflow, before any of it runs: ``sequence`` on
    ``scenario`` at 1x (what the others train on and the bodies off the candidates fly),
    then each of ``noises`` at the largest of ``multiples`` with every other source at
    1x, as the sweep simulates them
    (:func:`~inertia_id.physics.simulable.check_simulable`: up to 256 seeded realisations
    a candidate, tens of milliseconds). Before it, a sweep whose largest multiple
    overflowed failed at that point, after every point before it had run.

    :raises ~inertia_id.physics.simulable.NoiseOverflow: naming the source, the multiple
        and its value, then the noise figure, its 1x value and the step the rates
        overflow by.
    """
    from ..physics.simulable import DRIVING_FIELDS, NoiseOverflow, check_simulable

    unknown = [n for n in noises if n not in NOISE_KINDS]
    if unknown or not noises:
        raise InputError(f"noises must be among {list(NOISE_KINDS)}, got {list(noises)}")
    largest = max(check_multiples(multiples))
    check_simulable(scenario, sequence, sequence_name="the classifier's sequence")
    if largest <= 1.0:
        return
    # The gyro's noise and bias are added to the readings: they never reach the rates.
    for noise in (n for n in noises if NOISE_FIELDS[n] in DRIVING_FIELDS):
        field, level = NOISE_FIELDS[noise], noise_level(scenario, noise)
        try:
            check_simulable(
                scenario,
                sequence,
                multiples={field: largest},
                levels={field: level},
                sequence_name="the classifier's sequence",
            )
        except NoiseOverflow as exc:
            raise exc.said_of(
                f"{noise} noise at multiple {largest:g} ({largest * level:g} "
                f"{NOISE_UNITS[noise]}), the sweep's largest"
            ) from None


def run_sweep(
    classifier: CandidateClassifier,
    *,
    others: dict[str, CandidateClassifier] | None = None,
    scenario: Scenario | None = None,
    sequence: Any = None,
    multiples: Sequence[float] = DEFAULT_MULTIPLES,
    noises: Sequence[str] = DEFAULT_NOISES,
    n_test: int = 200,
    ceiling_realisations: int | None = None,
    limit_realisations: int = 0,
    seed: int = 0,
    progress: Callable[[float], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> SweepResult:
    """Accuracy of a trained classifier on fresh series at each noise multiple.

    :param classifier: fitted classifier (trained at 1x noise).
    :param others: more fitted classifiers by label, scored on the same test series
        (e.g. least squares as a reference line).
    :param scenario: the scenario to simulate; defaults to the one it was trained on.
    :param sequence: the actuation sequence; defaults to the one it was trained on.
    :param multiples: noise multiples to visit, >= 0.
    :param noises: which sources to sweep, among :data:`NOISE_KINDS`.
    :param n_test: test series per point, spread evenly over the candidates.
    :param ceiling_realisations: with a number > 0, also measure the ceiling at every
        point (:mod:`inertia_id.evaluation.ceiling`): per-candidate Gaussians fitted on
        that many realisations per candidate simulated *at that point's noise*, i.e. a
        classifier that knows the simulator, noise level included, scored on the same
        test series. :data:`~inertia_id.evaluation.ceiling.DEFAULT_CEILING_REALISATIONS`
        is where its accuracy has stopped moving on the paper preset; with far fewer it
        is an estimate, not a ceiling. None: ``limit_realisations``.
    :param limit_realisations: deprecated name of ``ceiling_realisations``.
    :param seed: seed of the test draws; every point gets its own independent stream
        (the ceiling's training draws come from other streams of the same seed).
    :param progress: called with the fraction done after each point.
    :param should_stop: polled between points; when it returns True the sweep stops and
        returns the points done so far (cooperative cancellation).
    """
    scenario = scenario if scenario is not None else classifier.scenario_
    sequence = sequence if sequence is not None else classifier.sequence_
    if scenario is None or sequence is None:
        raise InputError("the classifier does not carry its scenario and sequence; pass them")
    check_classifier_scenario(scenario, classifier.scenario_)
    sequence = scenario.check_sequence(sequence)
    unknown = [n for n in noises if n not in NOISE_KINDS]
    if unknown or not noises:
        raise InputError(f"noises must be among {list(NOISE_KINDS)}, got {list(noises)}")
    check_multiples(multiples)
    check_sweep_simulable(scenario, sequence, noises, multiples)
    others = dict(others or {})
    if n_test < scenario.n_candidates:
        raise InputError(f"n_test = {n_test} is fewer than the {scenario.n_candidates} candidates")
    per_candidate = n_test // scenario.n_candidates
    if ceiling_realisations is None:
        ceiling_realisations = limit_realisations
    ceiling_realisations = check_ceiling_realisations(ceiling_realisations)
    streams = np.random.SeedSequence(check_seed(seed)).spawn(len(noises) * len(multiples))
    limit_streams = np.random.SeedSequence([seed, 1]).spawn(len(streams))
    limit_points: list[SweepPoint] = []
    sources: list[str] = []
    points: list[SweepPoint] = []
    other_points: dict[str, list[SweepPoint]] = {label: [] for label in others}
    levels = {noise: noise_level(scenario, noise) for noise in noises}
    total = len(streams)
    for i, (noise, multiple) in enumerate((n, m) for n in noises for m in multiples):
        if should_stop is not None and should_stop():
            break
        value = float(multiple) * levels[noise]
        if noise in ("process", "measurement"):
            # The simulator scales these itself (same draws as a plain simulate call).
            scales: dict[str, Any] = {"process_noise_scale": 1.0, "measurement_noise_scale": 1.0}
            scales[f"{noise}_noise_scale"] = float(multiple)
            at_level, extra = scenario, scales
        else:
            # Not validated again: 1000x of a sigma at its bound is past it.
            at_level, extra = scenario.with_swept_noise(**{NOISE_FIELDS[noise]: value}), {}
        try:
            result = simulate(
                at_level, sequence, per_candidate, np.random.default_rng(streams[i]), **extra
            )
        except SimulationOverflow:
            # A scenario whose own 1x level is large can overflow below MAX_MULTIPLE.
            raise InputError(
                f"{noise} noise at multiple {float(multiple):g} ({value:g} "
                f"{NOISE_UNITS[noise]}) drives the simulated rates to inf or nan on this "
                "scenario: sweep smaller multiples"
            ) from None
        X, y = result.dataset()
        # The level as stated, to 15 significant digits: the product's binary dust
        # (3 x 0.05 = 0.15000000000000002 N m, 6 x 0.05 = 0.30000000000000004) was
        # written into every points table and chart a team reads; the simulation is as
        # before (process and measurement by their multiple, the others by ``value``).
        where = {"noise": noise, "multiple": float(multiple), "value": float(f"{value:.15g}")}
        points.append(_point(classifier, X, y, **where))
        for label, other in others.items():
            other_points[label].append(_point(other, X, y, **where))
        if ceiling_realisations:
            from .ceiling import fit_ceiling

            rng = np.random.default_rng(limit_streams[i])
            ceiling = fit_ceiling(at_level, sequence, ceiling_realisations, rng, **extra)
            sources.append(ceiling.source)
            limit_points.append(
                _point_from_predictions(ceiling.predict(X), y, scenario.n_candidates, **where)
            )
            _mark_above_ceiling(
                [points[-1], *(other_points[label][-1] for label in others)], limit_points[-1]
            )
        if progress is not None:
            progress((i + 1) / total)
    return SweepResult(
        candidate_names=scenario.candidate_names,
        sequence=sequence.tolist(),
        metric=classifier.metric,
        seed=seed,
        n_test_per_candidate=per_candidate,
        points=points,
        levels=levels,
        units={noise: NOISE_UNITS[noise] for noise in noises},
        others=other_points,
        ceiling=limit_points,
        ceiling_realisations=ceiling_realisations,
        ceiling_covariance=sources,
        limit=limit_points,
        limit_realisations=ceiling_realisations,
    )


class InertiaPoint(BaseModel):
    """How a classifier answers for a body that is not one of its candidates: the
    verdicts :func:`~inertia_id.evaluation.identify.identify` gives its series.

    :param body: "scaled" (candidate ``base`` times ``parameter``) or "between"
        (``(1 - parameter) I_a + parameter I_b`` for the pair ``a``, ``b``).
    :param matches_none_rate: fraction of the series identify says match none (status
        "matches-none" or "not-this-sequence"). In a result stored before the sweep used
        identify's rule (``required_confidence`` None): the fraction beyond the nearest
        candidate's novelty threshold only.
    :param predicted: how many series had each candidate most probable (whatever the
        status; before, nearest by distance).
    :param true_candidate: the candidate this body is (scale 1, position 0 or 1), else
        None: every "identified" is then wrong.
    :param statuses: how many series got each of identify's statuses (empty in an
        older result).
    :param identified: how many series were identified as each candidate.
    :param identified_right_rate: fraction identified as ``true_candidate`` (0 for a
        body that is none); ``identified_wrong_rate``: identified as another one;
        ``ambiguous_rate``: no candidate confident enough. None in an older result.
    """

    body: str
    parameter: float
    inertia_kg_m2: list[list[float]]
    n_series: int
    matches_none_rate: float
    ci_low: float
    ci_high: float
    predicted: list[int]
    true_candidate: int | None = None
    statuses: dict[str, int] = {}
    identified: list[int] = []
    identified_right_rate: float | None = None
    identified_wrong_rate: float | None = None
    ambiguous_rate: float | None = None


class InertiaSweepResult(BaseModel):
    """Answers for bodies scaled from a candidate and between two candidates (JSON-ready).

    ``required_confidence``: the posterior identify needed to name a candidate; None in
    a result stored before the sweep counted identify's verdicts.
    """

    candidate_names: list[str]
    base: int
    pair: tuple[int, int]
    seed: int
    points: list[InertiaPoint]
    required_confidence: float | None = None


def _closest_pair(scenario: Scenario) -> tuple[int, int]:
    tensors = [np.asarray(c.inertia_kg_m2, dtype=float) for c in scenario.inertia_candidates]
    best = (np.inf, (0, 1))
    for a in range(len(tensors)):
        for b in range(a + 1, len(tensors)):
            gap = np.linalg.norm(tensors[a] - tensors[b]) / np.linalg.norm(tensors[a])
            best = min(best, (float(gap), (a, b)))
    return best[1]


def body_series(
    scenario: Scenario,
    sequence: Any,
    inertia_kg_m2: np.ndarray,
    n_series: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """``n_series`` measured responses (n, length, 3) of a body of tensor
    ``inertia_kg_m2`` to ``sequence``, with the scenario's noise at 1x: the series
    :func:`run_inertia_sweep` gives each body (body ``i`` draws from stream ``i`` of
    ``SeedSequence(seed).spawn(n_bodies)``)."""
    document = scenario.model_dump()
    # A scenario needs two candidates: simulate the body beside candidate 0 and keep
    # only the body's series. Its noise is the scenario's own, which a classifier's
    # scenario may hold past today's bounds (AS_TRAINED: read as trained).
    test = Scenario.model_validate(
        {
            **document,
            "candidate_generator": None,
            "inertia_candidates": [
                {"name": "test body", "inertia_kg_m2": np.asarray(inertia_kg_m2).tolist()},
                document["inertia_candidates"][0],
            ],
        },
        context=AS_TRAINED,
    )
    return np.asarray(simulate(test, sequence, n_series, rng).omega_measured[0])


def _true_candidate(tensors: list[np.ndarray], tensor: np.ndarray) -> int | None:
    """The candidate whose tensor ``tensor`` is (to rounding: scale 1, position 0 or 1),
    or None."""
    for index, candidate in enumerate(tensors):
        if np.allclose(tensor, candidate, rtol=1e-12, atol=0.0):
            return index
    return None


def run_inertia_sweep(
    classifier: CandidateClassifier,
    *,
    scenario: Scenario | None = None,
    scales: Sequence[float] = (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4),
    between: Sequence[float] = (0.0, 0.25, 0.5, 0.75, 1.0),
    base: int = 0,
    pair: tuple[int, int] | None = None,
    n_test: int = 50,
    seed: int = 0,
    confidence: float = DEFAULT_CONFIDENCE,
    progress: Callable[[float], None] | None = None,
    should_stop: Callable[[], bool] | None = None,
) -> InertiaSweepResult:
    """Does the classifier say "matches none" when the true inertia is none of the candidates?

    At 1x noise, simulate ``n_test`` series of each test body and record the verdict
    :func:`~inertia_id.evaluation.identify.identify` gives each (telemetry of the
    sequence alone, no samples before its start): how often it says "matches none",
    names the right or a wrong candidate, or is ambiguous. Scale 1 and the ends of the
    pair are candidates themselves: there the matches-none rate should be near 0; far
    from every candidate it should be near 1.

    :param scales: multiples of candidate ``base``'s inertia tensor.
    :param between: positions along the segment from candidate ``pair[0]`` to
        ``pair[1]`` (0 and 1 are the candidates).
    :param scenario: the scenario whose noise the bodies are simulated with; defaults to
        the one the classifier was trained on (its candidates must be the classifier's).
    :param pair: defaults to the two candidates closest to each other (relative
        Frobenius distance), the pair hardest to tell apart.
    :param seed: seed of the draws; every body gets its own stream.
    :param confidence: the posterior identify needs to name a candidate, in (0, 1).
    """
    confidence = _check_probability("confidence", confidence)
    scenario = scenario if scenario is not None else classifier.scenario_
    sequence = classifier.sequence_
    if scenario is None or sequence is None:
        raise InputError("the classifier does not carry its scenario and sequence")
    check_classifier_scenario(scenario, classifier.scenario_)
    k = scenario.n_candidates
    pair = pair if pair is not None else _closest_pair(scenario)
    for name, index in (("base", base), ("pair[0]", pair[0]), ("pair[1]", pair[1])):
        if not 0 <= index < k:
            raise InputError(f"{name} = {index} is not a candidate index 0..{k - 1}")
    bad = [s for s in scales if not (math.isfinite(s) and s > 0)]
    if bad:
        raise InputError(f"scales must be finite and > 0, got {list(scales)}")
    bad = [t for t in between if not (math.isfinite(t) and 0 <= t <= 1)]
    if bad:
        raise InputError(f"between positions must be in [0, 1], got {list(between)}")
    if n_test < 1:
        raise InputError(f"n_test must be at least 1, got {n_test}")
    tensors = [np.asarray(c.inertia_kg_m2, dtype=float) for c in scenario.inertia_candidates]
    bodies = [("scaled", float(s), float(s) * tensors[base]) for s in scales] + [
        ("between", float(t), (1 - float(t)) * tensors[pair[0]] + float(t) * tensors[pair[1]])
        for t in between
    ]
    streams = np.random.SeedSequence(check_seed(seed)).spawn(len(bodies))
    points: list[InertiaPoint] = []
    for i, (body, parameter, tensor) in enumerate(bodies):
        if should_stop is not None and should_stop():
            break
        X = body_series(scenario, sequence, tensor, n_test, np.random.default_rng(streams[i]))
        answers = verdicts(classifier, X, confidence=confidence)
        counts = np.bincount(answers.status, minlength=len(STATUSES))
        statuses = {name: int(c) for name, c in zip(STATUSES, counts, strict=True)}
        flagged = statuses["matches-none"] + statuses["not-this-sequence"]
        named = answers.best[answers.status == STATUSES.index("identified")]
        identified = np.bincount(named, minlength=k)
        truth = _true_candidate(tensors, tensor)
        right = int(identified[truth]) if truth is not None else 0
        low, high = wilson_interval(flagged, len(X))
        points.append(
            InertiaPoint(
                body=body,
                parameter=parameter,
                inertia_kg_m2=tensor.tolist(),
                n_series=len(X),
                matches_none_rate=flagged / len(X),
                ci_low=low,
                ci_high=high,
                predicted=np.bincount(answers.best, minlength=k).tolist(),
                true_candidate=truth,
                statuses=statuses,
                identified=identified.tolist(),
                identified_right_rate=right / len(X),
                identified_wrong_rate=(statuses["identified"] - right) / len(X),
                ambiguous_rate=statuses["ambiguous"] / len(X),
            )
        )
        if progress is not None:
            progress((i + 1) / len(bodies))
    return InertiaSweepResult(
        candidate_names=scenario.candidate_names,
        base=base,
        pair=pair,
        seed=seed,
        points=points,
        required_confidence=confidence,
    )
