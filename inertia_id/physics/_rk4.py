"""The RK4 substep loop of :meth:`inertia_id.physics.dynamics.RigidBodies.run`, compiled
with numba.

Written out rather than left to numpy because the batches are small and the steps many:
a search simulates a population of 64 sequences x 5 candidates x 40 realisations (12,800
bodies) for 100 substeps a step, and numpy spent most of that time allocating the
temporaries of ``omega @ inertia``, the cross product and the four RK4 stages (each a
few hundred kilobytes) rather than computing them. Each body is integrated here in
registers, through every substep, with the same arithmetic as
:meth:`~inertia_id.physics.dynamics.RigidBodies.step` (which stays the readable
reference it is tested against).

Imported only when a simulation runs (``import inertia_id`` does not load numba); the
machine code is cached on disk (``cache=True``), so a fresh process loads it instead of
compiling again.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _rates(w0, w1, w2, t0, t1, t2, inertia, inverse):
    """dω/dt = I⁻¹ (M - ω × I ω) for one body, as :func:`~.dynamics.euler_rates`."""
    h0 = w0 * inertia[0, 0] + w1 * inertia[1, 0] + w2 * inertia[2, 0]
    h1 = w0 * inertia[0, 1] + w1 * inertia[1, 1] + w2 * inertia[2, 1]
    h2 = w0 * inertia[0, 2] + w1 * inertia[1, 2] + w2 * inertia[2, 2]
    r0 = t0 - (w1 * h2 - w2 * h1)
    r1 = t1 - (w2 * h0 - w0 * h2)
    r2 = t2 - (w0 * h1 - w1 * h0)
    return (
        r0 * inverse[0, 0] + r1 * inverse[1, 0] + r2 * inverse[2, 0],
        r0 * inverse[0, 1] + r1 * inverse[1, 1] + r2 * inverse[2, 1],
        r0 * inverse[0, 2] + r1 * inverse[1, 2] + r2 * inverse[2, 2],
    )


@njit(cache=True)
def integrate(
    omega,
    torque,
    commanded,
    disturbance,
    inertia,
    inverse,
    dt,
    rate,
    substeps,
    per_interval,
    per_sample,
    omega_out,
    torque_out,
):
    """Advance every body through ``substeps`` RK4 substeps, in place, recording the
    rates and applied torque every ``per_sample`` substeps.

    :param omega: (P, K, n, 3) rates, rad/s; overwritten with the rates at the end.
    :param torque: (P, K, n, 3) applied torque (the lag's state), N m; overwritten.
    :param commanded: (P, K, n, 3) commanded torque, held over the step, N m.
    :param disturbance: (K, n, intervals, 3) disturbance torque per interval, N m.
    :param inertia: (K, 3, 3) tensors; ``inverse`` their inverses.
    :param rate: 1 / tau; 0 for no lag (the applied torque is then the commanded).
    :param omega_out: (P, K, n, S, 3) rates at each sample; ``torque_out`` the torque.
    """
    n_pop, n_cand, n_real = omega.shape[0], omega.shape[1], omega.shape[2]
    lag = rate > 0.0
    half = 0.5 * dt
    sixth = dt / 6.0
    for p in range(n_pop):
        for k in range(n_cand):
            inertia_k = inertia[k]
            inverse_k = inverse[k]
            for i in range(n_real):
                w0, w1, w2 = omega[p, k, i, 0], omega[p, k, i, 1], omega[p, k, i, 2]
                c0, c1, c2 = commanded[p, k, i, 0], commanded[p, k, i, 1], commanded[p, k, i, 2]
                if lag:
                    m0, m1, m2 = torque[p, k, i, 0], torque[p, k, i, 1], torque[p, k, i, 2]
                else:
                    m0, m1, m2 = c0, c1, c2
                for sub in range(substeps):
                    interval = sub // per_interval
                    d0 = disturbance[k, i, interval, 0]
                    d1 = disturbance[k, i, interval, 1]
                    d2 = disturbance[k, i, interval, 2]
                    if lag:
                        # Stage by stage as RigidBodies.step: the lag's torque at each
                        # stage (m, a, b, e), and the lag's own RK4 update.
                        j10, j11, j12 = (c0 - m0) * rate, (c1 - m1) * rate, (c2 - m2) * rate
                        a0, a1, a2 = m0 + half * j10, m1 + half * j11, m2 + half * j12
                        j20, j21, j22 = (c0 - a0) * rate, (c1 - a1) * rate, (c2 - a2) * rate
                        b0, b1, b2 = m0 + half * j20, m1 + half * j21, m2 + half * j22
                        j30, j31, j32 = (c0 - b0) * rate, (c1 - b1) * rate, (c2 - b2) * rate
                        e0, e1, e2 = m0 + dt * j30, m1 + dt * j31, m2 + dt * j32
                        j40, j41, j42 = (c0 - e0) * rate, (c1 - e1) * rate, (c2 - e2) * rate
                        s10, s11, s12 = m0 + d0, m1 + d1, m2 + d2
                        s20, s21, s22 = a0 + d0, a1 + d1, a2 + d2
                        s30, s31, s32 = b0 + d0, b1 + d1, b2 + d2
                        s40, s41, s42 = e0 + d0, e1 + d1, e2 + d2
                        m0 = m0 + sixth * (j10 + 2.0 * (j20 + j30) + j40)
                        m1 = m1 + sixth * (j11 + 2.0 * (j21 + j31) + j41)
                        m2 = m2 + sixth * (j12 + 2.0 * (j22 + j32) + j42)
                    else:  # the commanded torque, at every stage
                        s10, s11, s12 = c0 + d0, c1 + d1, c2 + d2
                        s20, s21, s22 = s10, s11, s12
                        s30, s31, s32 = s10, s11, s12
                        s40, s41, s42 = s10, s11, s12
                    k10, k11, k12 = _rates(w0, w1, w2, s10, s11, s12, inertia_k, inverse_k)
                    k20, k21, k22 = _rates(
                        w0 + half * k10,
                        w1 + half * k11,
                        w2 + half * k12,
                        s20,
                        s21,
                        s22,
                        inertia_k,
                        inverse_k,
                    )
                    k30, k31, k32 = _rates(
                        w0 + half * k20,
                        w1 + half * k21,
                        w2 + half * k22,
                        s30,
                        s31,
                        s32,
                        inertia_k,
                        inverse_k,
                    )
                    k40, k41, k42 = _rates(
                        w0 + dt * k30,
                        w1 + dt * k31,
                        w2 + dt * k32,
                        s40,
                        s41,
                        s42,
                        inertia_k,
                        inverse_k,
                    )
                    w0 = w0 + sixth * (k10 + 2.0 * (k20 + k30) + k40)
                    w1 = w1 + sixth * (k11 + 2.0 * (k21 + k31) + k41)
                    w2 = w2 + sixth * (k12 + 2.0 * (k22 + k32) + k42)
                    if (sub + 1) % per_sample == 0:
                        s = (sub + 1) // per_sample - 1
                        omega_out[p, k, i, s, 0] = w0
                        omega_out[p, k, i, s, 1] = w1
                        omega_out[p, k, i, s, 2] = w2
                        torque_out[p, k, i, s, 0] = m0
                        torque_out[p, k, i, s, 1] = m1
                        torque_out[p, k, i, s, 2] = m2
                omega[p, k, i, 0], omega[p, k, i, 1], omega[p, k, i, 2] = w0, w1, w2
                torque[p, k, i, 0], torque[p, k, i, 1], torque[p, k, i, 2] = m0, m1, m2


def warm_up() -> None:
    """Compile (or load from the disk cache) the kernel on a tiny input, with and without
    the lag."""
    eye = np.eye(3)[None]
    for rate in (0.0, 10.0):
        state = np.zeros((1, 1, 1, 3))
        integrate(
            state,
            state.copy(),
            np.ones((1, 1, 1, 3)),
            np.zeros((1, 1, 1, 3)),
            eye,
            eye,
            0.01,
            rate,
            1,
            1,
            1,
            np.empty((1, 1, 1, 1, 3)),
            np.empty((1, 1, 1, 1, 3)),
        )
