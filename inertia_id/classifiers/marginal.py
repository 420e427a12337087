"""The marginal-likelihood classifier: the Bayes rule when the noise level is unknown.

The likelihood classifier (:mod:`inertia_id.classifiers.likelihood`) is the best a classifier can
do *at the noise level it was fitted at*. A deployed classifier does not know the level:
fitted at 1x, it over-trusts directions that grow with the noise (on the paper preset
at 8x process noise it falls 2 to 10 points short of a likelihood fitted at 8x). With
the level m unknown, the Bayes rule ranks candidates by the marginal likelihood

    p(x | k) = Σ_m w_m N(x; μ_k, Σ_m),

a mixture over a grid of noise conditions m (a process-noise multiple and a
measurement-noise multiple), here with equal weights w_m = 1 / M: over a geometric
grid that is a log-uniform prior on each multiple, no scale of noise preferred to
another. In 240 dimensions one series pins its noise level down to a few per cent, so
the mixture is dominated by the conditions nearest the true one and the rule behaves
like the likelihood classifier fitted at the right level.

The default grid (:data:`JOINT_GRID`) crosses process multiples 1, 2, 4, 8 with
measurement multiples 1 to 8 in thirds of an octave (40 conditions), so that both
noises may be up at once. Accuracy hardly depends on the grid (on the paper preset the
axes grid of 7 conditions, octaves, one noise at a time, classifies as well at every
one-noise point, and 2 to 3 points worse with both noises at 4x to 6x), but the
novelty distance below does on the measurement side: white gyro noise in 240 samples
fixes its level so sharply that a level between two octaves looks odd at both (genuine
series at 3x measurement noise exceed the novelty threshold 3 % of the time with
octaves, never with thirds), whereas the process noise acts in a few smooth directions
and octaves suffice.

Noise components, not one covariance per condition. The simulator draws standard normal
numbers and scales them (:mod:`inertia_id.physics.simulate`), so simulating the same
realisations three times from the same generator state, with process and measurement
noise off, with only process noise at 1x, and with only measurement noise at 1x,
isolates each source's contribution to every series exactly. The responses are linear in
both (on the paper preset 8x the process noise gives 8x its 1x response to 0.08 %), and
the sources are independent, so the pooled covariance at any condition is

    Σ(p, q) = Σ_quiet + p² Σ_process + q² Σ_measurement,

where Σ_quiet holds what neither multiple scales (duty jitter, thrust scale errors,
initial rates). Each component is the pooled sample covariance of its isolated
residuals, shrunk towards ``(tr S / dim) I`` by the likelihood classifier's cross-
validated rule. For white gyro noise that rule chooses full shrinkage, i.e. σ² I
estimated from every number at once (a random gyro bias, which the simulator scales with
the gyro noise, is kept apart as a constant per axis: :func:`_white_and_bias`); the
smooth quiet component gets almost none (0.001 to 0.02). The process component is
shrunk towards the covariance the scenario's disturbance torque gives the rates,
written out (:func:`_process_target`), rather than towards the identity: its random walk
has full rank, which 100 residuals cannot estimate in 3 T dimensions, and the same rule
chooses that target outright on the paper preset (6x process noise on a 480-value
braking sequence: 0.948 shrunk towards the identity, 0.958 towards the target, against a
ceiling of 0.962; ``bench/process_target.py``). Three matrices then
serve any grid, and the white measurement noise, which a per-condition sample covariance
must estimate (badly, in 240 dimensions), is known almost exactly. The candidates' mean
responses, shared by every condition (the mean does not move with the noise level, to
sampling error), are estimated from the quiet run, whose series vary least.

Distances and novelty: :meth:`MarginalLikelihoodClassifier.transform` gives the
*marginal Mahalanobis distance* ``sqrt(2 (log ν_m̂ - log p(x | k)))``, where m̂ is the
series' most probable condition (over every candidate) and ``ν_m̂ = w_m̂ N(0; 0, Σ_m̂)``
that condition's peak density. The subtracted term is the same for every candidate, so
the distances rank candidates exactly as the marginal likelihood does; with one
condition they are the Mahalanobis distances; and a genuine series lies at about the
same distance (the square root of a chi-square with 240 degrees of freedom, 15.5 ± 0.7)
whatever its noise level, where the likelihood classifier's distances grow with it (at
4x measurement noise every genuine series lies beyond its 1x novelty threshold). A
series "matches none" when it is farther from its nearest candidate than
``novelty_factor`` times the largest out-of-fold distance of the candidate's own
training series, synthesised at the quietest and noisiest conditions of the grid. The
default factor, 1.1, leaves 2 to 3 standard deviations of that chi beyond the largest
training distance: on the paper preset no genuine series was flagged at any level of
the grid (500 per level, three sequences).

Not knowing the noise level has a price: a misfit that some condition of the grid would
explain is accepted by the distance. On the paper preset at 1x noise, a body with the
inertia of candidate 0 scaled by 0.6 is beyond the novelty threshold on the three
sequences tried, 0.7 on two, 1.3 and 1.4 on one, and 0.8, 0.9 and 1.1 never (they look
like a known body at high process noise), where the 1x likelihood flags 0.6 to 0.8 and
1.1 to 1.4.

"None of these" therefore has a proper model beside the distance's novelty bound
(:meth:`MarginalLikelihoodClassifier.near_none_log_bayes`): another body near the
candidates, its six inertia parameters drawn around a candidate's (standard deviation
``none_spread``, default 0.2, of the candidate's mean principal moment), the response
linearised in them (:func:`inertia_sensitivity`, simulated without noise at fit time) and
marginalised exactly over the same noise grid. Both hypotheses may then call on the high
process noise; what tells them apart is that the other body explains the misfit in the
few directions an inertia change moves the response, at the noise the series shows. On
the paper preset with the hand-designed sequence, Basilisk telemetry at 10 to 200 Hz of
bodies 10 % (Frobenius) from every candidate is flagged every time (never before), and
no genuine series is (bench/telemetry_identify.py). Its power depends on the sequence:
with one axis at a time (1 s each) half the series of 1.1 times candidate 0 are flagged.
The posterior's "none" is this model or something else entirely, with equal weight
(:meth:`~inertia_id.classifiers.base.BaseClassifier.posterior_from_distances`).

Every quantity the distances need (means, the three components) is stored as JSON with
a SHA-256 checksum; nothing is pickled.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any, ClassVar, Self

import numpy as np

from ..errors import InputError
from ..physics.estimate import parameters_from_tensor, tensor_from_parameters
from ..physics.scenario import AS_TRAINED, Scenario
from ..physics.series import check_series
from ..physics.simulate import Simulator, disturbance_rate_covariance, simulate
from ..stopping import Checkpoint, no_checkpoint
from . import gaussian
from .base import BaseClassifier, is_number
from .gaussian import log_softmax, logsumexp

__all__ = [
    "AXES_GRID",
    "COMPONENTS",
    "DEFAULT_NONE_SPREAD",
    "JOINT_GRID",
    "MEASUREMENT_MULTIPLES",
    "PROCESS_MULTIPLES",
    "PROCESS_TARGETS",
    "MarginalLikelihoodClassifier",
    "inertia_sensitivity",
    "train_marginal",
]

#: What the process component may be shrunk towards: the covariance the scenario's
#: disturbance writes out (the default; where it cannot, the identity), or the identity.
PROCESS_TARGETS = ("disturbance model", "isotropic")
#: The noise sources a covariance is split into, in storage order.
COMPONENTS = ("quiet", "process", "measurement")
_OCTAVES = (1.0, 2.0, 4.0, 8.0)
#: Process-noise multiples of the default grid: octaves 1 to 8.
PROCESS_MULTIPLES = _OCTAVES
#: Measurement-noise multiples of the default grid: thirds of an octave, 1 to 8.
MEASUREMENT_MULTIPLES = tuple(2.0 ** (i / 3) for i in range(10))
#: The default grid, every pair of the two: 40 conditions.
JOINT_GRID = tuple((p, q) for p in PROCESS_MULTIPLES for q in MEASUREMENT_MULTIPLES)
#: One noise at a time, the other at 1x, in octaves, as a noise sweep visits them.
AXES_GRID = ((1.0, 1.0), *((m, 1.0) for m in _OCTAVES[1:]), *((1.0, m) for m in _OCTAVES[1:]))
_LOG_2PI = math.log(2.0 * math.pi)
#: Batches of at most this many series keep their whitening and joint density for the
#: next question about the same series: a verdict asks for the distances, the
#: log-likelihood and the near-none model of each (identify: one series; the sweep of
#: bodies off the candidates: 100 a body in the bench, where the three whitenings were
#: most of the cost). A training batch is larger and is not held.
_CACHED_SERIES = 128
#: Prior spread of another body's inertia parameters around a candidate's, as a fraction
#: of its mean principal moment (the "none of these" model, ``none_spread``).
DEFAULT_NONE_SPREAD = 0.2


def _symmetric(matrix: np.ndarray) -> np.ndarray:
    """The symmetric matrix of ``matrix``'s lower triangle: what storage keeps."""
    lower = np.tril(matrix)
    return lower + np.tril(lower, -1).T


