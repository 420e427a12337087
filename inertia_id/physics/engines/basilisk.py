"""Basilisk (AVS Lab) as a second, independent simulation engine.

:func:`simulate_basilisk` flies one series of a scenario with Basilisk instead of our own
RK4 (``inertia_id.physics.simulate``): Basilisk's rigid spacecraft hub integrates the rotational
dynamics, an external torque effector applies the thruster and disturbance torque, and
Basilisk's IMU sensor model adds the gyro's white noise and bias. Only the actuation model
is ours, because it is the definition of what a sequence commands.

The Basilisk simulation, per call::

    process "inertia-id", task "dynamics" every h ns (the hub step), in this order:
      spacecraft.Spacecraft       hub: IHubPntBc_B = candidate tensor, omega_BN_BInit = ω0,
                                  Basilisk's RK4 (its default integrator), no gravity
      _TorquePlayer (Python)      writes CmdTorqueBodyMsg: the torque over [t, t + h]
      extForceTorque              reads cmdTorqueInMsg, applies it to the hub
    task "gyro" every 1/sample_rate s, after "dynamics" at shared ticks:
      imuSensor.ImuSensor         reads SCStatesMsg, writes IMUSensorMsg (AngVelPlatform)
      recorders                   IMUSensorMsg and SCStatesMsg at every gyro tick

**Torque.** Step ``j`` commands ``c_j = A (s ⊙ u_j)``, ``u_j`` the duty of each thruster
plus its timing jitter (firing thrusters only, clipped to [0, 1]), ``s`` the thrust-scale
error: the same model as ours. What the hub receives is the first-order low-pass of the
commanded torque, ``dm/dt = (c - m) / τ``, applied *exactly*: over a hub step of length
``h`` starting from ``m``, the effector applies the step's mean ``c + (m - c) (τ/h)
(1 - e^(-h/τ))`` and the lag state advances to ``c + (m - c) e^(-h/τ)`` (closed form), so
every step's angular impulse is exact. The disturbance torque is added, held per
disturbance interval.

**Randomness** is drawn with our own :class:`inertia_id.Simulator`'s ``draw_noise``, so
``simulate_basilisk(scenario, seq, k, rng)`` uses exactly the duty jitter, thrust-scale
error, disturbance torque, initial rate and random gyro bias that
``simulate(scenario, seq, 1, rng2)`` uses for candidate ``k`` when ``rng2`` has the same
state: the two engines can be compared series by series, noise on. One more integer is
then drawn from ``rng``: the seed of the IMU's own generator, which makes the gyro's white
noise (the only randomness Basilisk draws itself).

**Time stamps** are Basilisk's: the recorder's clock (integer nanoseconds) at each gyro
tick, in seconds, plus ``start_time_s``. The IMU's first call (t = 0) outputs a zeroed
message by design, so samples are the ticks at ``k / sample_rate_hz``, ``k = 1 .. n``, the
last at the end of the sequence: the same convention as ours.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
from dataclasses import dataclass
from functools import reduce
from typing import Any

import numpy as np

from inertia_id import Scenario, Simulator
from inertia_id.checks import is_integer

__all__ = [
    "CANTED_SEQUENCE",
    "BasiliskTelemetry",
    "BasiliskUnavailableError",
    "basilisk_available",
    "basilisk_version",
    "canted_full_tensor_scenario",
    "simulate_basilisk",
]

_NS = 1_000_000_000
# At most this many hub steps per call (1 kHz telemetry over ~17 minutes).
_MAX_HUB_STEPS = 1_000_000
# Hub steps shorter than this are refused: they would take long and add nothing.
_MIN_HUB_STEP_NS = 100_000
# The IMU generator (std::minstd_rand) takes a 32-bit seed; 0 is a degenerate LCG state.
_SEED_HIGH = 2**31 - 1

INSTALL_HINT = 'pip install "inertia-id[basilisk]"  (the PyPI package bsk)'


class BasiliskUnavailableError(ImportError):
    """Basilisk is not installed (or does not import) in this environment."""


def basilisk_available() -> bool:
    """Whether Basilisk's modules this engine uses import here."""
    try:
        _modules()
    except BasiliskUnavailableError:
        return False
    return True


def basilisk_version() -> str | None:
    """The installed ``bsk`` distribution's version, or None."""
    try:
        return importlib.metadata.version("bsk")
    except importlib.metadata.PackageNotFoundError:
        return None


