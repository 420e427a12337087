"""Physics baseline: least-squares inertia from the integral form of Euler's equations.

Integrating ``I dω/dt + ω × (I ω) = M`` over a window [t_a, t_b] gives

    I (ω(t_b) - ω(t_a)) + ∫ ω × (I ω) dt = ∫ M dt,

which is linear in the six unique entries θ = (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) of the
inertia tensor: ``I ω = Φ(ω) θ`` with Φ a (3, 6) matrix of rates, so each window gives
three equations ``[Φ(ω_b) - Φ(ω_a) + ∫ ω × Φ(ω) dt] θ = ∫ M dt``. The gyro signal is
never differentiated: the rates enter as differences of samples and as trapezoid-rule
integrals, so white gyro noise is averaged, not amplified.

The torque is the one *commanded*, M = A (s ⊙ u) with nominal thrust (s = 1) and the
duty u each thruster delivers on average: the commanded duty, except at full duty, where
the delivered duty is clipped and the scenario's duty jitter leaves a mean shortfall of
σ/√(2π) (0.8 % at σ = 0.02; taken as the full duty, it biased the inertia up by as
much). The jitter about that mean and thrust-scale errors are unknown to the estimator
and end up in the equation error. The actuation low-pass is a property of the scenario, so
by default its known time constant τ is applied: with τ dm/dt = c - m, m(0) = 0 and c
piecewise constant, ``∫_0^t m = ∫_0^t c - τ m(t)`` exactly, which removes a bias of τ c
from every window that starts before the torque has settled. Because the torque is
known in absolute terms, the inertia is identified in absolute terms too (kg m²), not
just up to scale; a thrust-scale error biases it by the same factor.

A sequence that fires one fixed torque direction identifies I⁻¹ M well but the full
tensor poorly (only the weak gyroscopic term separates the rest); the estimate reports
its condition number and standard errors, and the classifier compares candidates
by how much worse their tensors fit the same equations, which stays meaningful in that
case (see :class:`LeastSquaresClassifier`).

The rates in the regressor are measured, so their gyro noise adds its own square to the
normal equations and least squares reads the tensor light (errors in variables: with
the gyro noise alone on the paper preset and an 8-step sequence, Ixx 1.8 % light, 1.7 of
its standard errors on average; 38 % at 6x gyro noise). The noise's expected share,
sized from the pass's own residuals, is taken out of the normal equations
(:func:`_noise_corrected`): 0.1 % and 2.4 % on the same rows.

The standard errors allow for the windows' shared errors. Cumulative windows all
contain the same early intervals, so the disturbance torque accumulates along them as a
random walk, each actuation step's duty jitter enters every later window whole, and
gyro noise enters each window at its end sample (and its start, unless that is the
known rest). The textbook ``s² (ΦᵀΦ)⁻¹``, which assumes independent equations, came out
3 to 8 times too small (the truth beyond 2 of them in 37-83 % of simulated series); the
figure reported is a sandwich covariance under that error model, with the random walk's
and the gyro term's size measured from the series' own residuals and the jitter's taken
from the scenario (:func:`_sandwich_covariance`). The textbook figure stays as
``independent_std_kg_m2``, the excitation ranking :meth:`InertiaEstimate.poorly_excited`
uses.
"""

from __future__ import annotations

import math
import sys
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import fft as scipy_fft

from ..errors import InputError
from ..wording import counted
from .actuation import delivered_duty_moments
from .dynamics import cross
from .scenario import Scenario
from .series import check_series

__all__ = [
    "PARAMETER_NAMES",
    "InertiaEstimate",
    "commanded_momentum",
    "estimate_inertia",
    "parameters_from_tensor",
    "tensor_from_parameters",
]

PARAMETER_NAMES = ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")

# Singular values below this fraction of the largest are treated as zero: the
# corresponding parameter combination is not excited at all.
_RCOND = 1e-12
# ln of the largest float: the normal matrix (the squared singular values) stays below it.
_LOG_FLOAT_MAX = math.log(sys.float_info.max)
# The smallest largest rate the least squares takes, rad/s: far below any gyro's
# resolution, and far above where (ΦᵀΦ)⁺ overflows (the smallest singular value kept is
# 1e-12 of the largest).
_SMALLEST_RATE = 1e-100


def tensor_from_parameters(parameters: np.ndarray) -> np.ndarray:
    """Symmetric (..., 3, 3) tensors from (..., 6) entries (Ixx, Iyy, Izz, Ixy, Ixz, Iyz)."""
    p = np.asarray(parameters, dtype=float)
    xx, yy, zz, xy, xz, yz = np.moveaxis(p, -1, 0)
    return np.stack(
        (np.stack((xx, xy, xz), -1), np.stack((xy, yy, yz), -1), np.stack((xz, yz, zz), -1)),
        axis=-2,
    )


def parameters_from_tensor(tensor: np.ndarray) -> np.ndarray:
    """The six unique entries (Ixx, Iyy, Izz, Ixy, Ixz, Iyz) of (..., 3, 3) tensors."""
    t = np.asarray(tensor, dtype=float)
    return np.stack(
        (t[..., 0, 0], t[..., 1, 1], t[..., 2, 2], t[..., 0, 1], t[..., 0, 2], t[..., 1, 2]),
        axis=-1,
    )


def _momentum_regressor(omega: np.ndarray) -> np.ndarray:
    """Φ(ω) with ``I ω = Φ(ω) θ``: (..., 3) rates to (..., 3, 6), rad/s."""
    wx, wy, wz = omega[..., 0], omega[..., 1], omega[..., 2]
    zero = np.zeros_like(wx)
    columns = (
        (wx, zero, zero),
        (zero, wy, zero),
        (zero, zero, wz),
        (wy, wx, zero),
        (wz, zero, wx),
        (zero, wz, wy),
    )
    return np.stack([np.stack(c, axis=-1) for c in columns], axis=-1)


