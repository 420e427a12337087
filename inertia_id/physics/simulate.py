"""Simulate every inertia candidate's response to an actuation sequence, all at once.

The randomness of a run is drawn first (:class:`SequenceNoise`: per-realisation
constants, then per-step draws, in step order) and the integration is a deterministic
function of it. Two consequences a user can rely on:

- the same ``rng`` state gives the same result, whatever the noise scales, because the
  scales multiply standard-normal draws rather than change what is drawn;
- a sequence can be extended step by step (:meth:`Simulator.advance`) and gives exactly
  what simulating the whole sequence at once gives.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import is_integer
from ..errors import InputError
from ..wording import counted
from .actuation import commanded_torque, delivered_duty
from .dynamics import RigidBodies
from .presets import NOISE_OFF
from .scenario import AS_TRAINED, MAX_GYRO_RATE_RAD_S, Scenario, _shown

__all__ = [
    "InitialDraw",
    "RatesBeyondGyro",
    "SequenceNoise",
    "SimulationOverflow",
    "SimulationResult",
    "SimulationState",
    "Simulator",
    "StepDraw",
    "StepResponse",
    "at_gyro_samples",
    "check_gyro_range",
    "check_nominal_gyro_range",
    "disturbance_rate_covariance",
    "disturbance_walk",
    "every_substep_scenario",
    "nominal_simulator",
    "settled_rates",
    "simulate",
    "weak_response_warning",
]


class SimulationOverflow(InputError):
    """The simulated rates overflowed to inf or nan: the scenario (or the noise multiples
    asked for) drives the bodies beyond what the integrator follows."""


class RatesBeyondGyro(SimulationOverflow):
    """The simulated rates stay finite but pass the largest rate an attitude gyro
    measures (:data:`~inertia_id.physics.scenario.MAX_GYRO_RATE_RAD_S`): a prediction of
    them is no prediction of a spacecraft (an inertia or a torque in the wrong units)."""


@dataclass(frozen=True)
class InitialDraw:
    """Randomness fixed for a whole realisation.

    :param omega0: initial body rates (K, n, 3), rad/s.
    :param thrust_scale: torque scale of each thruster (K, n, N), 1 = nominal.
    :param gyro_bias: constant gyro bias (K, n, 3), rad/s.
    """

    omega0: np.ndarray
    thrust_scale: np.ndarray
    gyro_bias: np.ndarray


@dataclass(frozen=True)
class StepDraw:
    """Randomness of one actuation step.

    :param duty_jitter: duty error of each thruster (K, n, N), fraction of full duty.
    :param disturbance: disturbance torque per interval (K, n, intervals, 3), N m.
    :param gyro_noise: white gyro noise per sample (K, n, samples, 3), rad/s.
    """

    duty_jitter: np.ndarray
    disturbance: np.ndarray
    gyro_noise: np.ndarray


@dataclass(frozen=True)
class SequenceNoise:
    """All the randomness of one simulated sequence."""

    initial: InitialDraw
    steps: list[StepDraw]


@dataclass(frozen=True)
class SimulationState:
    """Where a batch stands between actuation steps.

    :param omega: true body rates (K, n, 3), rad/s.
    :param torque: applied thruster torque (K, n, 3), N m (the low-pass state).
    :param initial: the per-realisation constants drawn at the start.
    :param n_steps: actuation steps simulated so far.
    """

    omega: np.ndarray
    torque: np.ndarray
    initial: InitialDraw
    n_steps: int


@dataclass(frozen=True)
class StepResponse:
    """Telemetry of one actuation step, sampled at the gyro rate.

    :param omega_true: (K, n, samples, 3) true body rates, rad/s.
    :param omega_measured: (K, n, samples, 3) gyro readings, rad/s.
    :param applied_torque: (K, n, samples, 3) thruster torque after the low-pass, N m.
    :param commanded_torque: (K, n, 3) torque commanded over the step (after jitter and
        scale error), N m.
    """

    omega_true: np.ndarray
    omega_measured: np.ndarray
    applied_torque: np.ndarray
    commanded_torque: np.ndarray


@dataclass(frozen=True)
class SimulationResult:
    """Responses of every candidate and realisation to one sequence.

    :param time_s: (T,) sample times from the start of the sequence, s.
    :param omega_measured: (K, n, T, 3) gyro telemetry, rad/s: what a classifier sees.
    :param omega_true: (K, n, T, 3) true body rates, rad/s.
    :param applied_torque_nm: (K, n, T, 3) thruster torque after the low-pass, N m.
    :param commanded_torque_nm: (K, n, L, 3) torque commanded per step, N m.
    :param sequence: (L, N) level indices simulated.
    :param impulse_nms: fuel use of the sequence, total commanded angular impulse, N m s.
    :param candidate_names: names of the K candidates, in order.
    """

    time_s: np.ndarray
    omega_measured: np.ndarray
    omega_true: np.ndarray
    applied_torque_nm: np.ndarray
    commanded_torque_nm: np.ndarray
    sequence: np.ndarray
    impulse_nms: float
    candidate_names: list[str]

    @property
    def final_rate_rad_s(self) -> np.ndarray:
        """|ω| at the end of the sequence for each candidate and realisation, (K, n)."""
        return np.linalg.norm(self.omega_true[:, :, -1, :], axis=-1)

    def settled_rate_rad_s(self, scenario: Scenario) -> np.ndarray:
        """|ω| once the torque still in the actuation lag at the end has been delivered,
        for each candidate and realisation, (K, n) (:func:`settled_rates`)."""
        omega = settled_rates(
            scenario, self.omega_true[:, :, -1, :], self.applied_torque_nm[:, :, -1, :]
        )
        return np.linalg.norm(omega, axis=-1)

    @property
    def mean_final_rate_rad_s(self) -> float:
        """The paper's terminal penalty: |ω_final| averaged over all series, rad/s."""
        return float(self.final_rate_rad_s.mean())

    def dataset(self) -> tuple[np.ndarray, np.ndarray]:
        """Measured series as a classifier dataset: X (K*n, T, 3) and labels y (K*n,)."""
        k, n, t, _ = self.omega_measured.shape
        return self.omega_measured.reshape(k * n, t, 3), np.repeat(np.arange(k), n)


