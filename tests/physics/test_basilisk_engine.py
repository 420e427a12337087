"""Basilisk as a second simulation engine (inertia_id.physics.engines.basilisk).

The tests that fly Basilisk skip when it is not installed (``pip install
"inertia-id[basilisk]"``), or fail when ``INERTIA_ID_REQUIRE_SERVICES=1`` (CI sets it).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE
from service_support import skip_or_fail

from inertia_id import Scenario, Telemetry, identify, simulate, train_classifier
from inertia_id.physics.attitude import quaternion_multiply, rotation_angle_deg
from inertia_id.physics.engines import (
    CANTED_SEQUENCE,
    basilisk_available,
    basilisk_version,
    canted_full_tensor_scenario,
    simulate_basilisk,
)
from inertia_id.physics.engines.basilisk import _lagged_torque
from inertia_id.search.plan import command_plan

QUIET_SEQUENCE = [[0, 0, 0, 0, 0, 0]]

# Basilisk against our RK4, noise off. Measured: 1.1e-6 rad/s on the paper preset (our
# RK4 step on the lag, h / tau = 0.5), 1.3e-7 on the canted scenario.
AGREEMENT_RAD_S = 1e-5


@pytest.fixture(scope="module")
def bsk() -> None:
    """Skip (or, in CI, fail) the tests that need Basilisk when it does not import."""
    if basilisk_available():
        return
    skip_or_fail('Basilisk is not installed: pip install "inertia-id[basilisk]" (PyPI bsk)')


# Without Basilisk: the closed-form lag and the cross-check scenario.


def test_lag_is_exact() -> None:
    tau, hub_ns, per_step = 0.1, 50_000_000, 20
    commanded = np.array([[2.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    mean, state = _lagged_torque(commanded, tau, hub_ns, per_step)
    h = hub_ns * 1e-9
    t = np.arange(per_step + 1) * h
    np.testing.assert_allclose(state[: per_step + 1], np.outer(1 - np.exp(-t / tau), commanded[0]))
    # The mean over each hub step integrates the exact exponential.
    exact = np.outer(h + tau * (np.exp(-(t[1:]) / tau) - np.exp(-t[:-1] / tau)), commanded[0])
    np.testing.assert_allclose(mean[:per_step] * h, exact, atol=1e-15)
    # The second step relaxes from where the first ended.
    m1 = state[per_step]
    np.testing.assert_allclose(
        state[-1], commanded[1] + (m1 - commanded[1]) * math.exp(-per_step * h / tau)
    )
    # No lag: the command itself.
    mean0, state0 = _lagged_torque(commanded, 0.0, hub_ns, per_step)
    np.testing.assert_array_equal(mean0, np.repeat(commanded, per_step, axis=0))
    np.testing.assert_array_equal(state0[-1], commanded[1])


def test_canted_scenario_has_products_of_inertia_and_canted_thrusters() -> None:
    scenario = canted_full_tensor_scenario()
    inertia = scenario.inertia_array
    off_diagonal = inertia[:, ~np.eye(3, dtype=bool)]
    assert np.all(np.abs(off_diagonal) >= 1.0)
    matrix = scenario.torque_matrix
    assert np.linalg.matrix_rank(matrix) == 3
    # No thruster torques about a single body axis.
    assert np.all(np.count_nonzero(np.abs(matrix) > 1e-9, axis=0) >= 2)
    scenario.check_sequence(CANTED_SEQUENCE)


# With Basilisk.


@pytest.mark.parametrize("which", ["paper", "canted"])
def test_engines_agree_with_noise_off(bsk: None, which: str, noise_off: dict[str, Any]) -> None:
    if which == "paper":
        scenario, sequence = Scenario.paper(), GOOD_SEQUENCE
    else:
        scenario, sequence = canted_full_tensor_scenario(), CANTED_SEQUENCE
    scenario = scenario.with_uncertainty(**noise_off)
    ours = simulate(scenario, sequence, 1, np.random.default_rng(0))
    for k in range(scenario.n_candidates):
        flown = simulate_basilisk(scenario, sequence, k, np.random.default_rng(0))
        np.testing.assert_allclose(flown.time_s, ours.time_s, rtol=0, atol=1e-12)
        assert np.abs(flown.omega_true - ours.omega_true[k, 0]).max() < AGREEMENT_RAD_S
        # The response is far above the tolerance: the check has teeth.
        assert np.abs(ours.omega_true[k, 0]).max() > 0.1
        # Noise off: the IMU reads the truth.
        np.testing.assert_allclose(flown.omega_measured, flown.omega_true, rtol=0, atol=1e-15)
        np.testing.assert_allclose(flown.commanded_torque_nm, ours.commanded_torque_nm[k, 0])


# A rest-ending sequence of the paper preset: fire, coast, brake (L = 8).
FIRE_COAST_BRAKE = [[4, 4, 4, 0, 0, 0]] * 2 + [[0] * 6] * 4 + [[0, 0, 0, 4, 4, 4]] * 2
# The plan's attitude change against Basilisk's sigma_BN, Basilisk on a 2 ms hub step
# (converged: the same attitude at 0.5 ms, to under 2e-6 degrees). Measured: 6.3e-4
# degrees at most on the paper preset, 2.6e-4 on the canted scenario: the plan
# propagates the rates at every integration step (0.05 s, 0.04 s), second order in it,
# whatever the gyro's rate (propagated from a 1 Hz gyro's samples it was 0.063 degrees
# off). (Basilisk on the scenario's own 0.05 s step is itself 5.4e-4 degrees off: its hub
# holds each step's mean torque.)
ATTITUDE_AGREEMENT_DEG = 1e-3
BASILISK_FINE_STEP_S = 0.002


def _mrp_to_quaternion(sigma: np.ndarray) -> np.ndarray:
    """Modified Rodrigues parameters to a unit quaternion (w, x, y, z), batched."""
    squared = np.sum(sigma * sigma, axis=-1, keepdims=True)
    return np.concatenate([(1.0 - squared) / (1.0 + squared), 2.0 * sigma / (1.0 + squared)], -1)


def _with_gyro_rate(scenario: Scenario, sample_rate_hz: float) -> Scenario:
    document = scenario.model_dump()
    document["timing"] = {**document["timing"], "sample_rate_hz": sample_rate_hz}
    return Scenario.model_validate(document)


@pytest.mark.parametrize(
    ("which", "sequence"),
    [
        ("paper", GOOD_SEQUENCE),
        ("paper", FIRE_COAST_BRAKE),
        ("canted", CANTED_SEQUENCE),
        # The same dynamics, a gyro at 1 Hz: the attitude must not depend on it.
        ("paper at 1 Hz", FIRE_COAST_BRAKE),
    ],
)
def test_the_plans_attitude_change_is_basilisks(
    bsk: None, which: str, sequence: list[list[int]], noise_off: dict[str, Any]
) -> None:
    """The command plan's final attitude per candidate, against Basilisk's own attitude."""
    scenario = Scenario.paper() if which.startswith("paper") else canted_full_tensor_scenario()
    if which == "paper at 1 Hz":
        scenario = _with_gyro_rate(scenario, 1.0)
    scenario = scenario.with_uncertainty(**noise_off)
    plan = command_plan(scenario, sequence)
    for k in range(scenario.n_candidates):
        flown = simulate_basilisk(
            scenario, sequence, k, np.random.default_rng(0), hub_step_s=BASILISK_FINE_STEP_S
        )
        theirs = _mrp_to_quaternion(flown.attitude_mrp[-1])
        ours = np.asarray(plan.attitude_quaternion[k])
        inverse = ours * np.array([1.0, -1.0, -1.0, -1.0])
        # The rotation between the two attitudes, whatever the sign (or MRP set) of each.
        apart = float(rotation_angle_deg(quaternion_multiply(inverse, theirs)))
        assert apart < ATTITUDE_AGREEMENT_DEG, (k, apart)
        assert plan.attitude_change_deg[k] == pytest.approx(
            float(rotation_angle_deg(theirs)), abs=ATTITUDE_AGREEMENT_DEG
        )
        # Teeth: the body turns by tens of degrees, and the opposite convention (the
        # inverse rotation) would be twice that far from Basilisk's.
        assert plan.attitude_change_deg[k] > 15.0
        assert float(rotation_angle_deg(quaternion_multiply(ours, theirs))) > 30.0


def test_same_draws_as_our_simulator_with_process_noise_on(bsk: None) -> None:
    """Jitter, thrust scale, disturbance, initial rate and random bias: the same draws."""
    scenario = Scenario.paper().with_uncertainty(
        thrust_scale_sigma=0.02, initial_rate_sigma_rad_s=5e-3, gyro_bias_sigma_rad_s=2e-3
    )
    ours = simulate(scenario, GOOD_SEQUENCE, 1, np.random.default_rng(3))
    for k in (0, 4):
        flown = simulate_basilisk(scenario, GOOD_SEQUENCE, k, np.random.default_rng(3))
        np.testing.assert_array_equal(flown.commanded_torque_nm, ours.commanded_torque_nm[k, 0])
        assert np.abs(flown.omega_true - ours.omega_true[k, 0]).max() < AGREEMENT_RAD_S
        assert np.abs(flown.initial_rate_rad_s).max() > 1e-3
        # Gyro noise is Basilisk's own: the measured series differ by about sqrt(2) sigma.
        rms = np.sqrt(np.mean((flown.omega_measured - ours.omega_measured[k, 0]) ** 2))
        assert 0.8e-3 < rms < 2.5e-3


def test_initial_rate_is_respected(bsk: None, noise_off: dict[str, Any]) -> None:
    quiet = Scenario.paper().with_uncertainty(**noise_off)
    # About a principal axis of a diagonal body, torque-free: the rate stays.
    spin = (0.0, 0.02, 0.0)
    flown = simulate_basilisk(
        quiet, QUIET_SEQUENCE, 0, np.random.default_rng(0), initial_rate_rad_s=spin
    )
    np.testing.assert_allclose(flown.omega_true, np.tile(spin, (20, 1)), rtol=0, atol=1e-15)
    np.testing.assert_array_equal(flown.initial_rate_rad_s, spin)
    # A tumbling full tensor: momentum magnitude and kinetic energy are conserved while
    # the rate itself moves.
    canted = canted_full_tensor_scenario().with_uncertainty(**noise_off)
    omega0 = np.array([0.03, -0.02, 0.05])
    flown = simulate_basilisk(
        canted, [[0] * 8] * 2, 3, np.random.default_rng(0), initial_rate_rad_s=omega0
    )
    inertia = canted.inertia_array[3]
    momentum = np.linalg.norm(flown.omega_true @ inertia, axis=1)
    energy = np.einsum("ti,ij,tj->t", flown.omega_true, inertia, flown.omega_true)
    np.testing.assert_allclose(momentum, np.linalg.norm(inertia @ omega0), rtol=1e-9)
    np.testing.assert_allclose(energy, omega0 @ inertia @ omega0, rtol=1e-9)
    assert np.abs(flown.omega_true - omega0).max() > 1e-3
    assert np.abs(flown.omega_true[0] - omega0).max() < 1e-3  # 0.04 s after the start


@pytest.mark.parametrize("rate", [1, 10, 50, 200])
def test_sample_rates(bsk: None, rate: int, noise_off: dict[str, Any]) -> None:
    scenario = Scenario.paper().with_uncertainty(**noise_off)
    flown = simulate_basilisk(
        scenario,
        GOOD_SEQUENCE,
        2,
        np.random.default_rng(0),
        sample_rate_hz=rate,
        start_time_s=812_345_678.0,
    )
    n = 4 * rate
    assert flown.time_s.shape == (n,)
    assert flown.omega_measured.shape == flown.omega_true.shape == (n, 3)
    np.testing.assert_allclose(
        flown.time_s - 812_345_678.0, np.arange(1, n + 1) / rate, rtol=0, atol=1e-6
    )
    assert flown.sample_rate_hz == rate
    assert flown.hub_step_s <= 0.05 + 1e-12
    # The same physics whatever the rate: against our 20 Hz series at common times.
    ours = simulate(scenario, GOOD_SEQUENCE, 1, np.random.default_rng(0))
    common = np.intersect1d(np.round(ours.time_s, 9), np.round(flown.time_s - 812_345_678.0, 6))
    assert common.size >= 4
    mine = np.searchsorted(np.round(ours.time_s, 9), common)
    theirs = np.searchsorted(np.round(flown.time_s - 812_345_678.0, 6), common)
    assert np.abs(flown.omega_true[theirs] - ours.omega_true[2, 0, mine]).max() < AGREEMENT_RAD_S


def test_noise_statistics(bsk: None, noise_off: dict[str, Any]) -> None:
    """A long quiet run: the IMU's white noise and bias are what was asked for."""
    sigma, bias = 2e-3, np.array([5e-3, -3e-3, 2e-3])
    scenario = Scenario.paper().with_uncertainty(**noise_off)
    flown = simulate_basilisk(
        scenario,
        QUIET_SEQUENCE * 40,
        0,
        np.random.default_rng(5),
        sample_rate_hz=100,
        gyro_noise_sigma_rad_s=sigma,
        gyro_bias_rad_s=bias,
        initial_rate_rad_s=(0.01, 0.0, -0.01),
    )
    error = flown.omega_measured - flown.omega_true
    n = len(error)
    assert n == 4000
    np.testing.assert_allclose(error.mean(axis=0), bias, rtol=0, atol=4 * sigma / math.sqrt(n))
    # The std of a sample std is sigma / sqrt(2 n): 1.1 % here; 5 % is > 4 of those.
    np.testing.assert_allclose(error.std(axis=0, ddof=1), sigma, rtol=0.05)
    for axis in range(3):
        e = error[:, axis] - error[:, axis].mean()
        assert abs(np.dot(e[:-1], e[1:]) / np.dot(e, e)) < 4 / math.sqrt(n)  # white
    assert flown.gyro_noise_sigma_rad_s == sigma
    np.testing.assert_array_equal(flown.gyro_bias_rad_s, bias)


