"""The tiny scenario the search tests run on, shared by test_search.py and test_cem.py."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from inertia_id import Scenario, preset

# Three thrusters, one per body axis, each off or on: (2^3)^2 = 64 sequences of 2 steps,
# small enough for the exhaustive search to be the ground truth.
TINY_THRUSTERS = {"torque_matrix_nm": np.diag([2.0, 2.0, 2.0]).tolist(), "levels": [0.0, 1.0]}


@pytest.fixture(scope="module")
def tiny() -> Scenario:
    return preset("paper", name="tiny", thrusters=TINY_THRUSTERS)


@pytest.fixture(scope="module")
def tiny_quiet(zero_uncertainty: dict[str, Any]) -> Scenario:
    """The tiny scenario almost noise-free: F1 = 1 is easy to reach.

    A trace of gyro noise is kept so that sequences starting with every thruster off do
    not give identical series (which k-means cannot split; see test_env.py).
    """
    uncertainty = {**zero_uncertainty, "gyro_noise_sigma_rad_s": 1e-6}
    return preset("paper", name="tiny quiet", thrusters=TINY_THRUSTERS, uncertainty=uncertainty)


@pytest.fixture
def stop_after() -> Callable[[int], Callable[[], bool]]:
    """``stop_after(n)``: a ``should_stop`` that answers False ``n`` times, then True, so a
    test sees exactly when a search checks for cancellation."""

    def make(n: int) -> Callable[[], bool]:
        calls = 0

        def should_stop() -> bool:
            nonlocal calls
            calls += 1
            return calls > n

        return should_stop

    return make