def _modules() -> dict[str, Any]:
    try:
        return {
            "messaging": importlib.import_module("Basilisk.architecture.messaging"),
            "sysModel": importlib.import_module("Basilisk.architecture.sysModel"),
            "spacecraft": importlib.import_module("Basilisk.simulation.spacecraft"),
            "extForceTorque": importlib.import_module("Basilisk.simulation.extForceTorque"),
            "imuSensor": importlib.import_module("Basilisk.simulation.imuSensor"),
            "SimulationBaseClass": importlib.import_module(
                "Basilisk.utilities.SimulationBaseClass"
            ),
        }
    except ImportError as exc:
        raise BasiliskUnavailableError(
            f"Basilisk is not available ({exc}); install it with {INSTALL_HINT}"
        ) from exc


@dataclass(frozen=True)
class BasiliskTelemetry:
    """One series flown with Basilisk.

    :param time_s: (T,) sample time stamps, s: Basilisk's clock at each gyro tick plus
        ``start_time_s`` (so ``k / sample_rate_hz`` from the sequence start by default).
    :param omega_measured: (T, 3) gyro readings (IMU ``AngVelPlatform``), rad/s.
    :param omega_true: (T, 3) true body rates (hub ``omega_BN_B``) at the same ticks, rad/s.
    :param attitude_mrp: (T, 3) the hub's attitude ``sigma_BN`` at the same ticks:
        modified Rodrigues parameters of the body frame relative to the frame it started
        in (Basilisk integrates them with the rates; it may switch to the shadow set past
        180 degrees).
    :param applied_torque_nm: (T, 3) thruster torque after the low-pass at the same
        ticks (without the disturbance), N m.
    :param commanded_torque_nm: (L, 3) torque commanded per step (after jitter and
        thrust-scale error), N m.
    :param candidate: name of the candidate flown.
    :param inertia_kg_m2: (3, 3) its tensor.
    :param sample_rate_hz: gyro rate.
    :param hub_step_s: Basilisk's dynamics task period (its RK4 step), s.
    :param initial_rate_rad_s: (3,) body rate at the sequence start, rad/s.
    :param gyro_bias_rad_s: (3,) constant gyro bias given to the IMU, rad/s.
    :param gyro_noise_sigma_rad_s: white noise std per axis and sample given to the IMU.
    :param imu_seed: seed of the IMU's generator (drawn from ``rng``).
    """

    time_s: np.ndarray
    omega_measured: np.ndarray
    omega_true: np.ndarray
    attitude_mrp: np.ndarray
    applied_torque_nm: np.ndarray
    commanded_torque_nm: np.ndarray
    candidate: str
    inertia_kg_m2: np.ndarray
    sample_rate_hz: float
    hub_step_s: float
    initial_rate_rad_s: np.ndarray
    gyro_bias_rad_s: np.ndarray
    gyro_noise_sigma_rad_s: float
    imu_seed: int

    def as_telemetry(self) -> dict[str, list[Any]]:
        """The measured series as telemetry JSON (``inertia_id.parse_telemetry`` reads it)."""
        return {"time_s": self.time_s.tolist(), "omega_rad_s": self.omega_measured.tolist()}


