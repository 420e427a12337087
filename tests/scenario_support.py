"""The inputs most tests start from: the paper's hand-designed sequence, the tensor of
its first candidate, and fresh noisy series at scaled noise.

Tests import this module as ``scenario_support`` (``tests/`` is on ``sys.path``, see
``service_support``). Every suite used to spell these out again; they are inputs, not
expectations, so one copy serves them all.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from inertia_id import Scenario, simulate

# The paper's "good" sequence: the three positive-axis thrusters at full duty, 4 steps.
GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4

# Candidate 0 of the paper preset (its base inertia), kg m².
I0 = np.diag([100.0, 60.0, 90.0])


def noisy(
    scenario: Scenario,
    sequence: Any,
    per_candidate: int,
    seed: int,
    process: float = 1.0,
    measurement: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """(X, y) of ``per_candidate`` fresh series per candidate, seeded by ``seed``, with the
    process and gyro noise scaled by ``process`` and ``measurement``."""
    return simulate(
        scenario,
        sequence,
        per_candidate,
        np.random.default_rng(seed),
        process_noise_scale=process,
        measurement_noise_scale=measurement,
    ).dataset()
