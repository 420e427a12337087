"""A command plan: what a flight team uploads for a sequence, and what it predicts.

Per step and thruster the commanded duty and its PWM on-time (duty x step duration, s);
per step the commanded body torque (N m, per axis); each candidate's predicted rates at
the end of every step (nominal: every source of noise off, the actuation lag kept), in
rad/s and deg/s, its residual rate (once the actuation lag has delivered the torque
still in it when the last command ends: :func:`~inertia_id.physics.simulate.settled_rates`;
the rate at that moment beside it) and its attitude change (quaternion propagation of
the predicted rates, :mod:`inertia_id.physics.attitude`); and the propellant figures
(on-time per thruster, the commanded impulse summed over thrusters, the propellant mass
when the scenario gives thrust and specific impulse). As JSON (:meth:`CommandPlan.to_dict`)
or CSV (:meth:`CommandPlan.to_csv`: one row per step, the summary as ``#`` lines first).

Rounding dust is an exact 0 in both: a torque, rate, attitude change or quaternion
component at most :data:`DUST_FRACTION` of its scale (:func:`dust_scales`: the largest
thruster's torque; per candidate, the largest rate the sequence's firings could give it
from rest, and the rotation that rate gives over the sequence), which the plan carries
(:attr:`CommandPlan.dust`, the JSON's ``dust``).

The prediction is the nominal flight. With ``flights`` the plan also flies the sequence
that many times a candidate at the scenario's own noise (duty jitter, disturbance torque,
any initial rate) and states how the residual and peak rates spread over single flights
(:class:`FlightDispersion`): the mean, the rate 95 % of flights stay under and the
largest.
"""

from __future__ import annotations

import csv
import functools
import io
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import csv_note_text, is_integer
from ..errors import InputError
from ..physics.attitude import propagate_attitude, rotation_angle_deg
from ..physics.scenario import Scenario
from ..physics.simulable import check_simulable
from ..physics.simulate import (
    at_gyro_samples,
    check_gyro_range,
    check_nominal_gyro_range,
    settled_rates,
    simulate,
    weak_response_warning,
)
from .firings import cancelling_warning
from .objectives import (
    FLIGHT_QUANTILE,
    QUANTILE_METHOD,
    flight_peaks,
    flight_quantile,
    initial_rate_floor,
    per_flight_bound,
)

__all__ = ["CommandPlan", "FlightDispersion", "command_plan"]

#: Most flights a plan may fly per candidate (they are flown in blocks: memory stays
#: bounded; the time grows with them, about 0.5 s per million candidate-flight-RK4-steps).
MAX_FLIGHTS = 100_000

_DEG = 180.0 / np.pi

#: A plan's figure whose size is at most this share of its scale is rounding dust and is
#: written an exact 0, in the JSON and the CSV alike (and so in the dashboard's plan): where
#: thrusters' torques cancel (0.1 + 0.2 - 0.3 N m), double rounding left a torque of
#: 5.6e-17 N m, rates of some 1e-18 rad/s, a quaternion component of 5.8e-19 and rotation
#: angles of 1e-16 deg, each written as a figure. The scales (:func:`dust_scales`): a
#: torque's is the largest thruster's torque, max_j |A_j| (N m); a candidate's rates' is the
#: largest rate the sequence's firings could give it, its commanded impulse summed over
#: thrusters (opposed or not) over its smallest principal moment (rad/s: from rest, no
#: nominal rate can pass it); its rotation angle's that rate over the sequence's duration,
#: and a quaternion's vector part's half that angle (at most 1; the scalar part's is 1).
#: Relative, not absolute: a scenario of weak thrusters keeps rates no gyro reads (1e-11
#: deg/s is a figure of its own there), while double rounding stays some 1e-16 of the scale
#: (RK4 over 1,280 steps adds at most some 1e-13; a plan's most, 100,000 RK4 steps,
#: fire, coast and brake on canted thrusters: 7.2e-16 of the scale, as 300 steps: 3.0e-16).
DUST_FRACTION = 1e-10