class Simulator:
    """Simulates K candidates x n realisations of a scenario, one step at a time.

    :param scenario: the spacecraft and its uncertainty.
    :param n_realisations: noisy realisations per candidate.
    :param process_noise_scale: multiple of the scenario's disturbance torque sigma.
    :param measurement_noise_scale: multiple of the scenario's gyro noise and random
        bias sigmas.
    """

    def __init__(
        self,
        scenario: Scenario,
        n_realisations: int,
        *,
        process_noise_scale: float = 1.0,
        measurement_noise_scale: float = 1.0,
    ) -> None:
        if not is_integer(n_realisations, minimum=1):
            raise InputError(f"n_realisations must be a positive integer, got {n_realisations!r}")
        for name, value in (
            ("process_noise_scale", process_noise_scale),
            ("measurement_noise_scale", measurement_noise_scale),
        ):
            if not np.isfinite(value) or value < 0:
                raise InputError(f"{name} must be finite and >= 0, got {value!r}")
        self.scenario = scenario
        self.n_realisations = int(n_realisations)
        self.process_noise_scale = float(process_noise_scale)
        self.measurement_noise_scale = float(measurement_noise_scale)
        timing, unc = scenario.timing, scenario.uncertainty
        self.bodies = RigidBodies(
            inertia=scenario.inertia_array,
            dt=timing.integration_step_s,
            tau=unc.lowpass_time_constant_s,
        )
        self.torque_matrix = scenario.torque_matrix
        self.level_values = scenario.level_values
        self.substeps = timing.substeps_per_step
        self.substeps_per_sample = timing.substeps_per_sample
        self.substeps_per_interval = round(unc.disturbance_interval_s / timing.integration_step_s)
        self.intervals = self.substeps // self.substeps_per_interval
        self.samples = timing.samples_per_step
        self.shape = (scenario.n_candidates, self.n_realisations)

    # Randomness.

    def draw_initial(self, rng: np.random.Generator) -> InitialDraw:
        unc = self.scenario.uncertainty
        k, n = self.shape
        n_thr = self.scenario.n_thrusters
        bias_sigma = unc.gyro_bias_sigma_rad_s * self.measurement_noise_scale
        return InitialDraw(
            omega0=unc.initial_rate_sigma_rad_s * rng.standard_normal((k, n, 3)),
            thrust_scale=1.0 + unc.thrust_scale_sigma * rng.standard_normal((k, n, n_thr)),
            gyro_bias=np.asarray(unc.gyro_bias_rad_s) + bias_sigma * rng.standard_normal((k, n, 3)),
        )

    def draw_step(self, rng: np.random.Generator) -> StepDraw:
        unc = self.scenario.uncertainty
        k, n = self.shape
        n_thr = self.scenario.n_thrusters
        disturbance_sigma = unc.disturbance_torque_sigma_nm * self.process_noise_scale
        gyro_sigma = unc.gyro_noise_sigma_rad_s * self.measurement_noise_scale
        return StepDraw(
            duty_jitter=unc.duty_jitter_sigma * rng.standard_normal((k, n, n_thr)),
            disturbance=disturbance_sigma * rng.standard_normal((k, n, self.intervals, 3)),
            gyro_noise=gyro_sigma * rng.standard_normal((k, n, self.samples, 3)),
        )

    def _overflowed(self) -> None:
        raise SimulationOverflow(_overflow_message(self))

    def check_finite(self, omega: np.ndarray) -> None:
        """Refuse rates that overflowed to inf or nan, naming what drives the bodies
        (:class:`SimulationOverflow`): for a caller that advances step by step, as
        :meth:`run` refuses them for a whole sequence."""
        if not np.isfinite(omega).all():
            self._overflowed()

    def draw_noise(self, rng: np.random.Generator, n_steps: int) -> SequenceNoise:
        initial = self.draw_initial(rng)
        return SequenceNoise(initial, [self.draw_step(rng) for _ in range(n_steps)])

    # Integration.

    def start(self, initial: InitialDraw) -> SimulationState:
        return SimulationState(
            omega=initial.omega0.copy(),
            torque=np.zeros((*self.shape, 3)),
            initial=initial,
            n_steps=0,
        )

    def start_population(self, initial: InitialDraw, size: int) -> SimulationState:
        """The start of ``size`` sequences simulated side by side on the same draws:
        arrays of shape (size, K, n, 3)."""
        omega = np.broadcast_to(initial.omega0, (size, *self.shape, 3)).copy()
        return SimulationState(omega=omega, torque=np.zeros_like(omega), initial=initial, n_steps=0)

    def advance(
        self, state: SimulationState, levels: np.ndarray, draw: StepDraw
    ) -> tuple[SimulationState, StepResponse]:
        """Simulate one more actuation step.

        A population of P sequences advances at once on the same draws (common random
        numbers): give ``levels`` of shape (P, N) and a state from
        :meth:`start_population`; every array then carries a leading P axis.

        :param state: where the batch stands.
        :param levels: (N,) level indices of this step, or (P, N) for a population.
        :param draw: this step's randomness.
        """
        commanded_duty = self.level_values[np.asarray(levels)]
        if commanded_duty.ndim == 2:
            commanded_duty = commanded_duty[:, None, None, :]  # (P, 1, 1, N)
        duty = delivered_duty(commanded_duty, draw.duty_jitter)
        commanded = commanded_torque(self.torque_matrix, duty, state.initial.thrust_scale)
        omega, torque, omega_true, applied = self.bodies.run(
            state.omega,
            state.torque,
            commanded,
            draw.disturbance,
            substeps=self.substeps,
            per_interval=self.substeps_per_interval,
            per_sample=self.substeps_per_sample,
        )
        measured = omega_true + state.initial.gyro_bias[..., None, :] + draw.gyro_noise
        response = StepResponse(omega_true, measured, applied, commanded)
        return SimulationState(omega, torque, state.initial, state.n_steps + 1), response

    def population_rates(
        self, sequences: np.ndarray, noise: SequenceNoise, *, measured: bool = False
    ) -> np.ndarray:
        """Body rates of P sequences (P, L, N) simulated side by side on the same draws,
        (P, K, n, T, 3) rad/s: how a search scores a whole population at once. The true
        rates, or with ``measured`` the gyro's readings (bias and white noise added).
        """
        return self.population_run(sequences, noise, measured=measured)[0]

    def settled(self, state: SimulationState) -> np.ndarray:
        """|ω| once the lag has delivered the torque still in it at ``state``: (..., K, n)
        (:func:`settled_rates`, with the inverse inertia this simulator already holds)."""
        omega = settled_rates(
            self.scenario, state.omega, state.torque, inertia_inv=self.bodies.inertia_inv
        )
        return np.linalg.norm(omega, axis=-1)

    def population_run(
        self, sequences: np.ndarray, noise: SequenceNoise, *, measured: bool = False
    ) -> tuple[np.ndarray, SimulationState]:
        """:meth:`population_rates`, and where the population stands at the end (the
        applied torque still in the actuation lag included: :func:`settled_rates`)."""
        state = self.start_population(noise.initial, len(sequences))
        parts = []
        for step in range(sequences.shape[1]):
            state, response = self.advance(state, sequences[:, step], noise.steps[step])
            parts.append(response.omega_measured if measured else response.omega_true)
        return np.concatenate(parts, axis=-2), state

    def run(self, sequence: np.ndarray, noise: SequenceNoise) -> SimulationResult:
        """Simulate a whole sequence with the given randomness."""
        sequence = self.scenario.check_sequence(sequence)
        if len(noise.steps) < len(sequence):
            raise InputError(
                f"noise holds {counted(len(noise.steps), 'step')}, the sequence {len(sequence)}"
            )
        state = self.start(noise.initial)
        responses = []
        for levels, draw in zip(sequence, noise.steps, strict=False):
            state, response = self.advance(state, levels, draw)
            responses.append(response)
        if not all(np.isfinite(r.omega_measured).all() for r in responses):
            self._overflowed()
        return SimulationResult(
            time_s=self.scenario.sample_times(len(sequence)),
            omega_measured=np.concatenate([r.omega_measured for r in responses], axis=2),
            omega_true=np.concatenate([r.omega_true for r in responses], axis=2),
            applied_torque_nm=np.concatenate([r.applied_torque for r in responses], axis=2),
            commanded_torque_nm=np.stack([r.commanded_torque for r in responses], axis=2),
            sequence=sequence,
            impulse_nms=self.scenario.impulse_nms(sequence),
            candidate_names=self.scenario.candidate_names,
        )