# The last few commanded impulses, by the scenario object itself (held, so its id is not
# reused; scenarios are frozen) and the sequence: a service identifies series after
# series against the same classifier, and this loop is a tenth of each verdict.
_MOMENTUM_CACHE: OrderedDict[tuple[int, bytes, bool, bool], tuple[Scenario, np.ndarray]] = (
    OrderedDict()
)
_MOMENTUM_CACHE_SIZE = 16
_MOMENTUM_LOCK = threading.Lock()


def commanded_momentum(
    scenario: Scenario, sequence: Any, *, lowpass: bool = True, at_start: bool = True
) -> np.ndarray:
    """Angular impulse of the expected commanded torque from the sequence start, N m s.

    The torque at nominal thrust and the duty each thruster delivers on average: the
    commanded duty, less the mean shortfall that clipping the scenario's duty jitter
    (``duty_jitter_sigma``) at full duty leaves (σ/√(2π)); the commanded duty itself
    where no jitter is stated.

    :param scenario: gives the torque matrix, levels, duty jitter, timing and the
        low-pass constant.
    :param sequence: (L, N) level indices.
    :param lowpass: apply the scenario's actuation low-pass (exact for piecewise-constant
        commands); False integrates the commanded steps as if applied instantly.
    :param at_start: prepend t = 0 (impulse 0) to the sample times.
    :returns: (T, 3) or, with ``at_start``, (T + 1, 3) impulse at the sample times
        (read-only: it may be shared with later calls).
    """
    sequence = scenario.check_sequence(sequence)
    key = (id(scenario), np.ascontiguousarray(sequence).tobytes(), lowpass, at_start)
    with _MOMENTUM_LOCK:
        hit = _MOMENTUM_CACHE.get(key)
        if hit is not None and hit[0] is scenario:
            _MOMENTUM_CACHE.move_to_end(key)
            return hit[1]
    impulse = _commanded_momentum(scenario, sequence, lowpass=lowpass, at_start=at_start)
    impulse.flags.writeable = False
    with _MOMENTUM_LOCK:
        _MOMENTUM_CACHE[key] = (scenario, impulse)
        while len(_MOMENTUM_CACHE) > _MOMENTUM_CACHE_SIZE:
            _MOMENTUM_CACHE.popitem(last=False)
    return impulse


def _commanded_momentum(
    scenario: Scenario, sequence: np.ndarray, *, lowpass: bool, at_start: bool
) -> np.ndarray:
    duty = scenario.duties(sequence)
    sigma = scenario.uncertainty.duty_jitter_sigma
    if sigma > 0.0:
        # The duty a thruster delivers on average: the clip at full duty passes only a
        # shortfall (σ/√(2π), 0.8 % of the thrust at σ = 0.02), which the nominal duty
        # left in every window as a bias of the same size on the inertia.
        duty = delivered_duty_moments(duty, sigma)[0]
    command = duty @ scenario.torque_matrix.T  # (L, 3), nominal thrust
    return _lowpass_impulse(scenario, command, lowpass=lowpass, at_start=at_start)


def _lowpass_impulse(
    scenario: Scenario, command: np.ndarray, *, lowpass: bool, at_start: bool
) -> np.ndarray:
    """Impulse at the sample times of (L, K) step-wise constant commands, (T (+1), K)."""
    timing = scenario.timing
    tau = scenario.uncertainty.lowpass_time_constant_s if lowpass else 0.0
    per_step = timing.samples_per_step
    offsets = np.arange(1, per_step + 1)[:, None] / timing.sample_rate_hz
    width = command.shape[1]
    impulse = np.empty((len(command) * per_step, width))
    done = np.zeros(width)  # impulse of the command up to the step start
    applied = np.zeros(width)  # low-pass state at the step start
    for step, c in enumerate(command):
        rows = slice(step * per_step, (step + 1) * per_step)
        if tau > 0.0:
            state = c + (applied - c) * np.exp(-offsets / tau)
            impulse[rows] = done + offsets * c - tau * state
            applied = state[-1]
        else:
            impulse[rows] = done + offsets * c
        done = done + timing.step_duration_s * c
    if at_start:
        impulse = np.concatenate([np.zeros((1, width)), impulse])
    return impulse


def _jitter_meat(
    scenario: Scenario,
    sequence: np.ndarray,
    regressor: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    *,
    lowpass: bool,
    at_start: bool,
) -> np.ndarray | None:
    """Var(Φᵀε) of the duty jitter, (n, 6, 6), or None without any.

    Each firing thruster's duty is off by an error drawn once per actuation step, so
    the torque error is constant over a step, along that thruster's torque, and
    enters every later cumulative window whole: a few large shared errors the
    per-interval random walk of :func:`_error_components` does not describe, and that
    the fit, which reads them as thrust scale, largely absorbs from the residuals. Its
    size is the scenario's stated ``duty_jitter_sigma``: one pass cannot measure it.
    With ``h_s`` the (low-passed) impulse of a unit command during step s, window w's
    error from step s is ``A e_s h_s(w)`` (e_s the thrusters' duty errors), so

        Var(Φᵀε) = Σ_s Ψ_sᵀ A diag(Var e_s) Aᵀ Ψ_s,   Ψ_s = Σ_w h_s(w) Φ_w.

    The mean shortfall the clip leaves at full duty (σ/√(2π), 0.8 % of the thrust at
    σ = 0.02) is in the expected torque (:func:`commanded_momentum`), not here.
    """
    sigma = scenario.uncertainty.duty_jitter_sigma
    if sigma <= 0.0:
        return None
    steps = len(sequence)
    unit = _lowpass_impulse(scenario, np.eye(steps), lowpass=lowpass, at_start=at_start)
    profile = unit[ends] - unit[starts]  # (W, L)
    n, n_windows = regressor.shape[:2]
    # Matrix products, not einsum: einsum does not reach BLAS here, and took 2.3x the
    # time of the whole estimate without the standard errors on a batch.
    psi = np.matmul(profile.T, regressor.reshape(n, n_windows, 18)).reshape(n, steps, 3, 6)
    torque = scenario.torque_matrix  # (3, N)
    variance = delivered_duty_moments(scenario.duties(sequence), sigma)[1]  # (L, N)
    middle = np.einsum("ai,si,bi->sab", torque, variance, torque)  # (L, 3, 3)
    weighted = np.matmul(middle[None], psi)  # (n, L, 3, 6)
    return np.asarray(
        np.matmul(np.swapaxes(psi.reshape(n, -1, 6), 1, 2), weighted.reshape(n, -1, 6))
    )


