"""From a commanded duty level to the torque a thruster actually delivers.

The duty level of a step is a pulse-width-modulation setting: the thruster is on for
that fraction of each PWM period, and since the PWM period is far shorter than the
dynamics (and the actuation low-pass smooths it further), its effect is the
duty-weighted torque. What is delivered differs from what was commanded by the
thruster's timing jitter (per firing, per step) and its scale error (per realisation).
"""

from __future__ import annotations

import numpy as np

__all__ = ["commanded_torque", "delivered_duty"]


def delivered_duty(commanded: np.ndarray, jitter: np.ndarray) -> np.ndarray:
    """Duty actually delivered: commanded plus jitter on firing thrusters, within [0, 1].

    A thruster commanded off stays off (no jitter); one commanded on delivers its duty
    shifted by its response-time jitter, which cannot push it below off or above full.

    :param commanded: commanded duty, shape (N,) or broadcastable to ``jitter``.
    :param jitter: duty error of each firing, (K, n, N), fraction of full duty.
    """
    firing = commanded > 0.0
    return np.where(firing, np.clip(commanded + jitter, 0.0, 1.0), 0.0)


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