def _component_document(matrix: np.ndarray) -> dict[str, Any]:
    """One covariance component as data: a scalar when it is a multiple of I."""
    diagonal = np.diag(matrix)
    if np.all(diagonal == diagonal[0]) and not np.any(matrix - np.diag(diagonal)):
        return {"isotropic_rad2_s2": float(diagonal[0])}
    return {"lower_rad2_s2": matrix[np.tril_indices(len(matrix))].tolist()}


def _component_from_document(data: dict[str, Any], dim: int) -> np.ndarray:
    if "isotropic_rad2_s2" in data:
        return float(data["isotropic_rad2_s2"]) * np.eye(dim)
    lower = np.asarray(data["lower_rad2_s2"], dtype=float)
    if lower.shape != (dim * (dim + 1) // 2,):
        raise InputError(
            f"{lower.size} covariance entries for {dim} dimensions "
            f"(expected {dim * (dim + 1) // 2})"
        )
    matrix = np.zeros((dim, dim))
    matrix[np.tril_indices(dim)] = lower
    return _symmetric(matrix)


#: A per-axis constant (gyro bias) in the measurement part is modelled apart from the white
#: noise when its coefficients' variance exceeds the white noise's by this many standard
#: errors of a variance estimate.
_BIAS_SIGNIFICANCE = 4.0


def _process_target(scenario: Scenario | None, sequence: Any, dim: int) -> np.ndarray | None:
    """What the process component is shrunk towards: the covariance the scenario's
    disturbance torque gives the rates, written out
    (:func:`~inertia_id.physics.simulate.disturbance_rate_covariance`); None (shrink
    towards the identity, as before) without a scenario or where it does not fit.

    Why a target from the model: the disturbance's random walk has a covariance of full
    rank, which 100 residuals per candidate cannot estimate in 3 T dimensions (a fifth of
    it at L = 8 on the paper preset), and shrinking towards the identity cannot restore
    its structure. The written-out covariance neglects how the gyroscopic coupling
    carries the noise between axes, so the cross-validated intensity decides how far to
    trust it; on the paper preset it chooses the target outright. A tiny ridge (1e-9 of
    the mean variance) keeps the target invertible where the disturbance intervals are
    fewer than the samples (its rank is 3 per interval).
    """
    if scenario is None or sequence is None:
        return None
    target = disturbance_rate_covariance(scenario, len(sequence))
    if target.shape != (dim, dim):
        return None
    ridge = 1e-9 * float(np.trace(target)) / dim
    if not ridge > 0.0:
        return None  # no disturbance: nothing to model
    target[np.diag_indices(dim)] += ridge
    return target


def _white_and_bias(residuals: np.ndarray, n_candidates: int) -> np.ndarray | None:
    """The measurement part's covariance as white noise plus a constant per-axis bias,
    ``σ² (I - P) + U C Uᵀ``, or None when no bias stands out of the white noise.

    The simulator scales the random gyro bias with the gyro noise, so the measurement
    part holds both: a shrinkage towards ``(tr S / dim) I`` would spread the bias's
    variance over every direction (with the paper preset's 2e-3 rad/s bias it took the
    white variance 1.6 times too high, so genuine series at 1x lay nearer their candidate
    than at any other noise level). ``U`` holds the unit per-axis constants
    ``1 / sqrt(length)`` (``P = U Uᵀ``), ``C`` the pooled covariance of the residuals'
    coefficients on them (3 x 3), ``σ²`` the residual variance off them.

    :param residuals: (n, dim) measurement parts less their candidate's mean, flattened
        as (length, 3) series.
    """
    n, dim = residuals.shape
    length = dim // 3
    dof = max(n - n_candidates, 1)
    series = residuals.reshape(n, length, 3)
    coefficients = series.sum(axis=1) / math.sqrt(length)  # (n, 3): on U
    off = series - series.mean(axis=1, keepdims=True)
    white = float(np.sum(off**2)) / (dof * 3 * (length - 1))
    bias = coefficients.T @ coefficients / dof
    if not np.all(np.diag(bias) > white * (1.0 + _BIAS_SIGNIFICANCE * math.sqrt(2.0 / dof))):
        return None
    constants = np.zeros((dim, 3))
    for axis in range(3):
        constants[axis::3, axis] = 1.0 / math.sqrt(length)
    return np.asarray(
        white * (np.eye(dim) - constants @ constants.T) + constants @ bias @ constants.T
    )


def _unit_updates_inverse(steps: list[_UnitUpdate], values: np.ndarray) -> np.ndarray:
    """``K_r⁻¹ ... K_1⁻¹ values`` for every condition, ``K`` the lower Cholesky factor of
    ``I + g gᵀ`` of each step (:meth:`_Mixture.updated`): ``(K⁻¹ y)_i = sqrt(β_i-1 / β_i)
    y_i - g_i / sqrt(β_i β_i-1) (g_1 y_1 + ... + g_i-1 y_i-1)``, ``β_i = 1 + g_1² + ... +
    g_i²``.

    :param steps: each step's ``g``, ``sqrt(β_i-1 / β_i)`` and ``g_i / sqrt(β_i β_i-1)``,
        each (M, dim).
    :param values: (M, dim, n).
    """
    # (M, n, dim): the cumulative sum runs along contiguous memory. A copy, always: it
    # is updated in place, and ``values`` may be a mixture's own (its white means).
    out = np.swapaxes(values, 1, 2).copy(order="C")
    for g, scale, coefficient in steps:
        weighted = g[:, None, :] * out
        before = np.empty_like(weighted)
        before[..., 0] = 0.0
        np.cumsum(weighted[..., :-1], axis=2, out=before[..., 1:])
        out *= scale[:, None, :]
        out -= coefficient[:, None, :] * before
    return np.swapaxes(out, 1, 2)


#: One rank-one step of :meth:`_Mixture.updated`: ``g``, ``sqrt(β_i-1 / β_i)``, ``g_i /
#: sqrt(β_i β_i-1)``, each (M, dim).
_UnitUpdate = tuple[np.ndarray, np.ndarray, np.ndarray]


class _Mixture:
    """The per-condition whitening of one set of means and components.

    :param means: (K, dim) flattened mean responses, rad/s.
    :param components: (3, dim, dim) quiet, process and measurement covariances at 1x.
    :param grid: (M, 2) process and measurement multiples of each condition.
    """

    #: An updated mixture's (:meth:`updated`) whitening: the mixture it updates and the
    #: steps that take that one's whitened values to its own; None for a factored one.
    _update: tuple[_Mixture, list[_UnitUpdate]] | None = None

    def __init__(
        self,
        means: np.ndarray,
        components: np.ndarray,
        grid: np.ndarray,
        checkpoint: Checkpoint = no_checkpoint,
    ) -> None:
        """Factor every condition of ``grid``; ``checkpoint`` is called before each (a
        training's, :mod:`inertia_id.stopping`: 40 factorisations in the joint grid)."""
        dim = means.shape[1]
        # Shared with reweighted copies, like the near-none factors.
        self._formed: dict[str, np.ndarray] = {}
        self._formed["whiteners"] = np.empty((len(grid), dim, dim))
        self.white_means = np.empty((len(grid), len(means), dim))
        self.log_norm = np.empty(len(grid))
        # The near-none model's factors by sensitivity, shared with reweighted copies
        # (they do not depend on the weights).
        self._near_cache: dict[str, Any] = {}
        #: log w_m of each condition: equal weights 1 / M unless :meth:`reweighted`.
        self.log_weights = np.full(len(grid), -math.log(len(grid)))
        # log of the Cholesky factor's diagonal: the leading block of a Cholesky factor
        # is the factor of the leading block, so these give every prefix's determinant.
        self.log_diagonal = np.empty((len(grid), dim))
        with gaussian.one_blas_thread():
            for c, (process, measurement) in enumerate(grid):
                checkpoint()
                self._factor(c, components, process, measurement, means)

    def _factor(
        self,
        c: int,
        components: np.ndarray,
        process: float,
        measurement: float,
        means: np.ndarray,
    ) -> None:
        """Whiten condition ``c``: its covariance's inverse factor, white means and norm."""
        dim = means.shape[1]
        covariance = components[0] + process**2 * components[1] + measurement**2 * components[2]
        try:
            chol = gaussian.cholesky(covariance)
            self.whiteners[c] = gaussian.inverse_cholesky(chol)
        except InputError as exc:
            raise InputError(
                f"at process x{process:g}, measurement x{measurement:g}: {exc}"
            ) from None
        self.white_means[c] = means @ self.whiteners[c].T
        self.log_diagonal[c] = np.log(np.diag(chol))
        log_det = 2.0 * float(np.sum(self.log_diagonal[c]))
        # log w_m - log det(2π Σ_m) / 2, with equal weights w_m = 1 / M.
        self.log_norm[c] = self.log_weights[c] - 0.5 * (log_det + dim * _LOG_2PI)

    @property
    def whiteners(self) -> np.ndarray:
        """(M, dim, dim) the inverse Cholesky factor of every condition's covariance; an
        updated mixture's formed when first asked for (the prefixes, identify_online),
        not by :meth:`updated`, whose verdicts need the whitening of a few vectors only."""
        if "whiteners" not in self._formed:
            assert self._update is not None
            base, steps = self._update
            self._formed["whiteners"] = _unit_updates_inverse(steps, base.whiteners)
        return self._formed["whiteners"]

    def whiten(self, columns: np.ndarray) -> np.ndarray:
        """``W_m columns`` for every condition's whitener ``W_m``, (M, dim, n), from (dim, n)."""
        if self._update is None:
            return np.asarray(self.whiteners @ columns)
        base, steps = self._update
        return _unit_updates_inverse(steps, base.whiten(columns))

    def updated(self, columns: np.ndarray) -> _Mixture:
        """This mixture with every condition's covariance plus ``X_m X_mᵀ``, ``X_m =
        columns[m]`` (M, dim, r), r small: the same means, equal weights.

        Exact, and without refactoring a dim x dim covariance: with ``L`` this one's
        Cholesky factor and ``g = L⁻¹ x``, ``L Lᵀ + x xᵀ = L (I + g gᵀ) Lᵀ``, and ``I + g
        gᵀ`` has a lower Cholesky factor ``K`` known in closed form (``K_jj =
        sqrt(β_j / β_j-1)``, ``K_ij = g_i g_j / sqrt(β_j β_j-1)`` below the diagonal,
        ``β_j = 1 + g_1² + ... + g_j²``). ``L K`` is lower triangular with a positive
        diagonal, so it *is* the updated covariance's Cholesky factor (the factor is
        unique): its whitening is ``K⁻¹ L⁻¹``, whose ``K⁻¹`` takes a cumulative sum
        (:func:`_unit_updates_inverse`), and its log-diagonal is this one's plus ``log
        diag K``, prefixes included. One column after another for rank r. The verdicts'
        numbers are those of factoring the updated covariance afresh, to rounding
        (tests/classifiers/test_marginal.py and tests/evaluation/test_identify_start.py
        compare them).
        """
        n_conditions, dim, rank = columns.shape
        pending = self.whiten(columns)  # (M, dim, r): g of the first column
        steps: list[_UnitUpdate] = []
        log_diagonal = self.log_diagonal.copy()
        for _ in range(rank):
            g = np.ascontiguousarray(pending[:, :, 0])
            beta = 1.0 + np.concatenate(
                [np.zeros((n_conditions, 1)), np.cumsum(g**2, axis=1)], axis=1
            )
            steps.append(
                (g, np.sqrt(beta[:, :-1] / beta[:, 1:]), g / np.sqrt(beta[:, 1:] * beta[:, :-1]))
            )
            log_diagonal += 0.5 * (np.log(beta[:, 1:]) - np.log(beta[:, :-1]))
            # The next column's g: under the factor updated so far.
            pending = _unit_updates_inverse(steps[-1:], pending[:, :, 1:])
        mixture = copy.copy(self)
        mixture.__dict__ = {
            k: v for k, v in self.__dict__.items() if k not in ("_white_cache", "_joint_cache")
        }
        mixture._update = (self, steps)
        mixture._formed = {}
        mixture._near_cache = {}
        mixture.log_diagonal = log_diagonal
        white_means = _unit_updates_inverse(steps, np.swapaxes(self.white_means, 1, 2))
        mixture.white_means = np.ascontiguousarray(np.swapaxes(white_means, 1, 2))
        log_det = 2.0 * np.sum(log_diagonal, axis=1)
        mixture.log_norm = self.log_weights - 0.5 * (log_det + dim * _LOG_2PI)
        return mixture

    def reweighted(self, log_weights: np.ndarray) -> _Mixture:
        """The same mixture with condition weights ``exp(log_weights)`` (they sum to 1):
        a posterior over the noise conditions from data the mixture does not see (the
        telemetry before the sequence start). The whitening is shared, not redone."""
        mixture = copy.copy(self)
        mixture.__dict__.pop("_joint_cache", None)
        mixture.log_weights = np.asarray(log_weights, dtype=float)
        mixture.log_norm = self.log_norm - self.log_weights + mixture.log_weights
        return mixture

    def whitened(self, F: np.ndarray) -> np.ndarray:
        """F whitened in every condition, (M, n, dim). The last series' whitening is
        kept: one verdict asks for the distances, the log-likelihood and the near-none
        model of the same series, and the 40 matrix products are most of its cost."""
        F = np.ascontiguousarray(F, dtype=float)
        key = (F.shape, F.tobytes())
        cached = getattr(self, "_white_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        if self._update is None:
            white = F[None] @ np.swapaxes(self.whiteners, 1, 2)  # (M, n, dim)
        else:
            white = np.swapaxes(self.whiten(F.T), 1, 2)
        if len(F) <= _CACHED_SERIES:  # a verdict's or a sweep point's, not a training batch
            self._white_cache = (key, white)
        return white

    def joint(self, F: np.ndarray) -> np.ndarray:
        """log w_m N(x; μ_k, Σ_m) of each condition, series and candidate, (M, n, K)."""
        whites = self.whitened(F)
        if len(F) <= _CACHED_SERIES:
            # A verdict's few series: every condition and candidate in one pass (the
            # loop below costs 40 round trips through numpy for a few thousand numbers),
            # kept for the series' next question (distances, then the posterior).
            cached = getattr(self, "_joint_cache", None)
            if cached is not None and cached[0] is whites:
                return cached[1]
            residual = whites[:, :, None, :] - self.white_means[:, None, :, :]
            squared = np.einsum("mnkd,mnkd->mnk", residual, residual)
            joint = self.log_norm[:, None, None] - 0.5 * squared
            joint.flags.writeable = False
            self._joint_cache = (whites, joint)
            return joint
        out = np.empty((len(self.log_norm), len(F), self.white_means.shape[1]))
        for c in range(len(self.log_norm)):
            white = whites[c]
            squared = np.sum((white[:, None, :] - self.white_means[c][None]) ** 2, axis=2)
            out[c] = self.log_norm[c] - 0.5 * squared
        return out

    def prefix_distances(self, F: np.ndarray, every: int = 3) -> np.ndarray:
        """The marginal Mahalanobis distance of every leading part of the series that
        ends on a whole sample (``every`` numbers), (n, dim // every, K).

        Exact for the Gaussians of each condition: the whitener is lower triangular, so
        the leading numbers of a whitened series are the leading block's whitening, and
        a prefix's squared distance is a cumulative sum.
        """
        dim = F.shape[1]
        ends = np.arange(every, dim + 1, every) - 1
        n_conditions = len(self.log_norm)
        log_norm = (
            self.log_weights[:, None]
            - np.cumsum(self.log_diagonal, axis=1)[:, ends]
            - 0.5 * (ends + 1) * _LOG_2PI
        )  # (M, T)
        joint = np.empty((n_conditions, len(F), len(ends), self.white_means.shape[1]))
        for c, whitener in enumerate(self.whiteners):
            white = F @ whitener.T
            squared = np.cumsum((white[:, None, :] - self.white_means[c][None]) ** 2, axis=2)
            joint[c] = log_norm[c][None, :, None] - 0.5 * np.swapaxes(squared[:, :, ends], 1, 2)
        log_likelihood = logsumexp(joint, axis=0)
        likeliest = np.argmax(logsumexp(joint, axis=3), axis=0)  # (n, T)
        peak = log_norm[likeliest, np.arange(len(ends))[None, :]]
        return np.sqrt(2.0 * np.maximum(peak[..., None] - log_likelihood, 0.0))

    def prefix_near_none_log_bayes(
        self, F: np.ndarray, sensitivity: np.ndarray, prior_sd: np.ndarray, every: int = 3
    ) -> np.ndarray:
        """:meth:`near_none_log_likelihood` against the candidates' mixture, as a log
        Bayes factor, for every leading part of the series that ends on a whole sample,
        (n, dim // every): exact, like :meth:`prefix_distances` (the whitener is lower
        triangular, so a prefix's whitened residual and sensitivity are the leading rows,
        and their inner products cumulative sums)."""
        dim = F.shape[1]
        ends = np.arange(every, dim + 1, every) - 1
        n_conditions, n_candidates = len(self.log_norm), sensitivity.shape[0]
        log_norm = (
            self.log_weights[:, None]
            - np.cumsum(self.log_diagonal, axis=1)[:, ends]
            - 0.5 * (ends + 1) * _LOG_2PI
        )  # (M, T)
        known = np.empty((n_conditions, len(F), len(ends), n_candidates))
        near = np.empty_like(known)
        for c, whitener in enumerate(self.whiteners):
            white = F @ whitener.T
            for k in range(n_candidates):
                residual = white - self.white_means[c][k]  # (n, dim)
                quad = np.cumsum(residual**2, axis=1)[:, ends]  # (n, T)
                known[c, :, :, k] = log_norm[c][None] - 0.5 * quad
                A = whitener @ sensitivity[k]  # (dim, 6)
                sd = np.full(A.shape[1], float(prior_sd[k]))
                gram = np.cumsum(A[:, :, None] * A[:, None, :], axis=0)[ends]  # (T, 6, 6)
                inner = np.diag(1.0 / sd**2)[None] + gram
                chol = np.linalg.cholesky(inner)
                log_det = 2.0 * (
                    np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1) + np.sum(np.log(sd))
                )  # (T,)
                inner_product = np.cumsum(residual[:, :, None] * A[None], axis=1)[:, ends]
                solved = np.linalg.solve(inner[None], inner_product[..., None])[..., 0]
                explained = np.sum(inner_product * solved, axis=2)  # (n, T)
                near[c, :, :, k] = (
                    log_norm[c][None] - 0.5 * log_det[None] - 0.5 * (quad - explained)
                )
        return np.asarray(logsumexp(near, axis=(0, 3)) - logsumexp(known, axis=(0, 3)))

    def near_none_log_likelihood(
        self, F: np.ndarray, sensitivity: np.ndarray, prior_sd: np.ndarray
    ) -> np.ndarray:
        """log p(x | another body near a candidate), (n,): the mean over candidates k
        and the mixture over conditions m of ``N(x; μ_k, Σ_m + S_k P_k S_kᵀ)``.

        The body's six inertia parameters are drawn around candidate k's with standard
        deviation ``prior_sd[k]`` each (``P_k``), and the response is linear in them
        (``S_k``, (dim, 6)): marginalised exactly, by Woodbury and the determinant lemma
        in each condition's whitened coordinates.
        """
        n_candidates = sensitivity.shape[0]
        A, chol_inv, log_det = self._near_factors(sensitivity, prior_sd)
        # (M, K, n, dim): every condition's and candidate's whitened residual at once.
        residual = self.whitened(F)[:, None] - self.white_means[:, :, None]
        # Two batched matrix products: einsum's path search alone cost 0.2 ms a call.
        projected = (residual @ A) @ np.swapaxes(chol_inv, 2, 3)  # (M, K, n, 6)
        quad = np.sum(residual**2, axis=3) - np.sum(projected**2, axis=3)  # (M, K, n)
        out = self.log_norm[:, None, None] - 0.5 * log_det[:, :, None] - 0.5 * quad
        return np.asarray(logsumexp(out, axis=(0, 1)) - math.log(n_candidates))

    def _near_factors(
        self, sensitivity: np.ndarray, prior_sd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per condition and candidate: the whitened sensitivity A (M, K, dim, 6), the
        inverse Cholesky factor of M = P⁻¹ + AᵀA (M, K, 6, 6) and
        log det(I + P^½ AᵀA P^½) = log det(P) det(M) (M, K).

        None of it depends on the series, so it is computed once per mixture (each
        request used to refactor 40 x K of them: 26 ms of a 28 ms identify)."""
        key = (sensitivity.tobytes(), np.asarray(prior_sd, dtype=float).tobytes())
        cached = self._near_cache.get("last")
        if cached is not None and cached[0] == key:
            return cached[1]
        n_conditions, n_candidates = len(self.log_norm), sensitivity.shape[0]
        dim, n_params = sensitivity.shape[1], sensitivity.shape[2]
        # Every condition's whitened sensitivity (M, dim, K * 6) at once, then every 6 x 6
        # factor at once: each conditioned copy (every start its verdict is given at)
        # builds these afresh, and the M x K loop of small LAPACK calls this replaces
        # took about 14 of their 19 ms (cProfile, paper preset, 40 conditions).
        flat = np.moveaxis(sensitivity, 0, 1).reshape(dim, n_candidates * n_params)
        white = self._white_sensitivity(flat)
        A = np.moveaxis(white.reshape(n_conditions, dim, n_candidates, n_params), 2, 1)
        sd = np.asarray(prior_sd, dtype=float)[:n_candidates, None] * np.ones(n_params)  # (K, 6)
        inner = np.swapaxes(A, 2, 3) @ A + (np.eye(n_params) / sd[:, :, None] ** 2)[None]
        chol = np.linalg.cholesky(inner)  # (M, K, 6, 6)
        log_det = 2.0 * (
            np.sum(np.log(np.diagonal(chol, axis1=2, axis2=3)), axis=2)
            + np.sum(np.log(sd), axis=1)[None]
        )
        chol_inv = np.linalg.inv(chol)
        factors = (A, chol_inv, log_det)
        self._near_cache["last"] = (key, factors)
        return factors

    def _white_sensitivity(self, flat: np.ndarray) -> np.ndarray:
        """``W_m S`` (M, dim, K * 6) of the sensitivities ``flat`` (dim, K * 6); an updated
        mixture's from its base's (:meth:`updated`), kept there for the next update."""
        if self._update is not None:
            base, steps = self._update
            return _unit_updates_inverse(steps, base._white_sensitivity(flat))
        key = flat.tobytes()
        cached = self._near_cache.get("sensitivity")
        if cached is not None and cached[0] == key:
            return np.asarray(cached[1])
        white = np.asarray(self.whiteners @ flat)
        self._near_cache["sensitivity"] = (key, white)
        return white

    def log_likelihood(self, F: np.ndarray) -> np.ndarray:
        """log p(x | k), the mixture over conditions, (n, K)."""
        return np.asarray(logsumexp(self.joint(F), axis=0))

    def distances(self, F: np.ndarray) -> np.ndarray:
        """Marginal Mahalanobis distance, (n, K); see ``MarginalLikelihoodClassifier.transform``."""
        joint = self.joint(F)
        # The series' most probable condition, over every candidate: the same for all K,
        # so subtracting its peak log-density keeps the marginal likelihood's ranking.
        likeliest = np.argmax(logsumexp(joint, axis=2), axis=0)
        return np.sqrt(np.maximum(self._excess(joint, likeliest), 0.0))

    def squares_at(self, F: np.ndarray, condition: int) -> np.ndarray:
        """``2 (log ν_c - log p(x | k))`` with one condition ``c``'s peak density for
        every series, (n, K): the marginal likelihood's ranking across series as well as
        candidates (below 0 where a quieter condition fits better than ``c``)."""
        return self._excess(self.joint(F), np.full(len(F), condition))

    def _excess(self, joint: np.ndarray, reference: np.ndarray) -> np.ndarray:
        return 2.0 * (self.log_norm[reference][:, None] - logsumexp(joint, axis=0))


class MarginalLikelihoodClassifier(BaseClassifier):
    """Most likely candidate with the noise level marginalised over a grid.

    Fit with :meth:`fit_scenario` or :func:`train_marginal` (which simulate what
    :meth:`fit_components` needs) or with :meth:`fit_components` directly.

    :param grid: (process multiple, measurement multiple) pairs, each >= 0 and finite,
        over which the likelihood is averaged with equal weights: the range of noise
        the classifier should expect. Default :data:`JOINT_GRID` (40 conditions); the
        components serve any grid, so it costs nothing to store, and prediction time
        grows with its size.
    :param novelty_factor: a series farther from its nearest candidate than this
        multiple of the candidate's largest out-of-fold training distance "matches
        none"; >= 1.
    :param none_spread: the "none of these" hypothesis includes other bodies near the
        candidates: each inertia parameter drawn around a candidate's with this standard
        deviation, as a fraction of the candidate's mean principal moment (see
        :meth:`near_none_log_bayes`); 0 leaves only the novelty tail. Needs the scenario
        at fit time (the response's sensitivity to the inertia is simulated).
    :param process_target: what the process component's sample covariance is shrunk
        towards, by the cross-validated intensity: "disturbance model" (the default: the
        covariance the scenario's disturbance torque gives the rates, written out; see
        :func:`_process_target`) or "isotropic" (a multiple of the identity, as before).
        Fitting from components without a scenario falls back to the identity; the
        fitted :attr:`process_target_` says which was used.
    """

    kind: ClassVar[str] = "marginal-likelihood"
    REMOVES_OFFSET = False
    GAUSSIAN_DISTANCES = True
    FORMAT = "inertia-id/marginal-likelihood-classifier"
    MIN_REALISATIONS = 3
    #: Three noise covariances of 240+ dimensions: from 100 realisations per candidate
    #: it comes within 0.4 points of a likelihood fitted at each noise level on 400
    #: (2.4 points short from 20).
    DEFAULT_REALISATIONS = 100
    IN_SAMPLE_SCORES = True
    LISTING_ORDER = 70
    LABEL = "marginal likelihood (default: the noise level marginalised)"
    metric = "marginal-mahalanobis"
    # The response's sensitivity to the inertia (K, length, 3, 6) and the "none" model's
    # prior spread per candidate (K,), kg m²; None without them (see none_spread).
    sensitivity_: np.ndarray | None = None
    none_prior_sd_: np.ndarray | None = None
    # The means (K, length, 3) and quiet part (dim, dim) of the series less their own
    # offset ω(0) + b, and the white gyro variance at 1x (rad²/s²): None without them
    # (fitted from components, or an older document; see conditioned_on_offset).
    offset_free_means_: np.ndarray | None = None
    offset_free_quiet_: np.ndarray | None = None
    white_variance_: float = 0.0
    # The grid conditions' log weights of a copy conditioned on pre-start telemetry.
    _condition_log_weights: np.ndarray | None = None

    def __init__(
        self,
        *,
        grid: Sequence[Sequence[float]] = JOINT_GRID,
        novelty_factor: float = 1.1,
        none_spread: float = DEFAULT_NONE_SPREAD,
        process_target: str = "disturbance model",
    ) -> None:
        self.grid = grid
        self.novelty_factor = novelty_factor
        self.none_spread = none_spread
        self.process_target = process_target

    def _checked_grid(self) -> np.ndarray:
        try:
            grid = np.asarray(self.grid, dtype=float)
        except (TypeError, ValueError):
            grid = np.empty(0)
        if (
            grid.ndim != 2
            or grid.shape[1:] != (2,)
            or len(grid) < 1
            or not np.all(np.isfinite(grid))
            or np.any(grid < 0)
        ):
            raise InputError(
                "grid must be a non-empty list of (process multiple, measurement multiple) "
                f"pairs, each finite and >= 0, got {self.grid!r}"
            )
        if len(np.unique(grid, axis=0)) != len(grid):
            raise InputError(f"grid conditions must be distinct, got {self.grid!r}")
        return grid

    def _check_params(self) -> None:
        super()._check_params()
        self._checked_grid()
        spread = self.none_spread
        if not is_number(spread, minimum=0.0):
            raise InputError(f"none_spread must be a finite number >= 0, got {spread!r}")
        if self.process_target not in PROCESS_TARGETS:
            raise InputError(
                f"process_target must be one of {list(PROCESS_TARGETS)}, "
                f"got {self.process_target!r}"
            )

    # Fitting.

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        # Not from one set of series: the noise components need three runs of the same
        # realisations.
        raise InputError(
            "the marginal-likelihood classifier is fitted from each noise source's part of "
            "the same realisations: use fit_components, or fit_scenario / train_marginal / "
            "train_classifier, which simulate them"
        )

    def _fit_simulated(
        self, scenario: Scenario, steps: np.ndarray, n_realisations: int, rng: np.random.Generator
    ) -> None:
        """The same ``n_realisations`` per candidate simulated three times from one
        generator state: process and measurement noise off, process noise only at 1x,
        measurement noise only at 1x (see :meth:`fit_components`).

        On the paper preset 100 realisations come within 0.4 points of a likelihood fitted
        at each noise level on 400 (20 within 2.4).
        Simulation is cheap; fitting takes about a second either way.
        """
        # One child stream, replayed for each run: the same standard-normal draws, scaled.
        stream = rng.spawn(1)[0]
        runs = []
        for process, measurement in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)):
            runs.append(
                simulate(
                    scenario,
                    steps,
                    n_realisations,
                    copy.deepcopy(stream),
                    process_noise_scale=process,
                    measurement_noise_scale=measurement,
                ).dataset()
            )
            self._checkpoint()
        (X_quiet, y), (X_process, _), (X_measurement, _) = runs
        # The same standard-normal draws again: each series' rate at the sequence start
        # and its gyro bias at 1x, for the offset-free parts (see conditioned_on_offset).
        initial = Simulator(scenario, n_realisations).draw_initial(copy.deepcopy(stream))
        self.fit_components(
            X_quiet,
            X_process,
            X_measurement,
            y,
            candidate_names=scenario.candidate_names,
            scenario=scenario,
            sequence=steps,
        )
        self._fit_offset_free(
            X_quiet,
            X_measurement,
            y,
            initial_rate=initial.omega0.reshape(-1, 3),
            bias=initial.gyro_bias.reshape(-1, 3),
            constant_bias=np.asarray(scenario.uncertainty.gyro_bias_rad_s, dtype=float),
        )

    def _fit_offset_free(
        self,
        X_quiet: np.ndarray,
        X_measurement: np.ndarray,
        y: np.ndarray,
        *,
        initial_rate: np.ndarray,
        bias: np.ndarray,
        constant_bias: np.ndarray,
    ) -> None:
        """The means and the quiet and white-noise parts of the series less their own
        offset ``ω(0) + b`` (each series' rate at the sequence start plus its gyro bias):
        what :meth:`conditioned_on_offset` needs when telemetry before the start measures
        that offset.

        :param initial_rate: (n_series, 3) rate at the sequence start of each series, rad/s.
        :param bias: (n_series, 3) gyro bias of each series at 1x measurement noise, rad/s.
        :param constant_bias: (3,) the scenario's constant bias (in the quiet run too).
        """
        n_candidates = self.n_candidates_
        quiet = X_quiet - initial_rate[:, None, :] - constant_bias
        white = (X_measurement - X_quiet) - (bias - constant_bias)[:, None, :]
        flat_quiet = quiet.reshape(len(quiet), -1)
        means, _, sample = gaussian.means_and_scatter(flat_quiet, y, n_candidates)
        _, white_residuals, _ = gaussian.means_and_scatter(
            white.reshape(len(white), -1), y, n_candidates
        )
        dof = max(len(white) - n_candidates, 1)
        self.offset_free_means_ = means.reshape(n_candidates, *X_quiet.shape[1:])
        self.offset_free_quiet_ = _symmetric(gaussian.shrink(sample, float(self.shrinkage_[0])))
        self.white_variance_ = float(np.sum(white_residuals**2)) / (dof * white.shape[1] * 3)
        self.__dict__.pop("_offset_models", None)
        self.__dict__.pop("_offset_free_factored", None)

    @property
    def supports_offset(self) -> bool:
        """Whether telemetry before the sequence start can pin the series' offset
        (fitted by simulation; documents from before this have no offset-free parts)."""
        return self.offset_free_means_ is not None

    def conditioned_on_offset(
        self,
        process_variance: np.ndarray,
        measurement_variance: np.ndarray,
        condition_log_weights: np.ndarray | None = None,
    ) -> MarginalLikelihoodClassifier:
        """This classifier for series less a measured offset ``ĉ`` of ``ω(0) + b``.

        Telemetry before the start measures the body's rate plus the gyro bias, which
        together shift every sample of the response (to first order). Without it the
        classifier integrates over their whole prior spread (5e-3 and 2e-3 rad/s per
        axis in orbit): at 1 Hz, four samples in the paper's 4 s sequence, that offset
        eats three of twelve numbers. With ``ĉ``, ``x - ĉ`` is Gaussian with the
        offset-free mean and quiet part, the white gyro noise, the in-sequence process
        noise, and the estimate's own error ``e = ĉ - (ω(0) + b)`` on every sample:

            Σ(p, q) = Σ_quiet⁰ + p² (Σ_process + 1 ⊗ V_p) + q² (σ² I + 1 ⊗ V_q),

        ``V_p`` from the disturbance between the pre-start samples and the start, ``V_q``
        from their gyro noise, both 3 x 3 at 1x (:func:`~inertia_id.evaluation.identify
        .initial_offset`). Every question a classifier answers (distances, posterior, the
        near-none model, measured-points blocks, prefixes) is then asked of the returned
        copy, on ``x - ĉ``. The last four copies are kept, per pair of variances (each
        holds its own whitening, 18 MB on the paper preset's 40 conditions).

        The same samples say how noisy the spacecraft is: their scatter about their mean
        is gyro noise and the disturbance's random walk. ``condition_log_weights``, the
        grid conditions' log posterior given them, then replace the equal weights (at
        1 Hz four samples in the sequence hardly pin the noise level, and a mixture over
        1x to 8x blurs every candidate's likelihood: on 200 native paper-in-orbit series
        at 1 Hz with 10 s before the start, known noise decided 97.5 % within the
        sequence, the equal-weight mixture 36.5 %, these weights 78 %).

        :param process_variance: (3, 3) ``V_p`` at 1x process noise, rad²/s².
        :param measurement_variance: (3, 3) ``V_q`` at 1x measurement noise, rad²/s².
        :param condition_log_weights: (M,) log weights of the grid conditions, summing
            to 1 in probability; default equal.
        """
        self._check_fitted()
        if not self.supports_offset:
            raise InputError(
                "this classifier has no offset-free parts (fitted from components, or an "
                "older document): retrain it to use telemetry before the start"
            )
        V_p = np.asarray(process_variance, dtype=float).reshape(3, 3)
        V_q = np.asarray(measurement_variance, dtype=float).reshape(3, 3)
        cache: dict[bytes, MarginalLikelihoodClassifier] = self.__dict__.setdefault(
            "_offset_models", {}
        )
        key = np.concatenate([V_p.ravel(), V_q.ravel()]).round(15).tobytes()
        if key not in cache:
            if len(cache) >= 4:
                cache.pop(next(iter(cache)))
            every = np.ones((self.length_, self.length_))
            assert self.offset_free_quiet_ is not None and self.offset_free_means_ is not None
            dim = 3 * self.length_
            components = np.stack(
                [
                    self.offset_free_quiet_,
                    self.components_[1] + np.kron(every, V_p),
                    self.white_variance_ * np.eye(dim) + np.kron(every, V_q),
                ]
            )
            model = copy.copy(self)
            model.__dict__ = {
                k: v
                for k, v in self.__dict__.items()
                if k not in ("_observed_mixtures", "_offset_models", "_offset_free_factored")
            }
            model.means_ = self.offset_free_means_
            model.components_ = components
            # Σ_m = Σ_m(0, 0) + 1 ⊗ (p² V_p + q² V_q): the mixture without the estimate's
            # error, factored once, updated by rank 3 (_Mixture.updated). Every start
            # conditions afresh (V_p grows with the lag from the last pre-start sample to
            # the start, which a start refined below the grid period moves), and factoring
            # the 40 dim x dim covariances (and the near-none factors) each time cost about
            # 55 ms of an 88 ms identify with a ±0.3 s search (20 Hz, one BLAS thread).
            B = (
                self.grid_[:, 0, None, None] ** 2 * V_p[None]
                + self.grid_[:, 1, None, None] ** 2 * V_q[None]
            )
            values, vectors = np.linalg.eigh(B)
            root = vectors * np.sqrt(np.maximum(values, 0.0))[:, None, :]  # root rootᵀ = B
            model._mixture = self._offset_free_mixture().updated(
                np.tile(root, (1, self.length_, 1))  # (M, dim, 3): 1 ⊗ root
            )
            # Its own measured-points blocks, which the reweighted copies below share.
            model.__dict__["_observed_mixtures"] = {}
            cache[key] = model
        if condition_log_weights is None:
            return cache[key]
        weights = np.asarray(condition_log_weights, dtype=float)
        if weights.shape != (len(self.grid_),) or not np.isclose(logsumexp(weights, axis=0), 0.0):
            raise InputError(
                f"condition_log_weights must be {len(self.grid_)} log probabilities summing "
                f"to 1, got shape {weights.shape}"
            )
        weighted = copy.copy(cache[key])
        weighted.__dict__ = dict(cache[key].__dict__)  # the measured-points blocks shared
        weighted._mixture = cache[key]._mixture.reweighted(weights)
        weighted._condition_log_weights = weights
        return weighted

    def _offset_free_mixture(self) -> _Mixture:
        """The mixture of series less an exactly known offset (no estimate error): what
        :meth:`conditioned_on_offset` updates, factored once per fit."""
        cached = self.__dict__.get("_offset_free_factored")
        if cached is None:
            assert self.offset_free_quiet_ is not None and self.offset_free_means_ is not None
            dim = 3 * self.length_
            components = np.stack(
                [self.offset_free_quiet_, self.components_[1], self.white_variance_ * np.eye(dim)]
            )
            cached = _Mixture(
                self.offset_free_means_.reshape(self.n_candidates_, -1), components, self.grid_
            )
            self.__dict__["_offset_free_factored"] = cached
        return cached

    def fit_components(
        self,
        X_quiet: Any,
        X_process: Any,
        X_measurement: Any,
        y: Any,
        *,
        candidate_names: list[str] | None = None,
        scenario: Scenario | None = None,
        sequence: Any = None,
    ) -> Self:
        """Estimate the mean responses and the three noise components.

        The three arrays hold the *same* realisations (simulated from the same
        generator state, as :meth:`fit_scenario` does them), so that their differences
        are each noise source's contribution alone.

        :param X_quiet: (n_series, length, 3) responses with process and measurement
            noise off, rad/s.
        :param X_process: the same realisations with process noise at 1x only.
        :param X_measurement: the same realisations with measurement noise at 1x only.
        :param y: true candidate index of each series (0..K-1, every candidate at
            least 3 times, so that a fold can be held out).
        :param candidate_names: names of the K candidates; default the scenario's.
        :param scenario: the scenario simulated; kept, with ``sequence``, for identify.
        :param sequence: the (L, N) level indices the series respond to.
        """
        X, y = self._prepare(X_quiet, y, candidate_names, scenario, sequence)
        grid = self._checked_grid()
        responses = [X] + [check_series(arr) for arr in (X_process, X_measurement)]
        for name, arr in zip(COMPONENTS[1:], responses[1:], strict=True):
            if arr.shape != X.shape:
                raise InputError(
                    f"the {name} responses are shaped {arr.shape}, the quiet ones {X.shape}"
                )
        n_candidates = self.n_candidates_
        quiet = X.reshape(len(X), -1)
        # Each source alone: the differences of the same realisations.
        parts = [quiet] + [arr.reshape(len(X), -1) - quiet for arr in responses[1:]]
        folds = gaussian.stratified_folds(y, min(gaussian.MAX_FOLDS, int(np.bincount(y).min())))
        process = None
        if self.process_target == "disturbance model":
            process = _process_target(scenario, self.sequence_, quiet.shape[1])
        targets = [None, process, None]
        intensities = np.array(
            [
                gaussian.cv_intensity(F, y, n_candidates, folds, target, self._checkpoint)
                for F, target in zip(parts, targets, strict=True)
            ]
        )
        means, components = self._estimate(parts, y, n_candidates, intensities, targets)
        spread = float(np.trace(components.sum(axis=0))) / means.shape[1]
        if not spread > 1e-20 * float(np.mean(means**2)):
            # Rounding alone leaves a covariance of ~1e-34: any "noise model" is absurd.
            raise InputError(
                f"the training series do not vary (variance {spread:.3g} rad²/s² at 1x): "
                "every noise of the scenario is off"
            )
        self.shrinkage_ = intensities
        self.components_ = components
        self.means_ = means.reshape(n_candidates, *X.shape[1:])
        self.grid_ = grid
        self._mixture = _Mixture(means, components, grid, self._checkpoint)
        self.__dict__.pop("_observed_mixtures", None)
        self.sensitivity_, self.none_prior_sd_ = None, None
        self.offset_free_means_, self.offset_free_quiet_ = None, None
        self.__dict__.pop("_offset_models", None)
        self.__dict__.pop("_offset_free_factored", None)
        if scenario is not None and self.none_spread > 0:
            self.sensitivity_ = inertia_sensitivity(scenario, self.sequence_, self._checkpoint)
            self.none_prior_sd_ = self.none_spread * np.array(
                [float(np.trace(t)) / 3.0 for t in scenario.inertia_array]
            )
        self.process_target_ = "isotropic" if targets[1] is None else "disturbance model"
        training = self._out_of_fold(parts, y, folds, intensities, targets)
        # Training scores, like the other kinds': the training series at 1x, which is
        # what the three parts add up to (the process noise acts linearly).
        self._record_training(self._at(parts, np.ones(2)).reshape(X.shape), y, training)
        return self

    @staticmethod
    def _estimate(
        parts: list[np.ndarray],
        y: np.ndarray,
        n_candidates: int,
        intensities: np.ndarray,
        targets: list[np.ndarray | None],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Means from the quiet part, and each part's shrunk pooled covariance (the
        measurement part's white noise and constant bias apart, where it has a bias:
        :func:`_white_and_bias`), shrunk towards its target where it has one
        (:func:`_process_target`), else towards a multiple of the identity."""
        means = gaussian.means_and_scatter(parts[0], y, n_candidates)[0]
        components = []
        for index, (F, intensity, target) in enumerate(
            zip(parts, intensities, targets, strict=True)
        ):
            _, residuals, sample = gaussian.means_and_scatter(F, y, n_candidates)
            structured = _white_and_bias(residuals, n_candidates) if index == 2 else None
            if structured is not None:
                components.append(structured)
            elif target is not None:
                components.append(_symmetric(gaussian.shrink_towards(sample, target, intensity)))
            else:
                components.append(_symmetric(gaussian.shrink(sample, intensity)))
        return means, np.stack(components)

    @staticmethod
    def _extremes(grid: np.ndarray) -> np.ndarray:
        """The quietest and the noisiest conditions of the grid, (m, 2).

        Those no other condition undercuts, or exceeds, in both multiples: (1, 1) and
        (8, 8) in the joint grid; (1, 1), (8, 1) and (1, 8) in the axes grid.
        """

        def frontier(sign: float) -> list[bool]:
            return [
                not np.any(np.all(sign * grid >= sign * c, axis=1) & np.any(grid != c, axis=1))
                for c in grid
            ]

        keep = np.asarray(frontier(1.0)) | np.asarray(frontier(-1.0))
        return np.asarray(grid[keep])

    @staticmethod
    def _at(parts: list[np.ndarray], condition: np.ndarray) -> np.ndarray:
        """The flattened series as they would be at ``condition`` (process, measurement)."""
        return np.asarray(parts[0] + condition[0] * parts[1] + condition[1] * parts[2])

    def _out_of_fold(
        self,
        parts: list[np.ndarray],
        y: np.ndarray,
        folds: np.ndarray,
        intensities: np.ndarray,
        targets: list[np.ndarray | None],
    ) -> np.ndarray:
        """Distance of each series to each candidate, out-of-fold, (n, K).

        The larger over the grid's extreme conditions: a series' distance at its most
        probable condition hardly depends on the condition (it is about the square root
        of a chi-square with ``3 length`` degrees of freedom at every one).
        """
        out = np.zeros((len(y), self.n_candidates_))
        for fold in np.unique(folds):
            train, test = folds != fold, folds == fold
            self._checkpoint()
            means, components = self._estimate(
                [F[train] for F in parts], y[train], self.n_candidates_, intensities, targets
            )
            mixture = _Mixture(means, components, self.grid_, self._checkpoint)
            for condition in self._extremes(self.grid_):
                self._checkpoint()
                at = self._at([F[test] for F in parts], condition)
                out[test] = np.maximum(out[test], mixture.distances(at))
        return out

    # Prediction.

    def _flat(self, X: Any) -> np.ndarray:
        arr = self._check_input(X)
        return arr.reshape(len(arr), -1)

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        """Marginal Mahalanobis distance of each series to each candidate, (n, K).

        ``sqrt(2 (log ν_m̂ - log p(x | k)))``, with m̂ the series' most probable grid
        condition and ν_m̂ its peak density ``w_m̂ N(0; 0, Σ_m̂)``: ranked as the
        marginal likelihood, the Mahalanobis distance when the grid has one condition,
        and for a genuine series about ``sqrt(3 length)`` at any noise level of the grid.
        (Clipped at 0, which takes a series within about ``sqrt(2 log(M K))`` of a
        mean, far closer than noise ever puts one.)
        """
        return self._mixture.distances(X.reshape(len(X), -1))

    def _prefix_distances(self, X: np.ndarray) -> np.ndarray:
        """Marginal Mahalanobis distance after each sample, from the leading block of every
        condition's mean and covariance (exact for Gaussians), (n, length, K)."""
        return self._mixture.prefix_distances(X.reshape(len(X), -1))

    # Slow telemetry: the exact marginal of the measured values.

    def _mixture_on(self, values: np.ndarray) -> _Mixture:
        """The mixture of the measured values' block: every condition's mean and
        covariance components restricted to ``values`` (the exact Gaussian marginal),
        cached per set of values."""
        cache: dict[bytes, _Mixture] = self.__dict__.setdefault("_observed_mixtures", {})
        key = values.tobytes()
        if key not in cache:
            if len(cache) >= 16:
                cache.clear()
            means = self.means_.reshape(self.n_candidates_, -1)[:, values]
            components = self.components_[:, values][:, :, values]
            cache[key] = _Mixture(means, components, self.grid_)
        if self._condition_log_weights is not None:
            return cache[key].reweighted(self._condition_log_weights)
        return cache[key]

    def squared_distances_at_noise(self, X: Any, observed: Any = None) -> np.ndarray | None:
        """Squared marginal distances of series (on the grid points ``observed`` marks as
        measured) all taken from one noise condition's peak density, (n, K): the
        likeliest under the condition weights the telemetry before the start gave
        (:meth:`conditioned_on_offset`); None without such weights.

        :meth:`transform` takes each series' own likeliest condition, so that a genuine
        series lies about ``sqrt(3 length)`` away at any noise level; but the start
        search scores one telemetry at many starts, and a wrong start that looked
        noisier moved to a noisier condition, whose lower peak density took tens off
        the square (20 Hz whole telemetry, paper-in-orbit, 1x: 3.5 conditions on
        average over 13 starts, the true start found in 31 of 100). The noise level is
        the spacecraft's, not the start's: with one condition the starts are ranked by
        their marginal likelihood (99 of 100); may fall below 0 where a quieter
        condition fits better than that one."""
        if self._condition_log_weights is None:
            return None
        condition = int(np.argmax(self._condition_log_weights))
        F = self._flat(X)
        values = self._observed_values(observed)
        if values is None:
            return self._mixture.squares_at(F, condition)
        return self._mixture_on(values).squares_at(F[:, values], condition)

    def squared_distances_by_noise(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Squared marginal distances of series (on the grid points ``observed`` marks as
        measured) from every noise condition's peak density, (n, M, K), and each series'
        likeliest condition, (n,) (the one :meth:`transform` takes).

        For the start search where no telemetry before the start weighs the conditions:
        it scores one telemetry at several starts, and must take every start's square
        from one condition (:meth:`quietest_condition` of the starts' own), not each
        start's own likeliest (see :meth:`squared_distances_at_noise`)."""
        F = self._flat(X)
        values = self._observed_values(observed)
        mixture = self._mixture if values is None else self._mixture_on(values)
        joint = mixture.joint(F if values is None else F[:, values])  # (M, n, K)
        likeliest = np.argmax(logsumexp(joint, axis=2), axis=0)
        log_likelihood = logsumexp(joint, axis=0)  # (n, K), the mixture's
        squares = 2.0 * (mixture.log_norm[None, :, None] - log_likelihood[:, None, :])
        return squares, likeliest

    def quietest_condition(self, conditions: Any) -> int:
        """Of the noise conditions ``conditions`` (indices into :attr:`grid_`), the one
        with the highest peak density over the whole series (the smallest covariance
        determinant): the least noise any of them needs."""
        chosen = [int(c) for c in conditions]
        return max(chosen, key=lambda c: float(self._mixture.log_norm[c]))

    def _observed_sensitivity(self, values: np.ndarray) -> np.ndarray | None:
        if self.sensitivity_ is None or self.none_prior_sd_ is None:
            return None
        return self.sensitivity_.reshape(self.n_candidates_, -1, 6)[:, values]

    def _observed_distances(self, X: np.ndarray, values: np.ndarray) -> np.ndarray:
        return self._mixture_on(values).distances(X.reshape(len(X), -1)[:, values])

    def _observed_near_log_bayes(self, X: np.ndarray, values: np.ndarray) -> np.ndarray | None:
        sensitivity = self._observed_sensitivity(values)
        if sensitivity is None or self.none_prior_sd_ is None:
            return None
        mixture = self._mixture_on(values)
        F = X.reshape(len(X), -1)[:, values]
        candidates = logsumexp(mixture.log_likelihood(F), axis=1) - math.log(self.n_candidates_)
        near = mixture.near_none_log_likelihood(F, sensitivity, self.none_prior_sd_)
        return np.asarray(near - candidates)

    def _observed_prefix_distances(self, X: np.ndarray, values: np.ndarray) -> np.ndarray:
        return self._mixture_on(values).prefix_distances(X.reshape(len(X), -1)[:, values])

    def _observed_prefix_near_log_bayes(
        self, X: np.ndarray, values: np.ndarray
    ) -> np.ndarray | None:
        sensitivity = self._observed_sensitivity(values)
        if sensitivity is None or self.none_prior_sd_ is None:
            return None
        return self._mixture_on(values).prefix_near_none_log_bayes(
            X.reshape(len(X), -1)[:, values], sensitivity, self.none_prior_sd_
        )

    def log_likelihood(self, X: Any) -> np.ndarray:
        """Marginal log-density log Σ_m w_m N(x; μ_k, Σ_m) of each series, (n, K)."""
        return self._mixture.log_likelihood(self._flat(X))

    def near_none_log_bayes(self, X: Any) -> np.ndarray | None:
        """log Bayes factor of "another body near a candidate" against the candidates,
        (n,); None when the classifier has no sensitivity (``none_spread`` 0, fitted
        without a scenario, or an older document).

        The alternative is a proper model, not a p-value: the inertia parameters of a
        body not on the list are drawn around each candidate's (standard deviation
        ``none_spread`` of its mean principal moment each), the response is linearised
        in them (:func:`inertia_sensitivity`), and both hypotheses marginalise the same
        noise grid. A genuine series pays the alternative's Occam factor (on the paper
        preset log Bayes factors of -10 to -4 at 1x, at most +4 at 8x process noise);
        a body 10 % off every candidate gains far more than it pays (+14 to +42), where
        the distance to the nearest candidate alone never told it from a known body at
        high process noise.
        """
        if self.sensitivity_ is None or self.none_prior_sd_ is None:
            return None
        F = self._flat(X)
        candidates = logsumexp(self._mixture.log_likelihood(F), axis=1) - math.log(
            self.n_candidates_
        )
        near = self._mixture.near_none_log_likelihood(
            F, self.sensitivity_.reshape(self.n_candidates_, -1, 6), self.none_prior_sd_
        )
        return np.asarray(near - candidates)

    def _near_log_bayes(self, X: np.ndarray) -> np.ndarray | None:
        return self.near_none_log_bayes(X)

    def _prefix_near_log_bayes(self, X: np.ndarray) -> np.ndarray | None:
        if self.sensitivity_ is None or self.none_prior_sd_ is None:
            return None
        return self._mixture.prefix_near_none_log_bayes(
            X.reshape(len(X), -1),
            self.sensitivity_.reshape(self.n_candidates_, -1, 6),
            self.none_prior_sd_,
        )

    def predict_proba(self, X: Any) -> np.ndarray:
        """Posterior probability of each candidate with equal priors, (n, K)."""
        return np.exp(log_softmax(self.log_likelihood(X), axis=1))

    def condition_posterior(self, X: Any) -> np.ndarray:
        """Posterior probability of each grid condition (:attr:`grid_`), (n, M).

        Over the candidates too, with equal priors: how noisy each series looks.
        """
        joint = self._mixture.joint(self._flat(X))
        return np.exp(log_softmax(logsumexp(joint, axis=2), axis=0)).T

    # Storage as data.

    def _document_params(self) -> dict[str, Any]:
        params = super()._document_params()
        params["grid"] = np.asarray(self.grid, dtype=float).tolist()
        return params

    @classmethod
    def stored_numbers(cls, n_candidates: int, values: int, n_realisations: int) -> int:
        """Four covariance triangles of ``values`` dimensions (the three components, each
        kept whole however sparse or isotropic it comes out, and the offset-free quiet
        one), and two means and the inertia sensitivity (6 numbers a value) a candidate."""
        return 2 * values * (values + 1) + 8 * n_candidates * values

    def _state(self) -> dict[str, Any]:
        near: dict[str, Any] = {}
        if self.sensitivity_ is not None and self.none_prior_sd_ is not None:
            near = {
                "inertia_sensitivity": self.sensitivity_.tolist(),
                "none_prior_sd_kg_m2": self.none_prior_sd_.tolist(),
            }
        offset_free: dict[str, Any] = {}
        if self.offset_free_means_ is not None and self.offset_free_quiet_ is not None:
            offset_free = {
                "offset_free": {
                    "means_rad_s": self.offset_free_means_.tolist(),
                    "quiet": _component_document(self.offset_free_quiet_),
                    "white_variance": self.white_variance_,
                }
            }
        return {
            **near,
            **offset_free,
            "shrinkage_intensities": dict(zip(COMPONENTS, self.shrinkage_.tolist(), strict=True)),
            # What the process component's intensity shrinks towards (_process_target).
            "process_shrinkage_target": self.process_target_,
            "means_rad_s": self.means_.tolist(),
            # Each symmetric component as its lower triangle, row by row, or as one
            # number when it is a multiple of the identity (white gyro noise).
            "components": {
                name: _component_document(matrix)
                for name, matrix in zip(COMPONENTS, self.components_, strict=True)
            },
        }

    def _load_state(self, data: dict[str, Any]) -> None:
        self.grid_ = self._checked_grid()
        intensities = data["shrinkage_intensities"]
        self.shrinkage_ = np.array([float(intensities[name]) for name in COMPONENTS])
        # Documents from before the target was written out shrank towards the identity.
        target = data.get("process_shrinkage_target", "isotropic")
        if target not in PROCESS_TARGETS:
            raise InputError(
                f"process_shrinkage_target must be one of {list(PROCESS_TARGETS)}, got {target!r}"
            )
        self.process_target_ = target
        means = check_series(data["means_rad_s"])
        k = self.n_candidates_
        if len(means) != k:
            raise InputError(f"{k} candidate names but {len(means)} means")
        dim = means.shape[1] * 3
        self.components_ = np.stack(
            [_component_from_document(data["components"][name], dim) for name in COMPONENTS]
        )
        self.means_ = means
        self.length_ = int(means.shape[1])
        self.__dict__.pop("_observed_mixtures", None)
        self.sensitivity_, self.none_prior_sd_ = None, None
        if data.get("inertia_sensitivity") is not None:
            sensitivity = np.asarray(data["inertia_sensitivity"], dtype=float)
            prior_sd = np.asarray(data["none_prior_sd_kg_m2"], dtype=float)
            if sensitivity.shape != (k, self.length_, 3, 6) or prior_sd.shape != (k,):
                raise InputError(
                    f"inertia sensitivity shaped {sensitivity.shape} and none prior "
                    f"{prior_sd.shape}; expected {(k, self.length_, 3, 6)} and {(k,)}"
                )
            self.sensitivity_, self.none_prior_sd_ = sensitivity, prior_sd
        self.offset_free_means_, self.offset_free_quiet_ = None, None
        self.__dict__.pop("_offset_models", None)
        self.__dict__.pop("_offset_free_factored", None)
        offset_free = data.get("offset_free")
        if offset_free is not None:
            free_means = check_series(offset_free["means_rad_s"])
            if free_means.shape != means.shape:
                raise InputError(
                    f"offset-free means shaped {free_means.shape}, the means {means.shape}"
                )
            self.offset_free_means_ = free_means
            self.offset_free_quiet_ = _component_from_document(offset_free["quiet"], dim)
            self.white_variance_ = float(offset_free["white_variance"])

    def _form_derived(self) -> None:
        """Factor every noise condition's covariance (:class:`_Mixture`)."""
        self._mixture = _Mixture(
            self.means_.reshape(self.n_candidates_, -1), self.components_, self.grid_
        )


#: The perturbed bodies :func:`inertia_sensitivity` flies in one scenario: eight
#: candidates' twelve each, within a scenario's 100 candidates.
SENSITIVITY_BATCH = 96


def inertia_sensitivity(
    scenario: Scenario, sequence: Any, checkpoint: Checkpoint = no_checkpoint
) -> np.ndarray:
    """How each candidate's noise-free response moves with its six inertia parameters
    (Ixx, Iyy, Izz, Ixy, Ixz, Iyz), by central differences: (K, length, 3, 6) rad/s
    per kg m².

    Noise-free: no jitter, disturbance, gyro noise or bias, at rest at the start (the
    lag of the thrusters kept); the step is 1e-4 of the candidate's mean principal
    moment, small enough to keep every perturbed tensor physical. ``checkpoint`` is
    called after each batch of bodies flown (a training's, :mod:`inertia_id.stopping`).
    """
    steps = scenario.check_sequence(sequence)
    tensors = scenario.inertia_array
    perturbed = []
    for tensor in tensors:
        base = parameters_from_tensor(tensor)
        h = 1e-4 * float(np.trace(tensor)) / 3.0
        for i in range(6):
            for sign in (1.0, -1.0):
                p = base.copy()
                p[i] += sign * h
                perturbed.append(tensor_from_parameters(p))
    data = scenario.model_dump()
    data["candidate_generator"] = None
    data["uncertainty"] = {
        "lowpass_time_constant_s": scenario.uncertainty.lowpass_time_constant_s,
        "disturbance_interval_s": scenario.uncertainty.disturbance_interval_s,
        **dict.fromkeys(
            (
                "duty_jitter_sigma",
                "thrust_scale_sigma",
                "disturbance_torque_sigma_nm",
                "gyro_noise_sigma_rad_s",
                "gyro_bias_sigma_rad_s",
                "initial_rate_sigma_rad_s",
            ),
            0.0,
        ),
    }
    # Twelve bodies a candidate, flown in scenarios of at most SENSITIVITY_BATCH of them
    # (a scenario holds at most 100 candidates): one of 9 candidates or more made 108 and
    # more, and the default kind could not be trained on it (a pydantic ValidationError).
    # Noise-free, so each body's response is the same in any batch.
    flown = []
    for start in range(0, len(perturbed), SENSITIVITY_BATCH):
        data["inertia_candidates"] = [
            {"name": f"perturbed {i}", "inertia_kg_m2": perturbed[i].tolist()}
            for i in range(start, min(start + SENSITIVITY_BATCH, len(perturbed)))
        ]
        # The classifier's own scenario, noise off: its lag as trained, past today's
        # bound on a stated lag or not (AS_TRAINED).
        quiet = Scenario.model_validate(data, context=AS_TRAINED)
        flown.append(simulate(quiet, steps, 1, np.random.default_rng(0)).omega_measured[:, 0])
        checkpoint()
    omega = np.concatenate(flown)
    omega = omega.reshape(len(tensors), 6, 2, *omega.shape[1:])
    h = 1e-4 * np.trace(tensors, axis1=1, axis2=2) / 3.0
    derivative = (omega[:, :, 0] - omega[:, :, 1]) / (2.0 * h[:, None, None, None])
    return np.moveaxis(derivative, 1, -1)


def train_marginal(
    scenario: Scenario,
    sequence: Any,
    n_realisations: int,
    rng: np.random.Generator,
    *,
    grid: Sequence[Sequence[float]] = JOINT_GRID,
    novelty_factor: float = 1.1,
    none_spread: float = DEFAULT_NONE_SPREAD,
    process_target: str = "disturbance model",
) -> MarginalLikelihoodClassifier:
    """Simulate every candidate's noise components under ``sequence`` and fit
    (:meth:`MarginalLikelihoodClassifier.fit_scenario`)."""
    model = MarginalLikelihoodClassifier(
        grid=grid,
        novelty_factor=novelty_factor,
        none_spread=none_spread,
        process_target=process_target,
    )
    return model.fit_scenario(scenario, sequence, n_realisations, rng)
