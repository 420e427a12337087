"""How separable the candidates' responses are, without clustering them.

The clustering F1 of :mod:`inertia_id.search.scorer` answers "would DTW k-means split
these series by candidate?" by running k-means, tens of milliseconds a prefix. This
module answers a related question in about a millisecond: model each candidate's
measured response (a series of T samples x 3 axes, flattened to d = 3 T numbers) as a
Gaussian, all candidates sharing one covariance Σ estimated from the realisations, and
bound the error of the best possible classifier by the pairwise Bhattacharyya
distances. With a common covariance the distance between candidates i and j is

    B_ij = (1/8) Δμᵀ Σ⁻¹ Δμ,   Δμ = μ_i − μ_j,

an eighth of their squared Mahalanobis distance, and with equal priors the Bayes error
is at most the union of the pairwise Bhattacharyya bounds,

    P_error ≤ (1/K) Σ_{i<j} exp(−B_ij).

Three estimation details matter at the sizes a search scores (K x n ≈ 100 series of
d = 240 to 600 numbers):

- the sample covariance has rank below 100 and cannot be inverted. It is shrunk towards
  a scaled identity by the Ledoit–Wolf rule (the intensity that minimises the expected
  squared error of the estimate, computed from the data), which makes it positive
  definite and well-conditioned. Neither Σ nor Σ⁻¹ is ever formed: a shrunk covariance
  is ``a I + b RᵀR`` with R the (N, d) residuals, so every quantity the rule needs comes
  from the N x N Gram matrix R Rᵀ and Σ⁻¹ is applied through the Woodbury identity,
  O(N² d) work instead of the O(d³) of a dense inverse, and no d x d array;
- the means are estimated from n realisations, so Δμ̂ carries noise whose squared
  Mahalanobis length is on average (2/n) tr(Σ⁻¹ Σ_true): about 60 for d = 240, n = 20,
  which alone would make identical candidates look separable. It is estimated out of
  sample (each residual measured against the covariance estimated without it, by
  Sherman–Morrison) and subtracted (``debias``);
- the bound is for one series classified against known means; an unsupervised
  clustering needs a wider margin. ``noise_margin`` m evaluates the bound as if the
  noise were m times larger (B / m²), so that the score keeps rising until the
  candidates are far enough apart to cluster, instead of reaching 1 long before.

``shrinkage`` fixes the intensity instead of estimating it; at 1 the covariance is the
mean noise variance times the identity, and the distances are Euclidean, as k-means
sees them. The Ledoit–Wolf covariance measures what a classifier given the labels could
do, which includes low-noise directions that k-means does not weight; the search's
objective uses shrinkage 1 (see :class:`~inertia_id.search.ScorerSettings`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, fields
from itertools import combinations
from typing import Any, Final

import numpy as np

from ..checks import is_number
from ..classifiers.gaussian import one_blas_thread
from ..errors import InputError

__all__ = [
    "PooledCovariance",
    "bhattacharyya_matrix",
    "error_bound",
    "mahalanobis_matrix",
    "pooled_covariance",
    "score_from_bound",
    "separability_score",
]

# Added to the identity weight, relative to the data's mean square: keeps Σ invertible
# when the responses hold no noise at all (distinct means are then infinitely far apart,
# equal ones at distance 0) without changing any noisy estimate.
_RELATIVE_VARIANCE_FLOOR = 1e-12


@dataclass(frozen=True)
class PooledCovariance:
    """The candidates' common covariance, shrunk, held as ``a I + b RᵀR`` (d x d).

    :param residuals: (N, d) responses minus their candidate's mean, rad/s.
    :param gram: (N, N) their Gram matrix R Rᵀ, (rad/s)².
    :param identity_weight: a, (rad/s)²: the shrinkage target's share (plus a floor).
    :param residual_weight: b: the sample covariance's share, per residual outer product.
    :param shrinkage: the shrinkage intensity ρ in [0, 1] (0 = sample covariance,
        1 = scaled identity).
    """

    residuals: np.ndarray
    gram: np.ndarray
    identity_weight: float
    residual_weight: float
    shrinkage: float

    @property
    def dim(self) -> int:
        return int(self.residuals.shape[1])

    def dense(self) -> np.ndarray:
        """The d x d matrix, for checks on small problems, (rad/s)²."""
        r = self.residuals
        return self.identity_weight * np.eye(self.dim) + self.residual_weight * (r.T @ r)

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        """(a I_N + b R Rᵀ)⁻¹ rhs: the N x N system behind every use of Σ⁻¹."""
        gram = self.gram
        system = self.identity_weight * np.eye(len(gram)) + self.residual_weight * gram
        return np.asarray(np.linalg.solve(system, rhs))

    def mahalanobis_sq(self, differences: np.ndarray) -> np.ndarray:
        """``vᵀ Σ⁻¹ v`` for each row v of ``differences`` (P, d), by Woodbury.

        Σ⁻¹ = (1/a) [I − b Rᵀ (a I_N + b R Rᵀ)⁻¹ R], so only an N x N system is solved.
        """
        a, b = self.identity_weight, self.residual_weight
        differences = np.atleast_2d(differences)
        plain = np.einsum("pd,pd->p", differences, differences)
        if b == 0.0:
            return plain / a
        projected = self.residuals @ differences.T  # (N, P)
        correction = b * np.einsum("np,np->p", projected, self._solve(projected))
        # The exact value is >= 0; rounding can leave a tiny negative.
        return np.maximum(plain - correction, 0.0) / a

    def left_out_mahalanobis_sq(self) -> np.ndarray:
        """``r_iᵀ Σ_{−i}⁻¹ r_i`` for each residual, Σ_{−i} = Σ − b r_i r_iᵀ, (N,).

        Each residual measured against the covariance estimated without it (the
        shrinkage intensity held fixed): an out-of-sample Mahalanobis length. With
        q_i = r_iᵀ Σ⁻¹ r_i, Sherman–Morrison gives q_i / (1 − b q_i), and the q_i are the
        diagonal of R Σ⁻¹ Rᵀ = (a I + b G)⁻¹ G, G = R Rᵀ.
        """
        a, b, gram = self.identity_weight, self.residual_weight, self.gram
        if b == 0.0:
            return np.diag(gram) / a
        inside = np.diag(self._solve(gram))
        return np.asarray(inside / (1.0 - b * inside))


def _flatten(omega: np.ndarray) -> np.ndarray:
    omega = np.asarray(omega, dtype=float)
    if omega.ndim != 4 or omega.shape[-1] != 3:
        raise InputError(f"omega must be shaped (K, n, T, 3), got {omega.shape}")
    k, n, t, _ = omega.shape
    if k < 2:
        raise InputError(f"separability needs at least 2 candidates, got K = {k}")
    if n < 2:
        raise InputError(f"a covariance needs at least 2 realisations per candidate, got n = {n}")
    if t < 1:
        raise InputError("omega holds no samples (T = 0)")
    if not np.all(np.isfinite(omega)):
        raise InputError("omega holds non-finite values")
    return omega.reshape(k, n, t * 3)


def _check_shrinkage(shrinkage: float | None) -> None:
    if shrinkage is not None and not 0.0 <= shrinkage <= 1.0:
        raise InputError(f"shrinkage must be None (Ledoit–Wolf) or in [0, 1], got {shrinkage!r}")


def pooled_covariance(omega: np.ndarray, *, shrinkage: float | None = None) -> PooledCovariance:
    """The shrunk covariance common to every candidate's response.

    The pooled residuals (each realisation minus its candidate's mean) are shrunk as
    scikit-learn's ``ledoit_wolf(residuals, assume_centered=True)`` would, then scaled
    by N / (N − K): K means were estimated from the N residuals, so N − K degrees of
    freedom remain. (The Ledoit–Wolf intensity does not depend on that scale.)

    :param omega: (K, n, T, 3) measured rates, rad/s: n realisations of each of K candidates.
    :param shrinkage: a fixed intensity in [0, 1] instead of the Ledoit–Wolf one (1 =
        every direction gets the mean variance: Euclidean distances, as k-means sees them).
    """
    _check_shrinkage(shrinkage)
    with one_blas_thread():
        return _pooled(_flatten(omega), shrinkage)


def _pooled(x: np.ndarray, shrinkage: float | None) -> PooledCovariance:
    k, n, d = x.shape
    residuals = (x - x.mean(axis=1, keepdims=True)).reshape(k * n, d)
    count = k * n
    gram = residuals @ residuals.T  # (N, N)
    # Every term of the Ledoit–Wolf rule through the Gram matrix, with S = RᵀR / N:
    # tr S = tr G / N, ||S||²_F = ||G||²_F / N², sum_i ||r_i||⁴ = sum_i G_ii².
    norms_sq = np.diag(gram)
    mean_variance = float(norms_sq.sum()) / (count * d)  # tr S / d
    if shrinkage is None:
        frobenius_sq = float(np.sum(gram * gram)) / count**2
        # ||S − μ I||²_F / d, and the estimate's variance, both per dimension.
        dispersion = (frobenius_sq - d * mean_variance**2) / d
        spread = (float(np.sum(norms_sq**2)) / count - frobenius_sq) / (d * count)
        spread = min(spread, dispersion)
        shrinkage = 0.0 if spread <= 0.0 else spread / dispersion
    dof_scale = count / (count - k)
    floor = _RELATIVE_VARIANCE_FLOOR * float(np.mean(x * x)) + np.finfo(float).tiny
    return PooledCovariance(
        residuals=residuals,
        gram=gram,
        identity_weight=dof_scale * shrinkage * mean_variance + floor,
        residual_weight=dof_scale * (1.0 - shrinkage) / count,
        shrinkage=float(shrinkage),
    )


def mahalanobis_matrix(
    omega: np.ndarray, *, shrinkage: float | None = None, debias: bool = True
) -> np.ndarray:
    """Squared Mahalanobis distances between the candidates' mean responses, (K, K).

    ``D²_ij = (μ_i − μ_j)ᵀ Σ⁻¹ (μ_i − μ_j)``, Σ the shrunk pooled covariance of
    :func:`pooled_covariance`; dimensionless, symmetric, zero on the diagonal.

    :param omega: (K, n, T, 3) measured rates, rad/s.
    :param shrinkage: see :func:`pooled_covariance` (None = Ledoit–Wolf).
    :param debias: subtract what the noise of the estimated means adds on average,
        (2/n) tr(Σ⁻¹ Σ_true), with tr(Σ⁻¹ Σ_true) estimated by the mean left-out length
        of the residuals over (1 − 1/n) (a residual's covariance is (1 − 1/n) Σ_true);
        clipped at 0. Without it, identical candidates are about 2 d / n apart.
    """
    _check_shrinkage(shrinkage)
    x = _flatten(omega)
    k, n, _ = x.shape
    pairs = list(combinations(range(k), 2))
    first, second = (np.array(side) for side in zip(*pairs, strict=True))
    with one_blas_thread():
        covariance = _pooled(x, shrinkage)
        means = x.mean(axis=1)
        # Differences of means, not a Gram matrix of the means: the means are large next
        # to their differences, and μ_iᵀΣ⁻¹μ_i + μ_jᵀΣ⁻¹μ_j − 2μ_iᵀΣ⁻¹μ_j would cancel.
        distances = covariance.mahalanobis_sq(means[first] - means[second])
        if debias:
            trace = float(np.mean(covariance.left_out_mahalanobis_sq())) / (1.0 - 1.0 / n)
            distances = np.maximum(distances - 2.0 * trace / n, 0.0)
    out = np.zeros((k, k))
    out[first, second] = distances
    out[second, first] = distances
    return out


def bhattacharyya_matrix(
    omega: np.ndarray, *, shrinkage: float | None = None, debias: bool = True
) -> np.ndarray:
    """Pairwise Bhattacharyya distances between the candidates' responses, (K, K).

    For Gaussians sharing one covariance, ``B_ij = D²_ij / 8`` (see
    :func:`mahalanobis_matrix`, whose options these are).

    :param omega: (K, n, T, 3) measured rates, rad/s.
    """
    return mahalanobis_matrix(omega, shrinkage=shrinkage, debias=debias) / 8.0


def _bound(distances: np.ndarray, noise_margin: float) -> float:
    if not (np.isfinite(noise_margin) and noise_margin > 0):
        raise InputError(f"noise_margin must be finite and > 0, got {noise_margin!r}")
    k = len(distances)
    upper = distances[np.triu_indices(k, 1)] / noise_margin**2
    return float(np.sum(np.exp(-upper)) / k)


def error_bound(
    omega: np.ndarray,
    *,
    noise_margin: float = 1.0,
    shrinkage: float | None = None,
    debias: bool = True,
) -> float:
    """Upper bound on the Bayes error of telling the K candidates apart, equal priors.

    ``(1/K) Σ_{i<j} exp(−B_ij / m²)``: the Bayes error is at most the sum over pairs of
    the two-class errors ``∫ min(p_i, p_j) / K``, each at most ``exp(−B_ij) / K``. It
    can exceed 1 (when it says nothing).

    :param omega: (K, n, T, 3) measured rates, rad/s.
    :param noise_margin: m, the bound as if every noise were m times larger (the
        covariance m² times): 1 is the bound for the noise measured.
    :param shrinkage: see :func:`pooled_covariance`.
    :param debias: see :func:`mahalanobis_matrix`.
    """
    distances = bhattacharyya_matrix(omega, shrinkage=shrinkage, debias=debias)
    return _bound(distances, noise_margin)


def separability_score(
    omega: np.ndarray,
    *,
    noise_margin: float = 1.0,
    shrinkage: float | None = None,
    debias: bool = True,
) -> float:
    """How separable the candidates are, in [0, 1]: 1 − the error bound over chance.

    ``1 − min(1, bound / ((K − 1) / K))``, the bound of :func:`error_bound` measured
    against the error of guessing, (K − 1) / K: identical candidates score 0 whatever K
    (the plain ``1 − bound`` would give 1/2 to two identical candidates), candidates
    many noise widths apart score 1. It stands where the clustering F1 stands in the
    search's reward.

    :param omega: (K, n, T, 3) measured rates, rad/s.
    :param noise_margin: see :func:`error_bound`.
    :param shrinkage: see :func:`pooled_covariance`.
    :param debias: see :func:`mahalanobis_matrix`.
    """
    bound = error_bound(omega, noise_margin=noise_margin, shrinkage=shrinkage, debias=debias)
    # error_bound checked omega's shape, so its first axis is K.
    return score_from_bound(bound, np.shape(omega)[0])


def score_from_bound(bound: float, n_candidates: int) -> float:
    """The score of :func:`separability_score` from an error bound for K candidates."""
    chance_error = (n_candidates - 1) / n_candidates
    return float(1.0 - min(1.0, bound / chance_error))


# What an operator states: accuracy at a design noise, residual rate, propellant, ...
#
# The separability score above leads a search towards sequences that cluster; an
# operator also asks what a sequence leaves behind (the residual rate), what it burns
# and how hard it spins the spacecraft, and how well the candidates are told apart at the
# noise the mission must survive, not at 1x, where most sequences already score 1.

#: The objectives a Pareto search may trade off: what each is, its sense, its unit.
OPERATOR_OBJECTIVES: dict[str, tuple[str, str, str]] = {
    "accuracy": (
        "accuracy of the Bayes classifier at the design noise (the scenario's noise model): "
        "predicted while searching, measured on fresh series for the front",
        "max",
        "",
    ),
    "final_rate": (
        "residual body rate once the last command's torque is delivered, mean over candidates",
        "min",
        "rad/s",
    ),
    "peak_rate": (
        "largest body rate during the sequence or while the last command's torque is "
        "delivered, worst candidate",
        "min",
        "rad/s",
    ),
    "impulse": ("commanded angular impulse summed over thrusters", "min", "N m s"),
    "on_time": ("thruster on-time summed over thrusters", "min", "s"),
    "propellant": ("propellant mass (needs thrust and specific impulse)", "min", "kg"),
    "duration": ("length of the sequence", "min", "s"),
}
#: The figure each objective reads from :class:`SequenceScores`.
OBJECTIVE_FIELDS = {
    "accuracy": "accuracy",
    "final_rate": "final_rate_rad_s",
    "peak_rate": "peak_rate_rad_s",
    "impulse": "impulse_nms",
    "on_time": "on_time_s",
    "propellant": "propellant_kg",
    "duration": "duration_s",
}
_DEG = 180.0 / np.pi
#: Constraint name -> (figure of :class:`SequenceScores`, sense, factor from the
#: constraint's unit to the figure's). A "max_" bound holds when figure <= bound.
CONSTRAINTS: dict[str, tuple[str, str, float]] = {
    "min_accuracy": ("accuracy", "min", 1.0),
    # A bound on the residual rate holds for every candidate: the operator does not know
    # which configuration the spacecraft is in (the objective is the mean over them).
    "max_final_rate_rad_s": ("final_rate_max_rad_s", "max", 1.0),
    "max_final_rate_deg_s": ("final_rate_max_rad_s", "max", 1.0 / _DEG),
    # The same bound on a rate at least 95 % of flights stay under, with 95 % confidence
    # (of the candidate whose flights end fastest; :func:`per_flight_bound`): a bound on the
    # mean leaves up to half the flights of a member near it above it.
    "max_final_rate_p95_rad_s": ("final_rate_p95_rad_s", "max", 1.0),
    "max_final_rate_p95_deg_s": ("final_rate_p95_rad_s", "max", 1.0 / _DEG),
    # The part of the residual the commands themselves leave (the plan's noise-free
    # prediction from rest, :attr:`SequenceScores.commanded_residual_rate_rad_s`): beside an
    # initial-rate spread the final-rate bounds hold |ω(0)|, which no open-loop sequence
    # removes, so a sequence that brakes and one that does not read alike there. The
    # mean over candidates, and the candidate the commands leave fastest ("_max_").
    "max_commanded_residual_rate_rad_s": ("commanded_residual_rate_rad_s", "max", 1.0),
    "max_commanded_residual_rate_deg_s": ("commanded_residual_rate_rad_s", "max", 1.0 / _DEG),
    "max_commanded_residual_rate_max_rad_s": ("commanded_residual_rate_max_rad_s", "max", 1.0),
    "max_commanded_residual_rate_max_deg_s": (
        "commanded_residual_rate_max_rad_s",
        "max",
        1.0 / _DEG,
    ),
    "max_peak_rate_rad_s": ("peak_rate_rad_s", "max", 1.0),
    "max_peak_rate_deg_s": ("peak_rate_rad_s", "max", 1.0 / _DEG),
    # The same on a peak rate at least 95 % of flights stay under, with 95 % confidence:
    # a single flight's peak is its own fastest instant, which the mean's bound left
    # exceeded on 19 % of a front member's flights (bench/per_flight_peak.py).
    "max_peak_rate_p95_rad_s": ("peak_rate_p95_rad_s", "max", 1.0),
    "max_peak_rate_p95_deg_s": ("peak_rate_p95_rad_s", "max", 1.0 / _DEG),
    "max_impulse_nms": ("impulse_nms", "max", 1.0),
    "max_on_time_s": ("on_time_s", "max", 1.0),
    "max_propellant_kg": ("propellant_kg", "max", 1.0),
    "max_duration_s": ("duration_s", "max", 1.0),
}
#: Figure of :data:`CONSTRAINTS` -> the scale, in the figure's unit, that a violation is
#: measured against when the bound is below it (a bound of exactly 0 included): a
#: violation is ``excess / max(bound, scale)``. Relative to the bound alone, a bound of
#: 0 had no scale and the penalised searches charged the absolute excess (0.02 rad/s
#: over cost 0.02 x constraint_penalty) while a bound of 1e-9 rad/s charged 2e7 times
#: that; with the scale, a bound of 0 costs what a bound at the scale or just under
#: it does. Rates: 1e-4 rad/s, a tenth of the paper preset's gyro noise (1e-3 rad/s).
CONSTRAINT_SCALES: dict[str, float] = {
    "accuracy": 0.01,
    "final_rate_max_rad_s": 1e-4,
    "final_rate_p95_rad_s": 1e-4,
    "commanded_residual_rate_rad_s": 1e-4,
    "commanded_residual_rate_max_rad_s": 1e-4,
    "peak_rate_rad_s": 1e-4,
    "peak_rate_p95_rad_s": 1e-4,
    "impulse_nms": 1e-3,
    "on_time_s": 1e-3,
    "propellant_kg": 1e-6,
    "duration_s": 1e-3,
}


def constraint_violation(name: str, value: float, bound: float) -> float:
    """A constraint's violation by a figure's value, relative to the bound or, for a
    bound below it (0 included), to the figure's :data:`CONSTRAINT_SCALES`: ``(value −
    bound) / max(bound, scale)`` for a "max_" bound (``bound − value`` for "min_"),
    <= 0 when it holds; inf for a value that is not finite.

    :param name: the constraint's name (:data:`CONSTRAINTS`), in whose unit ``bound`` is.
    :param value: the figure, in the figure's unit (rad/s for every rate).
    """
    figure, sense, factor = CONSTRAINTS[name]
    if not np.isfinite(value):
        return float("inf")
    limit = bound * factor
    excess = value - limit if sense == "max" else limit - value
    return float(excess / max(limit, CONSTRAINT_SCALES[figure]))


#: How a percentile of many flights is read (a command plan's flights): Hyndman and Fan's
#: type 8, median unbiased; numpy's default (type 7) reads the 95th percentile of 20
#: draws at about the 90th.
QUANTILE_METHOD: Final = "median_unbiased"
FLIGHT_QUANTILE: Final = 0.95
#: A per-flight bound is held with this confidence (:func:`per_flight_bound`).
FLIGHT_CONFIDENCE: Final = 0.95


def flight_quantile(rates: np.ndarray, axis: int) -> np.ndarray:
    """The rate :data:`FLIGHT_QUANTILE` of the flights along ``axis`` stay under: their
    percentile (:data:`QUANTILE_METHOD`), a figure of these flights; an estimate of the
    percentile of all flights that is as often below it as above."""
    return np.quantile(rates, FLIGHT_QUANTILE, axis=axis, method=QUANTILE_METHOD)


@functools.cache
def tolerance_factor(n: int) -> float:
    """The one-sided normal tolerance factor ``k``: with :data:`FLIGHT_CONFIDENCE`, at
    least :data:`FLIGHT_QUANTILE` of a normal population lies below ``mean + k sd`` of
    ``n`` draws (the noncentral t; 2.40 for 20 draws, 2.13 for 40, 26.3 for 2)."""
    from scipy.stats import nct, norm

    root = float(np.sqrt(n))
    return float(nct.ppf(FLIGHT_CONFIDENCE, df=n - 1, nc=norm.ppf(FLIGHT_QUANTILE) * root) / root)


def order_statistic_rank(n: int) -> int:
    """The largest ``r`` for which the ``r``-th largest of ``n`` flights is a
    distribution-free upper bound on the :data:`FLIGHT_QUANTILE` percentile with
    :data:`FLIGHT_CONFIDENCE` (at least ``r`` of ``n`` flights land above the percentile
    with that probability: a binomial tail); 0 below 59 flights (where even the largest
    falls short). 1 for 59 to 92, 2 for 100, 5 for 200, 39 for 1,000."""
    from scipy.stats import binom

    tail = 1.0 - FLIGHT_QUANTILE
    rank = 0
    while rank < n and binom.sf(rank, n, tail) >= FLIGHT_CONFIDENCE:
        rank += 1
    return rank


#: Flights a candidate from which a rate at least 95 % of flights stay under is read
#: without assuming a distribution (:func:`per_flight_bound`).
MIN_ORDER_FLIGHTS: Final = 59
#: Flights a candidate a front flies, on a draw of its own, for each member's and
#: baseline's per-flight figure: the 5th largest of 200 holds distribution-free.
FRONT_FLIGHTS: Final = 200


#: Realisations a candidate a search needs to rank by a per-flight bound (its proxy's
#: tolerance factor is 26 for 2, 4.2 for 5, 2.9 for 10: with fewer, every sequence
#: near the bound reads as breaking it).
MIN_PER_FLIGHT_REALISATIONS: Final = 10


def check_per_flight_realisations(constraints: dict[str, float], n_realisations: int) -> None:
    """A per-flight constraint needs :data:`MIN_PER_FLIGHT_REALISATIONS` realisations a
    candidate in the search."""
    per_flight = [name for name in constraints if "_p95_" in name]
    if per_flight and n_realisations < MIN_PER_FLIGHT_REALISATIONS:
        raise InputError(
            f"constraint {per_flight[0]} bounds a spread over flights: the search needs "
            f"n_realisations >= {MIN_PER_FLIGHT_REALISATIONS} to estimate it, got "
            f"{n_realisations} (the tolerance factor for {n_realisations} draws is "
            f"{tolerance_factor(n_realisations) if n_realisations > 1 else float('inf'):.1f})"
        )


def per_flight_bound(rates: np.ndarray, axis: int) -> np.ndarray:
    """A rate at least :data:`FLIGHT_QUANTILE` of all flights stay under, with
    :data:`FLIGHT_CONFIDENCE`, from the flights along ``axis``.

    From :data:`MIN_ORDER_FLIGHTS` flights on, an order statistic
    (:func:`order_statistic_rank`): it holds whatever the distribution of the residual
    rate. Fewer flights (a search's 20 realisations) bound nothing without a model, and
    the figure is then the normal tolerance bound ``mean + k sd`` of ``sqrt(|ω|)``,
    squared (:func:`tolerance_factor`). That is a proxy the searches rank by: the square
    of a residual rate is a noncentral chi-square, whose fourth root is near normal
    (Hawkins and Wixley, 1986), and it covered isotropic noise near rest and far from it
    (Maxwell: 97 % of 40-draw samples, against 85 % for the bound of the rate itself),
    but not noise lopsided across axes beside a residual on another axis (a reviewer's
    case: 35 to 46 % of 20- and 40-draw samples fell short, 88 % of 200-draw ones). So a
    front reads each member's figure from :data:`FRONT_FLIGHTS` flights of its own
    (:func:`~inertia_id.search.pareto.build_front`), and a command plan of 59 flights or
    more from its flights; one flight bounds nothing (inf). A flight's peak rate
    (:func:`flight_peaks`) is read the same way.
    """
    n = rates.shape[axis]
    if n >= MIN_ORDER_FLIGHTS:
        rank = order_statistic_rank(n)
        return np.take(np.sort(rates, axis=axis), n - rank, axis=axis)
    if n < 2:  # one flight bounds no spread (a constraint on it is refused: env.py)
        return np.full(np.delete(rates.shape, axis), np.inf)
    root = np.sqrt(rates)
    bound = root.mean(axis=axis) + tolerance_factor(n) * root.std(axis=axis, ddof=1)
    return np.square(bound)


def flight_peaks(rates: np.ndarray, settled: np.ndarray) -> np.ndarray:
    """Each flight's peak rate: its largest true |ω| at any sample, or once the lag has
    delivered the torque still in it when the last command ends (the settled rate).

    :param rates: (..., T, 3) a flight's true body rates at its samples, rad/s.
    :param settled: (...) its settled residual rate, rad/s.
    :returns: (...) rad/s, what :func:`per_flight_bound` reads for a peak-rate bound.
    """
    return np.maximum(np.linalg.norm(rates, axis=-1).max(axis=-1), settled)


#: Default design noise: 6x process noise (gyro at 1x), and 6x gyro noise (process at 1x).
DEFAULT_DESIGN_NOISE: tuple[tuple[float, float], ...] = ((6.0, 1.0), (1.0, 6.0))


def check_objectives(objectives: Any) -> tuple[str, ...]:
    """The objective names, checked: known, distinct, at least two (a front needs two)."""
    names = tuple(objectives)
    unknown = [n for n in names if n not in OPERATOR_OBJECTIVES]
    if unknown or len(set(names)) != len(names) or len(names) < 2:
        raise InputError(
            f"objectives must be at least two distinct names among "
            f"{list(OPERATOR_OBJECTIVES)}, got {list(names)}"
        )
    return names


def check_design_noise(design_noise: Any) -> tuple[tuple[float, float], ...]:
    """(process multiple, measurement multiple) pairs, each finite and >= 0, 1 to 8 pairs."""
    try:
        pairs = tuple((float(p), float(q)) for p, q in design_noise)
    except (TypeError, ValueError):
        raise InputError(
            f"design_noise must be a list of [process multiple, measurement multiple] pairs, "
            f"got {design_noise!r}"
        ) from None
    if not 1 <= len(pairs) <= 8 or not all(
        np.isfinite(v) and 0 <= v <= 1000 for pair in pairs for v in pair
    ):
        raise InputError(
            f"design_noise must hold 1 to 8 pairs of multiples in [0, 1000], got {design_noise!r}"
        )
    return pairs


#: The rate bounds that no sequence can bring below the initial-rate spread, with the
#: statistic of |ω(0)| each reads: the mean over flights, or the rate 95 % stay under.
_FLOOR_STATISTIC: Final = {
    "max_final_rate": "mean",
    "max_peak_rate": "mean",
    "max_final_rate_p95": "p95",
    "max_peak_rate_p95": "p95",
}


def initial_rate_floor(sigma_rad_s: float) -> dict[str, float]:
    """What the spread of the rate at the start alone leaves, rad/s: the mean of |ω(0)|
    over flights (``"mean"``, 2 σ sqrt(2/π) = 1.60 σ: ω(0) is N(0, σ² I), so |ω(0)|/σ
    is Maxwell-distributed) and the rate 95 % of flights stay under (``"p95"``, σ sqrt of
    the chi-square(3) 95th percentile = 2.80 σ).

    The all-off sequence leaves these (its residual is ω(0), the disturbance aside), and
    no open-loop sequence leaves less: a sequence adds the same change c to every flight
    and noise independent of ω(0), and for a centred Gaussian ω(0),
    P(|ω(0) + c| <= r) <= P(|ω(0)| <= r) for every r (Anderson's theorem), so neither
    the mean nor a percentile of the residual falls below ω(0)'s. (That holds while the
    gyroscopic coupling over the sequence is small, as it is at rates a spread of a few
    mrad/s gives.)
    """
    from scipy.stats import chi2

    sigma = float(sigma_rad_s)
    return {
        "mean": 2.0 * sigma * float(np.sqrt(2.0 / np.pi)),
        "p95": sigma * float(np.sqrt(chi2.ppf(FLIGHT_QUANTILE, 3))),
    }


#: Draws behind :func:`rest_rate_floor`'s figures (their error: about 0.1 % of the mean
#: and 0.2 % of the 95th percentile), from a fixed seed, so a bound is judged alike each
#: time.
_FLOOR_DRAWS: Final = 1 << 18


def rest_rate_floor(scenario: Any, sequence_length: int) -> dict[str, float]:
    """What the all-off sequence of ``sequence_length`` steps leaves, rad/s, for the
    candidate it leaves fastest: the mean over flights of |ω| at the end (``"mean"``) and
    the rate 95 % of flights stay under (``"p95"``). Its end rate is ω(0) plus the
    disturbance torque's random walk over the sequence (a torque of σ_M held over
    intervals δ: covariance σ_M² δ T I⁻¹I⁻ᵀ after T seconds), a centred Gaussian, and no
    open-loop sequence leaves less (Anderson's theorem, as :func:`initial_rate_floor`
    says; the firings add their jitter's noise on top).

    Drawn, not integrated: the mean and the percentile of the length of an anisotropic
    Gaussian have no closed form (:func:`initial_rate_floor` gives the isotropic one).
    Checked against the search's own scorer, 1,000 realisations of the all-off sequence:
    paper preset at L = 2, 3.66e-4 rad/s here against 3.67e-4 (p95 6.71e-4 against the
    order statistic's 6.95e-4).
    """
    unc = scenario.uncertainty
    duration = float(sequence_length) * float(scenario.timing.step_duration_s)
    walk = unc.disturbance_torque_sigma_nm**2 * unc.disturbance_interval_s * duration
    inertia = np.ascontiguousarray(scenario.inertia_array, dtype=float)
    mean, p95 = _rest_rate_floor(
        float(walk), float(unc.initial_rate_sigma_rad_s), inertia.tobytes(), len(inertia)
    )
    return {"mean": mean, "p95": p95}


@functools.lru_cache(maxsize=256)
def _rest_rate_floor(
    walk: float, initial_sigma: float, inertia: bytes, candidates: int
) -> tuple[float, float]:
    """:func:`rest_rate_floor` by its inputs, kept: a search's submission checks it in the
    request (0.27–0.37 s a call on the paper presets, measured on the 2-core machine
    with tests running beside it; 10 µs once kept), and the same scenario and length
    come back with every search of them."""
    start = initial_sigma**2 * np.eye(3)
    draws = _floor_draws()
    mean = p95 = 0.0
    for matrix in np.frombuffer(inertia, dtype=float).reshape(candidates, 3, 3):
        inverse = np.linalg.inv(matrix)
        covariance = walk * inverse @ inverse.T + start
        lengths = np.linalg.norm(draws @ np.linalg.cholesky(covariance).T, axis=1)
        mean = max(mean, float(lengths.mean()))
        p95 = max(p95, float(np.quantile(lengths, FLIGHT_QUANTILE)))
    return mean, p95


@functools.cache
def _floor_draws() -> np.ndarray:
    """The standard normals behind every floor, from a fixed seed (drawn once: 6 MiB)."""
    draws = np.random.default_rng(0).standard_normal((_FLOOR_DRAWS, 3))
    draws.setflags(write=False)
    return draws


def check_rate_floor(
    constraints: dict[str, float], scenario: Any, sequence_length: int | None = None
) -> None:
    """Refuse a rate bound below what the scenario's initial-rate spread alone leaves
    (:func:`initial_rate_floor`): no sequence meets it, the all-off one included, and a
    search would only report that none did. With ``sequence_length``, also one below
    what the disturbance torque adds over that many steps (:func:`rest_rate_floor`):
    before, a bound of 0.01 deg/s on the paper preset (the all-off sequence of 2 steps
    leaves 0.021) ran the whole search, then advised searching longer.

    :param constraints: checked bounds (:func:`check_constraints`).
    :raises InputError: naming the constraint, its bound, the floor in its unit and
        ``initial_rate_sigma_rad_s`` (or the disturbance's figures).
    """
    sigma = float(scenario.uncertainty.initial_rate_sigma_rad_s)
    if sigma > 0.0:
        _check_floor(constraints, initial_rate_floor(sigma), None, sigma)
    unc = scenario.uncertainty
    bounded = any(_floor_statistic(name) is not None for name in constraints)
    if bounded and sequence_length is not None and unc.disturbance_torque_sigma_nm > 0.0:
        floor = rest_rate_floor(scenario, sequence_length)
        _check_floor(constraints, floor, (scenario, sequence_length), sigma)


def _floor_statistic(name: str) -> str | None:
    """The statistic of |ω| a rate constraint reads, where a floor bounds it; else None."""
    return _FLOOR_STATISTIC.get(name.removesuffix("_s").removesuffix("_rad").removesuffix("_deg"))


def _check_floor(
    constraints: dict[str, float],
    floor: dict[str, float],
    disturbed: tuple[Any, int] | None,
    sigma: float,
) -> None:
    for name, bound in constraints.items():
        statistic = _floor_statistic(name)
        if statistic is None:
            continue
        factor = CONSTRAINTS[name][2]  # bound * factor is rad/s
        least = floor[statistic] / factor  # in the constraint's unit
        if bound < least:
            unit_text = "deg/s" if name.endswith("_deg_s") else "rad/s"
            what = "mean over flights" if statistic == "mean" else "rate 95 % of flights stay under"
            if disturbed is not None:
                scenario, length = disturbed
                unc = scenario.uncertainty
                duration = length * scenario.timing.step_duration_s
                spread = f" and initial_rate_sigma_rad_s = {sigma:g}" if sigma > 0 else ""
                raise InputError(
                    f"constraint {name} = {bound:g} {unit_text} is below what the "
                    f"disturbance torque alone leaves over the sequence's {duration:g} s "
                    f"({what} of |ω| after the all-off sequence, the candidate it leaves "
                    f"fastest: {least:.4g} {unit_text} for disturbance_torque_sigma_nm = "
                    f"{unc.disturbance_torque_sigma_nm:g} redrawn every "
                    f"{unc.disturbance_interval_s:g} s{spread}): no sequence, the all-off "
                    f"one included, can meet it; raise the bound to at least {least:.4g} "
                    f"{unit_text}"
                )
            raise InputError(
                f"constraint {name} = {bound:g} {unit_text} is below what the scenario's "
                f"initial-rate spread alone leaves ({what} of |ω(0)|: {least:.4g} {unit_text} "
                f"for initial_rate_sigma_rad_s = {sigma:g}): no sequence, the all-off one "
                f"included, can meet it; raise the bound to at least {least:.4g} {unit_text} "
                f"or give the scenario's true initial-rate spread"
            )


def check_constraints(constraints: Any, scenario: Any = None) -> dict[str, float]:
    """Constraint bounds by name (:data:`CONSTRAINTS`), finite and >= 0; a propellant bound
    needs a scenario that states thrust and specific impulse."""
    if constraints is None:
        return {}
    if not isinstance(constraints, dict):
        raise InputError(f"constraints must be a mapping of name to bound, got {constraints!r}")
    out = {}
    for name, bound in constraints.items():
        if name not in CONSTRAINTS:
            raise InputError(f"unknown constraint {name!r}; known: {sorted(CONSTRAINTS)}")
        # is_number, not np.isfinite: a whole number past int64 (the command line reads
        # 1e20 as one) made np.isfinite raise a TypeError with a traceback.
        if not is_number(bound, minimum=0.0):
            raise InputError(f"constraint {name} must be a finite number >= 0, got {bound!r}")
        if name == "min_accuracy" and bound > 1:
            raise InputError(f"constraint min_accuracy is a fraction in [0, 1], got {bound!r}")
        out[name] = float(bound)
    for figure in (
        "final_rate",
        "final_rate_p95",
        "commanded_residual_rate",
        "commanded_residual_rate_max",
        "peak_rate",
        "peak_rate_p95",
    ):
        both = [f"max_{figure}_rad_s", f"max_{figure}_deg_s"]
        if all(name in out for name in both):
            raise InputError(
                f"constraints {both[0]} = {out[both[0]]:g} and {both[1]} = {out[both[1]]:g} "
                "bound the same rate; give one"
            )
    if "max_propellant_kg" in out and scenario is not None:
        if scenario.thrust_per_thruster_n is None or scenario.thrusters.specific_impulse_s is None:
            raise InputError(
                "constraint max_propellant_kg needs the scenario's thrusters to state thrust_n "
                "(or lever_arm_m) and specific_impulse_s"
            )
    return out


def _deg_or_none(rad_s: float | None) -> float | None:
    return None if rad_s is None else rad_s * _DEG


@dataclass(frozen=True)
class SequenceScores:
    """What an operator asks of one sequence, on one noise draw.

    :param accuracy: accuracy of the Bayes classifier, the mean over the design-noise
        conditions, in [0, 1]: predicted (:class:`~inertia_id.search.noise_model.
        LinearNoiseModel`) while searching, measured on fresh test series for a front's
        members and baselines.
    :param accuracy_by_noise: the same at each design condition, in their order.
    :param final_rate_rad_s: the residual |ω|, once the actuation lag has delivered the
        torque still in it when the last command ends
        (:func:`~inertia_id.physics.simulate.settled_rates`), mean over candidates of
        each candidate's rate: the larger of its mean over realisations at the
        scenario's own noise and the command plan's noise-free prediction.
    :param final_rate_max_rad_s: the same, for the candidate that ends fastest: what the
        ``max_final_rate`` constraints bound (so a bound holds on the plan and on average
        over the noise; single realisations spread around that mean).
    :param final_rate_p95_rad_s: a residual rate at least 95 % of flights stay under,
        with 95 % confidence, of the candidate whose flights end fastest, at least its
        ``final_rate`` figure (:func:`per_flight_bound`): on a front, the order statistic
        of :data:`FRONT_FLIGHTS` flights of its own, whatever the distribution; on a
        search's draw, the normal proxy from its realisations. What the
        ``max_final_rate_p95`` constraints bound. None in scores stored before it.
    :param commanded_residual_rate_rad_s: the part of the residual rate the sequence
        itself leaves: the command plan's noise-free prediction from rest (ω(0) = 0, no
        disturbance, duty jitter or thrust-scale error), mean over candidates. Beside a
        scenario's initial-rate spread (``initial_rate_sigma_rad_s``) the ``final_rate``
        figures include |ω(0)|, which no open-loop sequence removes (its mean 1.60 σ):
        when that floor dominates, this figure tells a sequence that brakes from one
        that does not. What the ``max_commanded_residual_rate`` constraints bound (the
        ``max_final_rate`` ones hold the total); no objective reads it. None in scores
        stored before it.
    :param commanded_residual_rate_max_rad_s: the same, of the candidate the commands
        leave fastest: what the ``max_commanded_residual_rate_max`` constraints bound.
        None in scores stored before it.
    :param peak_rate_rad_s: the largest |ω| during the sequence or after it, while the
        lag delivers the torque still in it, of the candidate that spins fastest: the
        larger of the mean over realisations and the plan's prediction.
    :param peak_rate_p95_rad_s: a peak rate (each flight's own largest |ω|, during the
        sequence or once settled) at least 95 % of flights stay under, with 95 %
        confidence, of the candidate whose flights spin fastest, at least the
        ``peak_rate`` figure: read as ``final_rate_p95_rad_s`` is (on a front, the order
        statistic of its own flights; on a search's draw, the normal proxy). What the
        ``max_peak_rate_p95`` constraints bound. None in scores stored before it.
    :param impulse_nms: commanded angular impulse summed over thrusters (every firing
        counts, opposed or not): a propellant proxy.
    :param on_time_s: thruster on-time summed over thrusters.
    :param propellant_kg: propellant mass, when the scenario gives thrust and Isp.
    :param duration_s: length of the sequence.
    :param attitude_change_deg: the rotation the body makes over the sequence (angle of
        the final attitude quaternion from the nominal rates, the candidate that turns
        most), degrees.
    :param predicted_accuracy_by_noise: when ``accuracy`` was measured on fresh test
        series (a front's members), the prediction it replaced; None otherwise.
    :param accuracy_bound: with a predicted ``accuracy``, the union bound's ``1 - error``
        it comes from, mean over the conditions, not raised to chance (1/K): below
        chance it still ranks the sequences by how far apart they hold the candidates
        (:attr:`ranking_accuracy`); None for a measured accuracy. Not stored.
    """

    accuracy: float
    accuracy_by_noise: list[float]
    final_rate_rad_s: float
    final_rate_max_rad_s: float
    peak_rate_rad_s: float
    impulse_nms: float
    on_time_s: float
    propellant_kg: float | None
    duration_s: float
    attitude_change_deg: float
    predicted_accuracy_by_noise: list[float] | None = None
    final_rate_p95_rad_s: float | None = None
    peak_rate_p95_rad_s: float | None = None
    commanded_residual_rate_rad_s: float | None = None
    commanded_residual_rate_max_rad_s: float | None = None
    accuracy_bound: float | None = None

    @property
    def ranking_accuracy(self) -> float:
        """The accuracy as the search ranks and compares sequences: the prediction's
        bound where there is one, else the accuracy. The two are equal wherever the
        prediction lies above chance. At a design noise where every prediction is raised
        to chance (K = 5: 0.2), the accuracy alone told no sequence apart, and the one
        that fires nothing, cheapest and slowest, dominated the front alone, while
        sequences that fire measured 0.34-0.41 on the same series."""
        return self.accuracy if self.accuracy_bound is None else self.accuracy_bound

    @property
    def final_rate_deg_s(self) -> float:
        return self.final_rate_rad_s * _DEG

    @property
    def peak_rate_deg_s(self) -> float:
        return self.peak_rate_rad_s * _DEG

    def figure(self, name: str) -> float:
        value = getattr(self, name)
        return float("nan") if value is None else float(value)

    def objective_vector(self, objectives: tuple[str, ...]) -> np.ndarray:
        """The objectives as a vector to minimise (accuracy negated)."""
        out = []
        for name in objectives:
            field = OBJECTIVE_FIELDS[name]
            value = self.ranking_accuracy if field == "accuracy" else self.figure(field)
            out.append(-value if OPERATOR_OBJECTIVES[name][1] == "max" else value)
        return np.asarray(out)

    def violations(self, constraints: dict[str, float]) -> np.ndarray:
        """Each constraint's violation (:func:`constraint_violation`, <= 0 holds), in
        order."""
        return np.asarray(
            [
                constraint_violation(name, self.figure(CONSTRAINTS[name][0]), bound)
                for name, bound in constraints.items()
            ]
        )

    def feasible(self, constraints: dict[str, float]) -> bool:
        return bool(np.all(self.violations(constraints) <= 0.0))

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SequenceScores:
        """The scores :meth:`as_dict` wrote (its derived deg/s figures dropped)."""
        return cls(**{f.name: data[f.name] for f in fields(cls) if f.name in data})

    def as_dict(self) -> dict[str, Any]:
        return {
            "accuracy": self.accuracy,
            "accuracy_by_noise": list(self.accuracy_by_noise),
            "final_rate_rad_s": self.final_rate_rad_s,
            "final_rate_deg_s": self.final_rate_deg_s,
            "final_rate_max_rad_s": self.final_rate_max_rad_s,
            "final_rate_max_deg_s": self.final_rate_max_rad_s * _DEG,
            "final_rate_p95_rad_s": self.final_rate_p95_rad_s,
            "final_rate_p95_deg_s": None
            if self.final_rate_p95_rad_s is None
            else self.final_rate_p95_rad_s * _DEG,
            "commanded_residual_rate_rad_s": self.commanded_residual_rate_rad_s,
            "commanded_residual_rate_deg_s": _deg_or_none(self.commanded_residual_rate_rad_s),
            "commanded_residual_rate_max_rad_s": self.commanded_residual_rate_max_rad_s,
            "commanded_residual_rate_max_deg_s": _deg_or_none(
                self.commanded_residual_rate_max_rad_s
            ),
            "peak_rate_rad_s": self.peak_rate_rad_s,
            "peak_rate_deg_s": self.peak_rate_deg_s,
            "peak_rate_p95_rad_s": self.peak_rate_p95_rad_s,
            "peak_rate_p95_deg_s": None
            if self.peak_rate_p95_rad_s is None
            else self.peak_rate_p95_rad_s * _DEG,
            "impulse_nms": self.impulse_nms,
            "on_time_s": self.on_time_s,
            "propellant_kg": self.propellant_kg,
            "duration_s": self.duration_s,
            "attitude_change_deg": self.attitude_change_deg,
            "predicted_accuracy_by_noise": None
            if self.predicted_accuracy_by_noise is None
            else list(self.predicted_accuracy_by_noise),
        }
