"""Least-squares inertia from the integral form of Euler's equations, and its classifier."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from inertia_id import Scenario, identify, simulate
from inertia_id.classifiers.leastsquares import LeastSquaresClassifier, train_least_squares
from inertia_id.physics.estimate import (
    commanded_momentum,
    estimate_inertia,
    parameters_from_tensor,
    tensor_from_parameters,
)

GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4
# Every axis torqued in both senses and at two levels, one step at a time, so that the
# rates turn and all six inertia parameters are excited (condition number about 5).
MIXED_SEQUENCE = [[4, 0, 0, 0, 2, 0], [0, 4, 0, 0, 0, 2], [0, 0, 4, 2, 0, 0], [2, 2, 0, 0, 0, 4]]
# A full tensor: products of inertia of a few kg m², principal axes off the body axes.
TILTED = np.array([[50.0, 3.0, -2.0], [3.0, 30.0, 1.0], [-2.0, 1.0, 45.0]])
I0 = np.diag([100.0, 60.0, 90.0])


def relative_error(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(estimate - truth) / np.linalg.norm(truth))


@pytest.fixture(scope="module")
def quiet_tilted(
    scenario_like: Callable[..., Scenario], zero_uncertainty: dict[str, Any]
) -> Callable[[float], Scenario]:
    """The tilted body (and a heavier twin) with no noise, at a given low-pass constant."""

    def build(tau_s: float) -> Scenario:
        return scenario_like(
            {"tilted": TILTED, "heavier": 1.1 * TILTED},
            uncertainty={**zero_uncertainty, "lowpass_time_constant_s": tau_s},
        )

    return build


@pytest.fixture(scope="module")
def classifier(paper: Scenario) -> LeastSquaresClassifier:
    return train_least_squares(paper, GOOD_SEQUENCE, 10, np.random.default_rng(1))


# The estimator.


@pytest.mark.parametrize("tau_s", [0.0, 0.1, 0.3])
@pytest.mark.parametrize("window_s", [None, 0.5])
def test_recovers_a_full_tensor_without_noise(
    quiet_tilted: Callable[[float], Scenario], tau_s: float, window_s: float | None
) -> None:
    scenario = quiet_tilted(tau_s)
    omega = simulate(scenario, MIXED_SEQUENCE, 1, np.random.default_rng(0)).omega_measured[0, 0]
    estimate = estimate_inertia(scenario, MIXED_SEQUENCE, omega, window_s=window_s)
    assert relative_error(estimate.inertia_kg_m2, TILTED) < 0.005
    # The products of inertia, not just the moments: each within 0.05 kg m² (they are 1-3).
    np.testing.assert_allclose(estimate.parameters_kg_m2[3:], [3.0, -2.0, 1.0], atol=0.05)
    np.testing.assert_array_equal(estimate.inertia_kg_m2, estimate.inertia_kg_m2.T)
    assert estimate.condition_number < 20


def test_known_lowpass_is_what_makes_the_cumulative_form_exact(
    quiet_tilted: Callable[[float], Scenario],
) -> None:
    """Ignoring a 0.1 s lag leaves τ c unexplained in every window: a bias of percents."""
    scenario = quiet_tilted(0.1)
    omega = simulate(scenario, MIXED_SEQUENCE, 1, np.random.default_rng(0)).omega_measured[0, 0]
    ignored = estimate_inertia(scenario, MIXED_SEQUENCE, omega, lowpass=False)
    applied = estimate_inertia(scenario, MIXED_SEQUENCE, omega, lowpass=True)
    assert relative_error(ignored.inertia_kg_m2, TILTED) > 0.01
    assert ignored.residual_rms_nms > 100 * applied.residual_rms_nms


def test_known_torque_fixes_the_absolute_scale(quiet_tilted: Callable[[float], Scenario]) -> None:
    """Twice the torque on twice the inertia gives the same rates; the estimate doubles."""
    scenario = quiet_tilted(0.1)
    omega = simulate(scenario, MIXED_SEQUENCE, 1, np.random.default_rng(0)).omega_measured[0, 0]
    doubled = scenario.model_validate(
        {
            **scenario.model_dump(),
            "thrusters": {
                **scenario.thrusters.model_dump(),
                "torque_matrix_nm": (2.0 * scenario.torque_matrix).tolist(),
            },
        }
    )
    single = estimate_inertia(scenario, MIXED_SEQUENCE, omega)
    double = estimate_inertia(doubled, MIXED_SEQUENCE, omega)
    np.testing.assert_allclose(double.inertia_kg_m2, 2.0 * single.inertia_kg_m2, rtol=1e-9)


def test_one_torque_direction_leaves_the_tensor_poorly_determined(paper: Scenario) -> None:
    """A fixed torque direction pins I⁻¹M; the rest hangs on the weak gyroscopic term."""
    rng = np.random.default_rng(0)
    good = estimate_inertia(
        paper, GOOD_SEQUENCE, simulate(paper, GOOD_SEQUENCE, 8, rng).omega_measured[0]
    )
    mixed = estimate_inertia(
        paper, MIXED_SEQUENCE, simulate(paper, MIXED_SEQUENCE, 8, rng).omega_measured[0]
    )
    assert np.median(good.condition_number) > 10 * np.median(mixed.condition_number)
    assert set(good.poorly_excited()) == {"Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"}
    assert len(mixed.poorly_excited()) < 6
    np.testing.assert_allclose(np.linalg.norm(good.weakest_direction, axis=-1), 1.0)


def test_commanded_momentum_matches_the_first_order_lag() -> None:
    """One step of constant command c: ∫ m = c (t - τ (1 - exp(-t/τ)))."""
    scenario = Scenario.paper()
    tau = scenario.uncertainty.lowpass_time_constant_s
    impulse = commanded_momentum(scenario, [[4, 0, 2, 0, 0, 0]])
    t = np.concatenate([[0.0], scenario.sample_times(1)])
    c = np.array([2.0, 0.0, 1.0])
    expected = c * (t - tau * (1.0 - np.exp(-t / tau)))[:, None]
    np.testing.assert_allclose(impulse, expected, rtol=1e-12, atol=1e-15)
    instant = commanded_momentum(scenario, [[4, 0, 2, 0, 0, 0]], lowpass=False, at_start=False)
    np.testing.assert_allclose(instant, c * t[1:, None], rtol=1e-12)


def test_a_batch_is_solved_as_each_series_alone(paper: Scenario) -> None:
    omega = simulate(paper, MIXED_SEQUENCE, 3, np.random.default_rng(2)).omega_measured[1]
    batch = estimate_inertia(paper, MIXED_SEQUENCE, omega)
    for i in range(3):
        alone = estimate_inertia(paper, MIXED_SEQUENCE, omega[i])
        np.testing.assert_allclose(batch.inertia_kg_m2[i], alone.inertia_kg_m2, rtol=1e-10)
        np.testing.assert_allclose(batch.residual_rms_nms[i], alone.residual_rms_nms, rtol=1e-10)
    assert batch.windows_s.shape == (80, 2) and batch.n_equations == 240
    np.testing.assert_array_equal(batch.windows_s[:, 0], 0.0)


def test_parameters_round_trip() -> None:
    np.testing.assert_array_equal(tensor_from_parameters(parameters_from_tensor(TILTED)), TILTED)


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
    quiet_tilted: Callable[[float], Scenario],
) -> None:
    """Noise-free: zero to the true tensor; |I - 1.1 I|_F / |1.1 I|_F = 0.1/1.1 to its twin."""
    scenario = quiet_tilted(0.1)
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


def test_evaluate_has_the_inertia_classifier_keys(
    classifier: LeastSquaresClassifier, paper: Scenario
) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 4, np.random.default_rng(3)).dataset()
    scores = classifier.evaluate(X, y)
    assert set(scores) == {"f1", "accuracy", "confusion"}
    assert scores["confusion"].shape == (5, 5) and scores["confusion"].sum() == 20
    assert classifier.score(X, y) == scores["f1"]
    assert classifier.transform(X).shape == (20, 5)


def test_identify_names_each_candidate_and_refuses_strangers(
    classifier: LeastSquaresClassifier,
    paper: Scenario,
    scenario_like: Callable[..., Scenario],
) -> None:
    fresh = simulate(paper, GOOD_SEQUENCE, 2, np.random.default_rng(5))
    for k in range(paper.n_candidates):
        for i in range(2):
            verdict = identify(
                classifier,
                {
                    "time_s": fresh.time_s.tolist(),
                    "omega_rad_s": fresh.omega_measured[k, i].tolist(),
                },
            )
            assert verdict.candidate_index == k and not verdict.matches_none
    odd = simulate(
        scenario_like({"heavy": 1.3 * I0, "light": 0.6 * I0}),
        GOOD_SEQUENCE,
        2,
        np.random.default_rng(6),
    )
    for k in range(2):
        for i in range(2):
            verdict = identify(
                classifier,
                {"time_s": odd.time_s.tolist(), "omega_rad_s": odd.omega_measured[k, i].tolist()},
            )
            assert verdict.matches_none
            assert verdict.distances[verdict.candidate] > verdict.threshold


def test_json_round_trip_gives_identical_predictions(
    classifier: LeastSquaresClassifier, paper: Scenario, tmp_path: Path
) -> None:
    X, _ = simulate(paper, GOOD_SEQUENCE, 3, np.random.default_rng(4)).dataset()
    path = tmp_path / "ls.json"
    classifier.save(path)
    loaded = LeastSquaresClassifier.load(path)
    np.testing.assert_array_equal(loaded.transform(X), classifier.transform(X))
    np.testing.assert_array_equal(loaded.novelty_thresholds(), classifier.novelty_thresholds())
    assert loaded.get_params() == classifier.get_params()
    doc = json.loads(path.read_text())
    doc["classifier"]["max_training_distance"][0] *= 10.0
    with pytest.raises(ValueError, match="checksum mismatch"):
        LeastSquaresClassifier.from_json(json.dumps(doc))


# Refusals quote what they got.


def test_refuses_series_of_the_wrong_length(classifier: LeastSquaresClassifier) -> None:
    with pytest.raises(ValueError, match=r"omega has 79 samples; the 4-step sequence gives 80"):
        classifier.predict(np.zeros((2, 79, 3)))
    with pytest.raises(ValueError, match=r"got \(2, 80, 2\)"):
        classifier.predict(np.zeros((2, 80, 2)))


def test_refuses_nan_rates(classifier: LeastSquaresClassifier) -> None:
    X = np.zeros((2, 80, 3))
    X[1, 17, 2] = np.nan
    with pytest.raises(ValueError, match=r"series 1, sample 17, axis 2 is nan"):
        classifier.transform(X)


def test_refuses_bad_windows_and_labels(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 2, np.random.default_rng(0)).dataset()
    with pytest.raises(ValueError, match=r"window_s = 0.07 is not a whole number"):
        LeastSquaresClassifier(window_s=0.07).fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"got -1"):
        LeastSquaresClassifier(window_s=-1).fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"'cosine'"):
        LeastSquaresClassifier("cosine").fit(X, y, scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"missing \[4\]"):
        LeastSquaresClassifier().fit(X[y < 4], y[y < 4], scenario=paper, sequence=GOOD_SEQUENCE)
    with pytest.raises(ValueError, match=r"got \[7\]"):
        LeastSquaresClassifier().fit(
            X, np.where(y == 4, 7, y), scenario=paper, sequence=GOOD_SEQUENCE
        )
