"""The physics baseline as a classifier: the candidate whose tensor fits best."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import Scenario, simulate
from inertia_id.classifiers.leastsquares import LeastSquaresClassifier
from inertia_id.classifiers.registry import train_classifier
from inertia_id.physics.estimate import (
    estimate_inertia,
)

# Every axis torqued in both senses and at two levels: all six parameters excited.
MIXED_SEQUENCE = [[4, 0, 0, 0, 2, 0], [0, 4, 0, 0, 0, 2], [0, 0, 4, 2, 0, 0], [2, 2, 0, 0, 0, 4]]


@pytest.fixture(scope="module")
def classifier(paper: Scenario) -> LeastSquaresClassifier:
    model = train_classifier(
        paper, GOOD_SEQUENCE, 10, np.random.default_rng(1), kind="least-squares"
    )
    assert isinstance(model, LeastSquaresClassifier)
    return model


# The classifier.


@pytest.mark.parametrize(
    ("noise", "minimum"),
    [
        # Measured on 1000 series: 100 %, 99.7 % and 93.7 % (process noise accumulates
        # along the cumulative windows; 0.5 s sliding windows reach 96 % there).
        ({}, 0.98),
        ({"measurement_noise_scale": 6.0}, 0.95),
        ({"process_noise_scale": 6.0}, 0.85),
    ],
)
def test_picks_the_right_candidate_at_the_paper_noise(
    classifier: LeastSquaresClassifier, paper: Scenario, noise: dict[str, float], minimum: float
) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 40, np.random.default_rng(7), **noise).dataset()
    assert classifier.evaluate(X, y)["accuracy"] >= minimum


def test_finite_differences_collapse_where_the_integral_form_holds(
    paper: Scenario, classifier: LeastSquaresClassifier
) -> None:
    """One-sample windows difference the gyro signal: at 6x gyro noise, chance level."""
    X, y = simulate(
        paper, GOOD_SEQUENCE, 40, np.random.default_rng(7), measurement_noise_scale=6.0
    ).dataset()
    differencing = LeastSquaresClassifier(window_s=1.0 / paper.timing.sample_rate_hz)
    differencing.fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    assert differencing.evaluate(X, y)["accuracy"] < 0.5
    assert classifier.evaluate(X, y)["accuracy"] >= 0.95


def test_distances_without_noise_are_the_tensor_gaps(
    scenario_like: Callable[..., Scenario], zero_uncertainty: dict[str, Any]
) -> None:
    """Noise-free: zero to the true tensor; |I - 1.1 I|_F / |1.1 I|_F = 0.1/1.1 to its twin."""
    tilted = np.array([[50.0, 3.0, -2.0], [3.0, 30.0, 1.0], [-2.0, 1.0, 45.0]])
    scenario = scenario_like(
        {"tilted": tilted, "heavier": 1.1 * tilted},
        uncertainty={**zero_uncertainty, "lowpass_time_constant_s": 0.1},
    )
    X, y = simulate(scenario, MIXED_SEQUENCE, 1, np.random.default_rng(0)).dataset()
    frobenius = LeastSquaresClassifier("frobenius").fit(
        X, y, scenario=scenario, sequence=MIXED_SEQUENCE
    )
    np.testing.assert_allclose(frobenius.transform(X), [[0.0, 0.1 / 1.1], [0.1, 0.0]], atol=2e-4)
    equation = LeastSquaresClassifier().fit(X, y, scenario=scenario, sequence=MIXED_SEQUENCE)
    distances = equation.transform(X)
    assert distances[0, 0] < 1e-3 * distances[0, 1]
    assert distances[1, 1] < 1e-3 * distances[1, 0]


def test_frobenius_needs_every_parameter_excited(paper: Scenario) -> None:
    """Measured on 1000 series: 84 % with the mixed sequence, 12 % with one torque direction."""
    for sequence, low, high in ((MIXED_SEQUENCE, 0.7, 1.0), (GOOD_SEQUENCE, 0.0, 0.5)):
        X, y = simulate(paper, sequence, 20, np.random.default_rng(8)).dataset()
        model = LeastSquaresClassifier("frobenius").fit(X, y, scenario=paper, sequence=sequence)
        assert low <= model.accuracy_ <= high


# Refusals quote what they got.


def test_estimate_is_the_estimator_on_checked_series(
    classifier: LeastSquaresClassifier, paper: Scenario
) -> None:
    X, _ = simulate(paper, GOOD_SEQUENCE, 2, np.random.default_rng(3)).dataset()
    np.testing.assert_array_equal(
        classifier.estimate(X).parameters_kg_m2,
        estimate_inertia(paper, GOOD_SEQUENCE, X).parameters_kg_m2,
    )
    with pytest.raises(ValueError, match="79 samples; the classifier was trained on 80"):
        classifier.estimate(X[:, :79])


def test_fit_and_verdicts_skip_the_standard_errors_they_never_read(
    paper: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The shared-error sandwich holds two more (n, G, 3, 6) arrays (about half again a
    training's peak memory, helper-142); the fit and the distances read only the
    estimate, so they skip it. estimate() still gives them, and the estimates agree."""
    import inertia_id.physics.estimate as estimate_module

    X, y = simulate(paper, MIXED_SEQUENCE, 4, np.random.default_rng(5)).dataset()
    with_errors = estimate_inertia(paper, MIXED_SEQUENCE, X)
    without = estimate_inertia(paper, MIXED_SEQUENCE, X, standard_errors=False)
    np.testing.assert_array_equal(without.parameters_kg_m2, with_errors.parameters_kg_m2)
    np.testing.assert_array_equal(without.independent_std_kg_m2, with_errors.independent_std_kg_m2)
    assert np.isnan(without.parameter_std_kg_m2).all()
    assert np.isfinite(with_errors.parameter_std_kg_m2).all()

    def refuse(*_args: Any, **_kwargs: Any) -> Any:
        raise AssertionError("the sandwich was computed for a fit or a verdict")

    monkeypatch.setattr(estimate_module, "_sandwich_covariance", refuse)
    model = LeastSquaresClassifier().fit(X, y, scenario=paper, sequence=MIXED_SEQUENCE)
    assert model.predict(X).shape == y.shape
    monkeypatch.undo()
    np.testing.assert_array_equal(
        model.estimate(X).parameter_std_kg_m2, with_errors.parameter_std_kg_m2
    )


def test_refuses_bad_windows_and_labels(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 2, np.random.default_rng(0)).dataset()
    with pytest.raises(ValueError, match=r"window_s = 0.07 is not a whole number"):
        LeastSquaresClassifier(window_s=0.07).fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"got -1"):
        LeastSquaresClassifier(window_s=-1).fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"'cosine'"):
        LeastSquaresClassifier("cosine").fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"the scenario has 5 candidates, y labels 4"):
        LeastSquaresClassifier().fit(X[y < 4], y[y < 4], scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"series per candidate: \[2, 2, 2, 2, 0, 0, 0, 2\]"):
        LeastSquaresClassifier().fit(
            X, np.where(y == 4, 7, y), scenario=paper, sequence=GOOD_SEQUENCE
        )
    with pytest.raises(ValueError, match="needs the scenario and the sequence"):
        LeastSquaresClassifier().fit(X, y)