def _drive(scenario: Scenario) -> tuple[float, float]:
    """The largest thruster torque (N m) and the smallest principal moment of any
    candidate (kg m^2): what sets how fast a scenario spins its bodies up."""
    moment = min(
        float(np.linalg.eigvalsh(np.asarray(c.inertia_kg_m2)).min())
        for c in scenario.inertia_candidates
    )
    # A thruster's torque is its column's length: the largest component understated a
    # canted thruster's (0.577 N m for a tetrahedral 1 N m one).
    columns = np.abs(np.asarray(scenario.thrusters.torque_matrix_nm, dtype=float))
    # Scaled by each column's largest component first, so that a torque of 1e300 N m (a
    # scenario the overflow message describes) is not squared past a float's range.
    largest = columns.max(axis=0, initial=0.0)
    shares = columns / np.where(largest > 0.0, largest, 1.0)
    torque = float((largest * np.sqrt((shares**2).sum(axis=0))).max(initial=0.0))
    return torque, moment


def _overflow_message(simulator: Simulator) -> str:
    scenario = simulator.scenario
    torque, moments = _drive(scenario)
    noise = scenario.uncertainty
    # Every figure that can drive the rates: a disturbance, jitter or thrust-scale sigma
    # of 1e308 overflowed with a message that named the (nominal) torques alone.
    return (
        "the simulated rates overflowed to inf or nan: this scenario drives its bodies "
        f"beyond what the integrator follows (torques up to {torque:g} N m on a smallest "
        f"principal moment of {moments:g} kg m^2, disturbance torque sigma "
        f"{noise.disturbance_torque_sigma_nm:g} N m, duty jitter sigma "
        f"{noise.duty_jitter_sigma:g}, thrust-scale sigma {noise.thrust_scale_sigma:g}, "
        f"initial-rate sigma {noise.initial_rate_sigma_rad_s:g} rad/s, noise multiples "
        f"process x{simulator.process_noise_scale:g} and gyro "
        f"x{simulator.measurement_noise_scale:g}, integration step "
        f"{scenario.timing.integration_step_s:g} s); scale them down"
    )