def simulate_basilisk(
    scenario: Scenario,
    sequence: Any,
    candidate: int | str,
    rng: np.random.Generator,
    *,
    sample_rate_hz: float | None = None,
    initial_rate_rad_s: Any = None,
    gyro_bias_rad_s: Any = None,
    gyro_noise_sigma_rad_s: float | None = None,
    process_noise_scale: float = 1.0,
    measurement_noise_scale: float = 1.0,
    hub_step_s: float | None = None,
    start_time_s: float = 0.0,
) -> BasiliskTelemetry:
    """Fly one series of ``scenario`` with Basilisk and return its gyro telemetry.

    :param scenario: thrusters, timing and uncertainty (its candidates give the tensor).
    :param sequence: (L, N) level indices, one row per actuation step.
    :param candidate: index or name of the inertia candidate flown.
    :param rng: source of the randomness (see the module docstring: the same draws as
        ``simulate(scenario, sequence, 1, rng)`` for this candidate, then the IMU seed).
    :param sample_rate_hz: gyro rate, Hz (default the scenario's); its period must be a
        whole number of nanoseconds, Basilisk's clock (1e9 / rate an integer: 1, 2, 4, 5,
        8, 10, 16, 20, 25, 40, 50, 80, 100, 125, 200, 250, 400, 500, 1000 Hz, ...; not
        3 Hz), and share a hub step of at least 0.1 ms with the actuation step and the
        disturbance interval. The white noise std is per sample whatever the rate.
    :param initial_rate_rad_s: body rate at the sequence start, (3,) rad/s; default: the
        scenario's (its ``initial_rate_sigma_rad_s`` draw, zero when that is 0).
    :param gyro_bias_rad_s: constant gyro bias, (3,) rad/s; default: the scenario's
        ``gyro_bias_rad_s`` plus its random bias draw.
    :param gyro_noise_sigma_rad_s: white gyro noise std per axis and sample, rad/s;
        default: the scenario's, times ``measurement_noise_scale``.
    :param process_noise_scale: multiple of the scenario's disturbance torque sigma.
    :param measurement_noise_scale: multiple of the scenario's gyro noise and random bias
        sigmas.
    :param hub_step_s: Basilisk's dynamics step, s; default the longest step no longer
        than the scenario's integration step that divides the actuation step, the
        disturbance interval and the sample period.
    :param start_time_s: added to every time stamp (e.g. a mission clock), s.
    :raises BasiliskUnavailableError: Basilisk is not installed.
    :raises ValueError: an input breaks a rule (the message names it).
    """
    bsk = _modules()
    sequence = scenario.check_sequence(sequence)
    index = _candidate_index(scenario, candidate)
    timing, unc = scenario.timing, scenario.uncertainty
    rate = float(timing.sample_rate_hz if sample_rate_hz is None else sample_rate_hz)
    if not (math.isfinite(rate) and 0.0 < rate <= 10_000.0):
        raise ValueError(f"sample_rate_hz must be in (0, 10000] Hz, got {sample_rate_hz!r}")
    if not math.isfinite(start_time_s):
        raise ValueError(f"start_time_s must be finite, got {start_time_s!r}")

    step_ns = _whole_ns(timing.step_duration_s, "step_duration_s")
    interval_ns = _whole_ns(unc.disturbance_interval_s, "disturbance_interval_s")
    period_ns = _whole_ns(1.0 / rate, f"the sample period 1/{rate:g} Hz")
    if hub_step_s is None:
        grid = reduce(math.gcd, (step_ns, interval_ns, period_ns))
        hub_ns = _largest_divisor_at_most(
            grid, _whole_ns(timing.integration_step_s, "integration_step_s")
        )
    else:
        hub_ns = _whole_ns(hub_step_s, "hub_step_s")
        for name, value in (
            ("step_duration_s", step_ns),
            ("disturbance_interval_s", interval_ns),
            ("the sample period", period_ns),
        ):
            if value % hub_ns:
                raise ValueError(
                    f"hub_step_s = {hub_step_s} does not divide {name} ({value * 1e-9:g} s)"
                )
    if hub_ns < _MIN_HUB_STEP_NS:
        raise ValueError(
            f"the hub step would be {hub_ns * 1e-9:g} s (< {_MIN_HUB_STEP_NS * 1e-9:g} s): "
            "choose a sample rate whose period shares a longer step with the actuation "
            "step and the disturbance interval"
        )
    total_ns = step_ns * len(sequence)
    n_hub = total_ns // hub_ns
    if n_hub > _MAX_HUB_STEPS:
        raise ValueError(f"{n_hub} hub steps is too many (at most {_MAX_HUB_STEPS})")
    n_samples = total_ns // period_ns
    if n_samples < 1:
        raise ValueError(f"the sequence ({total_ns * 1e-9:g} s) is shorter than one sample")

    # Randomness: our simulator's draws for this candidate, then the IMU seed.
    draws = Simulator(
        scenario,
        1,
        process_noise_scale=process_noise_scale,
        measurement_noise_scale=measurement_noise_scale,
    ).draw_noise(rng, len(sequence))
    imu_seed = int(rng.integers(1, _SEED_HIGH))
    omega0 = _vector(
        draws.initial.omega0[index, 0] if initial_rate_rad_s is None else initial_rate_rad_s,
        "initial_rate_rad_s",
    )
    bias = _vector(
        draws.initial.gyro_bias[index, 0] if gyro_bias_rad_s is None else gyro_bias_rad_s,
        "gyro_bias_rad_s",
    )
    sigma = (
        unc.gyro_noise_sigma_rad_s * measurement_noise_scale
        if gyro_noise_sigma_rad_s is None
        else float(gyro_noise_sigma_rad_s)
    )
    if not (math.isfinite(sigma) and sigma >= 0.0):
        raise ValueError(f"gyro_noise_sigma_rad_s must be finite and >= 0, got {sigma!r}")

    # The torque over every hub step, in closed form (open loop: it does not depend on
    # the body's state).
    commanded = np.stack(
        [
            _commanded_torque(
                scenario.torque_matrix,
                scenario.level_values[levels],
                step.duty_jitter[index, 0],
                draws.initial.thrust_scale[index, 0],
            )
            for levels, step in zip(sequence, draws.steps, strict=True)
        ]
    )
    disturbance = np.concatenate([step.disturbance[index, 0] for step in draws.steps])
    hub_mean, hub_state = _lagged_torque(
        commanded, unc.lowpass_time_constant_s, hub_ns, step_ns // hub_ns
    )
    hub_torque = hub_mean + np.repeat(disturbance, interval_ns // hub_ns, axis=0)

    inertia = scenario.inertia_array[index]
    sim, recorders = _build(
        bsk, inertia, omega0, bias, sigma, imu_seed, hub_torque, hub_ns, period_ns
    )
    sim.InitializeSimulation()
    sim.ConfigureStopTime(total_ns)
    sim.ExecuteSimulation()

    imu_log, state_log = recorders
    times_ns = np.asarray(imu_log.times(), dtype=np.int64)
    expected = np.arange(n_samples + 1, dtype=np.int64) * period_ns
    if not np.array_equal(times_ns, expected) or not np.array_equal(
        np.asarray(state_log.times(), dtype=np.int64), expected
    ):
        raise RuntimeError(
            "Basilisk's gyro ticks are not at k / sample_rate_hz "
            f"(first {times_ns[:3].tolist()}, {len(times_ns)} ticks, expected {n_samples + 1})"
        )
    # Tick 0 is the IMU's zeroed first message: drop it.
    measured = np.asarray(imu_log.AngVelPlatform, dtype=float)[1:]
    true = np.asarray(state_log.omega_BN_B, dtype=float)[1:]
    attitude = np.asarray(state_log.sigma_BN, dtype=float)[1:]
    applied = hub_state[(expected[1:] // hub_ns)]
    return BasiliskTelemetry(
        time_s=times_ns[1:] * 1e-9 + float(start_time_s),
        omega_measured=measured,
        omega_true=true,
        attitude_mrp=attitude,
        applied_torque_nm=applied,
        commanded_torque_nm=commanded,
        candidate=scenario.candidate_names[index],
        inertia_kg_m2=inertia,
        sample_rate_hz=rate,
        hub_step_s=hub_ns * 1e-9,
        initial_rate_rad_s=omega0,
        gyro_bias_rad_s=bias,
        gyro_noise_sigma_rad_s=sigma,
        imu_seed=imu_seed,
    )


def _build(
    bsk: dict[str, Any],
    inertia: np.ndarray,
    omega0: np.ndarray,
    bias: np.ndarray,
    sigma: float,
    seed: int,
    hub_torque: np.ndarray,
    hub_ns: int,
    period_ns: int,
) -> tuple[Any, tuple[Any, Any]]:
    """The Basilisk simulation of one series (see the module docstring for its layout)."""
    spacecraft = bsk["spacecraft"]
    sim = bsk["SimulationBaseClass"].SimBaseClass()
    process = sim.CreateNewProcess("inertia-id")
    # Task priorities: higher runs first, so at a shared tick the hub has integrated up
    # to it before the IMU reads its state.
    process.addTask(sim.CreateNewTask("dynamics", hub_ns), 200)
    process.addTask(sim.CreateNewTask("gyro", period_ns), 100)

    hub = spacecraft.Spacecraft()
    hub.ModelTag = "inertia-id-hub"
    hub.hub.mHub = 1.0  # kg; only rotation is looked at (no gravity, no force)
    hub.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    hub.hub.IHubPntBc_B = np.asarray(inertia, dtype=float).tolist()
    hub.hub.omega_BN_BInit = [[float(w)] for w in omega0]

    player = _torque_player()(hub_torque, hub_ns)
    player.ModelTag = "inertia-id-thrusters"
    effector = bsk["extForceTorque"].ExtForceTorque()
    effector.ModelTag = "inertia-id-torque"
    effector.cmdTorqueInMsg.subscribeTo(player.cmdTorqueOutMsg)
    hub.addDynamicEffector(effector)
    # Within the task: the hub integrates [t - h, t] with the torque the effector read at
    # t - h; then the player writes the torque of [t, t + h] and the effector reads it.
    sim.AddModelToTask("dynamics", hub, 30)
    sim.AddModelToTask("dynamics", player, 20)
    sim.AddModelToTask("dynamics", effector, 10)

    imu = bsk["imuSensor"].ImuSensor()
    imu.ModelTag = "inertia-id-gyro"
    imu.scStateInMsg.subscribeTo(hub.scStateOutMsg)
    # White noise: the error model x' = A x + P n with A = 0 (Basilisk's default A = I
    # makes a random walk), P = sigma I, no walk bounds.
    imu.AMatrixGyro = np.zeros((3, 3)).tolist()
    imu.PMatrixGyro = (sigma * np.eye(3)).tolist()
    imu.senRotBias = [float(b) for b in bias]
    imu.RNGSeed = seed
    sim.AddModelToTask("gyro", imu, 30)
    imu_log = imu.sensorOutMsg.recorder()
    state_log = hub.scStateOutMsg.recorder()
    sim.AddModelToTask("gyro", imu_log, 20)
    sim.AddModelToTask("gyro", state_log, 20)
    # Keep the Python objects alive as long as the simulation (SWIG holds raw pointers).
    sim._inertia_id_keep = (hub, player, effector, imu)
    return sim, (imu_log, state_log)


def _torque_player() -> Any:
    """A Python Basilisk module that writes each hub step's torque as a CmdTorqueBodyMsg."""
    from Basilisk.architecture import messaging, sysModel

    class _TorquePlayer(sysModel.SysModel):
        def __init__(self, torque: np.ndarray, hub_ns: int) -> None:
            super().__init__()
            self.torque = [tuple(float(v) for v in row) for row in torque]
            self.hub_ns = hub_ns
            self.cmdTorqueOutMsg = messaging.CmdTorqueBodyMsg()
            self.payload = messaging.CmdTorqueBodyMsgPayload()

        def Reset(self, current_nanos: int) -> None:
            return None

        def UpdateState(self, current_nanos: int) -> None:
            k = current_nanos // self.hub_ns
            torque = self.torque[k] if k < len(self.torque) else (0.0, 0.0, 0.0)
            self.payload.torqueRequestBody = list(torque)
            self.cmdTorqueOutMsg.write(self.payload, current_nanos, self.moduleID)

    return _TorquePlayer


def _commanded_torque(
    torque_matrix: np.ndarray, levels: np.ndarray, jitter: np.ndarray, scale: np.ndarray
) -> np.ndarray:
    """M = A (s ⊙ u): u the commanded duty plus jitter on firing thrusters, in [0, 1]."""
    duty = np.where(levels > 0.0, np.clip(levels + jitter, 0.0, 1.0), 0.0)
    return torque_matrix @ (scale * duty)


def _lagged_torque(
    commanded: np.ndarray, tau: float, hub_ns: int, per_step: int
) -> tuple[np.ndarray, np.ndarray]:
    """The first-order lag of a piecewise-constant command, exactly, on the hub grid.

    :param commanded: (L, 3) torque commanded per actuation step, N m.
    :param tau: time constant, s (0: no lag).
    :param hub_ns: hub step, ns.
    :param per_step: hub steps per actuation step.
    :returns: the mean torque over each hub step (L * per_step, 3) and the lag state at
        each hub tick (L * per_step + 1, 3), starting from zero torque.
    """
    n = len(commanded) * per_step
    if tau == 0.0:
        mean = np.repeat(commanded, per_step, axis=0)
        state = np.vstack([np.zeros((1, 3)), mean])
        return mean, state
    x = hub_ns * 1e-9 / tau
    decay = math.exp(-x)
    mean_weight = -math.expm1(-x) / x  # (tau / h) (1 - e^(-h/tau))
    mean = np.empty((n, 3))
    state = np.empty((n + 1, 3))
    state[0] = 0.0
    m = np.zeros(3)
    powers = decay ** np.arange(per_step + 1)[:, None]
    for j, c in enumerate(commanded):
        start = c + (m - c) * powers  # state at the per_step + 1 ticks of this step
        state[j * per_step + 1 : (j + 1) * per_step + 1] = start[1:]
        mean[j * per_step : (j + 1) * per_step] = c + (start[:-1] - c) * mean_weight
        m = start[-1]
    return mean, state


def _candidate_index(scenario: Scenario, candidate: int | str) -> int:
    names = scenario.candidate_names
    if isinstance(candidate, str):
        if candidate not in names:
            raise ValueError(f"unknown candidate {candidate!r}; known: {names}")
        return names.index(candidate)
    if not is_integer(candidate):
        raise ValueError(f"candidate must be an index or a name, got {candidate!r}")
    if not 0 <= candidate < len(names):
        raise ValueError(f"candidate index {candidate} is outside 0..{len(names) - 1}")
    return int(candidate)


def _vector(value: Any, name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 3 numbers (rad/s), got {value!r}") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers (rad/s), got {value!r}")
    return arr


def _whole_ns(seconds: float, name: str) -> int:
    """``seconds`` as whole nanoseconds (Basilisk's clock), or a ValueError naming it."""
    ns = seconds * _NS
    # Rounding slack: a few ulps of the product, far below a nanosecond.
    if not math.isfinite(ns) or ns < 1.0 or abs(ns - round(ns)) > max(1e-3, 1e-12 * ns):
        raise ValueError(f"{name} = {seconds!r} s is not a whole number of nanoseconds")
    return round(ns)


def _largest_divisor_at_most(n: int, limit: int) -> int:
    """The largest divisor of ``n`` that is <= ``limit``."""
    if n <= limit:
        return n
    best = 1
    for d in range(1, math.isqrt(n) + 1):
        if n % d == 0:
            if d <= limit:
                best = max(best, d)
            if n // d <= limit:
                best = max(best, n // d)
    return best


# A scenario for cross-checking the engines beyond the paper preset: full tensors with
# products of inertia (principal axes off the body axes), eight canted thrusters whose
# torques are not along the body axes, and odd timing. Not a preset: a test fixture that
# the tests and bench/basilisk_agreement.py share.

CANTED_SEQUENCE: list[list[int]] = [
    [4, 0, 2, 0, 0, 3, 0, 1],
    [0, 4, 0, 2, 3, 0, 1, 0],
    [2, 2, 0, 0, 4, 4, 0, 0],
    [0, 0, 3, 3, 0, 0, 4, 4],
]


def canted_full_tensor_scenario() -> Scenario:
    """Four full-tensor candidates, eight canted thrusters, 2 s steps, 25 Hz gyro.

    Thrusters sit at the corners of a 1.2 x 1.2 x 1.8 m box, each pushing away from its
    z face with its thrust canted 20 degrees tangentially (2.5 N): the torque matrix has
    full rank with every column off the body axes. Noise at the paper's levels, plus a
    1 % thrust-scale error, a random gyro bias of 2e-3 rad/s and initial rates of
    5e-3 rad/s per axis.
    """
    cant = math.radians(20.0)
    columns = []
    for sz in (1.0, -1.0):
        for sx, sy in ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)):
            r = np.array([0.6 * sx, 0.6 * sy, 0.9 * sz])
            tangent = np.array([-sy, sx, 0.0]) / math.sqrt(2.0)
            force = 2.5 * (math.cos(cant) * np.array([0.0, 0.0, sz]) + math.sin(cant) * tangent)
            columns.append(np.cross(r, force))
    torque_matrix = np.array(columns).T
    candidates = {
        "stowed": [[110.0, 4.0, -3.0], [4.0, 80.0, 2.5], [-3.0, 2.5, 95.0]],
        "payload A ejected": [[100.0, 3.2, -2.0], [3.2, 74.0, 2.0], [-2.0, 2.0, 88.0]],
        "payload B ejected": [[104.0, 5.0, -4.0], [5.0, 71.0, 1.0], [-4.0, 1.0, 90.0]],
        "boom deployed": [[135.0, 6.0, -8.0], [6.0, 82.0, 3.0], [-8.0, 3.0, 118.0]],
    }
    return Scenario.model_validate(
        {
            "name": "canted full tensor",
            "inertia_candidates": [
                {"name": name, "inertia_kg_m2": tensor} for name, tensor in candidates.items()
            ],
            "thrusters": {"torque_matrix_nm": torque_matrix.tolist(), "n_levels": 5},
            "timing": {
                "step_duration_s": 2.0,
                "integration_step_s": 0.04,
                "sample_rate_hz": 25.0,
            },
            "uncertainty": {
                "duty_jitter_sigma": 0.02,
                "lowpass_time_constant_s": 0.15,
                "thrust_scale_sigma": 0.01,
                "disturbance_torque_sigma_nm": 0.03,
                "disturbance_interval_s": 0.2,
                "gyro_noise_sigma_rad_s": 1e-3,
                "gyro_bias_sigma_rad_s": 2e-3,
                "initial_rate_sigma_rad_s": 5e-3,
            },
        }
    )