@dataclass(frozen=True)
class DustScales:
    """What a plan's figures are dust against (see :data:`DUST_FRACTION`)."""

    torque_nm: float
    #: (K,) per candidate: the largest rate the sequence could give it from rest.
    rate_rad_s: list[float]
    #: (K,) per candidate: the largest rotation that rate gives over the sequence.
    angle_rad: list[float]


def dust_scales(scenario: Scenario, rows: np.ndarray) -> DustScales:
    """The scales a plan of ``rows`` on ``scenario`` reads its dust against
    (:data:`DUST_FRACTION`)."""
    torque = float(np.linalg.norm(scenario.torque_matrix, axis=0).max())
    rate = rate_dust_scale(scenario, scenario.impulse_nms(rows))
    angle = rate * len(rows) * scenario.timing.step_duration_s
    return DustScales(torque_nm=torque, rate_rad_s=rate.tolist(), angle_rad=angle.tolist())


def rate_dust_scale(scenario: Scenario, impulse_nms: Any) -> np.ndarray:
    """(..., K) the largest rate, rad/s, firings of ``impulse_nms`` (N m s, any shape:
    summed over thrusters and steps) could give each candidate from rest: its impulse
    over its smallest principal moment, the scale a rate's dust is read against (the
    front's commanded residual, :class:`~inertia_id.search.operator.OperatorScorer`, too)."""
    smallest = np.linalg.eigvalsh(scenario.inertia_array).min(axis=1)  # (K,) kg m^2
    return np.asarray(impulse_nms, dtype=float)[..., None] / smallest


def without_dust(values: Any, scale: Any) -> np.ndarray:
    """``values`` with every one at most :data:`DUST_FRACTION` of ``scale`` (broadcast)
    an exact 0 (-0.0 too)."""
    array = np.asarray(values, dtype=float)
    return np.where(np.abs(array) <= DUST_FRACTION * np.asarray(scale), 0.0, array)


def _rate_pair(figures: dict[str, Any], name: str, *, label: str = "", sep: str = ", ") -> str:
    """``figures``' rate ``name`` in rad/s and in deg/s, as the CSV's ``#`` lines write
    them: ``{label}_rad_s value{sep}{label}_deg_s value`` (``label``: ``name``)."""
    label = label or name
    return (
        f"{label}_rad_s {figures[name + '_rad_s']:.6g}{sep}"
        f"{label}_deg_s {figures[name + '_deg_s']:.6g}"
    )