@dataclass(frozen=True)
class InertiaEstimate:
    """Least-squares inertia of one series or of a batch (leading dimensions ``...``).

    :param inertia_kg_m2: (..., 3, 3) estimated tensors, kg m².
    :param parameters_kg_m2: (..., 6) the same as (Ixx, Iyy, Izz, Ixy, Ixz, Iyz).
    :param parameter_std_kg_m2: (..., 6) standard errors that allow for the equation
        errors the windows share (a random walk along them and white gyro noise at
        their ends, both measured from the residuals, and the scenario's stated duty
        jitter per actuation step: :func:`_sandwich_covariance`). On simulated series
        (bench/estimate_coverage.py, 8-step sequence) the RMS of (estimate - truth) /
        error is 0.58-0.96 at 1x and 6x process noise, paper and paper-in-orbit, with
        the truth beyond 2 of them in 0-4 % of passes, and 0.57-1.14 at 6x gyro noise.
        A systematic error, a thrust scale off nominal or what is left of the noisy
        rates' bias where the sequence excites the tensor poorly, is not in them.
    :param independent_std_kg_m2: (..., 6) the textbook figure, from the residual
        variance as if every equation's error were independent: 3 to 8 times too small
        for overlapping windows, but a fair ranking of which parameters the sequence
        excites (what :meth:`poorly_excited` compares).
    :param residual_rms_nms: (...) RMS equation error at the estimate, N m s.
    :param singular_values: (..., 6) of the stacked regressor, descending, rad/s.
    :param condition_number: (...) largest / smallest singular value (inf: some
        combination is not excited at all).
    :param weakest_direction: (..., 6) unit parameter combination least excited (the
        last right singular vector; its sign is arbitrary).
    :param normal_matrix: (..., 6, 6) ΦᵀΦ - K of the stacked equations, (rad/s)², K the
        gyro noise's expected share (:func:`_noise_corrected`); the equation error of any
        tensor θ less that share, ``|b - Φθ|² - θᵀKθ`` (what the noise-free rates would
        give, in expectation), exceeds the estimate's by ``(θ - θ̂)ᵀ (ΦᵀΦ - K) (θ - θ̂)``.
    :param windows_s: (W, 2) start and end of each window, s from the sequence start.
    """

    inertia_kg_m2: np.ndarray
    parameters_kg_m2: np.ndarray
    parameter_std_kg_m2: np.ndarray
    independent_std_kg_m2: np.ndarray
    residual_rms_nms: np.ndarray
    singular_values: np.ndarray
    condition_number: np.ndarray
    weakest_direction: np.ndarray
    normal_matrix: np.ndarray
    windows_s: np.ndarray

    @property
    def n_equations(self) -> int:
        """Scalar equations per series: three per window."""
        return 3 * len(self.windows_s)

    def poorly_excited(self, rtol: float = 0.01) -> list[str]:
        """Parameters whose independent-error standard error exceeds ``rtol`` x the mean
        moment.

        That figure, not :attr:`parameter_std_kg_m2`, because this rule ranks how well
        the sequence excites each parameter, and its thresholds (here and in
        ``identify``'s 2 %) were set on it; the honest error also grows with the noise,
        and would withhold a good estimate from noisy telemetry. The mean moment is
        tr(I)/3 of the estimate; for a batch the median over series is compared, so one
        wild series does not decide.
        """
        scale = np.trace(self.inertia_kg_m2, axis1=-2, axis2=-1) / 3.0
        relative = self.independent_std_kg_m2 / np.abs(scale)[..., None]
        typical = np.median(relative.reshape(-1, 6), axis=0)
        return [name for name, r in zip(PARAMETER_NAMES, typical, strict=True) if r > rtol]


def _windows(
    n_grid: int, sample_rate_hz: float, window_s: float | None
) -> tuple[np.ndarray, np.ndarray]:
    """Start and end grid indices of the windows."""
    if window_s is None:
        ends = np.arange(1, n_grid)
        return np.zeros_like(ends), ends
    width = window_s * sample_rate_hz
    samples = round(width) if math.isfinite(width) else 0
    if not (math.isfinite(width) and abs(width - samples) < 1e-6 and samples >= 1):
        raise InputError(
            f"window_s = {window_s!r} is not a whole number of sample periods "
            f"(1/{sample_rate_hz:g} s)"
        )
    if samples >= n_grid:
        raise InputError(
            f"window_s = {window_s!r} is {samples} samples; the telemetry grid has only "
            f"{n_grid} points"
        )
    starts = np.arange(0, n_grid - samples)
    return starts, starts + samples


