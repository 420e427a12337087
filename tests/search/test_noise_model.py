"""The accuracy a search predicts from the scenario's noise model: its algebra against
the covariance written out, its covariance against the simulator's, its accuracy
against what the ceiling measures on simulated series."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import ndtr

from inertia_id import Scenario, preset, simulate
from inertia_id.evaluation.ceiling import fit_ceiling
from inertia_id.physics import actuation, estimate
from inertia_id.physics.presets import NOISE_OFF
from inertia_id.search.noise_model import LinearNoiseModel, clipped_duty_moments

FIRE, BRAKE, OFF = [4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4], [0] * 6


@pytest.fixture(scope="module")
def every_noise() -> Scenario:
    """Full tensors, canted thrusters and every noise source on, so that no term of the
    covariance is zero and no axis decouples."""
    tensors = [
        [[100.0, 4.0, -2.0], [4.0, 60.0, 3.0], [-2.0, 3.0, 90.0]],
        [[90.0, 3.0, -1.0], [3.0, 55.0, 2.0], [-1.0, 2.0, 84.0]],
        [[95.0, 5.0, -3.0], [5.0, 52.0, 1.0], [-3.0, 1.0, 78.0]],
    ]
    torque = [[2.0, 0.5, 0.0, -1.8], [0.3, 1.9, 0.4, 0.2], [0.0, -0.4, 2.1, 1.0]]
    return preset(
        "paper",
        inertia_candidates=[
            {"name": f"c{i}", "inertia_kg_m2": tensor} for i, tensor in enumerate(tensors)
        ],
        thrusters={"torque_matrix_nm": torque, "levels": [0.0, 0.3, 0.7, 1.0]},
        timing={"step_duration_s": 0.5, "integration_step_s": 0.025, "sample_rate_hz": 10.0},
        uncertainty={
            "duty_jitter_sigma": 0.05,
            "thrust_scale_sigma": 0.03,
            "disturbance_torque_sigma_nm": 0.2,
            "disturbance_interval_s": 0.125,
            "gyro_noise_sigma_rad_s": 2e-3,
            "gyro_bias_sigma_rad_s": 1e-3,
            "initial_rate_sigma_rad_s": 2e-3,
            "lowpass_time_constant_s": 0.1,
        },
    )


@pytest.mark.parametrize(
    ("duty", "sigma", "mean", "variance"),
    [
        # Half the jitter clipped at full duty: the mean shortened, a third of the variance.
        (1.0, 0.02, 1.0 - 0.02 / np.sqrt(2 * np.pi), (0.5 - 0.5 / np.pi) * 0.02**2),
        (1.0, 1e-9, 1.0 - 1e-9 / np.sqrt(2 * np.pi), (0.5 - 0.5 / np.pi) * 1e-18),
        (0.5, 0.02, 0.5, 0.02**2),  # far from both bounds: the jitter's own
        (0.0, 0.02, 0.0, 0.0),  # a thruster commanded off does not fire
        (0.5, 0.0, 0.5, 0.0),
    ],
)
def test_the_delivered_duty_moments_in_closed_form(
    duty: float, sigma: float, mean: float, variance: float
) -> None:
    got_mean, got_variance = clipped_duty_moments(np.array(duty), sigma)
    assert got_mean == pytest.approx(mean, rel=1e-9)
    assert got_variance == pytest.approx(variance, rel=1e-6, abs=1e-300)


@pytest.mark.parametrize("duty", [0.05, 0.3, 0.95, 1.0])
def test_the_delivered_duty_moments_near_a_bound_match_sampling(duty: float) -> None:
    draws = np.clip(duty + 0.1 * np.random.default_rng(0).standard_normal(400_000), 0.0, 1.0)
    mean, variance = clipped_duty_moments(np.array(duty), 0.1)
    assert mean == pytest.approx(draws.mean(), abs=4 * draws.std() / np.sqrt(len(draws)))
    assert variance == pytest.approx(draws.var(), rel=0.01)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("sigma", [1e-160, 1e-300, 0.0, 5e-324])
def test_a_tiny_sigma_warns_of_nothing(sigma: float) -> None:
    """A tiny sigma is legal: its bounds are far past where the normal's tails are 0,
    and squaring them overflowed (a RuntimeWarning) before they were held there."""
    mean, variance = clipped_duty_moments(np.array([0.0, 0.5, 1.0]), sigma)
    np.testing.assert_array_equal(mean, [0.0, 0.5, 1.0])
    assert (variance <= sigma * sigma).all()


def test_the_estimator_and_the_noise_model_take_one_delivered_duty(paper: Scenario) -> None:
    """Both the search's noise model and the estimator's expected torque take their
    delivered duty from the one function: the estimator's impulse over the first step
    is the noise model's mean duty times the torque matrix, to the last bit (its former
    own copy differed from the search's in the last place at sigma = 0.1)."""
    sigma = 0.1
    jittery = paper.with_uncertainty(duty_jitter_sigma=sigma, lowpass_time_constant_s=0.0)
    sequence = [[4, 3, 2, 1, 0, 4]]
    impulse = estimate.commanded_momentum(jittery, sequence, lowpass=False, at_start=False)
    duty = clipped_duty_moments(jittery.duties(sequence), sigma)[0]
    timing = jittery.timing
    offsets = np.arange(1, timing.samples_per_step + 1)[:, None] / timing.sample_rate_hz
    np.testing.assert_array_equal(impulse, offsets * (duty @ jittery.torque_matrix.T))
    assert clipped_duty_moments is actuation.delivered_duty_moments
    assert estimate.delivered_duty_moments is actuation.delivered_duty_moments


