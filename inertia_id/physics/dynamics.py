"""Rigid-body rotational dynamics: Euler's equations integrated with classic RK4.

Everything is batched: angular velocities have shape (K, n, 3) for K inertia candidates
and n realisations each, and one call advances the whole batch. Only time is looped.

State per series: body rate ``omega`` (rad/s) and, when the actuation low-pass is on,
the applied thruster torque ``torque`` (N m), which relaxes towards the commanded torque
with time constant ``tau``:

    I dω/dt = -ω × (I ω) + m + d
    dm/dt   = (c - m) / tau          (m = c when tau = 0)

with c the commanded torque and d the disturbance torque, both held constant over an
integration step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["RigidBodies", "cross", "euler_rates"]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis; written out because ``np.cross`` is slow on batches."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def euler_rates(
    omega: np.ndarray, torque: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray
) -> np.ndarray:
    """dω/dt = I⁻¹ (M - ω × I ω), batched.

    :param omega: body rates (K, n, 3), rad/s.
    :param torque: total body torque (K, n, 3), N m.
    :param inertia: symmetric tensors (K, 3, 3), kg m^2; ``omega @ inertia`` is I ω
        because the tensor is symmetric.
    :param inertia_inv: their inverses.
    """
    momentum = omega @ inertia
    return (torque - cross(omega, momentum)) @ inertia_inv


@dataclass(frozen=True)
class RigidBodies:
    """A batch of rigid bodies sharing one integration step.

    :param inertia: (K, 3, 3) tensors, kg m^2 (symmetric, positive definite).
    :param dt: RK4 step, s.
    :param tau: actuation low-pass time constant, s; 0 disables the filter.
    """

    inertia: np.ndarray
    dt: float
    tau: float = 0.0
    inertia_inv: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "inertia_inv", np.linalg.inv(self.inertia))

    def step(
        self,
        omega: np.ndarray,
        torque: np.ndarray,
        commanded: np.ndarray,
        disturbance: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance rates and applied torque by one RK4 step.

        :param omega: (K, n, 3) rates at the start of the step, rad/s.
        :param torque: (K, n, 3) applied thruster torque at the start (ignored when
            ``tau`` is 0), N m.
        :param commanded: (K, n, 3) commanded thruster torque over the step, N m.
        :param disturbance: (K, n, 3) disturbance torque over the step, N m.
        :returns: rates and applied torque at the end of the step.
        """
        dt, inertia, inertia_inv = self.dt, self.inertia, self.inertia_inv
        if self.tau == 0.0:
            total = commanded + disturbance
            k1 = euler_rates(omega, total, inertia, inertia_inv)
            k2 = euler_rates(omega + 0.5 * dt * k1, total, inertia, inertia_inv)
            k3 = euler_rates(omega + 0.5 * dt * k2, total, inertia, inertia_inv)
            k4 = euler_rates(omega + dt * k3, total, inertia, inertia_inv)
            return omega + dt / 6.0 * (k1 + 2.0 * (k2 + k3) + k4), commanded
        rate = 1.0 / self.tau
        m1 = torque
        k1 = euler_rates(omega, m1 + disturbance, inertia, inertia_inv)
        j1 = (commanded - m1) * rate
        m2 = torque + 0.5 * dt * j1
        k2 = euler_rates(omega + 0.5 * dt * k1, m2 + disturbance, inertia, inertia_inv)
        j2 = (commanded - m2) * rate
        m3 = torque + 0.5 * dt * j2
        k3 = euler_rates(omega + 0.5 * dt * k2, m3 + disturbance, inertia, inertia_inv)
        j3 = (commanded - m3) * rate
        m4 = torque + dt * j3
        k4 = euler_rates(omega + dt * k3, m4 + disturbance, inertia, inertia_inv)
        j4 = (commanded - m4) * rate
        new_omega = omega + dt / 6.0 * (k1 + 2.0 * (k2 + k3) + k4)
        new_torque = torque + dt / 6.0 * (j1 + 2.0 * (j2 + j3) + j4)
        return new_omega, new_torque

    def run_reference(
        self,
        omega: np.ndarray,
        torque: np.ndarray,
        commanded: np.ndarray,
        disturbance: np.ndarray,
        *,
        substeps: int,
        per_interval: int,
        per_sample: int,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`run` as :meth:`step` looped in numpy: the reference the compiled kernel
        is tested against, and the one to call where :func:`euler_rates` is replaced
        (an ablation of the gyroscopic term: the kernel has its own arithmetic)."""
        shape = np.shape(omega)
        omegas, torques = [], []
        for sub in range(substeps):
            omega, torque = self.step(
                omega, torque, commanded, disturbance[..., sub // per_interval, :]
            )
            if (sub + 1) % per_sample == 0:
                omegas.append(omega)
                torques.append(np.broadcast_to(torque, shape))
        return (
            omega,
            np.broadcast_to(torque, shape),
            np.stack(omegas, axis=-2),
            np.stack(torques, axis=-2),
        )

    def run(
        self,
        omega: np.ndarray,
        torque: np.ndarray,
        commanded: np.ndarray,
        disturbance: np.ndarray,
        *,
        substeps: int,
        per_interval: int,
        per_sample: int,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`step` ``substeps`` times under one command, compiled (numba: see
        :mod:`inertia_id.physics._rk4`), recording every ``per_sample`` substeps.

        :param omega: (..., K, n, 3) rates at the start, rad/s (one leading population
            axis at most).
        :param torque: the applied torque then, same shape, N m.
        :param commanded: commanded torque over the step, broadcastable to ``omega``.
        :param disturbance: (K, n, intervals, 3) disturbance torque, each held for
            ``per_interval`` substeps, N m.
        :returns: rates and applied torque at the end, and at every sample, (..., K, n,
            S, 3).
        """
        from . import _rk4

        shape = np.shape(omega)
        if len(shape) not in (3, 4) or shape[-1] != 3:
            raise ValueError(f"omega must be (K, n, 3) or (P, K, n, 3), got {shape}")
        k, n = shape[-3:-1]
        if self.inertia.shape != (k, 3, 3):
            raise ValueError(f"{k} bodies a batch, but inertia is {self.inertia.shape}")
        if substeps % per_interval or substeps % per_sample:
            raise ValueError(
                f"{substeps} substeps are not whole intervals of {per_interval} and samples "
                f"of {per_sample}"
            )
        if np.shape(disturbance) != (k, n, substeps // per_interval, 3):
            raise ValueError(
                f"disturbance must be {(k, n, substeps // per_interval, 3)}, "
                f"got {np.shape(disturbance)}"
            )
        flat = (-1, *shape[-3:])  # one population axis, 1 when there is none

        def fresh(array: np.ndarray) -> np.ndarray:
            # A writable C-contiguous float64 copy: the one layout the kernel is compiled
            # (and warmed up) for, and the kernel writes into the state.
            return np.array(np.broadcast_to(array, shape), dtype=float, order="C").reshape(flat)

        omega_end, torque_end, held = fresh(omega), fresh(torque), fresh(commanded)
        samples = substeps // per_sample
        omega_out = np.empty((*omega_end.shape[:-1], samples, 3))
        torque_out = np.empty_like(omega_out)

        def layout(array: np.ndarray) -> np.ndarray:
            return np.require(array, dtype=float, requirements=["C", "W"])

        _rk4.integrate(
            omega_end,
            torque_end,
            held,
            layout(disturbance),
            layout(self.inertia),
            layout(self.inertia_inv),
            float(self.dt),
            0.0 if self.tau == 0.0 else 1.0 / self.tau,
            int(substeps),
            int(per_interval),
            int(per_sample),
            omega_out,
            torque_out,
        )
        return (
            omega_end.reshape(shape),
            torque_end.reshape(shape),
            omega_out.reshape(*shape[:-1], samples, 3),
            torque_out.reshape(*shape[:-1], samples, 3),
        )
