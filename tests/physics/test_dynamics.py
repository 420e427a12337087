"""Physics of inertia_id.physics.dynamics: Euler's equations with RK4, and the actuation low-pass.

All checks are against physics (conservation laws, closed-form solutions) or an
independent high-accuracy integrator, never against numbers the code itself produced.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from inertia_id.physics.dynamics import RigidBodies, cross, euler_rates

# An asymmetric body with products of inertia (principal moments ~59.2, 89.5, 101.3).
TUMBLER = np.array([[100.0, 5.0, -3.0], [5.0, 60.0, 2.0], [-3.0, 2.0, 90.0]])
W0 = np.array([0.1, 0.3, -0.2])
DIAG = np.diag([100.0, 60.0, 90.0])


def integrate(
    bodies: RigidBodies,
    omega0: np.ndarray,
    n_steps: int,
    commanded: np.ndarray | None = None,
    disturbance: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Step ``n_steps`` times from ``omega0`` (K, n, 3) with zero initial applied torque.

    Returns the histories of omega and applied torque, each (n_steps + 1, K, n, 3).
    """
    omega = np.array(omega0, dtype=float)
    torque = np.zeros_like(omega)
    commanded = np.zeros_like(omega) if commanded is None else commanded
    disturbance = np.zeros_like(omega) if disturbance is None else disturbance
    omegas, torques = [omega], [torque]
    for _ in range(n_steps):
        omega, torque = bodies.step(omega, torque, commanded, disturbance)
        omegas.append(omega)
        torques.append(torque)
    return np.array(omegas), np.array(torques)