def test_the_mean_response_is_the_simulators_with_clipped_jitter(every_noise: Scenario) -> None:
    """At full duty the clipped jitter shortens every firing on average: the model's
    means must be the simulated mean, not the commanded response."""
    clipped = every_noise.with_uncertainty(duty_jitter_sigma=0.1)
    sequence = np.array([[3, 0, 3, 3], [3, 3, 0, 3]])  # full duty
    model = LinearNoiseModel(clipped, len(sequence))
    rates = simulate(clipped, sequence, 20_000, np.random.default_rng(5)).omega_true
    sampled = rates.mean(axis=1)
    error = rates.std(axis=1) / np.sqrt(rates.shape[1])
    difference = np.abs(model.mean_responses(sequence[None])[0] - sampled)
    assert (difference < 5 * error + 1e-12).all()
    quiet = clipped.with_uncertainty(**NOISE_OFF)
    commanded = simulate(quiet, sequence, 1, np.random.default_rng(0))
    assert (np.abs(commanded.omega_true[:, 0] - sampled) > 5 * error).any()


def test_the_mean_run_gives_the_mean_and_each_candidates_settled_rate(paper: Scenario) -> None:
    """Fire then brake in the last step: the lag still holds braking torque when the
    command ends, so each candidate settles below its rate at the end; with no jitter
    the settled rate is the simulator's own."""
    quiet = paper.with_uncertainty(**NOISE_OFF)
    sequences = np.array([[[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]], [[4, 0, 0, 0, 0, 0]] * 2])
    model = LinearNoiseModel(quiet, 2)
    means, settled = model.mean_run(sequences)
    assert means.shape == (2, paper.n_candidates, model.n_samples, 3)
    assert settled.shape == (2, paper.n_candidates)
    np.testing.assert_array_equal(means, model.mean_responses(sequences))
    for sequence, rates in zip(sequences, settled, strict=True):
        run = simulate(quiet, sequence, 1, np.random.default_rng(0))
        np.testing.assert_allclose(rates, run.settled_rate_rad_s(quiet)[:, 0], rtol=1e-12)
    end = np.linalg.norm(means[0, :, -1], axis=-1)
    assert (settled[0] < 0.5 * end).all(), (settled[0], end)