def test_noise_defaults_come_from_the_scenario(bsk: None, noise_off: dict[str, Any]) -> None:
    scenario = Scenario.paper().with_uncertainty(
        **{**noise_off, "gyro_noise_sigma_rad_s": 1e-3, "gyro_bias_rad_s": (1e-3, 0.0, 0.0)}
    )
    flown = simulate_basilisk(
        scenario, GOOD_SEQUENCE, 0, np.random.default_rng(0), measurement_noise_scale=2.0
    )
    assert flown.gyro_noise_sigma_rad_s == 2e-3
    np.testing.assert_array_equal(flown.gyro_bias_rad_s, (1e-3, 0.0, 0.0))


def test_seeded_rng_is_deterministic(bsk: None) -> None:
    scenario = Scenario.paper()
    runs = [
        simulate_basilisk(scenario, GOOD_SEQUENCE, 1, np.random.default_rng(seed))
        for seed in (11, 11, 12)
    ]
    np.testing.assert_array_equal(runs[0].omega_measured, runs[1].omega_measured)
    np.testing.assert_array_equal(runs[0].omega_true, runs[1].omega_true)
    assert runs[0].imu_seed == runs[1].imu_seed != runs[2].imu_seed
    assert np.abs(runs[0].omega_measured - runs[2].omega_measured).max() > 1e-4