@dataclass(frozen=True)
class FlightDispersion:
    """How single flights spread around the nominal prediction: each candidate flown
    ``flights`` times at the scenario's own noise, drawn from ``seed``.

    Per candidate (K,): the residual rate (settled, as the plan's) over the flights, its
    mean, the rate :data:`~inertia_id.search.objectives.FLIGHT_QUANTILE` of them stay
    under (median-unbiased percentile), the rate at least that share of all flights stay
    under with 95 % confidence (:func:`~inertia_id.search.objectives.per_flight_bound`, the
    figure a front's ``final_rate_p95`` gives) and the largest; each flight's peak rate
    (its fastest instant, or once settled): their percentile and the same 95 %-confidence
    bound (a front's ``peak_rate_p95``).
    """

    flights: int
    seed: int
    residual_mean_rad_s: list[float]
    residual_p95_rad_s: list[float]
    residual_p95_bound_rad_s: list[float]
    residual_max_rad_s: list[float]
    peak_p95_rad_s: list[float]
    peak_p95_bound_rad_s: list[float]

    def candidate(self, k: int) -> dict[str, float]:
        figures = {
            "residual_rate_mean_rad_s": self.residual_mean_rad_s[k],
            "residual_rate_p95_rad_s": self.residual_p95_rad_s[k],
            "residual_rate_p95_bound_rad_s": self.residual_p95_bound_rad_s[k],
            "residual_rate_max_rad_s": self.residual_max_rad_s[k],
            "peak_rate_p95_rad_s": self.peak_p95_rad_s[k],
            "peak_rate_p95_bound_rad_s": self.peak_p95_bound_rad_s[k],
        }
        return {
            **figures,
            **{key.replace("_rad_s", "_deg_s"): v * _DEG for key, v in figures.items()},
        }

    def summary(self) -> dict[str, Any]:
        return {
            "flights_per_candidate": self.flights,
            "seed": self.seed,
            "percentile": FLIGHT_QUANTILE * 100,
            "percentile_method": QUANTILE_METHOD,
            "p95_bound_note": "residual_rate_p95_bound: a rate at least 95 % of all flights "
            "stay under with 95 % confidence, never below the mean or the nominal residual "
            "(from 59 flights an order statistic, whatever the distribution; below, a "
            "normal tolerance bound of the rate's root), the figure a front's "
            "final_rate_p95 gives; residual_rate_p95: the 95th percentile of these flights; "
            "peak_rate_p95 and peak_rate_p95_bound: the same of each flight's own peak rate "
            "(the bound a front's peak_rate_p95 gives)",
            "noise": "the scenario's own noise model: duty jitter, thrust-scale error, "
            "disturbance torque and any initial rate it draws (the gyro's noise and bias "
            "do not move the body)",
            "residual_rate_p95_max_rad_s": float(max(self.residual_p95_rad_s)),
            "residual_rate_p95_max_deg_s": float(max(self.residual_p95_rad_s) * _DEG),
            "residual_rate_p95_bound_max_rad_s": float(max(self.residual_p95_bound_rad_s)),
            "residual_rate_p95_bound_max_deg_s": float(max(self.residual_p95_bound_rad_s) * _DEG),
            "residual_rate_max_rad_s": float(max(self.residual_max_rad_s)),
            "residual_rate_max_deg_s": float(max(self.residual_max_rad_s) * _DEG),
            "peak_rate_p95_max_rad_s": float(max(self.peak_p95_rad_s)),
            "peak_rate_p95_max_deg_s": float(max(self.peak_p95_rad_s) * _DEG),
            "peak_rate_p95_bound_max_rad_s": float(max(self.peak_p95_bound_rad_s)),
            "peak_rate_p95_bound_max_deg_s": float(max(self.peak_p95_bound_rad_s) * _DEG),
        }


