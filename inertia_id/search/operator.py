"""Score whole populations of sequences on what an operator states.

:class:`OperatorScorer` scores P sequences at once and returns each sequence's
:class:`~inertia_id.search.objectives.SequenceScores`: the predicted accuracy at each
design condition ``(p, q)`` (disturbance torque times p, gyro noise and bias times q)
from the scenario's noise model (:class:`~inertia_id.search.noise_model.LinearNoiseModel`,
nothing random), and residual and peak rate, impulse, on-time, propellant, duration and
attitude change from one noise draw at the scenario's own noise, every sequence on the
same draws (common random numbers). :meth:`OperatorScorer.measured_accuracy` tests the
Bayes classifier of the noise model on fresh simulated series instead of predicting it:
what a front's members are re-scored with.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import is_integer
from ..errors import InputError
from ..physics.attitude import propagate_attitude, rotation_angle_deg
from ..physics.scenario import Scenario
from ..physics.simulate import (
    SimulationResult,
    Simulator,
    at_gyro_samples,
    nominal_simulator,
)
from .noise_model import LinearNoiseModel
from .objectives import (
    DEFAULT_DESIGN_NOISE,
    SequenceScores,
    check_constraints,
    check_design_noise,
    check_objectives,
    flight_peaks,
    per_flight_bound,
)
from .plan import rate_dust_scale, without_dust, written_s

__all__ = ["OperatorScorer", "OperatorSettings", "nominal_rates", "nominal_run"]

#: Sequences simulated in one batch: bounds the memory of a population's responses
#: (P x K x n x T x 3 doubles; 64 x 5 x 20 x 160 x 3 is 49 MB).
_CHUNK = 64
#: Bytes the gyro readings of one batch of measured sequences may take (P x K x n x T x 3
#: doubles, twice while the steps are joined): 8 sequences of 5 x 200 series at L = 8.
_TEST_BYTES = 64 * 2**20
#: Test series per candidate and condition a front's accuracy is measured on at most.
MAX_TEST_SERIES = 5000


@dataclass(frozen=True)
class OperatorSettings:
    """What a Pareto search optimises and respects.

    :param objectives: the objectives traded off (:data:`~inertia_id.search.objectives.
        OPERATOR_OBJECTIVES`), at least two.
    :param design_noise: (process multiple, measurement multiple) conditions at which the
        accuracy is predicted; the accuracy objective is their mean.
    :param constraints: bounds by name (:data:`~inertia_id.search.objectives.CONSTRAINTS`),
        e.g. ``{"max_final_rate_deg_s": 0.2, "max_impulse_nms": 20}``.
    :param n_realisations: realisations per candidate of the rates an operator sees
        (residual and peak rate); the accuracy needs none.
    """

    objectives: tuple[str, ...] = ("accuracy", "final_rate", "impulse")
    design_noise: tuple[tuple[float, float], ...] = DEFAULT_DESIGN_NOISE
    constraints: Mapping[str, float] = field(default_factory=dict)
    n_realisations: int = 20

    def check(
        self, scenario: Scenario | None = None, sequence_length: int | None = None
    ) -> OperatorSettings:
        """The settings with every value checked (and normalised to tuples and floats);
        with the scenario, what needs it (a design condition with some noise, propellant);
        with the sequence length too, a duration bound every sequence of that length
        breaks."""
        n = self.n_realisations
        if not is_integer(n, minimum=2, maximum=1000):
            raise InputError(f"n_realisations must be an integer in 2..1000, got {n!r}")
        objectives = check_objectives(self.objectives)
        if "propellant" in objectives and scenario is not None:
            if scenario.propellant_kg([[0] * scenario.n_thrusters]) is None:
                raise InputError(
                    "the propellant objective needs the scenario's thrusters to state "
                    "thrust_n (or lever_arm_m) and specific_impulse_s"
                )
        design_noise = check_design_noise(self.design_noise)
        constraints = check_constraints(dict(self.constraints), scenario)
        unc = None if scenario is None else scenario.uncertainty
        for p, q in design_noise:
            # The disturbance's random walk or the gyro's white noise makes the noise
            # model's covariance full rank; with neither, only the duty jitter's few
            # directions are left, every firing sequence is predicted at accuracy 1, and
            # the search cannot rank them (one such was measured at 0.63).
            process = p if unc is None else p * unc.disturbance_torque_sigma_nm
            gyro = q if unc is None else q * unc.gyro_noise_sigma_rad_s
            if process == 0 and gyro == 0:
                raise InputError(
                    f"design_noise condition [{p:g}, {q:g}] leaves neither disturbance nor "
                    "gyro noise"
                    + (
                        ""
                        if unc is None
                        else f" (the scenario's sigmas {unc.disturbance_torque_sigma_nm:g} N m "
                        f"and {unc.gyro_noise_sigma_rad_s:g} rad/s times the multiples)"
                    )
                    + ": the predicted accuracy then degenerates to 1 for every sequence "
                    "that fires; give a multiple above 0"
                )
        bound = constraints.get("max_duration_s")
        if bound is not None and scenario is not None and sequence_length is not None:
            duration = scenario.duration_s([[0] * scenario.n_thrusters] * int(sequence_length))
            if bound < duration * (1 - 1e-12):
                raise InputError(
                    f"constraint max_duration_s = {bound:g} s is below the duration of every "
                    f"sequence of {sequence_length} steps ({sequence_length} x "
                    f"{scenario.timing.step_duration_s:g} s = {duration:g} s): shorten the "
                    "sequence or raise the bound"
                )
        if scenario is not None:
            _check_a_firing_fits(scenario, constraints)
        return OperatorSettings(
            objectives=objectives,
            design_noise=design_noise,
            constraints=constraints,
            n_realisations=int(n),
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "objectives": list(self.objectives),
            "design_noise": [list(pair) for pair in self.design_noise],
            "constraints": dict(self.constraints),
            "n_realisations": self.n_realisations,
        }


class OperatorScorer:
    """Scores sequences of one length on one noise draw, a population at a time.

    :param scenario: the spacecraft and its 1x noise.
    :param sequence_length: L, steps of every sequence scored.
    :param settings: objectives, design noise, constraints, realisations.
    :param seed: seed of the noise draw: the same seed, the same scores.
    """

    def __init__(
        self,
        scenario: Scenario,
        sequence_length: int,
        settings: OperatorSettings | None = None,
        *,
        seed: int,
    ) -> None:
        if not is_integer(sequence_length, minimum=1):
            raise InputError(f"sequence_length must be a positive integer, got {sequence_length!r}")
        self.settings = (settings or OperatorSettings()).check(scenario, int(sequence_length))
        self.scenario = scenario
        self.sequence_length = int(sequence_length)
        self.seed = int(seed)
        self.simulator = Simulator(scenario, self.settings.n_realisations)
        self.noise = self.simulator.draw_noise(
            np.random.default_rng(self.seed), self.sequence_length
        )
        # The noise-free prediction a command plan shows: every rate bound holds on it too.
        # Recorded at every integration step, so that the attitude propagated from it does
        # not depend on the gyro's rate; the rate bounds read its gyro samples.
        self.nominal, self.nominal_noise = nominal_simulator(
            scenario, self.sequence_length, every_substep=True
        )
        self.model = LinearNoiseModel(scenario, self.sequence_length)
        self.evaluations = 0

    def _checked(self, sequences: Any) -> np.ndarray:
        """(P, L, N) level indices, checked (one (L, N) sequence becomes P = 1)."""
        arr = np.asarray(sequences)
        if arr.ndim == 2:
            arr = arr[None]
        if arr.ndim != 3 or arr.shape[1] != self.sequence_length:
            raise InputError(
                f"sequences must be shaped (P, {self.sequence_length}, N), got {arr.shape}"
            )
        return np.stack([self.scenario.check_sequence(s) for s in arr])

    def score(self, sequences: Any) -> list[SequenceScores]:
        """Scores of each sequence, (P, L, N) level indices (or one (L, N) sequence)."""
        checked = self._checked(sequences)
        out: list[SequenceScores] = []
        for start in range(0, len(checked), _CHUNK):
            out.extend(self._score_chunk(checked[start : start + _CHUNK]))
        self.evaluations += len(checked)
        return out

    def measured_accuracy(
        self,
        sequences: Any,
        test_series: int,
        *,
        seed: int,
        should_stop: Callable[[], bool] | None = None,
        progress: Callable[[float], None] | None = None,
    ) -> tuple[np.ndarray, int] | None:
        """Each sequence's accuracy at each design condition, measured: the noise model's
        Gaussians (:meth:`~inertia_id.search.noise_model.LinearNoiseModel.
        log_likelihoods`, a classifier that needs no training draw) classify
        ``test_series`` fresh series per candidate simulated at that condition. Every
        sequence meets the same draws (one per condition, from ``seed``), so differences
        between sequences are not sampling noise between draws.

        :param should_stop: polled between batches; True abandons the measurement.
        :param progress: called after every batch with the fraction of the batches done.
        :returns: accuracies (P, conditions) and the series tested per condition; None
            when stopped.
        """
        if not is_integer(test_series, minimum=1, maximum=MAX_TEST_SERIES):
            raise InputError(
                f"test_series must be an integer in 1..{MAX_TEST_SERIES}, got {test_series!r}"
            )
        if not is_integer(seed, minimum=0):
            raise InputError(f"seed must be a non-negative integer, got {seed!r}")
        checked = self._checked(sequences)
        conditions = self.settings.design_noise
        streams = np.random.SeedSequence([int(seed), 2]).spawn(len(conditions))
        k = self.scenario.n_candidates
        means = self.model.mean_responses(checked)  # (P, K, T, 3), every condition's
        # A batch of readings (and its per-step parts) within a memory budget: whole
        # sequences while one fits; past that, one sequence at a time on blocks of the
        # series, each block drawn from its own child of the condition's stream (so the
        # figures where one sequence fits are those of a single draw, as before).
        one = k * int(test_series) * self.model.n_samples * 3 * 8 * 2
        batch = max(1, _TEST_BYTES // one)
        blocks = min(int(test_series), -(-one // _TEST_BYTES))
        sizes = [len(part) for part in np.array_split(np.arange(int(test_series)), blocks)]
        right = np.zeros((len(checked), len(conditions)))
        batches, done = len(conditions) * blocks * -(-len(checked) // batch), 0
        for c, ((process, measurement), stream) in enumerate(zip(conditions, streams, strict=True)):
            parts = [stream] if blocks == 1 else stream.spawn(blocks)
            for size, part in zip(sizes, parts, strict=True):
                simulator = Simulator(
                    self.scenario,
                    size,
                    process_noise_scale=process,
                    measurement_noise_scale=measurement,
                )
                noise = simulator.draw_noise(np.random.default_rng(part), self.sequence_length)
                truth = np.repeat(np.arange(k), size)
                for start in range(0, len(checked), batch):
                    if should_stop is not None and should_stop():
                        return None
                    chunk = checked[start : start + batch]
                    readings = simulator.population_rates(chunk, noise, measured=True)
                    for i, sequence in enumerate(chunk):
                        likelihood = self.model.log_likelihoods(
                            sequence,
                            readings[i].reshape(len(truth), -1, 3),
                            process,
                            measurement,
                            means=means[start + i],
                        )
                        right[start + i, c] += np.count_nonzero(likelihood.argmax(axis=1) == truth)
                    done += 1
                    if progress is not None:
                        progress(done / batches)
        out = right / (k * int(test_series))
        return out, k * int(test_series)

    def per_flight_figures(self, sequences: Any, flights: int, *, seed: int) -> np.ndarray:
        """Each sequence flown ``flights`` times a candidate at the scenario's noise, on a
        draw from ``seed``: the candidate with the largest :func:`~inertia_id.search.
        objectives.per_flight_bound` of its residual rates, and the one with the largest
        of its flights' peak rates (:func:`flight_peaks`), (P, 2) rad/s. With 59 flights
        or more each holds whatever the distribution."""
        checked = self._checked(sequences)
        simulator = Simulator(self.scenario, int(flights))
        noise = simulator.draw_noise(np.random.default_rng(seed), self.sequence_length)
        out = []
        # Batches bound memory: P x K x flights x T x 3 doubles of rates per batch.
        batch = max(1, _CHUNK * self.settings.n_realisations // int(flights))
        for start in range(0, len(checked), batch):
            rates, end = simulator.population_run(checked[start : start + batch], noise)
            settled = simulator.settled(end)  # (P, K, flights)
            peaks = flight_peaks(rates, settled)
            out.append(
                np.stack(
                    [
                        per_flight_bound(settled, axis=2).max(axis=1),
                        per_flight_bound(peaks, axis=2).max(axis=1),
                    ],
                    axis=1,
                )
            )
        return np.concatenate(out)

    def _score_chunk(self, sequences: np.ndarray) -> list[SequenceScores]:
        scenario, settings = self.scenario, self.settings
        errors = self.model.predicted_error(sequences, settings.design_noise)
        # The union bound's 1 - error is a lower bound on the Bayes accuracy, and so is
        # chance (1/K, equal priors): the prediction is the larger.
        accuracy = np.clip(1.0 - errors, 1.0 / scenario.n_candidates, 1.0)  # (P, conditions)
        # The bound itself ranks them where chance would hide their differences.
        bound = (1.0 - errors).mean(axis=1)  # (P,)
        own, end = self.simulator.population_run(sequences, self.noise)
        speed = np.linalg.norm(own, axis=-1)  # (P, K, n, T)
        planned_fine, planned_end = self.nominal.population_run(sequences, self.nominal_noise)
        planned_fine = planned_fine[:, :, 0]  # (P, K, T_fine, 3): every integration step
        planned = at_gyro_samples(scenario, planned_fine)  # (P, K, T, 3): the plan's rates
        # Each rate is the larger of its mean over the realisations and the command plan's
        # noise-free prediction, so a bound holds on both: the duty jitter clipped at full
        # duty delivers 1 - σ/√(2π) of a full firing on average, and the mean alone ran
        # about 0.8 % below the plan the flight team uploads.
        # The residual rate is the one the spacecraft keeps: once the lag has delivered the
        # torque still in it when the last command ends (else braking in the last step
        # would look 0.005 rad/s worse than braking a step earlier and coasting).
        settled = self.simulator.settled(end)  # (P, K, n): each realisation's residual
        # The plan's prediction starts from rest with every noise off: what the commands
        # themselves leave, reported beside the total (which carries |ω(0)|, a floor no
        # open-loop sequence removes).
        commanded = self.nominal.settled(planned_end)[:, :, 0]  # (P, K)
        final_by_candidate = np.maximum(settled.mean(axis=2), commanded)  # (P, K)
        # Single flights spread around that mean: a rate at least 95 % of them stay
        # under, with 95 % confidence.
        p95_by_candidate = np.maximum(per_flight_bound(settled, axis=2), final_by_candidate)
        # The same for each flight's own peak (its fastest instant, which the mean speed
        # at each instant below understates).
        peak_p95 = per_flight_bound(flight_peaks(own, settled), axis=2).max(axis=1)  # (P,)
        # The largest rate of the manoeuvre: during the commands, or after the last one,
        # while the lag delivers the torque still in it. Without ω × Iω the rate then
        # moves on a straight line from where the commands leave it to the settled rate,
        # and |ω| is convex along it, so its largest is at one end (a sequence firing
        # to its last step is fastest once settled, not when the command ends).
        peak = np.maximum.reduce(
            [
                speed.mean(axis=2).max(axis=(1, 2)),
                np.linalg.norm(planned, axis=-1).max(axis=(1, 2)),
                final_by_candidate.max(axis=1),
            ]
        )
        # The attitude change is the plan's (quaternion propagation of the noise-free rates,
        # on the integration grid).
        attitude = propagate_attitude(planned_fine, scenario.timing.integration_step_s)
        turned = rotation_angle_deg(attitude[..., -1, :]).max(axis=1)  # (P,)
        # The plan's rounding dust (search.plan.DUST_FRACTION of the largest rate the
        # firings could give a candidate, rate_dust_scale) is 0 here too: fire-then-brake
        # on canted thrusters read 6.9e-19 rad/s commanded in the front, 0 in its plan.
        impulse = np.array([scenario.impulse_nms(sequence) for sequence in sequences])
        commanded = without_dust(commanded, rate_dust_scale(scenario, impulse))  # (P, K)
        out = []
        for i, sequence in enumerate(sequences):
            out.append(
                SequenceScores(
                    accuracy=float(accuracy[i].mean()),
                    accuracy_by_noise=[float(v) for v in accuracy[i]],
                    final_rate_rad_s=float(final_by_candidate[i].mean()),
                    final_rate_max_rad_s=float(final_by_candidate[i].max()),
                    final_rate_p95_rad_s=float(p95_by_candidate[i].max()),
                    commanded_residual_rate_rad_s=float(commanded[i].mean()),
                    commanded_residual_rate_max_rad_s=float(commanded[i].max()),
                    peak_rate_rad_s=float(peak[i]),
                    peak_rate_p95_rad_s=max(float(peak_p95[i]), float(peak[i])),
                    impulse_nms=float(impulse[i]),
                    # To 15 significant digits, as the plan writes them (0.4 + 0.4 +
                    # 0.08 s read 0.8800000000000001 s here, 0.88 in the plan).
                    on_time_s=written_s(scenario.on_time_s(sequence).sum()),
                    propellant_kg=scenario.propellant_kg(sequence),
                    duration_s=written_s(scenario.duration_s(sequence)),
                    attitude_change_deg=float(turned[i]),
                    accuracy_bound=float(bound[i]),
                )
            )
        return out


def nominal_run(
    scenario: Scenario, sequence: Any, *, every_substep: bool = False
) -> SimulationResult:
    """Each candidate's response with every source of noise off (the actuation lag kept):
    what a flight team predicts, one realisation a candidate; with ``every_substep``
    recorded at every integration step (:func:`~inertia_id.physics.simulate.at_gyro_samples`
    picks the gyro's samples out of it)."""
    rows = scenario.check_sequence(sequence)
    simulator, noise = nominal_simulator(scenario, len(rows), every_substep=every_substep)
    return simulator.run(rows, noise)


def nominal_rates(scenario: Scenario, sequence: Any) -> np.ndarray:
    """:func:`nominal_run`'s body rates, (K, T, 3) rad/s at the gyro's sample times."""
    return np.asarray(nominal_run(scenario, sequence).omega_true[:, 0])


#: The constraints on what firing costs, each with the unit its bound is in and the
#: scenario's figure for a sequence.
_FIRING_COSTS = {
    "max_impulse_nms": ("N m s", "impulse_nms"),
    "max_on_time_s": ("s", "on_time_total_s"),
    "max_propellant_kg": ("kg", "propellant_kg"),
}


def _check_a_firing_fits(scenario: Scenario, constraints: Mapping[str, float]) -> None:
    """Refuse a bound on what firing costs that no firing meets: below the cheapest
    firing (one thruster at the lowest duty level for one step) only the sequence that
    fires nothing is feasible, and it tells no candidate apart (``max_impulse_nms: 0``
    ran a search that "succeeded" with the all-off sequence, predicted accuracy 0.25)."""
    lowest = scenario.level_values[1]
    for name, (unit, figure) in _FIRING_COSTS.items():
        bound = constraints.get(name)
        if bound is None:
            continue
        costs = []
        for j in range(scenario.n_thrusters):
            step = [[int(k == j) for k in range(scenario.n_thrusters)]]
            if figure == "on_time_total_s":
                costs.append(float(scenario.on_time_s(step).sum()))
            else:
                costs.append(getattr(scenario, figure)(step))
        stated = [cost for cost in costs if cost is not None]
        if not stated:
            continue  # propellant not stated: check_constraints refuses the bound
        cheapest = min(stated)
        if bound < cheapest * (1 - 1e-12):
            raise InputError(
                f"constraint {name} = {bound:g} {unit} is below the cheapest firing, "
                f"{cheapest:.4g} {unit} (one thruster at duty {lowest:g} for one step): only "
                "the sequence that fires nothing meets it, and it tells no candidate apart; "
                "raise the bound"
            )