def torque_free_reference(inertia: np.ndarray, omega0: np.ndarray, t_end: float) -> np.ndarray:
    def rhs(_t: float, w: np.ndarray) -> np.ndarray:
        return np.linalg.solve(inertia, -np.cross(w, inertia @ w))

    sol = solve_ivp(rhs, (0.0, t_end), omega0, method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    return sol.y[:, -1]


def test_euler_rates_matches_textbook_formula() -> None:
    rng = np.random.default_rng(0)
    inertia = np.stack([TUMBLER, DIAG])
    omega = rng.normal(size=(2, 4, 3))
    torque = rng.normal(size=(2, 4, 3))
    got = euler_rates(omega, torque, inertia, np.linalg.inv(inertia))
    for k in range(2):
        for i in range(4):
            w, m = omega[k, i], torque[k, i]
            expected = np.linalg.solve(inertia[k], m - np.cross(w, inertia[k] @ w))
            np.testing.assert_allclose(got[k, i], expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(cross(omega, torque), np.cross(omega, torque), rtol=0, atol=1e-15)


def test_torque_free_tumble_conserves_momentum_and_energy() -> None:
    """|I ω| and ω·Iω/2 are invariants of torque-free motion (body frame)."""
    eigenvalues, axes = np.linalg.eigh(TUMBLER)
    # Two starts: the brief's (0.1, 0.3, -0.2), and one just off the intermediate axis,
    # which flips over (Dzhanibekov effect) within the 100 s simulated.
    near_intermediate = 0.3 * axes[:, 1] + 0.01 * axes[:, 0] + 0.01 * axes[:, 2]
    omega0 = np.stack([W0, near_intermediate])[None]  # (1, 2, 3)
    dt, t_end = 0.005, 100.0
    omegas, _ = integrate(RigidBodies(TUMBLER[None], dt), omega0, round(t_end / dt))
    w = omegas[:, 0]  # (T, 2, 3)

    # It really tumbles: the rate vector swings far from where it started ...
    cos_to_start = np.einsum("tni,ni->tn", w, w[0]) / (
        np.linalg.norm(w, axis=-1) * np.linalg.norm(w[0], axis=-1)
    )
    assert cos_to_start[:, 0].min() < 0.5  # > 60 degrees away
    # ... and the near-intermediate start flips its intermediate-axis component.
    intermediate = w[:, 1] @ axes[:, 1]
    assert intermediate[0] > 0.29 and intermediate.min() < -0.29

    momentum = np.linalg.norm(w @ TUMBLER, axis=-1)
    energy = 0.5 * np.einsum("tni,ij,tnj->tn", w, TUMBLER, w)
    assert np.max(np.abs(momentum / momentum[0] - 1.0)) < 1e-8
    assert np.max(np.abs(energy / energy[0] - 1.0)) < 1e-8
    # And the principal moments in use are the asymmetric ones.
    assert eigenvalues[0] < eigenvalues[1] < eigenvalues[2]


@pytest.mark.parametrize("tau", [0.0, 0.3])
def test_constant_principal_torque_from_rest_spins_up_linearly(tau: float) -> None:
    """ω ∥ Iω on a principal axis, so ω × Iω = 0 and ω = M t / I exactly (tau = 0).

    With the low-pass on, the closed form is ω = (M / I)(t - tau (1 - exp(-t / tau))).
    """
    dt, n_steps, torque = 0.01, 1000, 2.0
    inertia = np.stack([DIAG, TUMBLER])  # diagonal, and one with products of inertia
    moments, axes = np.linalg.eigh(TUMBLER)
    commanded = np.empty((2, 3, 3))
    commanded[0] = torque * np.eye(3)  # body x, y, z
    commanded[1] = torque * axes.T  # along each principal axis
    per_axis_moment = np.stack([np.diag(DIAG), moments])  # (2, 3)
    omegas, applied = integrate(
        RigidBodies(inertia, dt, tau), np.zeros((2, 3, 3)), n_steps, commanded=commanded
    )
    t = n_steps * dt
    ramp = t if tau == 0.0 else t - tau * (1.0 - np.exp(-t / tau))
    expected = commanded / per_axis_moment[:, :, None] * ramp
    scale = np.abs(expected).max()
    rtol = 1e-12 if tau == 0.0 else 1e-8
    assert np.max(np.abs(omegas[-1] - expected)) <= rtol * scale
    if tau == 0.0:
        # Every intermediate step is on the line too, and the torque is applied at once.
        times = dt * np.arange(n_steps + 1)
        line = commanded[None] / per_axis_moment[None, :, :, None] * times[:, None, None, None]
        assert np.max(np.abs(omegas - line)) <= 1e-12 * scale
        np.testing.assert_array_equal(applied[-1], commanded)


def test_disturbance_adds_to_thruster_torque() -> None:
    rng = np.random.default_rng(3)
    bodies = RigidBodies(TUMBLER[None], 0.05)
    omega = rng.normal(scale=0.1, size=(1, 2, 3))
    c, d = rng.normal(size=(2, 1, 2, 3))
    zero = np.zeros_like(c)
    together, _ = bodies.step(omega, zero, c, d)
    summed, _ = bodies.step(omega, zero, c + d, zero)
    np.testing.assert_allclose(together, summed, rtol=0, atol=1e-15)


def test_rk4_converges_at_fourth_order() -> None:
    t_end = 20.0
    reference = torque_free_reference(TUMBLER, W0, t_end)
    errors = []
    for dt in (0.4, 0.2, 0.1):
        omegas, _ = integrate(RigidBodies(TUMBLER[None], dt), W0[None, None], round(t_end / dt))
        errors.append(np.linalg.norm(omegas[-1, 0, 0] - reference))
    # The errors must be far above the reference's own error for the ratio to mean much.
    assert errors[-1] > 1e-11
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    for ratio in ratios:
        assert 12.0 <= ratio <= 20.0, f"error ratios {ratios} are not ~16 (RK4)"


def test_batch_equals_individual_bodies() -> None:
    """One batched call advances each (candidate, realisation) as if alone."""
    rng = np.random.default_rng(7)
    inertia = np.stack([TUMBLER, DIAG])
    omega = rng.normal(scale=0.2, size=(2, 3, 3))
    commanded = rng.normal(size=(2, 3, 3))
    disturbance = rng.normal(scale=0.1, size=(2, 3, 3))
    torque = rng.normal(size=(2, 3, 3))
    batch_w, batch_m = RigidBodies(inertia, 0.05, 0.1).step(omega, torque, commanded, disturbance)
    for k in range(2):
        single = RigidBodies(inertia[k : k + 1], 0.05, 0.1)
        for i in range(3):
            sl = (slice(k, k + 1), slice(i, i + 1))
            w, m = single.step(omega[sl], torque[sl], commanded[sl], disturbance[sl])
            np.testing.assert_allclose(batch_w[k, i], w[0, 0], rtol=1e-14, atol=1e-16)
            np.testing.assert_allclose(batch_m[k, i], m[0, 0], rtol=1e-14, atol=1e-16)


def test_lowpass_follows_first_order_step_response() -> None:
    """Applied torque relaxes as c (1 - exp(-t / tau)) towards a constant command."""
    tau, dt, n_steps = 0.1, 0.005, 400
    commanded = np.array([[[2.0, -1.0, 0.5]]])
    # A symmetric body (I = 80 * identity): ω × Iω = 0, so ω = ∫ m dt / 80 exactly.
    inertia = 80.0 * np.eye(3)
    omegas, applied = integrate(
        RigidBodies(inertia[None], dt, tau), np.zeros((1, 1, 3)), n_steps, commanded=commanded
    )
    t = dt * np.arange(n_steps + 1)
    expected_torque = commanded[0, 0] * (1.0 - np.exp(-t / tau))[:, None]
    np.testing.assert_allclose(applied[:, 0, 0], expected_torque, rtol=0, atol=1e-7 * 2.0)
    expected_omega = commanded[0, 0] / 80.0 * (t - tau * (1.0 - np.exp(-t / tau)))[:, None]
    np.testing.assert_allclose(omegas[:, 0, 0], expected_omega, rtol=0, atol=1e-9)
    # After 4 time constants the torque is within 2 % of the command, not before 1.
    assert np.all(np.abs(applied[round(4 * tau / dt), 0, 0] / commanded[0, 0] - 1) < 0.02)
    assert np.all(np.abs(applied[round(tau / dt), 0, 0] / commanded[0, 0] - 1) > 0.3)


def test_lowpass_off_applies_torque_at_once() -> None:
    rng = np.random.default_rng(11)
    omega = rng.normal(scale=0.1, size=(1, 2, 3))
    commanded = rng.normal(size=(1, 2, 3))
    stale = rng.normal(size=(1, 2, 3))  # ignored when tau = 0
    bodies = RigidBodies(TUMBLER[None], 0.05, 0.0)
    w1, m1 = bodies.step(omega, stale, commanded, np.zeros_like(omega))
    w2, _ = bodies.step(omega, np.zeros_like(omega), commanded, np.zeros_like(omega))
    np.testing.assert_array_equal(m1, commanded)
    np.testing.assert_array_equal(w1, w2)


@pytest.mark.parametrize("tau", [0.0, 0.1])
@pytest.mark.parametrize("population", [False, True])
def test_the_compiled_run_is_the_step_loop(tau: float, population: bool) -> None:
    """``RigidBodies.run`` (the numba kernel the simulator uses) integrates as ``step``
    looped in numpy does: tumbling bodies with products of inertia, a lag or none, the
    disturbance held per interval, a leading population axis or none."""
    rng = np.random.default_rng(5)
    inertia = np.stack([TUMBLER, DIAG])
    bodies = RigidBodies(inertia=inertia, dt=0.01, tau=tau)
    shape = (4, 2, 3, 3) if population else (2, 3, 3)
    omega0 = 0.3 * rng.standard_normal(shape)
    torque0 = rng.standard_normal(shape)
    commanded = rng.standard_normal(shape)
    substeps, per_interval, per_sample = 20, 5, 4
    disturbance = 0.1 * rng.standard_normal((2, 3, substeps // per_interval, 3))
    given = (omega0, torque0, commanded, disturbance)
    counts = {"substeps": substeps, "per_interval": per_interval, "per_sample": per_sample}
    # The reference: step looped in numpy.
    omega, torque, looped, looped_torque = bodies.run_reference(*given, **counts)
    end, applied, sampled, sampled_torque = bodies.run(*given, **counts)
    assert np.allclose(end, omega, rtol=1e-12, atol=1e-15)
    assert np.allclose(applied, np.broadcast_to(torque, shape), rtol=1e-12, atol=1e-15)
    assert np.allclose(sampled, looped, rtol=1e-12, atol=1e-15)
    assert np.allclose(sampled_torque, looped_torque, rtol=1e-12, atol=1e-15)
    # The loop is the step: its first sample is per_sample steps of it.
    first, first_torque = omega0, torque0
    for sub in range(per_sample):
        first, first_torque = bodies.step(
            first, first_torque, commanded, disturbance[:, :, sub // per_interval]
        )
    assert np.array_equal(looped[..., 0, :], first)
    assert np.abs(end - omega0).max() > 0.01  # it moved: the comparison can fail
    # The inputs are left as they were.
    assert np.array_equal(omega0, 0.3 * np.random.default_rng(5).standard_normal(shape))


def test_the_compiled_run_refuses_what_it_would_read_out_of_bounds() -> None:
    """The kernel checks no bounds, so ``run`` checks the shapes first (the numpy loop
    raised or broadcast where the kernel would read past an array)."""
    bodies = RigidBodies(inertia=np.stack([TUMBLER, DIAG]), dt=0.01, tau=0.1)
    omega = np.zeros((2, 3, 3))
    good = {"substeps": 20, "per_interval": 5, "per_sample": 4}
    disturbance = np.zeros((2, 3, 4, 3))
    cases = [
        (RigidBodies(inertia=TUMBLER[None], dt=0.01), omega, disturbance, good, "inertia is"),
        (bodies, omega, disturbance, {**good, "per_interval": 3}, "not whole intervals"),
        (bodies, omega, np.zeros((2, 3, 2, 3)), good, "disturbance must be"),
        (bodies, np.zeros((3, 3)), disturbance, good, "omega must be"),
    ]
    for which, rates, torque_noise, counts, match in cases:
        with pytest.raises(ValueError, match=match):
            which.run(rates, rates, rates, torque_noise, **counts)