@dataclass(frozen=True)
class CommandPlan:
    """A sequence as commands, with the predicted response (see the module docstring)."""

    scenario_name: str
    sequence: list[list[int]]
    step_duration_s: float
    duty: list[list[float]]  # (L, N)
    on_time_s: list[list[float]]  # (L, N)
    torque_nm: list[list[float]]  # (L, 3)
    candidate_names: list[str]
    rates_rad_s: list[list[list[float]]]  # (K, L, 3) at the end of each step
    residual_rate_rad_s: list[float]  # (K,) once the lag has delivered its torque
    end_rate_rad_s: list[float]  # (K,) |ω| when the last command ends
    peak_rate_rad_s: list[float]  # (K,) largest |ω| at a gyro sample or once settled
    attitude_quaternion: list[list[float]]  # (K, 4) final, (w, x, y, z)
    attitude_change_deg: list[float]  # (K,)
    on_time_per_thruster_s: list[float]  # (N,)
    impulse_nms: float
    propellant_kg: float | None
    #: Single flights' spread, when the plan was asked to fly the sequence.
    dispersion: FlightDispersion | None = None
    #: What the plan found doubtful but did not refuse (rates far below the gyro noise:
    #: :func:`~inertia_id.physics.simulate.weak_response_warning`).
    warnings: list[str] = field(default_factory=list)
    #: The scenario's initial-rate spread (σ a body axis, rad/s): a flight's residual
    #: carries |ω(0)|, which the nominal prediction (from rest) leaves out.
    initial_rate_sigma_rad_s: float = 0.0
    #: Why propellant_kg is None (the fields the scenario lacks); None when it is stated.
    propellant_unstated: str | None = None
    #: How propellant_kg is reached from the fields the scenario gives (thrust_n or the
    #: lever arms); None when it is not stated.
    propellant_basis: str | None = None
    #: The scales its figures were read against: at most :data:`DUST_FRACTION` of one is
    #: written 0 (None: a plan made without them, nothing was zeroed).
    dust: DustScales | None = None

    def _propellant_note(self) -> str:
        """How ``propellant_kg`` is reached, or why it is null (the words the CSV's
        ``# propellant_kg:`` line gives)."""
        if self.propellant_kg is not None:
            return self.propellant_basis or "stated"
        why = self.propellant_unstated
        return "not stated" + (f" ({why})" if why else "")

    def _floor(self) -> dict[str, float] | None:
        """What the initial-rate spread alone leaves (:func:`~inertia_id.search.
        objectives.initial_rate_floor`), rad/s and deg/s; None for a scenario at rest."""
        sigma = self.initial_rate_sigma_rad_s
        if not sigma > 0.0:
            return None
        floor = initial_rate_floor(sigma)
        return {
            "initial_rate_sigma_rad_s": sigma,
            "mean_rad_s": floor["mean"],
            "mean_deg_s": floor["mean"] * _DEG,
            "p95_rad_s": floor["p95"],
            "p95_deg_s": floor["p95"] * _DEG,
        }

    def to_dict(self) -> dict[str, Any]:
        rates = np.asarray(self.rates_rad_s)
        residual = np.asarray(self.residual_rate_rad_s)
        steps = []
        for i, row in enumerate(self.sequence):
            steps.append(
                {
                    "step": i + 1,  # numbered from 1, as the service's sequence tables
                    # As the on-times, to 15 significant digits (3 x 0.1 s read
                    # 0.30000000000000004 s).
                    "start_s": written_s(i * self.step_duration_s),
                    "end_s": written_s((i + 1) * self.step_duration_s),
                    "levels": row,
                    "duty": self.duty[i],
                    "on_time_s": self.on_time_s[i],
                    "torque_nm": self.torque_nm[i],
                }
            )
        return {
            "scenario": self.scenario_name,
            "sequence": self.sequence,
            "step_duration_s": self.step_duration_s,
            "duration_s": written_s(len(self.sequence) * self.step_duration_s),
            "steps": steps,
            "candidates": [
                {
                    "name": name,
                    # Numbered from 1 as the CSV's candidate_<number> columns and an
                    # identification's candidate_number number it.
                    "number": k + 1,
                    "rates_rad_s": rates[k].tolist(),
                    "rates_deg_s": (rates[k] * _DEG).tolist(),
                    "residual_rate_rad_s": float(residual[k]),
                    "residual_rate_deg_s": float(residual[k] * _DEG),
                    # The nominal prediction starts from rest: its residual is the part
                    # the commands leave, named so beside a flight's total.
                    "commanded_residual_rate_rad_s": float(residual[k]),
                    "commanded_residual_rate_deg_s": float(residual[k] * _DEG),
                    "end_rate_rad_s": self.end_rate_rad_s[k],
                    "end_rate_deg_s": self.end_rate_rad_s[k] * _DEG,
                    "peak_rate_rad_s": self.peak_rate_rad_s[k],
                    "peak_rate_deg_s": self.peak_rate_rad_s[k] * _DEG,
                    "attitude_quaternion": self.attitude_quaternion[k],
                    "attitude_change_deg": self.attitude_change_deg[k],
                    **(
                        {} if self.dispersion is None else {"flights": self.dispersion.candidate(k)}
                    ),
                }
                for k, name in enumerate(self.candidate_names)
            ],
            "flights": None if self.dispersion is None else self.dispersion.summary(),
            "residual_rate_max_rad_s": float(residual.max()),
            "residual_rate_max_deg_s": float(residual.max() * _DEG),
            "commanded_residual_rate_max_rad_s": float(residual.max()),
            "commanded_residual_rate_max_deg_s": float(residual.max() * _DEG),
            "initial_rate_floor": self._floor(),
            "peak_rate_max_rad_s": float(max(self.peak_rate_rad_s)),
            "peak_rate_max_deg_s": float(max(self.peak_rate_rad_s) * _DEG),
            "attitude_quaternion_convention": "(w, x, y, z), scalar first: rotates "
            "body-frame vectors into the frame the body had at the sequence's start",
            "residual_rate_note": "|ω| once the actuation lag has delivered the torque "
            "still in it when the last command ends (what the spacecraft keeps); "
            "end_rate is |ω| at that moment; peak_rate is the largest |ω| at the gyro's "
            "samples or once settled (between samples it can be a few tenths of a percent "
            "higher); the prediction starts from rest with every noise off, so "
            "residual_rate is the commanded residual (commanded_residual_rate: what the "
            "sequence itself leaves); a flight's residual (flights) adds the rate it "
            "started with, |ω(0)|, which no open-loop sequence removes (initial_rate_floor: "
            "its mean and the rate 95 % of flights' |ω(0)| stay under, for the scenario's "
            "initial_rate_sigma_rad_s; null when the scenario starts at rest)",
            "propellant": {
                "on_time_per_thruster_s": self.on_time_per_thruster_s,
                "on_time_s": float(np.sum(self.on_time_per_thruster_s)),
                "impulse_nms": self.impulse_nms,
                "impulse_note": "commanded angular impulse summed over thrusters (every "
                "firing counts, opposed or not): a propellant proxy",
                "propellant_kg": self.propellant_kg,
                "propellant_note": self._propellant_note(),
            },
            "warnings": list(self.warnings),
            "dust": None if self.dust is None else self._dust_dict(),
        }

    def _dust_dict(self) -> dict[str, Any]:
        assert self.dust is not None
        return {
            "fraction": DUST_FRACTION,
            "torque_scale_nm": self.dust.torque_nm,
            "rate_scale_rad_s": self.dust.rate_rad_s,
            "attitude_change_scale_deg": [a * _DEG for a in self.dust.angle_rad],
            "note": "a torque, rate, attitude change or quaternion component at most "
            "`fraction` of its scale is rounding dust (thrusters whose torques cancel) and "
            "is written 0: a torque's scale is the largest thruster's torque, a candidate's "
            "rates' the largest rate the sequence's firings could give it (the impulse "
            "summed over thrusters over its smallest principal moment), its attitude "
            "change's that rate over the sequence, a quaternion's vector part's half that "
            "angle (at most 1), its scalar part's 1",
        }

    def to_csv(self) -> str:
        """One row per step (on-times, duties, torque, each candidate's predicted rates at
        the step's end); the totals as ``# name: value`` lines before the header."""
        document = self.to_dict()
        out = io.StringIO()
        propellant = document["propellant"]
        # Names are the user's text: written as JSON strings (csv_note_text), so that a
        # newline or a comma in one cannot end the line or start a spreadsheet cell.
        out.write(f"# scenario: {csv_note_text(self.scenario_name)}\n")
        # All its digits (":g" wrote 0.1234567 s as 0.123457).
        out.write(f"# step_duration_s: {self.step_duration_s:.15g}\n")
        out.write(f"# attitude_quaternion: {document['attitude_quaternion_convention']}\n")
        out.write(f"# impulse_nms: {self.impulse_nms:.6g}\n")
        out.write(f"# on_time_s: {propellant['on_time_s']:.6g}\n")
        kg = self.propellant_kg
        # Kept when unknown, so that a reader by name finds it, in words (it was empty).
        stated = f"{kg:.6g}" if kg is not None else propellant["propellant_note"]
        out.write(f"# propellant_kg: {stated}\n")
        # What the JSON warns of, in the file a team hands on too (it was in the JSON
        # alone); as a JSON string: it names the scenario, the user's text.
        for warning in self.warnings:
            out.write(f"# warning: {csv_note_text(warning)}\n")
        floor = document["initial_rate_floor"]
        if floor is not None:
            out.write(
                "# initial_rate_floor: initial_rate_sigma_rad_s "
                f"{floor['initial_rate_sigma_rad_s']:g}"
                f"; {_rate_pair(floor, 'mean', sep='; ')}; {_rate_pair(floor, 'p95', sep='; ')}"
                " (|omega(0)|, in every flight's residual, removed by no open-loop sequence; the "
                "residual rates below start from rest: the commanded part)\n"
            )
        if self.dispersion is not None:
            summary = document["flights"]
            out.write(
                f"# flights: {self.dispersion.flights} per candidate at the scenario's noise, "
                f"seed {self.dispersion.seed}"
                + "".join(
                    f"; {_rate_pair(summary, figure, sep='; ')}"
                    for figure in (
                        "residual_rate_p95_max",
                        "residual_rate_p95_bound_max",
                        "peak_rate_p95_max",
                        "peak_rate_p95_bound_max",
                    )
                )
                + "\n"
            )
        for k, candidate in enumerate(document["candidates"], start=1):
            flown = candidate.get("flights") or {}
            out.write(
                f"# candidate_{k} {csv_note_text(candidate['name'])}: "
                + ", ".join(
                    _rate_pair(candidate, rate)
                    for rate in (
                        "residual_rate",
                        "commanded_residual_rate",
                        "end_rate",
                        "peak_rate",
                    )
                )
                + f", attitude_change_deg {candidate['attitude_change_deg']:.6g}"
                # The JSON's quaternion too (the README promises it in both forms).
                + "".join(
                    f", attitude_quaternion_{part} {value:.9g}"
                    for part, value in zip("wxyz", candidate["attitude_quaternion"], strict=True)
                )
                + (
                    ""
                    if self.dispersion is None
                    else "".join(
                        ", " + _rate_pair(flown, rate, label=f"flights_{rate}")
                        for rate in (
                            key.removesuffix("_rad_s") for key in flown if key.endswith("_rad_s")
                        )
                    )
                )
                + "\n"
            )
        n = len(self.sequence[0])
        header = ["step", "start_s", "end_s"]
        # Thrusters, steps and candidates numbered from 1, as the service's other tables
        # and the report number them (an upload must not be off by one).
        header += [f"on_time_s_thruster_{j}" for j in range(1, n + 1)]
        header += [f"duty_thruster_{j}" for j in range(1, n + 1)]
        header += ["torque_x_nm", "torque_y_nm", "torque_z_nm"]
        for k in range(len(self.candidate_names)):
            header += [f"candidate_{k + 1}_w{axis}_rad_s" for axis in "xyz"]
            header += [f"candidate_{k + 1}_w{axis}_deg_s" for axis in "xyz"]
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(header)
        rates = np.asarray(self.rates_rad_s)
        for i, step in enumerate(document["steps"]):
            row: list[Any] = [step["step"], step["start_s"], step["end_s"]]
            row += [f"{v:.6g}" for v in step["on_time_s"]] + [f"{v:.6g}" for v in step["duty"]]
            row += [f"{v:.6g}" for v in step["torque_nm"]]
            for k in range(len(self.candidate_names)):
                row += [f"{v:.6g}" for v in rates[k, i]]
                row += [f"{v:.6g}" for v in rates[k, i] * _DEG]
            writer.writerow(row)
        return out.getvalue()


