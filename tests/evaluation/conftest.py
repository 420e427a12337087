"""What the verdict and slow-telemetry tests share: the default kind trained once."""

from __future__ import annotations

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import Scenario
from inertia_id.classifiers.marginal import AXES_GRID, MarginalLikelihoodClassifier, train_marginal


@pytest.fixture(scope="session")
def marginal(drifting_paper: Scenario) -> MarginalLikelihoodClassifier:
    """The default kind on the shipped preset (initial rates and gyro biases drawn), on the
    axes grid. Session-scoped, so tests must not mutate it."""
    return train_marginal(
        drifting_paper, GOOD_SEQUENCE, 40, np.random.default_rng(11), grid=AXES_GRID
    )