def test_the_fast_distances_equal_the_covariance_written_out(every_noise: Scenario) -> None:
    model = LinearNoiseModel(every_noise, 3)
    sequences = np.array([[[3, 0, 2, 1], [0, 3, 0, 0], [1, 1, 3, 2]], [[0, 0, 0, 0]] * 3])
    means = model.mean_responses(sequences)
    for process, measurement in [(1.0, 1.0), (6.0, 1.0), (1.0, 6.0), (0.0, 2.0)]:
        fast = model.mahalanobis_sq(sequences, process, measurement)
        for p, sequence in enumerate(sequences):
            for column, (i, j) in enumerate(model.pairs):
                sigma = model.dense_covariance(sequence, (i, j), process, measurement)
                delta = (means[p, i] - means[p, j]).reshape(-1)
                dense = delta @ np.linalg.solve(sigma, delta)
                assert fast[p, column] == pytest.approx(dense, rel=1e-6, abs=1e-9)


def test_the_covariance_is_the_simulators_at_low_rates(every_noise: Scenario) -> None:
    """With the body slow, what the model neglects (the gyroscopic coupling of the noise)
    is negligible, so its covariance must be the sample covariance of the simulated
    series, every term at once."""
    sequence = np.array([[1, 0, 1, 0], [0, 1, 0, 1], [1, 1, 1, 0]])
    model = LinearNoiseModel(every_noise, len(sequence))
    measured = simulate(every_noise, sequence, 20_000, np.random.default_rng(3)).omega_measured
    for k in range(every_noise.n_candidates):
        series = measured[k].reshape(len(measured[k]), -1)
        sample = np.cov(series, rowvar=False)
        modelled = model.dense_covariance(sequence, (k,))
        error = np.linalg.norm(sample - modelled) / np.linalg.norm(modelled)
        assert error < 0.03, f"candidate {k}: relative error {error:.3f}"


@pytest.mark.parametrize(
    ("sequence", "process", "measurement"),
    [
        ([FIRE] * 4, 6.0, 1.0),
        ([FIRE] * 4, 1.0, 6.0),
        ([FIRE] * 2 + [BRAKE] * 2, 1.0, 6.0),
        ([FIRE] * 2 + [BRAKE] * 2, 6.0, 1.0),
    ],
)
def test_the_predicted_accuracy_is_what_the_ceiling_measures(
    paper: Scenario, sequence: list, process: float, measurement: float
) -> None:
    """The prediction against the sample-covariance ceiling (per-candidate Gaussians
    fitted on 3,000 realisations, nothing taken from the noise model, so the check is
    independent of it) on 1,000 simulated series per candidate, where a design is chosen
    (accuracies of 0.85 to 0.995): within sampling error plus a point and a half (the
    union bound, the neglected coupling of the noise). At lower accuracies the union
    bound counts errors twice and the prediction is pessimistic (it still ranks)."""
    sequence = np.array(sequence)
    model = LinearNoiseModel(paper, len(sequence))
    predicted = 1.0 - model.predicted_error(sequence[None], ((process, measurement),))[0, 0]
    scales = {"process_noise_scale": process, "measurement_noise_scale": measurement}
    ceiling = fit_ceiling(
        paper, sequence, 3000, np.random.default_rng(1), covariance="sample", **scales
    )
    test = simulate(paper, sequence, 1000, np.random.default_rng(2), **scales)
    x, y = test.dataset()
    measured = float(np.mean(ceiling.predict(x) == y))
    spread = 2.0 * np.sqrt(measured * (1.0 - measured) / len(y))
    assert abs(predicted - measured) < spread + 0.015, (predicted, measured)
    assert 0.8 < measured < 0.999  # a case where the noise matters, not a saturated one


def test_the_prediction_is_exact_for_two_gaussians_without_a_low_rank_part() -> None:
    """Only white gyro noise and the random walk: two candidates, one pair, and the
    union bound is the exact two-class error Φ(−D/2)."""
    scenario = preset(
        "paper",
        inertia_candidates=[
            {"name": "a", "inertia_kg_m2": np.diag([100.0, 60.0, 90.0]).tolist()},
            {"name": "b", "inertia_kg_m2": np.diag([97.0, 58.0, 88.0]).tolist()},
        ],
        uncertainty={"duty_jitter_sigma": 0.0},
    )
    model = LinearNoiseModel(scenario, 2)
    sequence = np.array([[FIRE, FIRE]])
    d2 = model.mahalanobis_sq(sequence, 6.0, 1.0)[0, 0]
    error = model.predicted_error(sequence, ((6.0, 1.0),))[0, 0]
    assert error == pytest.approx(ndtr(-0.5 * np.sqrt(d2)))
    assert 0.0 < error < 0.5