#: Flights simulated at once: a block's arrays (K x block x samples x 3 doubles each:
#: true and measured rates, applied and commanded torque) stay near 130 MB whatever
#: ``flights`` is.
_FLIGHT_BLOCK_VALUES = 4_000_000


def _flight_words(i: int, *, first: int, flights: int, seed: int) -> str:
    return f"flight {first + i} of {flights} at the scenario's noise (seed {seed})"


def flight_dispersion(
    scenario: Scenario,
    rows: np.ndarray,
    flights: int,
    seed: int,
    nominal: np.ndarray,
    nominal_peak: np.ndarray,
) -> FlightDispersion:
    """Each candidate flown ``flights`` times at the scenario's own noise (see
    :class:`FlightDispersion`), in blocks drawn one after the other from ``seed`` (one
    block, up to 1,666 flights of 8 paper steps, draws what one call would).
    ``nominal`` and ``nominal_peak`` (K,): the plan's residual and peak rates, below
    which no bound is stated."""
    rng = np.random.default_rng(seed)
    samples = scenario.timing.samples_per_step * len(rows)
    block = max(1, _FLIGHT_BLOCK_VALUES // (scenario.n_candidates * samples * 3))
    residual_parts, peak_parts = [], []
    for start in range(0, flights, block):
        result = simulate(scenario, rows, min(block, flights - start), rng)
        settled = settled_rates(
            scenario, result.omega_true[:, :, -1], result.applied_torque_nm[:, :, -1]
        )
        check_gyro_range(
            scenario,
            rows,
            result.omega_true,
            settled=settled,
            flight=functools.partial(_flight_words, first=start + 1, flights=flights, seed=seed),
        )
        residual = np.linalg.norm(settled, axis=-1)  # (K, n)
        residual_parts.append(residual)
        peak_parts.append(flight_peaks(result.omega_true, residual))
    residual = np.concatenate(residual_parts, axis=1)
    peak = np.concatenate(peak_parts, axis=1)
    floor = np.maximum(residual.mean(axis=1), nominal)  # as a front's figure
    return FlightDispersion(
        flights=flights,
        seed=seed,
        residual_mean_rad_s=residual.mean(axis=1).tolist(),
        residual_p95_rad_s=flight_quantile(residual, axis=1).tolist(),
        residual_p95_bound_rad_s=np.maximum(per_flight_bound(residual, axis=1), floor).tolist(),
        residual_max_rad_s=residual.max(axis=1).tolist(),
        peak_p95_rad_s=flight_quantile(peak, axis=1).tolist(),
        peak_p95_bound_rad_s=np.maximum(
            per_flight_bound(peak, axis=1), np.maximum(peak.mean(axis=1), nominal_peak)
        ).tolist(),
    )


def written_s(seconds: float) -> float:
    """A time to 15 significant digits: what the upload says, without the last bit of
    binary rounding (a duty of 0.6 for 0.4 s read 0.23999999999999996 s in the JSON, 3 x
    0.1 s 0.30000000000000004 s). The front's times are its plans' by it
    (:class:`~inertia_id.search.operator.OperatorScorer`)."""
    return float(f"{float(seconds):.15g}")


def _as_written(seconds: np.ndarray) -> np.ndarray:
    """On-times to 15 significant digits (:func:`written_s`, element by element)."""
    return np.array([written_s(v) for v in np.ravel(seconds)]).reshape(np.shape(seconds))


def command_plan(
    scenario: Scenario, sequence: Any, *, flights: int = 0, seed: int = 0
) -> CommandPlan:
    """The command plan of ``sequence`` ((L, N) level indices) for ``scenario``; with
    ``flights`` > 0 (at least 2), how single flights spread, drawn from ``seed``.

    :raises ~inertia_id.physics.simulate.RatesBeyondGyro: a candidate's predicted rate,
        nominal or in a flight, passes any attitude gyro's range
        (:func:`~inertia_id.physics.simulate.check_nominal_gyro_range`, and
        :func:`~inertia_id.physics.simulate.check_gyro_range` on flights): no prediction of a
        spacecraft, but of a scenario in the wrong units.
    """
    rows = scenario.check_sequence(sequence)
    if not is_integer(flights, minimum=0, maximum=MAX_FLIGHTS) or flights == 1:
        raise InputError(
            f"flights must be 0 (none) or an integer in 2..{MAX_FLIGHTS}, got {flights!r}"
        )
    if not is_integer(seed, minimum=0):
        raise InputError(f"seed must be a non-negative integer, got {seed!r}")
    duty = scenario.duties(rows)  # (L, N)
    step = scenario.timing.step_duration_s
    run = check_nominal_gyro_range(scenario, rows)
    if flights:
        # Flights fly the scenario's noise: one that overflows the rates is named by
        # its figure before any is flown.
        check_simulable(scenario, rows, sequence_name="the plan's sequence")
    weak = weak_response_warning(scenario, rows, run)
    settled = settled_rates(scenario, run.omega_true[:, :, -1], run.applied_torque_nm[:, :, -1])
    fine = run.omega_true[:, 0]  # (K, T_fine, 3) at every integration step
    rates = at_gyro_samples(scenario, fine)  # (K, T, 3) at the gyro's samples
    per_step = scenario.timing.samples_per_step
    # Propagated on the integration grid: the attitude must not depend on how often the
    # gyro reports (at 0.1 Hz, from the gyro's samples, it was 4.6 degrees off a 115
    # degree turn).
    quaternions = propagate_attitude(fine, scenario.timing.integration_step_s)[:, -1]
    # Rounding dust where thrusters cancel is written an exact 0 (DUST_FRACTION).
    scales = dust_scales(scenario, rows)
    rate_scale = np.asarray(scales.rate_rad_s)  # (K,)
    angle_scale = np.asarray(scales.angle_rad)  # (K,)
    part_scale = np.minimum(1.0, angle_scale / 2.0)[:, None]  # |sin(θ/2)| <= θ/2
    quaternions = without_dust(
        quaternions, np.concatenate([np.ones_like(part_scale), np.repeat(part_scale, 3, 1)], 1)
    )
    end = without_dust(rates[:, per_step - 1 :: per_step], rate_scale[:, None, None])
    residual = without_dust(np.linalg.norm(settled[:, 0], axis=-1), rate_scale)
    # As the operator's scorer reads it: at every sample, or once the lag has delivered
    # the torque still in it (|ω| moves on a line to the settled rate, convex: see
    # OperatorScorer).
    peak = without_dust(
        np.maximum(np.linalg.norm(rates, axis=-1).max(axis=1), residual), rate_scale
    )
    return CommandPlan(
        scenario_name=scenario.name,
        sequence=rows.tolist(),
        step_duration_s=step,
        duty=duty.tolist(),
        on_time_s=_as_written(duty * step).tolist(),
        torque_nm=without_dust(duty @ scenario.torque_matrix.T, scales.torque_nm).tolist(),
        candidate_names=scenario.candidate_names,
        rates_rad_s=end.tolist(),
        residual_rate_rad_s=residual.tolist(),
        end_rate_rad_s=without_dust(np.linalg.norm(rates[:, -1], axis=-1), rate_scale).tolist(),
        peak_rate_rad_s=peak.tolist(),
        attitude_quaternion=quaternions.tolist(),
        attitude_change_deg=without_dust(
            rotation_angle_deg(quaternions), angle_scale * _DEG
        ).tolist(),
        on_time_per_thruster_s=_as_written(scenario.on_time_s(rows)).tolist(),
        impulse_nms=scenario.impulse_nms(rows),
        propellant_kg=scenario.propellant_kg(rows),
        dispersion=(
            flight_dispersion(scenario, rows, int(flights), int(seed), residual, peak)
            if flights
            else None
        ),
        warnings=[w for w in (weak, cancelling_warning(scenario, rows)) if w is not None],
        initial_rate_sigma_rad_s=float(scenario.uncertainty.initial_rate_sigma_rad_s),
        propellant_unstated=scenario.propellant_unstated,
        propellant_basis=scenario.propellant_basis,
        dust=scales,
    )