def _visibly_past(value: float, ceiling: float) -> tuple[str, str]:
    """``value`` and ``ceiling`` (``value`` > ``ceiling``) with the fewest significant
    digits that show the value above the ceiling: at least 3, and the ceiling's whole
    part (5,730 deg/s, not 5.73e+03). ``:.3g`` showed a peak of 100.4 rad/s as "100",
    the ceiling's own figure."""
    whole = len(f"{abs(ceiling):.0f}")
    for digits in range(max(3, whole), 18):
        shown, limit = f"{value:,.{digits}g}", f"{ceiling:,.{digits}g}"
        if float(shown.replace(",", "")) > float(limit.replace(",", "")):
            return shown, limit
    return repr(value), repr(ceiling)  # not past the ceiling: each as it is


def check_gyro_range(
    scenario: Scenario,
    sequence: np.ndarray,
    omega: np.ndarray,
    *,
    settled: np.ndarray | None = None,
    flight: Callable[[int], str] = lambda _n: "the nominal prediction",
) -> None:
    """Refuse predicted body rates that no attitude gyro measures.

    A scenario whose inertia or torques are off by orders of magnitude (kg m^2 typed
    for g cm^2, say) is valid in every rule of its own, yet spins its bodies up to
    rates of 1e29 rad/s: a plan or a response that showed them would be read as a
    prediction. The ceiling is telemetry's: a rate past
    :data:`~inertia_id.physics.scenario.MAX_GYRO_RATE_RAD_S` about any body axis, as a
    gyro measures it axis by axis.

    :param sequence: (L, N) the level indices flown.
    :param omega: (K, n, T, 3) true body rates, rad/s, T a whole number of samples a
        step (a gyro's samples, or every integration step).
    :param settled: (K, n, 3) the rates once the actuation lag has emptied, if shown.
    :param flight: the words for realisation ``i`` (the nominal prediction, a flight).
    :raises RatesBeyondGyro: naming the sequence, the candidate and where (flight,
        step, axis) its rate is largest, in rad/s and deg/s, and the scenario's largest
        torque and smallest principal moment.
    """
    rates = np.abs(np.asarray(omega, dtype=float))
    after = None if settled is None else np.abs(np.asarray(settled, dtype=float))
    during_max = rates.max(initial=0.0)
    after_max = 0.0 if after is None else after.max(initial=0.0)
    largest = max(during_max, after_max)
    if not largest > MAX_GYRO_RATE_RAD_S:  # nan is left to the overflow check
        return
    rows = np.asarray(sequence)
    if after is not None and after_max > during_max:
        k, i, axis = np.unravel_index(int(np.argmax(after)), after.shape)
        when = "once the actuation lag has emptied"
    else:
        k, i, _t, axis = np.unravel_index(int(np.argmax(rates)), rates.shape)
        when = "at its fastest"
    # Where that flight first passes the ceiling: the step to look at.
    past = np.flatnonzero(rates[k, i].max(axis=-1) > MAX_GYRO_RATE_RAD_S)
    per_step = max(1, rates.shape[2] // len(rows))
    rate, ceiling = _visibly_past(float(largest), MAX_GYRO_RATE_RAD_S)
    rate_deg, ceiling_deg = _visibly_past(math.degrees(largest), math.degrees(MAX_GYRO_RATE_RAD_S))
    first = (
        f"past {ceiling} rad/s from step {int(past[0]) // per_step + 1} of {len(rows)}"
        if past.size
        else f"past {ceiling} rad/s once the lag has emptied"
    )
    torque, moment = _drive(scenario)
    raise RatesBeyondGyro(
        f"sequence {_shown(rows.tolist())} spins candidate "
        f"{scenario.candidate_names[int(k)]!r} to {rate} rad/s "
        f"({rate_deg} deg/s) about its {'xyz'[int(axis)]} axis {when} in "
        f"{flight(int(i))} ({first}): beyond any attitude gyro's range (at most "
        f"{ceiling} rad/s, {ceiling_deg} deg/s), so "
        "no attitude gyro measures it; the scenario's inertia (smallest principal moment "
        f"{moment:.3g} kg m^2) or torques (up to {torque:.3g} N m) are likely wrong in units"
    )


def check_nominal_gyro_range(scenario: Scenario, sequence: Any) -> SimulationResult:
    """The one rule for a sequence whose rates pass any attitude gyro's range: refuse
    ``sequence`` on ``scenario`` when its nominal prediction (every source of noise off,
    the actuation lag kept: :func:`nominal_simulator`) passes
    :data:`~inertia_id.physics.scenario.MAX_GYRO_RATE_RAD_S` about any body axis, at any
    integration step or once the lag has delivered the torque still in it
    (:func:`settled_rates`): what a gyro would see if the pass went on. A plan, a
    response, a training, a sweep and a search's submission all decide with it, so that
    none shows a prediction another refuses (a response read 94 rad/s at its gyro
    samples where the plan refused 105 once the lag emptied).

    :param sequence: (L, N) level indices.
    :returns: the nominal run, recorded at every integration step
        (:func:`at_gyro_samples` picks the gyro's samples out of it).
    :raises RatesBeyondGyro: as :func:`check_gyro_range` words it.
    """
    rows = scenario.check_sequence(sequence)
    simulator, noise = nominal_simulator(scenario, len(rows), every_substep=True)
    run = simulator.run(rows, noise)
    settled = settled_rates(scenario, run.omega_true[:, :, -1], run.applied_torque_nm[:, :, -1])
    check_gyro_range(scenario, rows, run.omega_true, settled=settled)
    return run


#: A sequence whose predicted rates stay this many times below the gyro's white noise (its
#: sigma a sample) is flagged, not refused: a classifier trained on it reads noise (a
#: scenario whose inertia was typed in kg mm^2 as kg m^2 peaked at 7.7e-7 deg/s under a
#: 0.03 deg/s gyro and trained to F1 0.31, 0.25 being chance, without a word).
WEAK_RESPONSE_FACTOR = 100.0


def weak_response_warning(scenario: Scenario, sequence: Any, run: SimulationResult) -> str | None:
    """A warning when ``sequence``'s nominal prediction ``run`` (from
    :func:`check_nominal_gyro_range`) peaks at least :data:`WEAK_RESPONSE_FACTOR` times
    below the scenario's gyro noise, naming both figures and the likely cause; None
    otherwise (or without gyro noise). A warning, not a refusal: a spacecraft may be that
    quiet on purpose, but a classifier of it then reads noise.
    """
    sigma = float(scenario.uncertainty.gyro_noise_sigma_rad_s)
    if not sigma > 0.0:
        return None
    settled = settled_rates(scenario, run.omega_true[:, :, -1], run.applied_torque_nm[:, :, -1])
    peak = max(
        float(np.linalg.norm(run.omega_true, axis=-1).max(initial=0.0)),
        float(np.linalg.norm(settled, axis=-1).max(initial=0.0)),
    )
    if not peak * WEAK_RESPONSE_FACTOR <= sigma:  # nan is left to the overflow check
        return None
    try:
        scenario.check_fires(sequence)
    except InputError as exc:
        # Nothing to blame on units: the sequence applies no torque (a front's all-off
        # member, whose plan had said the inertia or torques were "likely wrong in units").
        return str(exc)
    below = "(it moves no candidate at all)" if peak == 0.0 else f"by {sigma / peak:.3g}x"
    torque, moment = _drive(scenario)
    return (
        f"sequence {_shown(scenario.check_sequence(sequence).tolist())} on scenario "
        f"{scenario.name!r} is predicted to peak at {peak:.3g} rad/s "
        f"({math.degrees(peak):.3g} deg/s), below the gyro noise ({sigma:.3g} rad/s, "
        f"{math.degrees(sigma):.3g} deg/s a sample) {below}: its responses are noise to a "
        "classifier; the scenario's inertia (smallest principal moment "
        f"{moment:.3g} kg m^2) or torques (up to {torque:.3g} N m) are likely wrong in "
        "units (an inertia in kg mm^2 typed as kg m^2 makes every rate 1e6 too small), "
        "or the sequence fires too little"
    )


def nominal_simulator(
    scenario: Scenario, n_steps: int, *, every_substep: bool = False
) -> tuple[Simulator, SequenceNoise]:
    """A simulator of one realisation a candidate with every source of noise off (the
    actuation lag kept), and its draw for ``n_steps`` steps (nothing random in it): the
    response a flight team predicts, the one a command plan shows.

    With ``every_substep`` it records the rates at every integration step rather than at
    the gyro's samples (:func:`every_substep_scenario`): what the attitude is propagated from, so
    that the attitude does not depend on how often the gyro reports.
    """
    # Read back with AS_TRAINED (not with_uncertainty): the noise goes to zero and the
    # lag is the scenario's own, which a classifier trained before today's bound on a
    # stated lag may hold past it (its sweep refused it here otherwise).
    dump = scenario.model_dump()
    quiet = type(scenario).model_validate(
        {**dump, "uncertainty": {**dump["uncertainty"], **NOISE_OFF}}, context=AS_TRAINED
    )
    simulator = Simulator(every_substep_scenario(quiet) if every_substep else quiet, 1)
    return simulator, simulator.draw_noise(np.random.default_rng(0), n_steps)


def every_substep_scenario(scenario: Scenario) -> Scenario:
    """A copy of ``scenario`` whose "gyro" samples every integration step: the same
    dynamics, recorded on the integration grid. Sample ``s`` of it is at the time
    ``(s + 1) * integration_step_s``, so the gyro's own samples are every
    ``substeps_per_sample``-th of them, from index ``substeps_per_sample - 1``
    (:func:`at_gyro_samples`)."""
    timing = scenario.timing
    if timing.substeps_per_sample == 1:
        return scenario
    dump = scenario.model_dump()
    dump["timing"] = {**dump["timing"], "sample_rate_hz": 1.0 / timing.integration_step_s}
    # The same figures on a finer gyro grid: nothing newly stated (AS_TRAINED keeps a
    # classifier's scenario past today's noise bounds as it was trained).
    return type(scenario).model_validate(dump, context=AS_TRAINED)


def at_gyro_samples(scenario: Scenario, fine: np.ndarray) -> np.ndarray:
    """The samples of a run recorded every integration step (..., T_fine, 3) that fall
    on ``scenario``'s gyro samples (..., T, 3)."""
    per_sample = scenario.timing.substeps_per_sample
    return fine[..., per_sample - 1 :: per_sample, :]


def settled_rates(
    scenario: Scenario,
    omega: np.ndarray,
    torque: np.ndarray,
    *,
    inertia_inv: np.ndarray | None = None,
) -> np.ndarray:
    """The body rates once the actuation lag has delivered the torque still in it.

    When the last command ends, the applied torque ``m`` does not stop at once: the lag
    ``dm/dt = -m / tau`` still delivers ``∫ m dt = tau m`` (a first-order lag delivers
    every commanded impulse in full, late). So the rate the spacecraft is left with is
    ``ω + I⁻¹ tau m``, not the rate when the command ends: on the paper preset a sequence
    that brakes in its last step ends that step at about 0.005 rad/s and settles below
    0.0004. The gyroscopic term over the few ``tau`` the lag takes to empty is left out:
    it turns the rate vector and barely changes its size. Against scipy's DOP853 flying
    the lag out with it (compared at the same instant, since |ω| is not conserved
    torque-free either), |ω| agrees to about 1e-6 rad/s (1.01e-6 measured) on the paper
    preset's hand-designed and braking sequences, and to 2e-5 to 2.1e-4 of the rate on
    a smaller body with products of inertia and a 0.2 s lag spinning at 0.11 to 0.39
    rad/s (``tests/physics/test_simulate.py`` holds it to 5e-4).

    :param omega: (..., K, n, 3) body rates when the last command ends, rad/s.
    :param torque: (..., K, n, 3) applied thruster torque then (the lag's state), N m.
    :param inertia_inv: (K, 3, 3) the inverse inertia tensors when the caller holds them
        (a simulator does: :meth:`Simulator.settled`); inverted here otherwise.
    :returns: (..., K, n, 3) settled body rates, rad/s.
    """
    tau = scenario.uncertainty.lowpass_time_constant_s
    if tau == 0.0:
        return np.asarray(omega, dtype=float)
    inverse = np.linalg.inv(scenario.inertia_array) if inertia_inv is None else inertia_inv
    return omega + tau * np.einsum("kij,...knj->...kni", inverse, torque)


def simulate(
    scenario: Scenario,
    sequence: np.ndarray | list[list[int]],
    n_realisations: int,
    rng: np.random.Generator,
    process_noise_scale: float = 1.0,
    measurement_noise_scale: float = 1.0,
) -> SimulationResult:
    """Simulate every candidate's response to ``sequence``, ``n_realisations`` times each.

    :param scenario: spacecraft, thrusters, timing and uncertainty.
    :param sequence: (L, N) level indices, one row per actuation step.
    :param n_realisations: noisy realisations per candidate.
    :param rng: source of all randomness; the same state gives the same result.
    :param process_noise_scale: multiple of the disturbance torque sigma.
    :param measurement_noise_scale: multiple of the gyro noise (and random bias) sigma.
    """
    sequence = scenario.check_sequence(sequence)
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy Generator (np.random.default_rng(seed)), got {rng!r}"
        )
    simulator = Simulator(
        scenario,
        n_realisations,
        process_noise_scale=process_noise_scale,
        measurement_noise_scale=measurement_noise_scale,
    )
    return simulator.run(sequence, simulator.draw_noise(rng, len(sequence)))


