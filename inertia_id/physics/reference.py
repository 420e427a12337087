"""Plain implementations: the yardsticks for the batched simulator and the fast scorer.

This is what a straightforward implementation looks like: one series at a time, one
RK4 step at a time, 3-vectors and ``np.cross`` / ``np.linalg.solve``. It consumes the
same :class:`~inertia_id.physics.simulate.SequenceNoise` as the batched simulator, so the two
must agree to rounding error (tests check 1e-12), and it is the baseline the
simulation benchmark measures the batched simulator against
(:func:`~inertia_id.search.reference.plain_prefix_score` builds the plain search step on
it). Not for production use.
"""

from __future__ import annotations

import numpy as np

from .scenario import Scenario
from .simulate import SequenceNoise

__all__ = ["simulate_per_series"]


def simulate_per_series(
    scenario: Scenario, sequence: np.ndarray, noise: SequenceNoise
) -> np.ndarray:
    """Measured ω of every series, (K, n, T, 3), computed one series at a time."""
    sequence = scenario.check_sequence(sequence)
    timing, unc = scenario.timing, scenario.uncertainty
    dt, tau = timing.integration_step_s, unc.lowpass_time_constant_s
    substeps = timing.substeps_per_step
    per_sample = timing.substeps_per_sample
    per_interval = round(unc.disturbance_interval_s / dt)
    torque_matrix, levels = scenario.torque_matrix, scenario.level_values
    k_count, n_count = noise.initial.omega0.shape[:2]
    out = np.empty((k_count, n_count, len(sequence) * timing.samples_per_step, 3))
    for k, inertia in enumerate(scenario.inertia_array):

        def rates(w: np.ndarray, m: np.ndarray, inertia: np.ndarray = inertia) -> np.ndarray:
            return np.linalg.solve(inertia, m - np.cross(w, inertia @ w))

        for r in range(n_count):
            w = noise.initial.omega0[k, r].copy()
            m = np.zeros(3)
            sample = 0
            for step, row in enumerate(sequence):
                draw = noise.steps[step]
                duty = levels[row]
                delivered = np.where(duty > 0, np.clip(duty + draw.duty_jitter[k, r], 0, 1), 0)
                c = torque_matrix @ (delivered * noise.initial.thrust_scale[k, r])
                for sub in range(substeps):
                    d = draw.disturbance[k, r, sub // per_interval]
                    if tau == 0.0:
                        k1 = rates(w, c + d)
                        k2 = rates(w + 0.5 * dt * k1, c + d)
                        k3 = rates(w + 0.5 * dt * k2, c + d)
                        k4 = rates(w + dt * k3, c + d)
                    else:
                        j1 = (c - m) / tau
                        k1 = rates(w, m + d)
                        m2 = m + 0.5 * dt * j1
                        j2 = (c - m2) / tau
                        k2 = rates(w + 0.5 * dt * k1, m2 + d)
                        m3 = m + 0.5 * dt * j2
                        j3 = (c - m3) / tau
                        k3 = rates(w + 0.5 * dt * k2, m3 + d)
                        m4 = m + dt * j3
                        j4 = (c - m4) / tau
                        k4 = rates(w + dt * k3, m4 + d)
                        m = m + dt / 6 * (j1 + 2 * j2 + 2 * j3 + j4)
                    w = w + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                    if (sub + 1) % per_sample == 0:
                        within = (sub + 1) // per_sample - 1
                        out[k, r, sample] = (
                            w + noise.initial.gyro_bias[k, r] + draw.gyro_noise[k, r, within]
                        )
                        sample += 1
    return out
