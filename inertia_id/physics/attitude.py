"""The body's attitude change over a sequence, from its rates: quaternion propagation.

Convention: a unit quaternion ``q = (w, x, y, z)`` (scalar first) rotates body-frame
vectors into the frame the body started in, and obeys ``q̇ = ½ q ⊗ (0, ω)`` with ω the
body rate (rad/s). Over a sample interval of length h the rate is taken as constant at
the mean of its two end samples, and the step is the exact rotation by that rate:
``q ← q ⊗ (cos(|ω| h / 2), sin(|ω| h / 2) ω / |ω|)``. For a rate that really is constant
this is exact (the test checks the closed form); otherwise it is second-order accurate in
h, and renormalised each step so rounding never leaves the unit sphere.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

__all__ = ["propagate_attitude", "quaternion_multiply", "rotation_angle_deg"]


def quaternion_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` over the last axis (scalar first), batched."""
    pw, px, py, pz = (p[..., i] for i in range(4))
    qw, qx, qy, qz = (q[..., i] for i in range(4))
    return np.stack(
        (
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ),
        axis=-1,
    )


def propagate_attitude(
    omega_rad_s: np.ndarray,
    sample_period_s: float,
    *,
    omega0_rad_s: np.ndarray | None = None,
) -> np.ndarray:
    """Attitude quaternions at each sample, from the body rates, batched.

    :param omega_rad_s: (..., T, 3) body rates at the end of each sample period, rad/s.
    :param sample_period_s: time between samples, s.
    :param omega0_rad_s: (..., 3) rate at the start (the sample before the first);
        default at rest.
    :returns: (..., T, 4) unit quaternions (w, x, y, z); the start is the identity.
    """
    omega = np.asarray(omega_rad_s, dtype=float)
    if omega.ndim < 2 or omega.shape[-1] != 3:
        raise InputError(f"omega must be shaped (..., T, 3), got {omega.shape}")
    if not (np.isfinite(sample_period_s) and sample_period_s > 0):
        raise InputError(f"sample_period_s must be finite and > 0, got {sample_period_s!r}")
    start = (
        np.zeros((*omega.shape[:-2], 3))
        if omega0_rad_s is None
        else np.broadcast_to(np.asarray(omega0_rad_s, dtype=float), (*omega.shape[:-2], 3))
    )
    previous = np.concatenate([start[..., None, :], omega[..., :-1, :]], axis=-2)
    mean_rate = 0.5 * (previous + omega)  # (..., T, 3)
    speed = np.linalg.norm(mean_rate, axis=-1, keepdims=True)
    half_angle = 0.5 * speed * sample_period_s
    # sin(x)/|ω| written with sinc so a zero rate gives the identity, not 0/0.
    axis_part = mean_rate * (0.5 * sample_period_s) * np.sinc(half_angle / np.pi)
    steps = np.concatenate([np.cos(half_angle), axis_part], axis=-1)  # (..., T, 4)
    out = np.empty(steps.shape)
    q = np.zeros((*omega.shape[:-2], 4))
    q[..., 0] = 1.0
    for t in range(steps.shape[-2]):
        q = quaternion_multiply(q, steps[..., t, :])
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        out[..., t, :] = q
    return out


def rotation_angle_deg(quaternion: np.ndarray) -> np.ndarray:
    """The angle of the rotation a unit quaternion describes, in [0, 180] degrees.

    ``2 atan2(|v|, |w|)``, not ``2 arccos(|w|)``: near the identity |w| rounds to 1 and
    arccos's slope is infinite there, so a turn of 1e-7 degrees read 0 (and one of 1e-5
    degrees 9.96e-6), where the vector part keeps its full relative precision."""
    q = np.asarray(quaternion, dtype=float)
    vector = np.linalg.norm(q[..., 1:], axis=-1)
    return np.asarray(np.degrees(2.0 * np.arctan2(vector, np.abs(q[..., 0]))))
