"""Responses of the paper preset to the hand-designed sequence, shared by the kind tests."""

from __future__ import annotations

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import Scenario, SimulationResult, simulate


@pytest.fixture(scope="session")
def good_training(paper: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """What ``train_classifier(paper, GOOD_SEQUENCE, 8, np.random.default_rng(0))`` simulates."""
    return simulate(paper, GOOD_SEQUENCE, 8, np.random.default_rng(0)).dataset()


@pytest.fixture(scope="session")
def good_fresh(paper: Scenario) -> SimulationResult:
    """Six responses per candidate never seen in training."""
    return simulate(paper, GOOD_SEQUENCE, 6, np.random.default_rng(1))