def _check_fittable(rates: np.ndarray, span_s: float, n_equations: int) -> None:
    """Refuse rates too large (or too small) for the least squares, before any arithmetic
    on them.

    A regressor entry is a rate difference (at most 2 |ω|) plus the gyroscopic term's
    integral over at most ``span_s`` (|ω × Φ(ω)| <= √6 |ω|², so at most 2√6 span |ω|²),
    and the largest singular value's square (the normal matrix ΦᵀΦ holds it) is at most
    the trace of ΦᵀΦ: the squares of the 6 × ``n_equations`` entries. Past the float
    range, that arithmetic gave inf, then NaN (numpy's RuntimeWarnings "overflow" and
    "invalid value"), and either an SVD that failed or an estimate with an infinite
    normal matrix. The bound is worked out in Python floats, which overflow to inf
    quietly, and compared in logarithms.
    """
    peak = float(np.abs(rates).max())
    if 0.0 < peak < _SMALLEST_RATE:
        # The inverse singular values squared, (ΦᵀΦ)⁺, passed the float range below about
        # 1e-142 rad/s: the standard errors came out NaN after RuntimeWarnings "overflow"
        # and "invalid value". Rates all 0 stay: nothing is excited, the errors are inf.
        raise InputError(
            f"the least squares cannot fit rates this small (the largest is {peak:g} "
            f"rad/s, under {_SMALLEST_RATE:g}): are they in rad/s, and uncorrupted?"
        )
    entry = 2.0 * peak + 2.0 * math.sqrt(6.0) * span_s * peak * peak
    if entry > 0.0 and 2.0 * math.log(entry) + math.log(6 * n_equations) >= _LOG_FLOAT_MAX:
        raise InputError(
            f"the least squares cannot fit rates this large (the largest is {peak:g} "
            "rad/s: its square and fourth power pass the floating-point range): are they "
            "in rad/s, and uncorrupted?"
        )


def _psd(matrix: np.ndarray) -> np.ndarray:
    """Symmetric (..., 3, 3) matrices with their negative eigenvalues clipped to 0."""
    symmetric = 0.5 * (matrix + np.swapaxes(matrix, -1, -2))
    values, vectors = np.linalg.eigh(symmetric)
    return np.einsum("...ik,...k,...jk->...ij", vectors, np.maximum(values, 0.0), vectors)


# Random-walk to white variance ratios the Whittle fit tries (0: white only, and a
# fine logarithmic grid; the pure random walk is tried apart).
_WALK_RATIOS = np.concatenate([[0.0], np.geomspace(1e-7, 1e4, 111)])


def _error_components(
    grid_residual: np.ndarray, on_grid: np.ndarray, *, rest_start: bool
) -> tuple[np.ndarray, np.ndarray]:
    """W and R (each (n, 3, 3)) of :func:`_sandwich_covariance`, from the residuals.

    Between consecutive measured grid points (g intervals apart) the equation error's
    increments d_i = w_i + v_i - v_(i-1) have the covariance ``W g I + R T``, T the
    second-difference matrix (2 on the diagonal, -1 beside it). Their variance and
    lag-1 covariance would give W and R by moments, but at the noise levels that matter
    the white term dominates every lag by far (at 1x on the paper preset R is a
    thousand times the random walk's per-interval variance) and W drowns in its sampling
    noise: the random walk shows only in the slowest components. The orthonormal
    discrete sine transform (DST-I) diagonalises T exactly (eigenvalues
    ``λ_k = 2 - 2 cos(π k / (m + 1))``), so the transformed increments are independent
    with variances ``W g + R λ_k``: an exact Gaussian likelihood per axis, maximised
    over a grid of ratios W / R with R profiled out. (A periodogram of the increments
    instead reads its end points' noise as low-frequency power and found a random walk
    in white gyro noise alone.) The cross-axis terms then come by weighted least
    squares of the transformed cross-products on the two shapes, and each matrix is
    made positive semi-definite. At a known rest start the first increment (no noise at
    its start) is left out; irregular gaps (a dropout) are read at their mean width.
    """
    n = grid_residual.shape[0]
    points = np.flatnonzero(on_grid)
    zero = np.zeros((n, 3, 3))
    gap = float(np.mean(np.diff(points))) if len(points) > 1 else 1.0
    d = grid_residual[:, points[1:]] - grid_residual[:, points[:-1]]  # (n, m, 3)
    rest = rest_start and len(points) > 0 and points[0] == 0
    if d.shape[1] - rest < 6:
        # Too few increments to tell the two terms apart (sparse telemetry): all of
        # their spread is read as the random walk, which the windows accumulate, so the
        # figure errs large, not at 0 as if the residuals had shown no error at all.
        # The fit's 6 parameters take 2 of the k increments' 3 k components out of
        # them (cumulative windows: one window per increment), hence k - 2.
        k = d.shape[1]
        if k == 0:
            return zero, zero
        return _psd(np.einsum("nka,nkb->nab", d, d) / (max(k - 2, 1) * gap)), zero
    if rest:
        d = d[:, 1:]
    m = d.shape[1]
    y = scipy_fft.dst(d, type=1, axis=1, norm="ortho")  # (n, m, 3), independent
    white_shape = 2.0 - 2.0 * np.cos(np.pi * np.arange(1, m + 1) / (m + 1))  # (m,)
    products = np.einsum("nka,nkb->nkab", y, y)
    power = np.einsum("nkaa->nka", products)
    shapes = _WALK_RATIOS[:, None] + white_shape[None, :]  # (P, m): variance / R
    tiny = np.finfo(float).tiny
    # R profiled out: R̂ = mean(y² / shape); the negative log-likelihood up to constants
    # is Σ log shape + m log R̂.
    white_hat = np.einsum("nka,pk->nap", power, 1.0 / shapes) / m  # (n, 3, P)
    cost = np.sum(np.log(shapes), axis=1)[None, None, :] + m * np.log(np.maximum(white_hat, tiny))
    walk_only = np.mean(power, axis=1)  # (n, 3): the pure random walk, R = 0
    cost_walk = m * np.log(np.maximum(walk_only, tiny))
    best = np.argmin(cost, axis=-1)  # (n, 3)
    white_axis = np.take_along_axis(white_hat, best[..., None], axis=-1)[..., 0]
    walk_axis = _WALK_RATIOS[best] * white_axis
    pure = cost_walk < np.take_along_axis(cost, best[..., None], axis=-1)[..., 0]
    white_axis = np.where(pure, 0.0, white_axis)
    walk_axis = np.where(pure, walk_only, walk_axis)
    # Cross terms: y_a y_b ≈ W_ab + R_ab λ_k, weighted by 1 / (S_a S_b), each S over its
    # axis's largest (a factor per pair, which leaves the weighted least squares as it
    # is). An axis whose residual does not vary (S = 0 throughout: constant rates of
    # 1e-40 rad/s, no rest start) shares no covariance: weights of 1 / tiny overflowed
    # the normal matrix, pinv made the cross terms NaN and eigh raised LinAlgError.
    fitted = walk_axis[:, None, :] + white_axis[:, None, :] * white_shape[None, :, None]
    peak = np.max(fitted, axis=1, keepdims=True)
    scaled = np.divide(fitted, peak, out=np.zeros_like(fitted), where=peak > 0.0)
    product = scaled[:, :, :, None] * scaled[:, :, None, :]
    weight = np.divide(1.0, product, out=np.zeros_like(product), where=product > 0.0)
    basis = np.stack([np.ones_like(white_shape), white_shape], axis=-1)  # (m, 2)
    normal = np.einsum("nkab,ki,kj->nabij", weight, basis, basis)
    rhs = np.einsum("nkab,ki,nkab->nabi", weight, basis, products)
    solved = np.einsum("nabij,nabj->nabi", np.linalg.pinv(normal), rhs)
    walk = solved[..., 0]
    white = solved[..., 1]
    diagonal = np.arange(3)
    walk[:, diagonal, diagonal] = walk_axis
    white[:, diagonal, diagonal] = white_axis
    return _psd(walk / gap), _psd(white)