def test_the_same_sequence_gets_the_same_prediction(paper: Scenario) -> None:
    model = LinearNoiseModel(paper, 2)
    one = model.predicted_error(np.array([[FIRE, BRAKE]]), ((6.0, 1.0),))
    many = model.predicted_error(np.array([[FIRE, FIRE], [FIRE, BRAKE]]), ((6.0, 1.0),))
    assert one[0, 0] == pytest.approx(many[1, 0], rel=1e-9)


def test_a_prediction_does_not_depend_on_the_batch_or_need_white_noise(paper: Scenario) -> None:
    """With no gyro noise the variance floor is all that keeps Σ invertible: it must be
    the scenario's, so an all-off sequence is scored (finite) and a sequence scores the
    same alone or beside others."""
    quiet = paper.with_uncertainty(**{**NOISE_OFF, "thrust_scale_sigma": 0.02})
    model = LinearNoiseModel(quiet, 2)
    off, fire = [OFF, OFF], [FIRE, BRAKE]
    alone = model.mahalanobis_sq(np.array([fire]))
    for batch in ([fire, off], [fire, [FIRE, FIRE]]):
        assert model.mahalanobis_sq(np.array(batch))[0] == pytest.approx(alone[0], rel=1e-9)
    error = model.predicted_error(np.array([off]), ((1.0, 0.0), (0.0, 0.0)))
    assert np.isfinite(error).all()


def test_the_candidate_gaussians_carry_the_fixed_bias_and_each_candidates_covariance(
    paper: Scenario,
) -> None:
    biased = paper.with_uncertainty(gyro_bias_rad_s=(0.01, -0.02, 0.0))
    sequence = np.array([[4, 0, 4, 0, 0, 0], [0, 0, 0, 4, 0, 4]])
    plain_means, plain_covariances = LinearNoiseModel(paper, 2).candidate_gaussians(sequence)
    model = LinearNoiseModel(biased, 2)
    means, covariances = model.candidate_gaussians(sequence, 2.0, 3.0)
    shift = (means - plain_means).reshape(paper.n_candidates, -1, 3)
    assert np.allclose(shift, [0.01, -0.02, 0.0])
    for k in range(paper.n_candidates):
        assert np.allclose(covariances[k], model.dense_covariance(sequence, (k,), 2.0, 3.0))
    # Different inertias, different covariances.
    assert not np.allclose(covariances[0], covariances[1])
    assert np.allclose(
        plain_covariances[0], LinearNoiseModel(paper, 2).dense_covariance(sequence, (0,))
    )


def test_the_fast_log_likelihoods_are_the_dense_gaussians(every_noise: Scenario) -> None:
    """The Woodbury path against the d x d covariance factored: full tensors, canted
    thrusters, every noise source and a fixed gyro bias on."""
    scenario = every_noise.with_uncertainty(gyro_bias_rad_s=(0.01, 0.0, -0.01))
    model = LinearNoiseModel(scenario, 3)
    sequence = np.array([[3, 0, 2, 1], [0, 3, 0, 3], [1, 1, 1, 0]])
    X, _ = simulate(
        scenario,
        sequence,
        20,
        np.random.default_rng(1),
        process_noise_scale=3.0,
        measurement_noise_scale=2.0,
    ).dataset()
    means, covariances = model.candidate_gaussians(sequence, 3.0, 2.0)
    d = means.shape[1]
    expected = np.empty((len(X), len(means)))
    for k in range(len(means)):
        sigma = covariances[k] + model._floor * np.eye(d)
        residual = X.reshape(len(X), -1) - means[k]
        quadratic = np.einsum("nd,nd->n", residual, np.linalg.solve(sigma, residual.T).T)
        expected[:, k] = -0.5 * (quadratic + np.linalg.slogdet(sigma)[1] + d * np.log(2 * np.pi))
    got = model.log_likelihoods(sequence, X, 3.0, 2.0)
    assert np.allclose(got, expected, rtol=1e-9, atol=1e-8)
