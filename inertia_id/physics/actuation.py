"""From a commanded duty level to the torque a thruster actually delivers.

The duty level of a step is a pulse-width-modulation setting: the thruster is on for
that fraction of each PWM period, and since the PWM period is far shorter than the
dynamics (and the actuation low-pass smooths it further), its effect is the
duty-weighted torque. What is delivered differs from what was commanded by the
thruster's timing jitter (per firing, per step) and its scale error (per realisation).
The delivered duty's mean and variance under that jitter (:func:`delivered_duty_moments`)
are what the estimator and the search's noise model take as the expected torque and its
spread; both call this one function.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError

__all__ = ["commanded_torque", "delivered_duty", "delivered_duty_moments"]

# Standard deviations past which a normal's density and tail probability are 0 in floats
# (scipy's ndtr(-38) is already 0, and exp(-0.5 · 40²) underflows to 0).
_NORMAL_REACH = 40.0

#: The largest duty jitter sigma whose moments are computed. The variance's rounding
#: error grows as about 4e-16 σ² (4e-14 relative at σ = 10, 4e-10 at 1e3, 4e-4 at 1e6,
#: against 80-digit arithmetic); a noise sweep reaches 1e4 (the scenario's bound of 10 at
#: the sweep's largest multiple, 1000x), and past 1e6 the figures would be noise.
MAX_MOMENT_SIGMA = 1e6


def delivered_duty(commanded: np.ndarray, jitter: np.ndarray) -> np.ndarray:
    """Duty actually delivered: commanded plus jitter on firing thrusters, within [0, 1].

    A thruster commanded off stays off (no jitter); one commanded on delivers its duty
    shifted by its response-time jitter, which cannot push it below off or above full.

    :param commanded: commanded duty, shape (N,) or broadcastable to ``jitter``.
    :param jitter: duty error of each firing, (K, n, N), fraction of full duty.
    """
    firing = commanded > 0.0
    return np.where(firing, np.clip(commanded + jitter, 0.0, 1.0), 0.0)


def delivered_duty_moments(commanded: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance of the delivered duty ``clip(d + ε, 0, 1)``, ε ~ N(0, σ²), for
    each commanded duty d (0 and 0 where the thruster is off: it does not fire).

    The censored normal's moments, computed in units of σ so that the variance keeps its
    precision as σ shrinks (E[Y²] − E[Y]² in absolute units was 3e-4 of itself off at
    σ = 1e-6 and 0 at 1e-12). Away from both bounds the mean is d and the variance σ²;
    at full duty the mean is 1 − σ/√(2π) and half the jitter is clipped away, the
    variance (1/2 − 1/(2π)) σ², about a third of σ². As σ → 0 the mean goes to
    clip(d, 0, 1) and the variance to 0; σ = 0 gives those limits exactly.

    :param commanded: commanded duty, any shape; ≤ 0 is off.
    :param sigma: the duty jitter's standard deviation, within [0, :data:`MAX_MOMENT_SIGMA`].
    :raises InputError: for a ``sigma`` outside that range, or NaN.
    """
    # Imported here: the simulator imports this module, and scipy is not needed to simulate.
    from scipy.special import ndtr

    sigma = float(sigma)
    if not 0.0 <= sigma <= MAX_MOMENT_SIGMA:  # NaN fails both comparisons
        raise InputError(
            f"duty jitter sigma = {sigma!r} (fraction of full duty) must be within "
            f"[0, {MAX_MOMENT_SIGMA:g}] for the delivered duty's moments"
        )
    d = np.asarray(commanded, dtype=float)
    firing = d > 0.0
    if sigma == 0.0:
        return np.where(firing, np.clip(d, 0.0, 1.0), 0.0), np.zeros_like(d)
    # The bounds of Z = (Y − d) / σ, held within the reach where every term below is
    # already 0 or 1 in floats. The distances are clipped before they are divided, so
    # that no quotient, square or 0 · inf overflows for a tiny σ (1e-160, 5e-324).
    reach = _NORMAL_REACH * sigma
    # Underflow is expected and harmless: a tiny σ makes the densities, σ² and the
    # bounds of a subnormal duty 0 or subnormal, which is their value.
    with np.errstate(under="ignore"):
        a = -np.clip(d, -reach, reach) / sigma
        b = np.clip(1.0 - d, -reach, reach) / sigma
        pdf_a = np.exp(-0.5 * a * a) / math.sqrt(2.0 * math.pi)
        pdf_b = np.exp(-0.5 * b * b) / math.sqrt(2.0 * math.pi)
        below, above = ndtr(a), ndtr(-b)
        first = a * below + b * above + pdf_a - pdf_b
        second = a * a * below + b * b * above + (1.0 - below - above) + a * pdf_a - b * pdf_b
        mean = d + sigma * first
        variance = sigma * sigma * np.maximum(second - first * first, 0.0)
    # A duty past full by more than the reach is held at full by the clip: its held
    # bound b would otherwise stand in for the true (1 − d) / σ.
    held = b <= -_NORMAL_REACH
    return (
        np.where(firing, np.where(held, 1.0, mean), 0.0),
        np.where(firing & ~held, variance, 0.0),
    )


def commanded_torque(
    torque_matrix: np.ndarray, duty: np.ndarray, thrust_scale: np.ndarray
) -> np.ndarray:
    """Body torque of the thrusters, M = A (scale ⊙ duty), batched.

    :param torque_matrix: A, (3, N), N m at full duty.
    :param duty: delivered duty, (K, n, N).
    :param thrust_scale: per-thruster torque scale of each realisation, (K, n, N).
    :returns: (K, n, 3) torque, N m.
    """
    return (duty * thrust_scale) @ torque_matrix.T