def disturbance_walk(scenario: Scenario, sequence_length: int) -> np.ndarray:
    """σ_d² O Oᵀ, (T, T) in N² m² s²: how the disturbance torque's random walk makes the
    rates at the sequence's T samples covary, per unit inverse inertia.

    The simulator draws a torque per axis that is constant over each disturbance
    interval (:meth:`Simulator.draw_step`), so, to first order (the gyroscopic coupling
    of the noise neglected), the rate at sample t gains ``J d_m O[t, m]``, with O[t, m]
    the part of interval m that lies before t.
    """
    unc = scenario.uncertainty
    times = scenario.sample_times(sequence_length)
    interval = unc.disturbance_interval_s
    n_intervals = round(sequence_length * scenario.timing.step_duration_s / interval)
    starts = np.arange(n_intervals) * interval
    overlap = np.clip(times[:, None] - starts, 0.0, interval)  # (T, intervals)
    return np.asarray(unc.disturbance_torque_sigma_nm**2 * (overlap @ overlap.T))


def disturbance_rate_covariance(scenario: Scenario, sequence_length: int) -> np.ndarray:
    """The covariance the disturbance torque at 1x gives the flattened rate series
    (time-major, 3 axes), pooled over the candidates: ``(σ_d² O Oᵀ) ⊗ mean_k J_k J_kᵀ``,
    (3 T, 3 T) in (rad/s)², to first order (:func:`disturbance_walk`).

    What a classifier's process-noise covariance estimates from simulated residuals;
    written out, it needs none: in 3 T dimensions (480 at L = 8 on the paper preset)
    100 residuals span a fifth of this full-rank matrix.
    """
    inverse = np.linalg.inv(scenario.inertia_array)
    spread = np.einsum("kab,kcb->kac", inverse, inverse).mean(axis=0)
    return np.asarray(np.kron(disturbance_walk(scenario, sequence_length), spread))
