"""The batched simulator: agreement with the per-series reference, physics, noise, API."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest

from inertia_id import Scenario, Simulator, simulate
from inertia_id.physics.reference import simulate_per_series
from inertia_id.physics.simulate import SequenceNoise

ALL_NOISE_ON = {
    "duty_jitter_sigma": 0.05,
    "thrust_scale_sigma": 0.03,
    "disturbance_torque_sigma_nm": 0.05,
    "gyro_noise_sigma_rad_s": 1e-3,
    "gyro_bias_rad_s": (1e-3, -2e-3, 5e-4),
    "gyro_bias_sigma_rad_s": 2e-3,
    "initial_rate_sigma_rad_s": 0.01,
}
# Uses every level, full duty (so jitter gets clipped at 1) and every thruster.
MIXED_SEQUENCE = [[4, 0, 2, 1, 3, 0], [0, 3, 0, 4, 1, 2], [1, 1, 1, 1, 1, 1]]


@pytest.fixture(scope="module")
def custom() -> Scenario:
    """Two tumbling bodies with products of inertia, 4 skewed thrusters, odd timing."""
    return Scenario.model_validate(
        {
            "name": "custom",
            "inertia_candidates": [
                {
                    "name": "a",
                    "inertia_kg_m2": [[50.0, 3.0, -2.0], [3.0, 30.0, 1.0], [-2.0, 1.0, 45.0]],
                },
                {
                    "name": "b",
                    "inertia_kg_m2": [[45.0, -1.0, 0.5], [-1.0, 28.0, 2.0], [0.5, 2.0, 40.0]],
                },
            ],
            "thrusters": {
                "torque_matrix_nm": [
                    [3.0, 0.0, -1.0, 0.5],
                    [4.0, 1.0, 0.0, -0.5],
                    [0.0, -2.0, 1.0, 0.5],
                ],
                "levels": [0.0, 0.3, 1.0],
            },
            "timing": {"step_duration_s": 0.5, "integration_step_s": 0.025, "sample_rate_hz": 10.0},
            "uncertainty": {
                **ALL_NOISE_ON,
                "lowpass_time_constant_s": 0.2,
                "disturbance_interval_s": 0.05,
            },
        }
    )


def run_both(scenario: Scenario, sequence: Any, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    simulator = Simulator(scenario, n)
    noise = simulator.draw_noise(np.random.default_rng(seed), len(sequence))
    vectorised = simulator.run(np.asarray(sequence), noise).omega_measured
    reference = simulate_per_series(scenario, np.asarray(sequence), noise)
    return vectorised, reference


# Agreement with the plain per-series implementation.


@pytest.mark.parametrize("tau", [0.1, 0.0])
def test_vectorised_equals_reference_on_paper(paper: Scenario, tau: float) -> None:
    scenario = paper.with_uncertainty(**ALL_NOISE_ON, lowpass_time_constant_s=tau)
    vectorised, reference = run_both(scenario, MIXED_SEQUENCE, 3, seed=42)
    assert vectorised.shape == reference.shape == (5, 3, 60, 3)
    # Not trivially zero, and the realisations really differ.
    assert np.abs(reference).max() > 0.02
    assert np.abs(reference[:, 0] - reference[:, 1]).max() > 1e-3
    np.testing.assert_allclose(vectorised, reference, rtol=0, atol=1e-12)


@pytest.mark.parametrize("tau", [0.2, 0.0])
def test_vectorised_equals_reference_on_custom(custom: Scenario, tau: float) -> None:
    scenario = custom.with_uncertainty(lowpass_time_constant_s=tau)
    sequence = [[2, 0, 1, 2], [0, 2, 2, 1], [1, 1, 0, 0], [2, 2, 2, 2]]
    vectorised, reference = run_both(scenario, sequence, 3, seed=7)
    assert vectorised.shape == (2, 3, 4 * 5, 3)
    assert np.abs(reference).max() > 0.05
    np.testing.assert_allclose(vectorised, reference, rtol=0, atol=1e-12)


# Shapes and bookkeeping.


def test_result_shapes_and_times(paper: Scenario, good_sequence: np.ndarray) -> None:
    result = simulate(paper, good_sequence, 4, np.random.default_rng(0))
    assert result.omega_measured.shape == (5, 4, 80, 3)
    assert result.omega_true.shape == (5, 4, 80, 3)
    assert result.applied_torque_nm.shape == (5, 4, 80, 3)
    assert result.commanded_torque_nm.shape == (5, 4, 4, 3)
    np.testing.assert_allclose(result.time_s, np.arange(1, 81) * 0.05, rtol=1e-15)
    assert result.time_s[-1] == pytest.approx(4.0)
    np.testing.assert_array_equal(result.sequence, good_sequence)
    assert result.candidate_names == paper.candidate_names
    X, y = result.dataset()
    assert X.shape == (20, 80, 3)
    np.testing.assert_array_equal(y, np.repeat(np.arange(5), 4))
    np.testing.assert_array_equal(X[5], result.omega_measured[1, 1])


def test_impulse_matches_hand_computation(paper: Scenario, custom: Scenario) -> None:
    # Paper: A = 2 [I3, -I3], each column has |A_j| = 2 N m; steps last 1 s.
    assert paper.impulse_nms([[4, 4, 4, 0, 0, 0]] * 4) == pytest.approx(24.0, rel=1e-15)
    # Level 2 = 0.5 duty on thruster 3 once, level 1 = 0.25 on thruster 0 twice.
    sequence = [[0, 0, 0, 2, 0, 0], [1, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0]]
    assert paper.impulse_nms(sequence) == pytest.approx(2.0 * (0.5 + 0.25 + 0.25), rel=1e-15)
    assert paper.impulse_nms([[0] * 6] * 3) == 0.0
    result = simulate(paper, [[4, 4, 4, 0, 0, 0]] * 4, 2, np.random.default_rng(0))
    assert result.impulse_nms == pytest.approx(24.0, rel=1e-15)
    # Custom: |A_0| = 5, |A_1| = sqrt(5), levels (0, 0.3, 1), steps of 0.5 s.
    sequence = [[2, 1, 0, 0], [2, 0, 0, 0]]
    expected = (5.0 * 2.0 + np.sqrt(5.0) * 0.3) * 0.5
    assert custom.impulse_nms(sequence) == pytest.approx(expected, rel=1e-14)


def test_single_axis_spin_up_final_rate(quiet_paper: Scenario) -> None:
    """Noise-free, no low-pass, +x thruster at full duty for 4 s: ω = (8 / I_xx) x."""
    result = simulate(quiet_paper, [[4, 0, 0, 0, 0, 0]] * 4, 2, np.random.default_rng(0))
    ixx = quiet_paper.inertia_array[:, 0, 0]
    expected = 2.0 * 4.0 / ixx
    np.testing.assert_allclose(
        result.final_rate_rad_s, np.repeat(expected[:, None], 2, 1), rtol=1e-12
    )
    assert result.mean_final_rate_rad_s == pytest.approx(expected.mean(), rel=1e-12)
    np.testing.assert_allclose(result.omega_true[..., 1:], 0.0, atol=1e-15)
    # The ramp is linear at every sample.
    np.testing.assert_allclose(
        result.omega_true[:, 0, :, 0], 2.0 / ixx[:, None] * result.time_s[None, :], rtol=1e-12
    )
    # The -x thruster brings it back to rest: the commanded torque is linear in duty.
    back = simulate(
        quiet_paper,
        [[4, 0, 0, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 0, 0]] * 2,
        1,
        np.random.default_rng(0),
    )
    np.testing.assert_allclose(back.final_rate_rad_s, 0.0, atol=1e-14)


@pytest.mark.parametrize(("dt", "tol"), [(0.05, 1e-3), (0.005, 1e-6)])
def test_lowpass_response_in_the_simulator(quiet_paper: Scenario, dt: float, tol: float) -> None:
    """First-order lag: m = c (1 - exp(-t/tau)), ω_y = (c / I_yy)(t - tau (1 - exp(-t/tau))).

    RK4's error on the lag scales as (dt / tau)^4: ~1e-3 relative at the paper's
    dt = 0.05 s with tau = 0.1 s, ~1e-7 at dt = 0.005 s.
    """
    tau = 0.1
    data = quiet_paper.with_uncertainty(lowpass_time_constant_s=tau).model_dump()
    data["timing"]["integration_step_s"] = dt
    scenario = Scenario.model_validate(data)
    result = simulate(scenario, [[0, 4, 0, 0, 0, 0]], 1, np.random.default_rng(0))
    t = result.time_s
    np.testing.assert_allclose(
        result.applied_torque_nm[0, 0, :, 1], 2.0 * (1.0 - np.exp(-t / tau)), rtol=0, atol=2.0 * tol
    )
    iyy = scenario.inertia_array[:, 1, 1]
    expected = 2.0 / iyy[:, None] * (t - tau * (1.0 - np.exp(-t / tau)))[None, :]
    np.testing.assert_allclose(
        result.omega_true[:, 0, :, 1], expected, rtol=0, atol=tol * expected.max()
    )
    np.testing.assert_allclose(result.omega_true[:, 0, :, [0, 2]], 0.0, atol=1e-15)
    np.testing.assert_array_equal(result.commanded_torque_nm[:, 0, 0], [[0.0, 2.0, 0.0]] * 5)


def test_torque_free_coast_conserves_momentum_and_energy(quiet_paper: Scenario) -> None:
    """After the thrusters stop (no low-pass, no disturbance), |Iω| and energy stay put."""
    sequence = [[4, 4, 4, 0, 0, 0], [0] * 6, [0] * 6]
    result = simulate(quiet_paper, sequence, 1, np.random.default_rng(0))
    w = result.omega_true[:, 0]  # (K, T, 3)
    inertia = quiet_paper.inertia_array
    momentum = np.linalg.norm(np.einsum("kij,ktj->kti", inertia, w), axis=-1)
    energy = 0.5 * np.einsum("kti,kij,ktj->kt", w, inertia, w)
    coast = slice(19, None)  # from the end of step 1 on
    assert np.max(np.abs(momentum[:, coast] / momentum[:, [19]] - 1.0)) < 1e-10
    assert np.max(np.abs(energy[:, coast] / energy[:, [19]] - 1.0)) < 1e-10
    # While firing, energy grows (power ω·M > 0 from rest).
    assert np.all(np.diff(energy[:, :20], axis=1) > 0)
    # The body-fixed rates do change during the coast: gyroscopic coupling is on.
    assert np.abs(w[:, -1] - w[:, 19]).max() > 1e-4


# Randomness.


def test_same_seed_same_result_different_seed_differs(
    paper: Scenario, good_sequence: np.ndarray
) -> None:
    a = simulate(paper, good_sequence, 3, np.random.default_rng(5))
    b = simulate(paper, good_sequence, 3, np.random.default_rng(5))
    c = simulate(paper, good_sequence, 3, np.random.default_rng(6))
    np.testing.assert_array_equal(a.omega_measured, b.omega_measured)
    np.testing.assert_array_equal(a.omega_true, b.omega_true)
    assert np.abs(a.omega_measured - c.omega_measured).max() > 1e-4
    assert np.abs(a.omega_true - c.omega_true).max() > 1e-5


def test_advance_step_by_step_equals_run(paper: Scenario) -> None:
    scenario = paper.with_uncertainty(**ALL_NOISE_ON)
    sequence = np.asarray(MIXED_SEQUENCE)
    simulator = Simulator(scenario, 3)
    whole = simulator.run(sequence, simulator.draw_noise(np.random.default_rng(9), 3))

    rng = np.random.default_rng(9)  # draw as we go: initial first, then step by step
    state = simulator.start(simulator.draw_initial(rng))
    measured, true, applied, commanded = [], [], [], []
    for levels in sequence:
        state, response = simulator.advance(state, levels, simulator.draw_step(rng))
        measured.append(response.omega_measured)
        true.append(response.omega_true)
        applied.append(response.applied_torque)
        commanded.append(response.commanded_torque)
    assert state.n_steps == 3
    np.testing.assert_array_equal(np.concatenate(measured, axis=2), whole.omega_measured)
    np.testing.assert_array_equal(np.concatenate(true, axis=2), whole.omega_true)
    np.testing.assert_array_equal(np.concatenate(applied, axis=2), whole.applied_torque_nm)
    np.testing.assert_array_equal(np.stack(commanded, axis=2), whole.commanded_torque_nm)
    np.testing.assert_array_equal(state.omega, whole.omega_true[:, :, -1])


def test_prefix_of_a_sequence_simulates_identically(
    paper: Scenario, good_sequence: np.ndarray
) -> None:
    short = simulate(paper, good_sequence[:2], 3, np.random.default_rng(4))
    full = simulate(paper, good_sequence, 3, np.random.default_rng(4))
    np.testing.assert_array_equal(short.omega_measured, full.omega_measured[:, :, :40])


def test_zero_uncertainty_gives_exact_identical_realisations(
    quiet_paper: Scenario, good_sequence: np.ndarray
) -> None:
    for tau in (0.0, 0.1):
        scenario = quiet_paper.with_uncertainty(lowpass_time_constant_s=tau)
        result = simulate(scenario, good_sequence, 4, np.random.default_rng(0))
        np.testing.assert_array_equal(result.omega_measured, result.omega_true)
        for i in range(1, 4):
            np.testing.assert_array_equal(result.omega_true[:, i], result.omega_true[:, 0])
        # Candidates differ from one another, though (different inertia).
        assert np.abs(result.omega_true[0, 0] - result.omega_true[1, 0]).max() > 1e-3


def test_measurement_scale_zero_gives_true_rates(
    paper: Scenario, good_sequence: np.ndarray
) -> None:
    scenario = paper.with_uncertainty(gyro_bias_sigma_rad_s=5e-3)
    result = simulate(
        scenario, good_sequence, 3, np.random.default_rng(0), measurement_noise_scale=0.0
    )
    np.testing.assert_array_equal(result.omega_measured, result.omega_true)
    # With the default scale the readings do carry noise and bias.
    noisy = simulate(scenario, good_sequence, 3, np.random.default_rng(0))
    assert np.abs(noisy.omega_measured - noisy.omega_true).max() > 1e-3
    # Measurement noise never changes the truth: the same draws drive the dynamics.
    np.testing.assert_array_equal(noisy.omega_true, result.omega_true)


def test_noise_scales_multiply_the_same_draws(paper: Scenario) -> None:
    scenario = paper.with_uncertainty(**ALL_NOISE_ON)

    def draws(**scales: float) -> SequenceNoise:
        return Simulator(scenario, 3, **scales).draw_noise(np.random.default_rng(123), 2)

    base = draws()
    process = draws(process_noise_scale=3.0)
    measurement = draws(measurement_noise_scale=0.5)
    bias_constant = np.asarray(ALL_NOISE_ON["gyro_bias_rad_s"])
    for b, p, m in zip(base.steps, process.steps, measurement.steps, strict=True):
        np.testing.assert_allclose(p.disturbance, 3.0 * b.disturbance, rtol=1e-15)
        np.testing.assert_array_equal(p.gyro_noise, b.gyro_noise)
        np.testing.assert_array_equal(p.duty_jitter, b.duty_jitter)
        np.testing.assert_allclose(m.gyro_noise, 0.5 * b.gyro_noise, rtol=1e-15)
        np.testing.assert_array_equal(m.disturbance, b.disturbance)
    np.testing.assert_array_equal(process.initial.gyro_bias, base.initial.gyro_bias)
    np.testing.assert_allclose(
        measurement.initial.gyro_bias - bias_constant,
        0.5 * (base.initial.gyro_bias - bias_constant),
        rtol=1e-12,
    )
    np.testing.assert_array_equal(measurement.initial.omega0, base.initial.omega0)
    np.testing.assert_array_equal(measurement.initial.thrust_scale, base.initial.thrust_scale)
    # The disturbance draws have the scenario's sigma (there are 5*3*2*20*3 = 1800).
    all_d = np.concatenate([s.disturbance.ravel() for s in base.steps])
    assert all_d.std() == pytest.approx(0.05, rel=0.1)


def test_process_noise_spread_grows_with_its_scale(
    quiet_paper: Scenario, good_sequence: np.ndarray
) -> None:
    """Only disturbances on: the spread of final rates is linear in the process scale."""
    scenario = quiet_paper.with_uncertainty(disturbance_torque_sigma_nm=0.05)
    spreads = []
    for scale in (0.0, 1.0, 2.0):
        result = simulate(
            scenario, good_sequence, 8, np.random.default_rng(1), process_noise_scale=scale
        )
        spreads.append(result.omega_true[:, :, -1].std(axis=1).mean())
    assert spreads[0] < 1e-14
    assert spreads[1] > 1e-4
    assert spreads[2] / spreads[1] == pytest.approx(2.0, rel=0.05)


# Validation.


@pytest.mark.parametrize(
    ("sequence", "match"),
    [
        ([[5, 0, 0, 0, 0, 0]], r"step 1, thruster 1: level index 5 is outside 0\.\.4"),
        ([[0, 0, 0, 0, 0, 0], [0, 0, -1, 0, 0, 0]], r"step 2, thruster 3: level index -1"),
        ([[4, 4, 4]], r"L x 6 .*got shape \(1, 3\)"),
        ([[[4] * 6]], r"got shape \(1, 1, 6\)"),
        ([[1.5, 0, 0, 0, 0, 0]], r"integer level indices, got \[\[1\.5"),
        ([[float("nan"), 0, 0, 0, 0, 0]], r"integer level indices, got \[\[nan"),
        ([["a", "0", "0", "0", "0", "0"]], r"integer level indices.*'a'"),
        ([[4, 4, 4, 0, 0], [4, 4, 4, 0, 0, 0]], r"not an array of level indices"),
        # numpy reads [4, True] as [4, 1]: a JSON true is not level 1.
        ([[4, 4, 4, 0, 0, True]], r"integer level indices, got \[\[4, 4, 4, 0, 0, True"),
        ([[4, 4, 4, 0, 0, np.bool_(False)]], r"integer level indices"),
        ([[True] * 6], r"integer level indices"),
    ],
)
def test_bad_sequences_are_rejected_naming_the_value(
    paper: Scenario, sequence: Any, match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        simulate(paper, sequence, 1, np.random.default_rng(0))


def test_one_row_sequence_may_be_flat(paper: Scenario) -> None:
    np.testing.assert_array_equal(paper.check_sequence([4, 0, 0, 0, 0, 0]), [[4, 0, 0, 0, 0, 0]])
    np.testing.assert_array_equal(
        paper.check_sequence([[2.0, 0, 0, 0, 0, 1]]), [[2, 0, 0, 0, 0, 1]]
    )


def test_simulator_parameter_validation(paper: Scenario) -> None:
    with pytest.raises(ValueError, match="n_realisations must be a positive integer, got 0"):
        Simulator(paper, 0)
    with pytest.raises(ValueError, match=r"n_realisations .* got 2\.5"):
        Simulator(paper, 2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"process_noise_scale .* got -1"):
        Simulator(paper, 2, process_noise_scale=-1.0)
    with pytest.raises(ValueError, match=r"measurement_noise_scale .* got nan"):
        Simulator(paper, 2, measurement_noise_scale=float("nan"))
    simulator = Simulator(paper, 2)
    noise = simulator.draw_noise(np.random.default_rng(0), 1)
    with pytest.raises(ValueError, match="noise holds 1 step, the sequence 2"):
        simulator.run(np.array([[4, 0, 0, 0, 0, 0]] * 2), noise)


def test_a_population_is_each_sequence_on_the_same_draws(paper: Scenario) -> None:
    """Scoring P sequences side by side must give each one what simulating it alone on
    the same noise gives (common random numbers, no cross-talk between sequences)."""
    simulator = Simulator(paper, 3)
    noise = simulator.draw_noise(np.random.default_rng(4), 3)
    sequences = np.array(
        [
            [[4, 4, 4, 0, 0, 0], [0, 2, 0, 0, 0, 1], [0, 0, 0, 4, 4, 4]],
            [[0] * 6, [1, 0, 3, 0, 4, 0], [2, 2, 2, 2, 2, 2]],
        ]
    )
    together = simulator.population_rates(sequences, noise)
    assert together.shape == (2, paper.n_candidates, 3, 3 * 20, 3)
    for p, sequence in enumerate(sequences):
        assert np.array_equal(together[p], simulator.run(sequence, noise).omega_true)


@pytest.mark.parametrize(
    ("sequence", "lag_moves_it"),
    [
        ([[4, 4, 4, 0, 0, 0]] * 4, True),  # hand-designed, left spinning at ~0.2 rad/s
        ([[4, 4, 4, 0, 0, 0]] * 2 + [[0, 0, 0, 4, 4, 4]] * 2, True),  # brakes to the end
        # Every level and thruster, the last step torquing all three axes.
        ([[4, 0, 2, 1, 3, 0], [0, 3, 0, 4, 1, 2], [1, 4, 0, 0, 2, 3]], True),
    ],
)
@pytest.mark.parametrize("preset_name", ["paper", "custom"])
def test_settled_rate_agrees_with_an_independent_integration_of_the_lag_tail(
    request: pytest.FixtureRequest,
    sequence: list[list[int]],
    lag_moves_it: bool,
    preset_name: str,
) -> None:
    """The settled rate adds the torque still in the lag at once (ω + I⁻¹ τ m) and leaves
    out the gyroscopic term while the lag empties. Checked against scipy's DOP853
    integrating Euler's equations with the lag's decaying torque, 2 s on, beside a
    torque-free integration from the settled rate over the same 2 s (|ω| is not
    conserved torque-free, so they are compared at the same instant): the rate
    magnitude, the figure a residual bound acts on, agrees to 5e-4 of itself (about
    1e-6 rad/s on the paper preset's sequences; the error is second order in the rate), while
    the torque still in the lag moves it by far more."""
    from scipy.integrate import solve_ivp

    from inertia_id.physics.presets import NOISE_OFF
    from inertia_id.physics.simulate import settled_rates

    # Every noise off, the actuation lag kept.
    scenario = request.getfixturevalue(preset_name).with_uncertainty(**NOISE_OFF)
    top = scenario.n_levels - 1
    sequence = [[min(v, top) for v in row[: scenario.n_thrusters]] for row in sequence]
    simulator = Simulator(scenario, 1)
    noise = simulator.draw_noise(np.random.default_rng(0), len(sequence))
    _, end = simulator.population_run(np.array([sequence]), noise)
    settled = settled_rates(scenario, end.omega, end.torque)[0, :, 0]  # (K, 3)
    tau = scenario.uncertainty.lowpass_time_constant_s
    assert tau > 0
    omega, torque = end.omega[0, :, 0], end.torque[0, :, 0]
    moved = 0.0
    for k, inertia in enumerate(scenario.inertia_array):

        def lag(t: float, w: np.ndarray, k: int = k, inertia: np.ndarray = inertia) -> np.ndarray:
            applied = torque[k] * np.exp(-t / tau)
            return np.linalg.solve(inertia, applied - np.cross(w, inertia @ w))

        def free(_t: float, w: np.ndarray, inertia: np.ndarray = inertia) -> np.ndarray:
            return np.linalg.solve(inertia, -np.cross(w, inertia @ w))

        tight = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-14}
        flown = solve_ivp(lag, (0.0, 2.0), omega[k], **tight).y[:, -1]
        closed = solve_ivp(free, (0.0, 2.0), settled[k], **tight).y[:, -1]
        speed = np.linalg.norm(closed)
        assert np.linalg.norm(flown) == pytest.approx(speed, rel=5e-4, abs=1e-7)
        moved = max(moved, abs(np.linalg.norm(settled[k]) - np.linalg.norm(omega[k])))
    if lag_moves_it or preset_name == "custom":
        assert moved > 1e-3


@pytest.mark.parametrize(
    ("peak_rad_s", "shown"),
    [
        (100.4, "to 100.4 rad/s (5,752 deg/s)"),
        (100.0001, "to 100.0001 rad/s (5,729.584 deg/s)"),
        (125.0, "to 125 rad/s (7,162 deg/s)"),
    ],
)
def test_a_rate_just_past_the_gyro_ceiling_is_shown_above_it(
    paper: Scenario, peak_rad_s: float, shown: str
) -> None:
    """A peak of 100.4 rad/s read "spins ... to 100 rad/s ... past 100 rad/s" (``:.3g``):
    the measured peak is written with the digits that show it past the ceiling, in rad/s
    and deg/s, the ceiling with as many (5,730 deg/s is 5,729.578 beside 5,729.584)."""
    from inertia_id.physics.scenario import MAX_GYRO_RATE_RAD_S
    from inertia_id.physics.simulate import RatesBeyondGyro, check_gyro_range

    sequence = np.array([[4, 4, 4, 0, 0, 0]] * 2)
    omega = np.zeros((paper.n_candidates, 1, 2 * 10, 3))
    omega[0, 0, 15, 2] = -peak_rad_s
    with pytest.raises(RatesBeyondGyro) as refused:
        check_gyro_range(paper, sequence, omega)
    message = str(refused.value)
    assert shown in message, message
    assert "about its z axis at its fastest" in message
    number = r"([0-9][0-9,.e+]*)"
    peak = re.search(rf"to {number} rad/s \({number} deg/s\)", message)
    ceiling = re.search(rf"at most {number} rad/s, {number} deg/s", message)
    assert peak is not None and ceiling is not None, message
    rad, deg, ceiling_rad, ceiling_deg = (
        float(text.replace(",", "")) for text in (*peak.groups(), *ceiling.groups())
    )
    assert rad > ceiling_rad == MAX_GYRO_RATE_RAD_S and deg > ceiling_deg
    assert f"past {ceiling_rad:g} rad/s from step 2 of 2" in message
