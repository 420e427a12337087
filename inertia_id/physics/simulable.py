"""Whether a scenario can be simulated at the noise a job asks for, told before the job.

Every noise figure of a scenario has a bound of its own, yet a scenario within all of
them may still be impossible to simulate: on the paper preset a disturbance torque sigma
of 1e4 N m (a hundredth of its bound) spins the bodies past what the RK4 step follows
within a few steps, and the rates overflow to inf. A job on it was accepted, queued,
and failed at run time with :class:`~inertia_id.physics.simulate.SimulationOverflow`.

:func:`check_simulable` tells it before: it flies seeded realisations of one
representative sequence (the job's own, or the hand-designed baseline) with the
simulator every job uses, at the noise the job asks for, and refuses rates that turn
inf or nan, naming the noise figure that drives them, its value, the noise multiple and
the step by which they overflow. Rates that are large but finite are not its business
(the gyro-range rule is :func:`~inertia_id.physics.simulate.check_nominal_gyro_range`).

Overflow is a tail event: a job flies hundreds of realisations a candidate (training's
calibration at least about 200, a ceiling thousands), and a noise that 8 realisations fly
through may overflow one of those. So the check flies as many realisations a candidate as
a work budget allows (:func:`check_realisations`: :data:`CHECK_BUDGET` candidate x
realisation x RK4 steps, between :data:`CHECK_REALISATIONS_MIN` and
:data:`CHECK_REALISATIONS_MAX`): 256 on the paper preset's 4-step check, fewer on long
sequences, 8 on huge ones. Still a check, not a proof: near the threshold a job that
passed it may overflow, and is then refused at run time as before.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import InputError
from .scenario import Scenario, _shown
from .simulate import SimulationOverflow, Simulator, check_nominal_gyro_range

__all__ = [
    "CHECK_BUDGET",
    "CHECK_REALISATIONS_MAX",
    "CHECK_REALISATIONS_MIN",
    "CHECK_SEED",
    "DRIVING_FIELDS",
    "SCENARIO_CHECK_RK4_STEPS",
    "SCENARIO_CHECK_STEPS",
    "NoiseOverflow",
    "check_conditions",
    "check_realisations",
    "check_scenario_simulable",
    "check_simulable",
    "overflow_step",
    "representative_sequence",
]

#: The work a check's flight may take: candidates x realisations x RK4 steps. 256
#: realisations a candidate on the paper preset's 4-step check (5 candidates x 80 RK4
#: steps) are 102,400 of it (about 17 ms on a 2-core machine), so every sequence up to 8
#: steps of it flies the most realisations; 64 steps fly 40, 256 steps the least.
CHECK_BUDGET = 262_144
#: The fewest realisations a candidate a check flies, however long the sequence (a huge
#: scenario's check then costs more than the budget, as the check of 8 always did).
CHECK_REALISATIONS_MIN = 8
#: The most realisations a candidate a check flies: about what a job flies at the least
#: (training's calibration: about 200), where an overflow is a tail event.
CHECK_REALISATIONS_MAX = 256
#: The check's seed: the same scenario and noise are refused, or not, every time.
CHECK_SEED = 0
#: Steps of the hand-designed sequence a scenario is checked on when it is stored: the
#: length a search takes unless told (and the README's example). A scenario whose rates
#: overflow within it at its own noise serves no job worth running; one that overflows
#: only on longer sequences is stored, and a job of those is refused when submitted.
SCENARIO_CHECK_STEPS = 4
#: The most RK4 steps a flight of that check takes (the simulated response's cap): a
#: scenario of longer steps is checked on fewer of them, or, past one, when a job asks.
SCENARIO_CHECK_RK4_STEPS = 1_280
#: The noise figures that drive the bodies' rates (the gyro's noise and bias are added to
#: the readings and never reach the dynamics), with their units.
DRIVING_FIELDS: dict[str, str] = {
    "disturbance_torque_sigma_nm": "N m",
    "thrust_scale_sigma": "",
    "duty_jitter_sigma": "full duties",
    "initial_rate_sigma_rad_s": "rad/s",
}


class NoiseOverflow(SimulationOverflow):
    """The rates overflow at the noise asked for; the message names the figure.

    :param fields: the noise figures named (each overflows the rates alone; all of them
        when none does alone).
    :param multiple: the noise multiple of the first of them (1: the scenario's own).
    :param step: the step (from 1) by which some realisation's rates were inf or nan.
    :param n_steps: the steps of the sequence checked.
    """

    def __init__(
        self, message: str, *, fields: tuple[str, ...], multiple: float, step: int, n_steps: int
    ) -> None:
        super().__init__(message)
        self.fields = fields
        self.multiple = multiple
        self.step = step
        self.n_steps = n_steps

    def said_of(self, context: str) -> NoiseOverflow:
        """The same refusal with ``context`` (what was checked: a sweep's largest
        multiple, a search's design noise) before its message; raise it ``from None``."""
        return NoiseOverflow(
            f"{context}: {self}",
            fields=self.fields,
            multiple=self.multiple,
            step=self.step,
            n_steps=self.n_steps,
        )


def representative_sequence(scenario: Scenario, n_steps: int) -> np.ndarray:
    """The hand-designed sequence of ``n_steps`` steps (the baseline every search is
    scored against), or full duty on every thruster where the thrusters give no torque
    along the principal diagonal: (n_steps, N) level indices."""
    from .sequences import hand_designed

    try:
        return hand_designed(scenario, n_steps)
    except InputError:
        return np.full((int(n_steps), scenario.n_thrusters), scenario.n_levels - 1)


def check_realisations(scenario: Scenario, n_steps: int) -> int:
    """The realisations a candidate a check flies on ``n_steps`` steps of ``scenario``:
    :data:`CHECK_BUDGET` // (candidates x RK4 steps), within
    [:data:`CHECK_REALISATIONS_MIN`, :data:`CHECK_REALISATIONS_MAX`]."""
    work = max(1, scenario.n_candidates * int(n_steps) * scenario.timing.substeps_per_step)
    return int(min(CHECK_REALISATIONS_MAX, max(CHECK_REALISATIONS_MIN, CHECK_BUDGET // work)))


def _at(scenario: Scenario, levels: Mapping[str, float]) -> Scenario:
    """``scenario`` with some uncertainty figures set, not validated: a noise multiple
    takes a figure past what a person may state (as a noise sweep's copy does)."""
    noise = scenario.uncertainty.model_copy(update={k: float(v) for k, v in levels.items()})
    return scenario.model_copy(update={"uncertainty": noise})


def overflow_step(
    scenario: Scenario,
    sequence: np.ndarray,
    *,
    n_realisations: int | None = None,
    seed: int = CHECK_SEED,
) -> int | None:
    """The step (from 1) by which some realisation's rates turn inf or nan when
    ``sequence`` is flown on ``scenario`` at its noise; None when they stay finite.
    ``n_realisations`` a candidate: :func:`check_realisations` unless told.

    The job's simulator (:class:`~inertia_id.physics.simulate.Simulator`), advanced a
    step at a time so that it stops at the first step that overflows.
    """
    if n_realisations is None:
        n_realisations = check_realisations(scenario, len(sequence))
    simulator = Simulator(scenario, n_realisations)
    rng = np.random.default_rng(seed)
    state = simulator.start(simulator.draw_initial(rng))
    with np.errstate(over="ignore", invalid="ignore"):
        for step, levels in enumerate(sequence, start=1):
            state, response = simulator.advance(state, levels, simulator.draw_step(rng))
            if not (np.isfinite(response.omega_measured).all() and np.isfinite(state.omega).all()):
                return step
    return None


def check_simulable(
    scenario: Scenario,
    sequence: Any,
    *,
    multiples: Mapping[str, float] | None = None,
    levels: Mapping[str, float] | None = None,
    sequence_name: str = "the sequence",
) -> None:
    """Refuse ``sequence`` on ``scenario`` when its rates overflow at the noise asked for.

    :param sequence: (L, N) level indices: the job's own, or a representative one
        (:func:`representative_sequence`).
    :param multiples: noise multiples by uncertainty field (``disturbance_torque_sigma_nm``:
        6 for a design noise of 6x process); every other figure at 1x.
    :param levels: the 1x level of a field whose multiple is asked for where the
        scenario's own is not it (a noise sweep scales a reference level where the
        scenario states 0).
    :param sequence_name: how the refusal names the sequence.
    :raises NoiseOverflow: naming the noise figure (or figures) that overflow the rates
        alone, its 1x value, the multiple, the scaled value, and the step by which the
        rates were inf or nan.
    """
    rows = scenario.check_sequence(sequence)
    multiples = dict(multiples or {})
    base = {field: float(getattr(scenario.uncertainty, field)) for field in multiples}
    base.update({k: float(v) for k, v in (levels or {}).items() if k in multiples})
    at = _at(scenario, {field: multiples[field] * base[field] for field in multiples})
    flown = check_realisations(scenario, len(rows))
    step = overflow_step(at, rows, n_realisations=flown)
    if step is None:
        return
    driving = {
        field: float(getattr(at.uncertainty, field))
        for field in DRIVING_FIELDS
        if float(getattr(at.uncertainty, field)) > 0.0
    }
    quiet = {field: 0.0 for field in driving}
    if overflow_step(_at(at, quiet), rows, n_realisations=flown) is not None:
        # No noise is to blame: the sequence overflows the bodies with every source of
        # it off (torques of 1e300 N m, an inertia of 1e-30 kg m^2).
        raise SimulationOverflow(
            f"the simulated rates of {sequence_name} {_shown(rows.tolist(), 120)} overflow to "
            f"inf or nan within {step} of its {len(rows)} steps with every source of noise "
            "off: the scenario's torques or inertia are likely wrong in units"
        )
    alone = tuple(
        field
        for field in driving
        if overflow_step(_at(at, {**quiet, field: driving[field]}), rows, n_realisations=flown)
        is not None
    )
    fields = alone or tuple(driving)

    def named(field: str) -> str:
        unit = f" {DRIVING_FIELDS[field]}" if DRIVING_FIELDS[field] else ""
        multiple = float(multiples.get(field, 1.0))
        own = base.get(field, float(getattr(scenario.uncertainty, field)))
        if multiple == 1.0:
            return f"{field} = {own:g}{unit} at noise multiple 1 (the scenario's own)"
        return f"{field} = {own:g}{unit} at noise multiple {multiple:g} ({driving[field]:g}{unit})"

    drives = (
        f"{named(fields[0])} drives"
        if len(fields) == 1
        else ("together, " if not alone else "each alone, ")
        + ", ".join(named(f) for f in fields)
        + " drive"
    )
    moment = min(float(np.linalg.eigvalsh(c).min()) for c in scenario.inertia_array)
    raise NoiseOverflow(
        f"{drives} the simulated rates to inf or nan within {step} of the {len(rows)} steps "
        f"of {sequence_name} {_shown(rows.tolist(), 120)} (a seeded check of "
        f"{flown} realisations a candidate; smallest principal moment "
        f"{moment:.3g} kg m^2, integration step {scenario.timing.integration_step_s:g} s): "
        "the bodies spin faster than the integrator follows, so nothing can be simulated "
        "at that noise; lower "
        + (
            "it"
            if all(float(multiples.get(f, 1.0)) == 1.0 for f in fields)
            else "it or the multiple"
        ),
        fields=fields,
        multiple=float(multiples.get(fields[0], 1.0)),
        step=step,
        n_steps=len(rows),
    )


def check_scenario_simulable(scenario: Scenario, n_steps: int = SCENARIO_CHECK_STEPS) -> None:
    """Refuse a scenario that cannot be simulated at its own noise: the representative
    sequence (:func:`representative_sequence`) of ``n_steps`` steps overflows at 1x
    because of its noise. What storing a scenario runs (:data:`SCENARIO_CHECK_STEPS`).

    Not refused here: a scenario whose sequence passes any gyro's range or overflows
    with every noise off (only the ratio of torque to inertia matters, and a gentler
    sequence may fly; the plan's and the jobs' rules on each sequence decide, README
    "Scenario"), and the steps past
    :data:`SCENARIO_CHECK_RK4_STEPS` (hour-long steps: a job of them is checked when it
    is submitted, after its size).

    :raises NoiseOverflow: as :func:`check_simulable` words it.
    """
    n_steps = min(int(n_steps), SCENARIO_CHECK_RK4_STEPS // scenario.timing.substeps_per_step)
    if n_steps < 1:
        return
    sequence = representative_sequence(scenario, n_steps)
    try:
        check_nominal_gyro_range(scenario, sequence)
    except SimulationOverflow:
        # Spun past any gyro's range (or to inf) with the noise off: the inertia or the
        # torques, not the noise, and the rules on each sequence refuse it.
        return
    try:
        check_simulable(
            scenario,
            sequence,
            sequence_name=f"the hand-designed sequence of scenario {scenario.name!r}",
        )
    except NoiseOverflow:
        raise
    except SimulationOverflow:
        return


def check_conditions(
    scenario: Scenario,
    sequence: Any,
    conditions: Sequence[Mapping[str, float]],
    *,
    levels: Mapping[str, float] | None = None,
    sequence_name: str = "the sequence",
) -> None:
    """:func:`check_simulable` at 1x, then at each of ``conditions`` (noise multiples by
    field) that is not 1x, refusing at the first that overflows."""
    check_simulable(scenario, sequence, sequence_name=sequence_name)
    for multiples in conditions:
        if any(float(m) != 1.0 for m in multiples.values()):
            check_simulable(
                scenario,
                sequence,
                multiples=multiples,
                levels=levels,
                sequence_name=sequence_name,
            )