def _sandwich_covariance(
    regressor: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    grid_residual: np.ndarray,
    on_grid: np.ndarray,
    *,
    rest_start: bool,
    inverse_normal: np.ndarray,
    known_meat: np.ndarray | None = None,
) -> np.ndarray:
    """Covariance of the estimate under the equation errors the windows share, (n, 6, 6).

    The textbook ``s² (ΦᵀΦ)⁻¹`` assumes independent equation errors; windows that
    overlap share theirs (cumulative windows share everything before the earlier end),
    and that figure came out 3 to 8 times too small on simulated series. The equation
    error of window [a, b] is ``ε(b) - ε(a)`` of one error process on the grid, whose
    increment over grid interval j is

        d_j = w_j + v_j - v_(j-1):

    w a random walk's increments (disturbance torque, and duty jitter, drawn once per
    actuation step, which at the scales the estimate feels, seconds, acts as one; W per
    interval, 3 x 3 over the axes) and v white per sample (gyro noise times the inertia:
    R; v = 0 at a known rest start). Writing ``E_k`` for the sum of the regressors of
    the windows that end at grid point k less those that start there,
    ``Φᵀε = Σ_k E_kᵀ ε(k) = Σ_j G_jᵀ d_j`` with ``G_j = Σ_(k > j) E_k`` (the windows that
    contain interval j), so

        Var(Φᵀε) = Σ_j G_jᵀ W G_j + Σ_k E_kᵀ R E_k,

    that is Cov(window 1, window 2) = W x (intervals they share) + R x (the shared end
    points, with sign), and ``Cov(θ̂) = (ΦᵀΦ)⁻¹ Var(Φᵀε) (ΦᵀΦ)⁻¹`` (the sandwich) for
    whatever windows were used. W and R come from the telemetry's own residuals
    (:func:`_error_components`), not from the scenario's stated noise, which real
    telemetry need not follow. No library estimator fits this: a HAC (Newey-West,
    statsmodels' ``cov_hac``) on the window residuals assumes a stationary error, which
    a random walk along cumulative windows is not, and a kernel on the increments would
    not cancel the over-differenced gyro term. The duty jitter, a duty error per
    firing thruster drawn once per actuation step, is neither: the fit reads it as
    thrust scale and absorbs most of it from the residuals (with only the two terms
    above, the RMS z was 1.31-1.64 and 11-21 % beyond 2 at 1x on the paper preset, and
    2.3-5.2 on the jitter alone), so its covariance ``known_meat`` (:func:`_jitter_meat`, the
    scenario's stated size) is added to the meat. A systematic error (a thrust scale
    off nominal, a gyro bias) is not in the residuals' spread, and not in this figure.

    :param regressor: (n, W, 3, 6) each window's regressor.
    :param starts: (W,) each window's start grid index; ``ends`` likewise.
    :param grid_residual: (n, G, 3) equation error at each grid point (windows: differences).
    :param on_grid: (G,) the grid points that are measurements the windows may use.
    :param rest_start: grid point 0 is the known rest (no gyro noise there).
    :param inverse_normal: (n, 6, 6) (ΦᵀΦ - K)⁺, the corrected normal matrix's inverse
        (:func:`_noise_corrected`).
    :param known_meat: (n, 6, 6) Var(Φᵀε) of errors not measured from the residuals
        (the duty jitter), added to the meat.
    """
    n, n_grid = grid_residual.shape[:2]
    walk, white = _error_components(grid_residual, on_grid, rest_start=rest_start)
    ends_weight = np.zeros((n, n_grid, 3, 6))
    # Sliding windows have distinct starts and ends; cumulative ones share one start,
    # where a buffered ``-=`` would subtract only one window (hence the sum).
    ends_weight[:, ends] += regressor
    if np.all(starts == starts[0]):
        ends_weight[:, starts[0]] -= regressor.sum(axis=1)
    else:
        np.add.at(np.moveaxis(ends_weight, 1, 0), starts, -np.moveaxis(regressor, 1, 0))
    containing = np.flip(np.cumsum(np.flip(ends_weight, axis=1), axis=1), axis=1)[:, 1:]
    noisy = ends_weight[:, 1:] if rest_start else ends_weight

    def quadratic(weights: np.ndarray, middle: np.ndarray) -> np.ndarray:
        # Σ_j A_jᵀ M A_j as two matrix products (a three-operand einsum took 5x longer).
        weighted = np.matmul(middle[:, None], weights).reshape(n, -1, 6)
        return np.matmul(np.swapaxes(weights.reshape(n, -1, 6), 1, 2), weighted)

    meat = quadratic(containing, walk) + quadratic(noisy, white)
    if known_meat is not None:
        meat = meat + known_meat
    return np.asarray(inverse_normal @ meat @ inverse_normal)