def test_candidate_by_name_and_refusals(bsk: None) -> None:
    scenario = Scenario.paper()
    by_name = simulate_basilisk(
        scenario, GOOD_SEQUENCE, "payload 2 ejected", np.random.default_rng(0)
    )
    by_index = simulate_basilisk(scenario, GOOD_SEQUENCE, 2, np.random.default_rng(0))
    np.testing.assert_array_equal(by_name.omega_measured, by_index.omega_measured)
    assert by_name.candidate == "payload 2 ejected"
    with pytest.raises(ValueError, match="unknown candidate"):
        simulate_basilisk(scenario, GOOD_SEQUENCE, "payload 9", np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"outside 0\.\.4"):
        simulate_basilisk(scenario, GOOD_SEQUENCE, 5, np.random.default_rng(0))
    with pytest.raises(ValueError, match="whole number of nanoseconds"):
        simulate_basilisk(scenario, GOOD_SEQUENCE, 0, np.random.default_rng(0), sample_rate_hz=3)
    with pytest.raises(ValueError, match="does not divide"):
        simulate_basilisk(scenario, GOOD_SEQUENCE, 0, np.random.default_rng(0), hub_step_s=0.03)
    with pytest.raises(ValueError, match="level index"):
        simulate_basilisk(scenario, [[5, 0, 0, 0, 0, 0]], 0, np.random.default_rng(0))


def test_identify_on_basilisk_telemetry(bsk: None) -> None:
    """Telemetry we did not generate: a classifier trained on ours names every candidate."""
    scenario = Scenario.paper()
    classifier = train_classifier(
        scenario,
        GOOD_SEQUENCE,
        20,
        np.random.default_rng(1),
        kind="nearest-centroid",
        metric="euclidean",
    )
    rng = np.random.default_rng(2)
    for k, name in enumerate(scenario.candidate_names):
        flown = simulate_basilisk(scenario, GOOD_SEQUENCE, k, rng)
        verdict = identify(classifier, Telemetry.model_validate(flown.as_telemetry()))
        assert verdict.candidate == name


def test_version_is_reported(bsk: None) -> None:
    version = basilisk_version()
    assert version is not None and version[0].isdigit()
