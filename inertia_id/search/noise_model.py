"""The Bayes classifier's accuracy predicted from the simulator's own noise model.

A search needs the accuracy of a sequence at a design noise thousands of times, so it
cannot train and test a classifier each time. Estimating each candidate's covariance
from a few tens of simulated realisations (the pooled covariance of
:func:`~inertia_id.search.objectives.predicted_error`) misses most of it: a response of
d = 3 T numbers (480 at L = 8) has a random-walk covariance of full rank, and 100
residuals span a fifth of it, so the distances come out too large, the more so the
longer the sequence. Braking sequences were predicted 3 points better than a classifier
measured them, and the front ranked them wrongly.

The covariance need not be estimated: the scenario states every noise source, and to
first order (the gyroscopic coupling of the noise neglected, the mean response kept
exact) each enters the measured rates linearly. For candidate k, with ``J_k = I_k⁻¹``,
the flattened series (time-major, 3 axes) has covariance

    Σ_k = q² σ_g² I                                  gyro white noise
        + p² σ_d² (O Oᵀ) ⊗ (J_k J_kᵀ)                disturbance torque, piecewise constant:
                                                     O[t, m] is how much of interval m lies
                                                     before sample t (a random walk)
        + (σ_0² + q² σ_b²) (1 1ᵀ) ⊗ I₃               initial rate and gyro bias (constant)
        + Σ_{s, j firing} v(d_sj) u_sj u_sjᵀ          duty jitter: u_sj = g_s ⊗ J_k A_j, g_s
                                                     the low-passed step pulse integrated,
                                                     v the variance of the delivered duty
                                                     clip(d + ε, 0, 1) (censored normal)
        + σ_s² Σ_j w_j w_jᵀ                          thrust-scale error: w_j = Σ_s d_sj u_sj

(``p``, ``q`` the design multiples of the disturbance and of the gyro noise and bias, as
:class:`~inertia_id.physics.simulate.Simulator` scales them). The means are the
noise-free responses, simulated exactly (coupling included). A pair of candidates is
judged under their average covariance, ``D²_ij = Δμᵀ Σ̄_ij⁻¹ Δμ``, and the union bound
``P_error ≈ (2/K) Σ_{i<j} Φ(−D_ij / 2)`` is the prediction.

How it is computed, and why it is fast: the first two terms are a Kronecker product,
diagonal in the basis ``W ⊗ V`` (W the eigenvectors of O Oᵀ, once per length; V those
of the pair's 3 x 3 ``J Jᵀ``), so Σ̄'s base part is whitened by two small matrix
products; the low-rank rest (L N + N + 3 columns: pulses ⊗ directions, offsets) goes through the
Woodbury identity, its columns whitened once per pair and weighted per sequence. No
d x d matrix is formed or factored per sequence, and nothing is random: the same
sequence always gets the same prediction.

On the paper preset, where the accuracy is above 0.95, its predictions sit up to about a
point below what the ceiling measures (6x process: 0.964 against 0.973 for the
hand-designed sequence, 0.963 against 0.969 for the L = 8 front's best; one braking
sequence 0.4 above); lower down the union bound is looser and the prediction further
below. The union bound over-counts errors where several candidates are close, and the
first-order covariance neglects how the noise couples between axes (which of the two
weighs more is not measured). ``bench/pareto_front.py`` prints the prediction beside the
default classifier and the ceiling for every row, and ``tests/search/test_noise_model.py``
checks it against the ceiling.

The same Gaussians classify: :meth:`LinearNoiseModel.log_likelihoods` is the density of
a measured series under each candidate's mean and covariance, by the same Woodbury
algebra per candidate, with no d x d matrix formed. A front's members are tested with it
on fresh series, and the ceiling takes its covariance where it classifies better than
the sample covariance.
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np

# The delivered duty's moments live beside the clip they describe; the estimator takes its
# expected torque from the same function, and the old name stays importable from here.
from ..physics.actuation import delivered_duty_moments as clipped_duty_moments
from ..physics.scenario import Scenario
from ..physics.simulate import disturbance_walk, nominal_simulator

__all__ = ["LinearNoiseModel", "clipped_duty_moments"]

#: Bytes the arrays of one block of pairs may take (P x pairs x R x R Gram matrices).
_BLOCK_BYTES = 64 * 2**20


def _integrated_pulses(scenario: Scenario, length: int, times: np.ndarray) -> np.ndarray:
    """(T, L): ∫₀ᵗ of the applied torque of a unit pulse commanded over step s, through
    the actuation low-pass (linear, so pulses superpose), at every sample time t."""
    step = scenario.timing.step_duration_s
    tau = scenario.uncertainty.lowpass_time_constant_s

    def ramp(u: np.ndarray) -> np.ndarray:
        u = np.maximum(u, 0.0)
        if tau == 0.0:
            return u
        return np.asarray(u - tau * -np.expm1(-u / tau))

    starts = np.arange(length) * step
    return ramp(times[:, None] - starts) - ramp(times[:, None] - starts - step)


class LinearNoiseModel:
    """Predicted accuracy of sequences of one length under a scenario's noise model.

    :param scenario: the spacecraft, its thrusters and its 1x noise.
    :param sequence_length: L, steps of every sequence scored.
    """

    def __init__(self, scenario: Scenario, sequence_length: int) -> None:
        self.scenario = scenario
        self.sequence_length = int(sequence_length)
        unc = scenario.uncertainty
        times = scenario.sample_times(self.sequence_length)
        self.n_samples = len(times)
        gamma, self._w = np.linalg.eigh(disturbance_walk(scenario, self.sequence_length))
        self._gamma = np.maximum(gamma, 0.0)
        pulses = _integrated_pulses(scenario, self.sequence_length, times)  # (T, L)
        self._pulses_w = self._w.T @ pulses  # (T, L) in W's basis
        self._ones_w = self._w.T @ np.ones(self.n_samples)  # (T,)
        inverse = np.linalg.inv(scenario.inertia_array)  # (K, 3, 3)
        torque = scenario.torque_matrix  # (3, N)
        self._pairs = list(combinations(range(scenario.n_candidates), 2))
        first, second = (np.array(side) for side in zip(*self._pairs, strict=True))
        self._first, self._second = first, second
        spread = np.einsum("kab,kcb->kac", inverse, inverse)  # J Jᵀ, (K, 3, 3)
        lam, self._v = np.linalg.eigh(0.5 * (spread[first] + spread[second]))  # pairs
        self._lam = np.maximum(lam, 0.0)  # (pairs, 3)
        mean_inverse = 0.5 * (inverse[first] + inverse[second])  # (pairs, 3, 3)
        # Each thruster's rate direction J A_j of the pair, in V's basis: (pairs, N, 3).
        self._directions_v = np.einsum(
            "pba,pbc,cn->pna", self._v, mean_inverse, torque, optimize=True
        )
        self._jitter = unc.duty_jitter_sigma
        self._scale = unc.thrust_scale_sigma
        self._initial = unc.initial_rate_sigma_rad_s
        self._bias = unc.gyro_bias_sigma_rad_s
        self._white = unc.gyro_noise_sigma_rad_s**2
        # The mean response fires each thruster at its expected delivered duty (clipping
        # at full duty shortens it by σ/√(2π)), as the classifier's training means do.
        self._quiet, self._quiet_noise = nominal_simulator(scenario, self.sequence_length)
        self._quiet.level_values = clipped_duty_moments(
            scenario.level_values, unc.duty_jitter_sigma
        )[0]
        # A variance floor keeps Σ invertible with every noise off: 1e-12 of the squared
        # rate one full-duty step gives the lightest axis, a property of the scenario
        # (never of the batch scored, so a sequence's prediction is its own).
        step_rate = (
            float(np.linalg.norm(torque, axis=0).max())
            * scenario.timing.step_duration_s
            / float(np.linalg.eigvalsh(scenario.inertia_array).min())
        )
        self._floor = 1e-12 * step_rate**2 + np.finfo(float).tiny

    def mean_responses(self, sequences: np.ndarray) -> np.ndarray:
        """Noise-free rates of every candidate, (P, K, T, 3), rad/s."""
        return self._quiet.population_rates(np.asarray(sequences), self._quiet_noise)[:, :, 0]

    def mean_run(self, sequences: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`mean_responses`, and each candidate's residual rate on that mean
        response once the actuation lag has delivered the torque still in it
        (:meth:`Simulator.settled`), (P, K) rad/s, from the same simulation. Like the
        means, it fires each thruster at the clipped jitter's mean duty and has no other
        noise: the settled rate of the mean, not the mean settled rate an
        :class:`~inertia_id.search.operator.OperatorScorer` averages over realisations."""
        rates, end = self._quiet.population_run(np.asarray(sequences), self._quiet_noise)
        return rates[:, :, 0], self._quiet.settled(end)[:, :, 0]

    @property
    def pairs(self) -> list[tuple[int, int]]:
        """The candidate pairs (i < j), in the order of :meth:`mahalanobis_sq`'s columns."""
        return list(self._pairs)

    def predicted_error(
        self,
        sequences: np.ndarray,
        conditions: tuple[tuple[float, float], ...],
        means: np.ndarray | None = None,
    ) -> np.ndarray:
        """The union-bound error of each sequence at each (process, measurement)
        multiple pair, (P, conditions); may exceed 1 for hopeless sequences (it still
        ranks them).

        :param sequences: (P, L, N) level indices, already checked.
        :param means: their noise-free responses, if already simulated.
        """
        from scipy.special import ndtr

        sequences = np.asarray(sequences)
        if means is None:
            means = self.mean_responses(sequences)
        k = self.scenario.n_candidates
        out = np.zeros((len(sequences), len(conditions)))
        for c, (process, measurement) in enumerate(conditions):
            d2 = self.mahalanobis_sq(sequences, process, measurement, means)
            out[:, c] = (2.0 / k) * ndtr(-0.5 * np.sqrt(d2)).sum(axis=1)
        return out

    def mahalanobis_sq(
        self,
        sequences: np.ndarray,
        process: float = 1.0,
        measurement: float = 1.0,
        means: np.ndarray | None = None,
    ) -> np.ndarray:
        """``D²_ij = Δμᵀ Σ̄_ij⁻¹ Δμ`` of each sequence and pair (:attr:`pairs`), (P, pairs).

        :param process: multiple of the disturbance torque sigma.
        :param measurement: multiple of the gyro noise and bias sigmas.
        """
        sequences = np.asarray(sequences)
        if means is None:
            means = self.mean_responses(sequences)
        # The thrust scale multiplies the delivered duty: its expected value.
        duties, variance = clipped_duty_moments(self.scenario.level_values[sequences], self._jitter)
        jitter_sd = np.sqrt(variance)  # (P, L, N)
        white = measurement**2 * self._white + self._floor
        offset_sd = math.sqrt(self._initial**2 + (measurement * self._bias) ** 2)
        rank = self.sequence_length * self.scenario.n_thrusters + self.scenario.n_thrusters + 3
        per_pair = 8 * len(sequences) * (4 * rank * rank + 4 * self.n_samples * (rank + 3))
        size = max(1, min(len(self._pairs), _BLOCK_BYTES // per_pair))
        blocks = [
            self._pair_distances(
                means,
                jitter_sd,
                duties,
                slice(start, start + size),
                process**2,
                white,
                offset_sd,
            )
            for start in range(0, len(self._pairs), size)
        ]
        return np.concatenate(blocks, axis=1)

    def dense_covariance(
        self,
        sequence: np.ndarray,
        candidates: tuple[int, ...],
        process: float = 1.0,
        measurement: float = 1.0,
    ) -> np.ndarray:
        """The covariance of the flattened series (d x d, time-major, (rad/s)²) written
        out term by term: one candidate's own, or for a pair the average
        :meth:`mahalanobis_sq` uses (the random walk's ``J Jᵀ`` averaged, the low-rank
        terms through the mean ``J``)."""
        sequence = np.asarray(sequence)
        unc = self.scenario.uncertainty
        inverse = np.linalg.inv(self.scenario.inertia_array[list(candidates)])
        spread = np.mean(np.einsum("kab,kcb->kac", inverse, inverse), axis=0)
        mean_inverse = inverse.mean(axis=0)
        walk = self._w @ np.diag(self._gamma) @ self._w.T
        t = self.n_samples
        sigma = process**2 * np.kron(walk, spread)
        sigma += measurement**2 * self._white * np.eye(3 * t)
        offset = self._initial**2 + (measurement * self._bias) ** 2
        sigma += offset * np.kron(np.ones((t, t)), np.eye(3))
        pulses = self._w @ self._pulses_w  # (T, L)
        duties, variance = clipped_duty_moments(
            self.scenario.level_values[sequence], unc.duty_jitter_sigma
        )
        directions = mean_inverse @ self.scenario.torque_matrix  # (3, N)
        # Column (s, j) is u_sj = g_s ⊗ J A_j, time-major like the series: (3 T, L N).
        columns = np.einsum("ts,aj->tasj", pulses, directions).reshape(3 * t, -1)
        sigma += (columns * variance.reshape(-1)) @ columns.T
        scale_columns = (columns.reshape(3 * t, *duties.shape) * duties[None]).sum(axis=1)
        sigma += unc.thrust_scale_sigma**2 * scale_columns @ scale_columns.T
        return np.asarray(sigma)

    def candidate_gaussians(
        self, sequence: np.ndarray, process: float = 1.0, measurement: float = 1.0
    ) -> tuple[np.ndarray, np.ndarray]:
        """Each candidate's mean (K, d) and covariance (K, d, d) of the flattened measured
        series (time-major, rad/s): the Gaussians of a classifier that knows the noise
        model rather than estimating it (the ceiling's other half, and how a front's
        members are tested on fresh draws). The means carry the scenario's fixed gyro
        bias; the covariances every noise term (no variance floor).
        """
        sequence = np.asarray(sequence)
        k = self.scenario.n_candidates
        bias = np.asarray(self.scenario.uncertainty.gyro_bias_rad_s, dtype=float)
        means = self.mean_responses(sequence[None])[0] + bias  # (K, T, 3)
        covariances = np.stack(
            [self.dense_covariance(sequence, (i,), process, measurement) for i in range(k)]
        )
        return means.reshape(k, -1), covariances

    def log_likelihoods(
        self,
        sequence: np.ndarray,
        series: np.ndarray,
        process: float = 1.0,
        measurement: float = 1.0,
        means: np.ndarray | None = None,
    ) -> np.ndarray:
        """Gaussian log-density of each measured series (n, T, 3) under each candidate's
        Gaussian of :meth:`candidate_gaussians` (plus the variance floor), (n, K).

        The same density as factoring the d x d covariance, without forming it: the
        random walk and the white noise are diagonal in ``W ⊗ V_k`` and the rest is a
        rank ``L N + N + 3`` Woodbury update, as in :meth:`mahalanobis_sq` but with each
        candidate's own ``J_k`` (about 5x faster than a Cholesky factor per candidate at
        L = 8, and the memory is n x d, not d x d).

        :param means: the noise-free responses (K, T, 3) of ``sequence``, if simulated.
        """
        sequence = np.asarray(sequence)
        x = np.asarray(series, dtype=float).reshape(len(series), self.n_samples, 3)
        k_count = self.scenario.n_candidates
        if means is None:
            means = self.mean_responses(sequence[None])[0]
        means = means + np.asarray(self.scenario.uncertainty.gyro_bias_rad_s, dtype=float)
        duties, variance = clipped_duty_moments(self.scenario.level_values[sequence], self._jitter)
        white = measurement**2 * self._white + self._floor
        offset = self._initial**2 + (measurement * self._bias) ** 2
        inverse = np.linalg.inv(self.scenario.inertia_array)
        torque = self.scenario.torque_matrix
        x_w = _time_basis(self._w, x)  # Wᵀ X, once for every candidate
        means_w = _time_basis(self._w, means)
        length, n_thr = duties.shape
        d = 3 * self.n_samples
        out = np.empty((len(x), k_count))
        for k in range(k_count):
            lam, v = np.linalg.eigh(inverse[k] @ inverse[k].T)
            eig = white + process**2 * self._gamma[:, None] * np.maximum(lam, 0.0)[None, :]
            scale = 1.0 / np.sqrt(eig)  # (T, 3)
            centred = (x_w - means_w[k]).reshape(-1, 3) @ v
            z = (centred.reshape(len(x), self.n_samples, 3) * scale).reshape(len(x), d)
            # The low-rank columns, whitened, as (d, R): jitter of each firing, the thrust
            # scale of each thruster, the constant offset on each axis.
            directions_v = (inverse[k] @ torque).T @ v  # (N, 3): (J_k A_j)ᵀ V
            unit = np.einsum("ts,ja->tasj", self._pulses_w, directions_v) * scale[:, :, None, None]
            jitter = unit * np.sqrt(variance)[None, None]
            thrust = (unit * duties[None, None]).sum(axis=2) * self._scale  # (T, 3, N)
            constant = self._ones_w[:, None, None] * v[None] * scale[:, :, None] * math.sqrt(offset)
            columns = np.concatenate(
                [
                    jitter.reshape(d, length * n_thr),
                    thrust.reshape(d, n_thr),
                    constant.reshape(d, 3),
                ],
                axis=1,
            )
            system = np.eye(columns.shape[1]) + columns.T @ columns
            lower = np.linalg.cholesky(system)
            projected = np.linalg.solve(lower, (z @ columns).T)  # (R, n)
            quadratic = np.einsum("nd,nd->n", z, z) - np.einsum("rn,rn->n", projected, projected)
            log_det = float(np.sum(np.log(eig)) + 2.0 * np.sum(np.log(np.diag(lower))))
            out[:, k] = -0.5 * (quadratic + log_det + d * math.log(2.0 * math.pi))
        return out

    def _pair_distances(
        self,
        means: np.ndarray,
        jitter_sd: np.ndarray,
        duties: np.ndarray,
        pairs: slice,
        process_sq: float,
        white: float,
        offset_sd: float,
    ) -> np.ndarray:
        """Squared Mahalanobis distances, (P, pairs in the block)."""
        v = self._v[pairs]  # (B, 3, 3)
        eig = white + process_sq * self._gamma[None, :, None] * self._lam[pairs][:, None, :]
        scale = 1.0 / np.sqrt(eig)  # (B, T, 3)
        delta = means[:, self._first[pairs]] - means[:, self._second[pairs]]  # (P, B, T, 3)
        z = np.matmul(np.matmul(self._w.T, delta), v) * scale
        # The low-rank part's columns, whitened: the pulse of each step (L of them)
        # times each thruster's direction, then the constant offset on each axis,
        # (B, d, L N + 3). Every sequence weights the same columns (its jitter, its
        # duties for the thrust scale), so their Gram matrix is formed once a block.
        b_count, length, n_thr = len(v), self.sequence_length, self.scenario.n_thrusters
        directions = self._directions_v[pairs]  # (B, N, 3)
        pulses = np.einsum("tl,bna->btaln", self._pulses_w, directions) * scale[..., None, None]
        offset = np.einsum("t,bac->btca", self._ones_w, v) * scale[..., None]
        base = np.concatenate(
            [pulses.reshape(b_count, -1, length * n_thr), offset.reshape(b_count, -1, 3)], axis=-1
        )
        flat_z = z.reshape(len(z), b_count, -1)
        d2 = np.einsum("pbd,pbd->pb", flat_z, flat_z)
        # Each sequence's columns as combinations of the base ones, (P, L N + 3, R).
        blocks = []
        if self._jitter > 0.0:
            blocks.append(_diagonal(jitter_sd.reshape(len(z), -1), 3))
        if self._scale > 0.0:
            # w_j = Σ_s d_sj u_sj: one column per thruster.
            summed = np.zeros((len(z), length, n_thr, n_thr))
            summed[:, :, np.arange(n_thr), np.arange(n_thr)] = duties * self._scale
            blocks.append(_pad(summed.reshape(len(z), length * n_thr, n_thr), 3))
        if offset_sd > 0.0:
            corner = np.zeros((len(z), length * n_thr + 3, 3))
            corner[:, length * n_thr :, :] = offset_sd * np.eye(3)
            blocks.append(corner)
        if not blocks:
            return d2
        mix = np.concatenate(blocks, axis=-1)  # (P, R0, R)
        base_gram = np.matmul(base.transpose(0, 2, 1), base)  # (B, R0, R0)
        base_projected = np.matmul(flat_z[:, :, None, :], base)[:, :, 0]  # (P, B, R0)
        projected = np.matmul(base_projected, mix)  # (P, B, R)
        mix_t = mix.transpose(0, 2, 1)[:, None]
        gram = np.matmul(np.matmul(mix_t, base_gram[None]), mix[:, None])  # (P, B, R, R)
        system = gram + np.eye(gram.shape[-1])
        solved = np.linalg.solve(system, projected[..., None])[..., 0]
        return np.maximum(d2 - np.einsum("pbr,pbr->pb", projected, solved), 0.0)


def _time_basis(w: np.ndarray, series: np.ndarray) -> np.ndarray:
    """``Wᵀ X`` for each series X (T, 3) of a stack (n, T, 3), as one matrix product."""
    n, t, _ = series.shape
    stacked = series.transpose(1, 0, 2).reshape(t, n * 3)
    return np.asarray((w.T @ stacked).reshape(t, n, 3).transpose(1, 0, 2))


def _diagonal(values: np.ndarray, extra_rows: int) -> np.ndarray:
    """(P, R) -> (P, R + extra_rows, R): each row of values on a diagonal, zero rows below."""
    p_count, r = values.shape
    out = np.zeros((p_count, r + extra_rows, r))
    out[:, np.arange(r), np.arange(r)] = values
    return out


def _pad(matrix: np.ndarray, extra_rows: int) -> np.ndarray:
    """(P, R0, R) with extra_rows zero rows below."""
    return np.concatenate([matrix, np.zeros((len(matrix), extra_rows, matrix.shape[-1]))], axis=1)