# The most of the least-squares excitation in any direction that the gyro noise's
# expected share (Λ of :func:`_noise_corrected`) may take out: past it the corrected
# normal equations would be near singular, and the estimate's spread unbounded.
_MOST_NOISE_SHARE = 0.5

# Φ(e_a)ᵀ Φ(e_b), (3, 3, 6, 6): the regressor's noise Φ(n) = Σ_a n_a Φ(e_a) at one sample
# gives E[Φ(n)ᵀΦ(n)] = Σ_ab Cov(n)_ab Φ(e_a)ᵀ Φ(e_b).
_UNIT_PRODUCTS = np.einsum(
    "aki,bkj->abij", _momentum_regressor(np.eye(3)), _momentum_regressor(np.eye(3))
)


def _noise_corrected(
    theta: np.ndarray,
    grid_residual: np.ndarray,
    on_grid: np.ndarray,
    endpoint_count: np.ndarray,
    uncorrected: np.ndarray,
    inverse: np.ndarray,
    vt: np.ndarray,
    *,
    rest_start: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """The gyro noise's expected share of the normal equations, in the SVD's frame.

    The rates in the regressor are measured: Φ̃ = Φ + N with N the gyro noise's part,
    so ``E[Φ̃ᵀΦ̃] = ΦᵀΦ + K``, ``K = E[NᵀN]``, and least squares shrinks the tensor
    (errors in variables: Ixx 1.8 % light with 1x gyro noise alone on the paper preset,
    tens of percent at 6x). The corrected estimate solves ``(Φ̃ᵀΦ̃ - K) θ = Φ̃ᵀb``.
    A window's noise is ``Φ(n_b) - Φ(n_a)`` (its end samples; none at a known rest
    start) plus the gyroscopic integral's. That term is quadratic in ω; its part
    quadratic in n, ``n × (E_p n)`` per column (E_p symmetric), has mean 0 and adds
    O(σ⁴) to K; the part linear in n enters with the sample period h against |ω|, and
    adds under h |ω| ≈ 0.2 % of K on the paper preset (20 Hz, 0.03 rad/s): both left
    out. So K = Σ_k c_k Σ_ab Cov(n)_ab Φ(e_a)ᵀΦ(e_b), c_k the windows that start or end
    at sample k, over the samples not ``uncorrected`` (a known rest, and the start that
    cumulative windows share: see :func:`estimate_inertia`).

    Cov(n) is sized from the first fit's residuals, not the scenario's stated noise
    (which real telemetry need not follow): their white part R (the sandwich's,
    :func:`_error_components`) is Cov(Î n), so Cov(n) = Î⁻¹ R Î⁻¹, whatever the first
    fit's bias (the residual's white part is the noise through the same Î).

    No library estimator fits: total least squares (scipy.odr, an SVD of [Φ̃ b]) assumes
    every regressor entry noisy with one known variance ratio, independent across
    rows, while here the 18 entries of a window's regressor are a fixed linear map of
    three rates, the cumulative windows share their start's, and b is not noisy.

    In the SVD's frame (Φ̃ = U S Vᵀ), ``Φ̃ᵀΦ̃ - K = V S (1 - M) S Vᵀ`` with
    ``M = S⁻¹ Vᵀ K V S⁻¹ = Q Λ Qᵀ``: Λ is the noise's share of the excitation along
    each of Q's directions, capped at ``_MOST_NOISE_SHARE`` (where the noise is most
    of the excitation, the corrected equations are near singular).

    :returns: Q (n, 6, 6) and 1 / (1 - Λ) (n, 6).
    """
    white = _error_components(grid_residual, on_grid, rest_start=rest_start)[1]
    tensor_inverse = np.linalg.pinv(tensor_from_parameters(theta))
    rate_covariance = _psd(tensor_inverse @ white @ tensor_inverse)  # (n, 3, 3)
    noisy_ends = float(np.sum(np.where(uncorrected, 0, endpoint_count)))
    expected = noisy_ends * np.einsum("nab,abij->nij", rate_covariance, _UNIT_PRODUCTS)
    share = inverse[:, :, None] * np.matmul(vt, np.matmul(expected, np.swapaxes(vt, 1, 2)))
    share = share * inverse[:, None, :]
    values, turn = np.linalg.eigh(0.5 * (share + np.swapaxes(share, 1, 2)))
    return turn, 1.0 / (1.0 - np.clip(values, 0.0, _MOST_NOISE_SHARE))


def estimate_inertia(
    scenario: Scenario,
    sequence: Any,
    omega: Any,
    *,
    window_s: float | None = None,
    lowpass: bool = True,
    start_at_rest: bool | None = None,
    covered: Any = None,
    standard_errors: bool = True,
) -> InertiaEstimate:
    """Least-squares inertia tensor from gyro rates and the commanded torque.

    :param scenario: thrusters, levels, timing and low-pass of the spacecraft.
    :param sequence: (L, N) level indices the spacecraft was driven with.
    :param omega: (T, 3) or (n_series, T, 3) measured rates at ``scenario.sample_times``,
        rad/s; a batch is solved at once.
    :param window_s: None (default): every window starts at the first grid point and
        ends at a later one (cumulative form). Each equation then carries the gyro noise
        of one sample, not the difference of two, against a signal that grows with the
        window, so noise in the regressor biases the estimate least (errors in
        variables, corrected for: :func:`_noise_corrected`); the price is that process
        noise accumulates along the windows. A
        number: sliding windows of that length (a whole number of sample periods), one
        per start sample. Short windows suit strong process noise but shrink the signal
        in the regressor until gyro noise dominates it and the estimate collapses
        towards zero; one sample is finite differencing in disguise. On the paper
        preset with ``[[4, 4, 4, 0, 0, 0]] * 4``, cumulative windows classify 99 % right
        at 6x gyro noise and 95 % at 6x process noise, 0.5 s windows 26 % and 95 %.
    :param lowpass: apply the scenario's known actuation time constant to the commanded
        torque (see the module docstring).
    :param start_at_rest: the rate at t = 0 is known to be zero, so t = 0 joins the grid
        as an exact sample; None takes it from the scenario (its initial-rate spread is
        0). Otherwise the grid starts at the first measured sample, whose gyro noise
        then enters every cumulative window. A constant gyro bias is not modelled.
    :param covered: (T,) booleans, the grid times the telemetry measured (False inside
        a dropout, where ``omega`` is interpolated across it): only the windows that
        start and end at measured times give equations (cumulative windows start at
        the first measured time). The gyroscopic term's integral
        still runs through the interpolated rates (second order in the rate). None:
        every time.
    :param standard_errors: False skips the shared-error standard errors (their
        sandwich holds two more (n, G, 3, 6) arrays: a least-squares classifier's
        fit to 1,250 series of 8 steps peaked at 306 MB with them, 248 MB without, by
        tracemalloc; 207 MB without before the gyro noise's share was sized from the
        first fit's residuals) and
        leaves ``parameter_std_kg_m2`` NaN; what reads only the estimate, the normal
        matrix or the excitation ranking (``independent_std_kg_m2``) needs no more.
    """
    sequence = scenario.check_sequence(sequence)
    timing = scenario.timing
    n_samples = len(sequence) * timing.samples_per_step
    rates = check_series(omega)
    if rates.shape[1] != n_samples:
        raise InputError(
            f"omega has {rates.shape[1]} samples; the {len(sequence)}-step sequence gives "
            f"{n_samples} at {timing.sample_rate_hz:g} Hz"
        )
    single = np.ndim(omega) == 2
    if start_at_rest is None:
        start_at_rest = scenario.uncertainty.initial_rate_sigma_rad_s == 0.0
    impulse = commanded_momentum(scenario, sequence, lowpass=lowpass, at_start=start_at_rest)
    times = np.concatenate([[0.0], scenario.sample_times(len(sequence))])
    if start_at_rest:
        rates = np.concatenate([np.zeros((len(rates), 1, 3)), rates], axis=1)
    else:
        times = times[1:]
    starts, ends = _windows(len(times), timing.sample_rate_hz, window_s)
    if covered is not None:
        measured = np.asarray(covered, dtype=bool).reshape(-1)
        if measured.shape != (n_samples,):
            raise InputError(
                f"covered must hold {n_samples} booleans (one per grid time), got "
                f"{measured.shape[0]}"
            )
        if start_at_rest:
            measured = np.concatenate([[True], measured])  # the known rest at t = 0
        if window_s is None:
            # Cumulative windows from the first measured time: the grid's first time may
            # hold no sample (10 Hz telemetry on a 20 Hz grid), and from it every window
            # would be dropped.
            first = int(np.argmax(measured))
            ends = first + 1 + np.flatnonzero(measured[first + 1 :])
            starts = np.full_like(ends, first)
        else:
            use = measured[starts] & measured[ends]
            starts, ends = starts[use], ends[use]
    if 3 * len(starts) <= len(PARAMETER_NAMES):
        gives = "gives" if len(starts) == 1 else "give"
        fewer = "fewer" if 3 * len(starts) < len(PARAMETER_NAMES) else "no more"
        # As many equations as parameters fit exactly, whatever the noise: no residual
        # is left to measure the error by, and both standard errors came out 0.
        raise InputError(
            f"{counted(len(starts), 'window')} {gives} {fewer} equations than the 6 "
            "parameters (at least 3 windows are needed)"
        )
    _check_fittable(rates, float(times[-1] - times[0]), 3 * len(starts))

    momentum = _momentum_regressor(rates)  # (n, G, 3, 6)
    # ω × Φ(ω) column by column: the gyroscopic term ω × (I ω) is linear in θ too.
    gyroscopic = np.swapaxes(cross(rates[:, :, None, :], np.swapaxes(momentum, -1, -2)), -1, -2)
    half_step = 0.5 / timing.sample_rate_hz
    integral = np.zeros_like(gyroscopic)
    integral[:, 1:] = np.cumsum(half_step * (gyroscopic[:, 1:] + gyroscopic[:, :-1]), axis=1)
    regressor = (momentum[:, ends] - momentum[:, starts]) + (
        integral[:, ends] - integral[:, starts]
    )
    n = len(rates)
    design = regressor.reshape(n, -1, 6)
    target = (impulse[ends] - impulse[starts]).reshape(-1)

    try:
        u, singular, vt = np.linalg.svd(design, full_matrices=False)
    except np.linalg.LinAlgError:
        raise InputError(
            "the least squares did not converge on these rates (the largest is "
            f"{float(np.abs(rates).max()):g} rad/s): are they in rad/s, and uncorrupted?"
        ) from None
    keep = singular > _RCOND * singular[:, :1]
    inverse = np.divide(1.0, singular, out=np.zeros_like(singular), where=keep)
    projected = np.einsum("nmj,m->nj", u, target)  # Uᵀb
    theta = np.einsum("nji,nj->ni", vt, inverse * projected)
    on_grid = np.ones(len(times), dtype=bool) if covered is None else measured.copy()
    if window_s is None:
        on_grid[: starts[0]] = False
    # Errors in variables: the gyro noise in the regressor, sized from the first fit's
    # residuals, taken out of the normal equations (:func:`_noise_corrected`).
    uncorrected = np.zeros(len(times), dtype=bool)
    uncorrected[0] = bool(start_at_rest)  # the known rest holds no noise
    if np.all(starts == starts[0]):
        # Cumulative windows share their start sample: its noise is one draw, an offset
        # of the start rate in every window, which no average over windows removes, and
        # subtracting its expected square overcorrected (paper preset with an initial
        # rate, 1x gyro noise alone: Ixx from 1.7 % light to 2.4 % heavy; without that
        # share, 0.3 % heavy).
        uncorrected[starts[0]] = True
    turn, shrink = _noise_corrected(
        theta,
        impulse[None] - np.matmul(momentum + integral, theta[:, None, :, None])[..., 0],
        on_grid,
        np.bincount(starts, minlength=len(times)) + np.bincount(ends, minlength=len(times)),
        uncorrected,
        inverse,
        vt,
        rest_start=bool(start_at_rest),
    )
    # θ = V S⁻¹ Q (1 - Λ)⁻¹ Qᵀ Uᵀb, the least squares of the corrected normal equations.
    solver = np.einsum("nji,nj,njk,nk,nlk->nil", vt, inverse, turn, shrink, turn)
    theta = np.einsum("nil,nl->ni", solver, projected)
    residual = target[None, :] - np.einsum("nmj,nj->nm", design, theta)
    n_equations = design.shape[1]
    sum_squares = np.sum(residual**2, axis=1)
    dof = max(n_equations - len(PARAMETER_NAMES), 1)
    # (ΦᵀΦ - K)⁺ = V S⁻¹ Q (1 - Λ)⁻¹ Qᵀ S⁻¹ Vᵀ, the corrected normal matrix's inverse.
    inverse_normal = np.einsum("nij,nj,njl->nil", solver, inverse, vt)
    independent_diag = np.einsum("nii->ni", inverse_normal) * (sum_squares / dof)[:, None]
    excited = np.all(keep, axis=1)
    if standard_errors:
        # The equation error at every grid point, at the estimate: a window's error is
        # the difference of its end's and its start's.
        grid_residual = (
            impulse[None] - np.matmul(momentum + integral, theta[:, None, :, None])[..., 0]
        )
        covariance = _sandwich_covariance(
            regressor,
            starts,
            ends,
            grid_residual,
            on_grid,
            rest_start=bool(start_at_rest),
            inverse_normal=inverse_normal,
            known_meat=_jitter_meat(
                scenario,
                sequence,
                regressor,
                starts,
                ends,
                lowpass=lowpass,
                at_start=bool(start_at_rest),
            ),
        )
        std = np.where(
            excited[:, None], np.sqrt(np.maximum(np.einsum("nii->ni", covariance), 0.0)), np.inf
        )
    else:
        std = np.full_like(theta, np.nan)
    independent_std = np.where(excited[:, None], np.sqrt(independent_diag), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(excited, singular[:, 0] / singular[:, -1], np.inf)
    # ΦᵀΦ - K = V S Q (1 - Λ) Qᵀ S Vᵀ: the corrected equation error of θ, the expected
    # error free of gyro noise, grows from θ̂'s by (θ - θ̂)ᵀ (ΦᵀΦ - K) (θ - θ̂).
    scaled = np.einsum("nji,nj,njk->nik", vt, singular, turn)
    normal = np.einsum("nik,nk,njk->nij", scaled, 1.0 / shrink, scaled)

    def shaped(a: np.ndarray) -> np.ndarray:
        return a[0] if single else a

    return InertiaEstimate(
        inertia_kg_m2=shaped(tensor_from_parameters(theta)),
        parameters_kg_m2=shaped(theta),
        parameter_std_kg_m2=shaped(std),
        independent_std_kg_m2=shaped(independent_std),
        residual_rms_nms=shaped(np.sqrt(sum_squares / n_equations)),
        singular_values=shaped(singular),
        condition_number=shaped(condition),
        weakest_direction=shaped(vt[:, -1, :]),
        normal_matrix=shaped(normal),
        windows_s=np.stack([times[starts], times[ends]], axis=-1),
    )
