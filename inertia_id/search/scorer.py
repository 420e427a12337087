"""Score actuation-sequence prefixes fast: extend the batch, cluster, F1, with a cache.

Every environment step asks "how well do the candidates separate under this prefix?".
Answering it the plain way (re-simulate the whole prefix series by series, then
tslearn's ``TimeSeriesKMeans``) takes about two seconds on a laptop. The
:class:`PrefixScorer` computes the same quantities, much faster:

- the randomness of a scorer is drawn once (common random numbers), so a prefix always
  gets the same score, sequences are compared on the same noise, and a result can be
  reused: scored prefixes live in a cache bounded by memory;
- a prefix is simulated by extending its parent's state by one step
  (:meth:`~inertia_id.physics.simulate.Simulator.advance`), all candidates and realisations at
  once;
- clustering is the numba DTW k-means of :mod:`inertia_id.classifiers.dtw`, band-constrained by
  default (thruster timing jitter and the actuator lag shift responses by about two
  samples at 20 Hz, so a wider warping only blurs candidates), warm-started from the
  parent's centroids plus ``n_init`` k-means++ runs, the lowest inertia kept.

``metric="softdtw"`` clusters with :class:`~inertia_id.classifiers.clustering.InertiaClassifier`
(tslearn), which is correct but slow; it is there for comparison, not for PPO.

``objective="separability"`` scores a prefix without clustering: the candidates'
responses are modelled as Gaussians with a shared, shrunk covariance and scored by the
Bhattacharyya bound on the Bayes error (:mod:`inertia_id.search.objectives`), about a
millisecond instead of tens. The simulation, the cache and the common random numbers
are the same; only the score differs.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import is_integer
from ..classifiers.clustering import InertiaClassifier, match_clusters
from ..classifiers.dtw import kmeans_dtw
from ..errors import InputError
from ..physics.scenario import Scenario
from ..physics.simulate import SequenceNoise, SimulationState, Simulator, nominal_simulator
from .objectives import error_bound, per_flight_bound, score_from_bound

__all__ = [
    "SCORER_METRICS",
    "SCORER_OBJECTIVES",
    "PrefixScore",
    "PrefixScorer",
    "ScorerSettings",
]

SCORER_METRICS = ("dtw", "euclidean", "softdtw")
#: What a prefix's score measures: the clustering F1, or the Bhattacharyya separability.
SCORER_OBJECTIVES = ("f1", "separability")

Prefix = tuple[tuple[int, ...], ...]


@dataclass(frozen=True)
class ScorerSettings:
    """How prefixes are simulated and scored.

    :param n_realisations: noisy realisations per candidate (the paper: 20).
    :param objective: "f1", the macro F1 of a DTW k-means clustering (the paper's), or
        "separability", the Bhattacharyya bound on the Bayes error (no clustering; the
        clustering options below are then unused; needs 2 realisations or more).
    :param metric: "dtw" (the paper's), "euclidean" (DTW with a zero band) or "softdtw".
    :param sakoe_chiba_radius: DTW band half-width in samples; None = unconstrained.
    :param n_init: k-means++ runs per prefix, besides the warm start.
    :param warm_start: also start k-means from the parent prefix's centroids, extended
        by the mean new segment of each parent cluster.
    :param max_iter: Lloyd iterations per run.
    :param max_iter_barycenter: DBA iterations per Lloyd iteration.
    :param process_noise_scale: multiple of the scenario's disturbance torque.
    :param measurement_noise_scale: multiple of the scenario's gyro noise.
    :param cache_mb: memory for scored prefixes (their states and series), MB.
    :param separability_margin: the separability objective's noise margin m: the bound
        is taken as if the noise were m times larger, because the bound is for
        classifying against known means and an unsupervised clustering needs a wider
        gap (at m = 1 the score of many random sequences of the paper preset is already
        about 1, so it cannot lead a search further).
    :param separability_shrinkage: the separability objective's covariance shrinkage
        intensity in [0, 1]; None = Ledoit–Wolf's, estimated from the data. The default
        1 measures distances as k-means does, Euclidean over the mean noise variance:
        the Ledoit–Wolf covariance keeps the noise's low-variance directions, which a
        classifier given the labels could use but k-means does not, and a search led by
        it settles on sequences that separate there and cluster worse
        (``bench/separability_rank.py`` and ``bench/search_objectives.py``).
    """

    n_realisations: int = 20
    objective: str = "f1"
    metric: str = "dtw"
    sakoe_chiba_radius: int | None = 2
    n_init: int = 1
    warm_start: bool = True
    max_iter: int = 50
    max_iter_barycenter: int = 5
    process_noise_scale: float = 1.0
    measurement_noise_scale: float = 1.0
    cache_mb: float = 256.0
    separability_margin: float = 4.0
    separability_shrinkage: float | None = 1.0

    def check(self) -> None:
        if self.objective not in SCORER_OBJECTIVES:
            raise InputError(
                f"objective must be one of {list(SCORER_OBJECTIVES)}, got {self.objective!r}"
            )
        if self.metric not in SCORER_METRICS:
            raise InputError(f"metric must be one of {list(SCORER_METRICS)}, got {self.metric!r}")
        for name in ("n_realisations", "max_iter", "max_iter_barycenter"):
            value = getattr(self, name)
            if not is_integer(value, minimum=1, numpy=False):
                raise InputError(f"{name} must be a positive integer, got {value!r}")
        if not is_integer(self.n_init, minimum=0, numpy=False):
            raise InputError(f"n_init must be an integer >= 0, got {self.n_init!r}")
        if self.n_init == 0 and not self.warm_start:
            raise InputError("n_init = 0 needs warm_start (something must start k-means)")
        radius = self.sakoe_chiba_radius
        if radius is not None and (
            isinstance(radius, bool) or not isinstance(radius, int) or radius < 0
        ):
            raise InputError(f"sakoe_chiba_radius must be None or an integer >= 0, got {radius!r}")
        if not (np.isfinite(self.cache_mb) and self.cache_mb >= 0):
            raise InputError(f"cache_mb must be >= 0, got {self.cache_mb!r}")
        margin = self.separability_margin
        if isinstance(margin, bool) or not (np.isfinite(margin) and margin > 0):
            raise InputError(f"separability_margin must be finite and > 0, got {margin!r}")
        shrinkage = self.separability_shrinkage
        if shrinkage is not None and (isinstance(shrinkage, bool) or not 0 <= shrinkage <= 1):
            raise InputError(f"separability_shrinkage must be None or in [0, 1], got {shrinkage!r}")
        if self.objective == "separability" and self.n_realisations < 2:
            raise InputError(
                "the separability objective estimates a covariance: n_realisations must be "
                f"at least 2, got {self.n_realisations}"
            )
        if self.n_realisations < 2:
            # One series a candidate makes every clustering perfect: a search reported
            # F1 1.000 (fresh too) for a sequence 0.32 accurate at its design noise.
            raise InputError(
                "n_realisations must be at least 2: with one series a candidate every "
                f"clustering is perfect (F1 1.0 whatever the sequence), got {self.n_realisations}"
            )

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class PrefixScore:
    """How well the candidates separate under one prefix.

    ``f1`` is the objective's score, whichever the objective: what the reward uses and
    what searches rank by.

    :param f1: objective "f1": macro F1 of the clustering under the best
        cluster-candidate matching; objective "separability": the separability score
        (:func:`~inertia_id.search.objectives.separability_score`), both in [0, 1].
    :param accuracy: objective "f1": fraction of series whose cluster maps to their
        candidate; "separability": 1 − the error bound (at most 1), a lower bound on the
        accuracy of the best classifier under the Gaussian model, at the noise margin.
    :param final_rate_rad_s: mean |ω| over all series at the end of the prefix, rad/s.
    :param impulse_nms: fuel of the whole prefix (commanded angular impulse), N m s.
    :param step_impulse_nms: fuel of its last step, N m s.
    :param objective: which objective ``f1`` and ``accuracy`` come from.
    :param error_bound: objective "separability": the Bhattacharyya bound on the Bayes
        error at the noise margin (may exceed 1); None for "f1".
    :param peak_rate_rad_s: the largest |ω| of a manoeuvre that ends with this prefix, the
        candidate that spins fastest (the larger of the mean over its series and the
        command plan's noise-free prediction): at any sample so far, or after the last
        command while the lag delivers the torque still in it (the settled rate), as the
        operator's ``peak_rate`` reads it.
    :param final_rate_max_rad_s: the residual rate once the actuation lag has delivered
        the torque still in it (:func:`~inertia_id.physics.simulate.settled_rates`), of
        the candidate that ends fastest (the larger of the mean over its series and the
        plan's prediction): what a ``max_final_rate`` constraint bounds.
    :param residual_rate_rad_s: the same residual rate, mean over candidates of each
        candidate's figure (the larger of its mean over its series and the plan's
        prediction): the operator's ``final_rate`` objective, as a front reads it, while
        ``final_rate_rad_s`` is the rate when the last command ends, the paper's reward.
    :param final_rate_p95_rad_s: a residual rate at least 95 % of that candidate's
        flights stay under, with 95 % confidence, as its series estimate it (the larger of
        :func:`~inertia_id.search.objectives.per_flight_bound` of its series, the normal
        proxy below 59, and ``final_rate_max_rad_s``'s figure for it), the candidate
        whose series end fastest: what a ``max_final_rate_p95`` constraint penalises. The
        search's best is judged again on flights of its own (its front).
    :param peak_rate_p95_rad_s: the same for each series' own peak rate (its fastest
        instant, or once settled), at least ``peak_rate_rad_s``: what a
        ``max_peak_rate_p95`` constraint penalises.
    :param commanded_residual_rate_rad_s: the residual rate the command plan predicts from
        rest with every noise off (the part the commands themselves leave, without
        |ω(0)|), mean over candidates: what a ``max_commanded_residual_rate`` constraint
        penalises.
    :param commanded_residual_rate_max_rad_s: the same, of the candidate the commands
        leave fastest: what a ``max_commanded_residual_rate_max`` constraint penalises.
    """

    f1: float
    accuracy: float
    final_rate_rad_s: float
    impulse_nms: float
    step_impulse_nms: float
    objective: str = "f1"
    error_bound: float | None = None
    peak_rate_rad_s: float = 0.0
    final_rate_max_rad_s: float = 0.0
    final_rate_p95_rad_s: float = 0.0
    residual_rate_rad_s: float = 0.0
    peak_rate_p95_rad_s: float = 0.0
    commanded_residual_rate_rad_s: float = 0.0
    commanded_residual_rate_max_rad_s: float = 0.0


@dataclass
class _Node:
    state: SimulationState
    #: The same prefix with every noise off: the command plan's prediction.
    planned: SimulationState
    series: np.ndarray  # (K*n, T, 3) measured rates, rad/s
    centers: np.ndarray | None  # (K, T, 3) centroids, rad/s
    labels: np.ndarray | None
    score: PrefixScore | None
    #: The largest |ω| at any sample so far (the candidate that spins fastest); the
    #: settling after the last command is added only to the score, not handed on.
    peak_during: float = 0.0
    #: (K, n) each series' own largest true |ω| at any sample so far (None at the root).
    series_peak: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        centers = 0 if self.centers is None else self.centers.nbytes
        states = self.state.omega.nbytes + self.planned.omega.nbytes
        return int(self.series.nbytes + centers + 2 * states)


class PrefixScorer:
    """Scores prefixes of actuation sequences of one scenario on one draw of noise.

    :param scenario: the spacecraft and its uncertainty.
    :param max_length: longest sequence that will be scored (noise is drawn for it).
    :param settings: simulation and scoring settings.
    :param seed: seed of the noise draw and of the k-means initialisations.
    """

    def __init__(
        self,
        scenario: Scenario,
        max_length: int,
        settings: ScorerSettings | None = None,
        *,
        seed: int | None = None,
    ) -> None:
        self.settings = settings or ScorerSettings()
        self.settings.check()
        if not is_integer(max_length, minimum=1, numpy=False):
            raise InputError(f"max_length must be a positive integer, got {max_length!r}")
        self.scenario = scenario
        self.max_length = max_length
        self.simulator = Simulator(
            scenario,
            self.settings.n_realisations,
            process_noise_scale=self.settings.process_noise_scale,
            measurement_noise_scale=self.settings.measurement_noise_scale,
        )
        # The noise-free prediction a command plan shows: the rate bounds hold on it too.
        self._planner, self._planner_noise = nominal_simulator(scenario, max_length)
        self.labels = np.repeat(np.arange(scenario.n_candidates), self.settings.n_realisations)
        self._thruster_impulse = (
            np.linalg.norm(scenario.torque_matrix, axis=0) * scenario.timing.step_duration_s
        )
        #: Prefixes asked for whose score was cached / had to be computed.
        self.hits = 0
        self.misses = 0
        self.reseed(seed)

    def reseed(self, seed: int | None) -> None:
        """Draw new noise (and forget every cached score)."""
        self.seed = (
            int(np.random.SeedSequence().generate_state(1, np.uint32)[0])
            if seed is None
            else int(seed)
        )
        self.noise: SequenceNoise = self.simulator.draw_noise(
            np.random.default_rng(self.seed), self.max_length
        )
        k, n = self.simulator.shape
        root = _Node(
            state=self.simulator.start(self.noise.initial),
            planned=self._planner.start(self._planner_noise.initial),
            series=np.empty((k * n, 0, 3)),
            centers=None,
            labels=None,
            score=None,
        )
        self._root = root
        self._cache: OrderedDict[Prefix, _Node] = OrderedDict()
        self._cache_bytes = 0

    def check_prefix(self, prefix: Any) -> Prefix:
        rows = self.scenario.check_sequence(prefix)
        if len(rows) > self.max_length:
            raise InputError(f"prefix has {len(rows)} steps; this scorer holds {self.max_length}")
        return tuple(tuple(int(v) for v in row) for row in rows)

    def score(self, prefix: Any) -> PrefixScore:
        """Score of the sequence ``prefix`` ((L, N) level indices), cached."""
        key = self.check_prefix(prefix)
        if key in self._cache:
            self.hits += 1
        else:
            self.misses += 1
        node = self._node(key)
        assert node.score is not None
        return node.score

    def _node(self, prefix: Prefix) -> _Node:
        if not prefix:
            return self._root
        node = self._cache.get(prefix)
        if node is not None:
            self._cache.move_to_end(prefix)
            return node
        node = self._extend(self._node(prefix[:-1]), prefix)
        self._remember(prefix, node)
        return node

    def _remember(self, prefix: Prefix, node: _Node) -> None:
        budget = self.settings.cache_mb * 1e6
        self._cache[prefix] = node
        self._cache_bytes += node.nbytes
        while self._cache_bytes > budget and len(self._cache) > 1:
            _, old = self._cache.popitem(last=False)
            self._cache_bytes -= old.nbytes

    def _extend(self, parent: _Node, prefix: Prefix) -> _Node:
        levels = np.asarray(prefix[-1], dtype=int)
        step = len(prefix) - 1
        state, response = self.simulator.advance(parent.state, levels, self.noise.steps[step])
        # Rates that overflowed are refused here, naming the scenario's drive: clustered,
        # they ended in k-means' seeding as "Probabilities contain NaN", which names nothing.
        self.simulator.check_finite(response.omega_measured)
        k, n, samples, _ = response.omega_measured.shape
        series = np.concatenate(
            [parent.series, response.omega_measured.reshape(k * n, samples, 3)], axis=1
        )
        step_impulse = float(self.scenario.level_values[levels] @ self._thruster_impulse)
        impulse = step_impulse + (0.0 if parent.score is None else parent.score.impulse_nms)
        planned, prediction = self._planner.advance(
            parent.planned, levels, self._planner_noise.steps[step]
        )
        final_rate = float(np.linalg.norm(state.omega, axis=-1).mean())
        # Each rate as the operator's scorer reads it: the larger of the mean over the
        # series and the plan's noise-free prediction.
        # (K, n) -> the candidate ending fastest
        settled = self.simulator.settled(state)  # (K, n): each series' residual
        # The plan's prediction from rest, every noise off: what the commands leave.
        commanded = self._planner.settled(planned)[:, 0]  # (K,)
        by_candidate = np.maximum(settled.mean(axis=1), commanded)
        worst = float(by_candidate.max())
        p95 = float(np.maximum(per_flight_bound(settled, axis=1), by_candidate).max())
        # (K, n, samples) -> the candidate spinning fastest at its fastest
        during = max(
            float(np.linalg.norm(response.omega_true, axis=-1).mean(axis=1).max()),
            float(np.linalg.norm(prediction.omega_true, axis=-1).max()),
            parent.peak_during,
        )
        peak = max(during, worst)
        # Each series' own peak (its fastest instant, or once settled), and a peak rate
        # at least 95 % of flights stay under, read as the residual's p95 is.
        own = np.linalg.norm(response.omega_true, axis=-1).max(axis=-1)  # (K, n)
        series_peak = own if parent.series_peak is None else np.maximum(parent.series_peak, own)
        peak_p95 = max(
            float(per_flight_bound(np.maximum(series_peak, settled), axis=1).max()), peak
        )
        if self.settings.objective == "separability":
            bound = error_bound(
                series.reshape(k, n, -1, 3),
                noise_margin=self.settings.separability_margin,
                shrinkage=self.settings.separability_shrinkage,
            )
            score = PrefixScore(
                f1=score_from_bound(bound, k),
                accuracy=1.0 - min(1.0, bound),
                final_rate_rad_s=final_rate,
                impulse_nms=impulse,
                step_impulse_nms=step_impulse,
                objective="separability",
                error_bound=bound,
                peak_rate_rad_s=peak,
                final_rate_max_rad_s=worst,
                final_rate_p95_rad_s=p95,
                residual_rate_rad_s=float(by_candidate.mean()),
                peak_rate_p95_rad_s=peak_p95,
                commanded_residual_rate_rad_s=float(commanded.mean()),
                commanded_residual_rate_max_rad_s=float(commanded.max()),
            )
            return _Node(state, planned, series, None, None, score, during, series_peak)
        labels, centers = self._cluster(series, parent, prefix)
        scores = match_clusters(self.labels, labels, k)
        score = PrefixScore(
            f1=scores.f1,
            accuracy=scores.accuracy,
            final_rate_rad_s=final_rate,
            impulse_nms=impulse,
            step_impulse_nms=step_impulse,
            peak_rate_rad_s=peak,
            final_rate_max_rad_s=worst,
            final_rate_p95_rad_s=p95,
            residual_rate_rad_s=float(by_candidate.mean()),
            peak_rate_p95_rad_s=peak_p95,
            commanded_residual_rate_rad_s=float(commanded.mean()),
            commanded_residual_rate_max_rad_s=float(commanded.max()),
        )
        return _Node(state, planned, series, centers, labels, score, during, series_peak)

    def _cluster(
        self, series: np.ndarray, parent: _Node, prefix: Prefix
    ) -> tuple[np.ndarray, np.ndarray]:
        settings = self.settings
        k = self.scenario.n_candidates
        # The k-means seed depends on the prefix only, so a prefix scores the same
        # whatever was scored before it (and the cache changes nothing).
        rng = np.random.default_rng([self.seed, *(v for row in prefix for v in row)])
        rms = float(np.sqrt(np.mean(series**2)))
        scale = rms if rms > 0 else 1.0
        if settings.metric == "softdtw":
            model = InertiaClassifier(
                "softdtw",
                n_init=max(settings.n_init, 1),
                max_iter=settings.max_iter,
                random_state=int(rng.integers(2**31 - 1)),
            ).fit(series, self.labels)
            return model.labels_, model.cluster_centers_
        init = None
        if settings.warm_start and parent.centers is not None and parent.labels is not None:
            new = series[:, parent.series.shape[1] :, :]
            segment = np.stack([new[parent.labels == c].mean(axis=0) for c in range(k)])
            init = np.concatenate([parent.centers, segment], axis=1) / scale
        result = kmeans_dtw(
            series / scale,
            k,
            rng,
            radius=0 if settings.metric == "euclidean" else settings.sakoe_chiba_radius,
            n_init=settings.n_init if init is not None else max(settings.n_init, 1),
            init=init,
            max_iter=settings.max_iter,
            max_iter_barycenter=settings.max_iter_barycenter,
        )
        return result.labels, result.centers * scale

    @property
    def cache_size(self) -> int:
        return len(self._cache)
