"""``inertia-id scenario`` and ``inertia-id simulate``: the spacecraft and its responses."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import Any, TypeVar

import click

from .options import (
    DEFAULT_SEQUENCE_TEXT,
    FloatRange,
    IntRange,
    _json_file_name,
    friendly_errors,
    load_scenario,
    parse_sequence,
    realisations_option,
    refuse_past_memory,
    scenario_options,
    seed_option,
    sequence_option,
    write_json,
    write_output,
)

__all__ = ["scenario_cmd", "simulate_cmd"]

F = TypeVar("F", bound=Callable[..., Any])


def _noise_option(flag: str, source: str) -> Callable[[F], F]:
    """A noise source's scale: a multiple (0 to 1000, 1 by default) of the scenario's own."""
    return click.option(
        flag,
        default=1.0,
        show_default=True,
        type=FloatRange(0),
        help=f"Multiple of the scenario's {source}, 0 to 1000 (a sweep's range).",
    )


@click.command("scenario")
@scenario_options
@click.option(
    "--out",
    type=click.Path(dir_okay=False),
    callback=_json_file_name,
    help="Write the JSON here instead of stdout.",
)
@friendly_errors
def scenario_cmd(preset_name: str, scenario_path: str | None, out: str | None) -> None:
    """Print a scenario as JSON (a starting point to edit), after validating it: its
    rules, and that it can be simulated at its own noise (the service's rule for a
    scenario it stores). A thruster that gives no torque is warned of on stderr
    (:func:`~inertia_id.cli.options.load_scenario`, as every command that loads one)."""
    from ..physics.simulable import check_scenario_simulable

    scenario = load_scenario(preset_name, scenario_path)
    check_scenario_simulable(scenario)
    write_json(out, scenario.model_dump(mode="json"))


def _arrays_file_name(context: click.Context, param: click.Parameter, value: str | None) -> Any:
    """An output named for neither format simulate writes is refused (JSON text went into
    s.csv), as click refuses a bad option: a usage error, as `search --out r.csv` is."""
    if value is not None and not value.lower().endswith((".npz", ".json")):
        raise click.BadParameter(f"simulate writes .npz (arrays) or .json, got {value!r}")
    return value


@click.command("simulate")
@scenario_options
@sequence_option(DEFAULT_SEQUENCE_TEXT)
@realisations_option("Noisy realisations per candidate.")
@_noise_option("--process-noise", "disturbance torque")
@_noise_option("--measurement-noise", "gyro noise")
@seed_option
@click.option(
    "--out",
    type=click.Path(dir_okay=False),
    callback=_arrays_file_name,
    help="Write every series: .npz (arrays) or .json.",
)
@click.option(
    "--telemetry",
    type=click.Path(dir_okay=False),
    help="Write one series as telemetry CSV (time_s,wx_rad_s,wy_rad_s,wz_rad_s) for `identify`.",
)
@click.option(
    "--candidate",
    default=None,
    help="Candidate whose series --telemetry writes: its name, or its number from 1 as plan "
    "tables and identify's candidate_number give it [default: 1]. A value that is one "
    "candidate's name and another's number is refused: give --candidate-number.",
)
@click.option(
    "--candidate-number",
    default=None,
    type=IntRange(1),
    help="The same by its number from 1 only, never read as a name.",
)
@click.option(
    "--realisation",
    default=0,
    show_default=True,
    type=IntRange(0),
    help="Which realisation --telemetry writes.",
)
@click.option(
    "--engine",
    default="numpy",
    show_default=True,
    type=click.Choice(["numpy", "basilisk"]),
    help="numpy: our RK4, every candidate and realisation. basilisk: Basilisk (pip install "
    "'inertia-id[basilisk]') flies the one series --telemetry writes (needs --telemetry).",
)
@click.option(
    "--sample-rate",
    "sample_rate_hz",
    default=None,
    type=FloatRange(0.01, 10_000),
    help="Gyro rate, Hz [default: the scenario's]; the gyro noise sigma stays per sample.",
)
@click.option(
    "--time-offset",
    default=None,
    help="Write --telemetry stamps in another clock: seconds added to every stamp (e.g. "
    "mission time), or an ISO-8601 UTC sequence start (a time_utc column). Pass the same "
    "value to `identify --sequence-start`.",
)
@click.option(
    "--pre-start",
    "pre_start_s",
    default=0.0,
    show_default=True,
    type=FloatRange(0),
    help="Begin the telemetry this many seconds before the sequence start (whole actuation "
    "steps, no thruster firing: the body drifts under the disturbance from its drawn "
    "initial rate), as a spacecraft's continuous telemetry does; `identify` measures the "
    "rate plus gyro bias there.",
)
@friendly_errors
def simulate_cmd(
    preset_name: str,
    scenario_path: str | None,
    sequence_text: str,
    realisations: int,
    process_noise: float,
    measurement_noise: float,
    seed: int,
    out: str | None,
    telemetry: str | None,
    candidate: str | None,
    candidate_number: int | None,
    realisation: int,
    engine: str,
    sample_rate_hz: float | None,
    time_offset: str | None,
    pre_start_s: float,
) -> None:
    """Simulate every candidate's gyro response to a sequence."""
    import numpy as np

    from ..checks import MAX_NOISE_MULTIPLE
    from ..errors import InputError
    from ..evaluation.telemetry import parse_sequence_start
    from ..physics.simulable import check_simulable
    from ..physics.simulate import check_nominal_gyro_range, simulate

    if telemetry is None:
        # These shape the telemetry file only: without one they were dropped silently.
        context = click.get_current_context()
        given = [
            f"--{name.replace('_', '-')}"
            for name in ("candidate", "candidate_number", "realisation", "time_offset")
            if context.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT
        ]
        if given:
            verb = "applies" if len(given) == 1 else "apply"
            raise InputError(f"{', '.join(given)} {verb} with --telemetry only")
    if candidate is not None and candidate_number is not None:
        raise InputError(
            f"--candidate {candidate!r} and --candidate-number {candidate_number} both name "
            "the candidate; give one"
        )
    if engine == "basilisk":
        # Basilisk flies one series: these were dropped without a word.
        context = click.get_current_context()
        dropped = [
            option
            for name, option in (("realisations", "-n"), ("realisation", "--realisation"))
            if context.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT
        ]
        if dropped:
            verb = "applies" if len(dropped) == 1 else "apply"
            raise InputError(
                f"{', '.join(dropped)} {verb} with --engine numpy only: --engine basilisk "
                "flies the one series --telemetry writes"
            )
    elif telemetry and realisation >= realisations:
        # Before the flight: it had been refused once --out was written.
        raise InputError(f"--realisation {realisation} but only {realisations} simulated")
    for option, multiple in (
        ("--process-noise", process_noise),
        ("--measurement-noise", measurement_noise),
    ):
        # nan had been blamed on the scenario's units ("overflow ... with every source of
        # noise off"), and 1e300 x the gyro noise wrote rates identify refuses.
        if not 0 <= multiple <= MAX_NOISE_MULTIPLE:
            raise InputError(
                f"{option} {multiple:g}: a multiple of the scenario's own, 0 to "
                f"{MAX_NOISE_MULTIPLE:g} (a sweep's range: beyond it the simulated rates leave "
                "what the integrator follows)"
            )
    scenario = load_scenario(preset_name, scenario_path)
    # Before the flight, not after it: a candidate the scenario lacks is refused at once.
    k = _candidate_index(scenario.candidate_names, candidate, candidate_number)
    offset = parse_sequence_start(time_offset, "--time-offset")
    sequence, coast_s = _with_coast(scenario, parse_sequence(sequence_text, scenario), pre_start_s)
    # The plan's and the response's rule: a scenario that spins its bodies past any
    # gyro's range (wrong units) is refused before either engine flies it.
    check_nominal_gyro_range(scenario, sequence)
    if engine == "numpy":
        # And one whose noise, at the multiple asked for, overflows the rates is refused
        # naming that noise figure (the response's rule), not after the flight.
        check_simulable(
            scenario,
            sequence,
            multiples={"disturbance_torque_sigma_nm": process_noise},
            sequence_name="the sequence",
        )
    if engine == "basilisk":
        _fly_basilisk(
            scenario,
            sequence,
            coast_s=coast_s,
            k=k,
            seed=seed,
            process_noise=process_noise,
            measurement_noise=measurement_noise,
            sample_rate_hz=sample_rate_hz,
            out=out,
            telemetry=telemetry,
            offset=offset,
        )
        return
    if sample_rate_hz is not None:
        scenario = _at_rate(scenario, sample_rate_hz)
    if telemetry:
        # Stamps the offset cannot hold are refused before the flight.
        _telemetry_stamps(scenario.sample_times(len(sequence)) - coast_s, offset)
    refuse_past_memory(
        f"-n {realisations}",
        candidates=scenario.n_candidates,
        realisations=realisations,
        samples=len(sequence) * scenario.timing.samples_per_step,
    )
    result = simulate(
        scenario,
        sequence,
        realisations,
        np.random.default_rng(seed),
        process_noise_scale=process_noise,
        measurement_noise_scale=measurement_noise,
    )
    summary = {
        "candidates": result.candidate_names,
        "series_shape": list(result.omega_measured.shape),
        "impulse_nms": result.impulse_nms,
        "mean_final_rate_rad_s": result.mean_final_rate_rad_s,
        "final_rate_rad_s_per_candidate": result.final_rate_rad_s.mean(axis=1).tolist(),
    }
    if out:
        arrays = {
            "time_s": result.time_s - coast_s,
            "omega_measured_rad_s": result.omega_measured,
            "omega_true_rad_s": result.omega_true,
            "applied_torque_nm": result.applied_torque_nm,
            "sequence": result.sequence,
        }
        if out.lower().endswith(".npz"):
            # The names and figures the JSON carries, beside the arrays.
            # An open file: numpy adds ".npz" to a name that ends ".NPZ".
            write_output(
                out,
                lambda handle: np.savez_compressed(
                    handle,
                    **arrays,  # type: ignore[arg-type]
                    candidate_names=np.array(result.candidate_names),
                    impulse_nms=np.array(result.impulse_nms),
                ),
            )
        else:
            write_output(out, json.dumps({**summary, **{k: v.tolist() for k, v in arrays.items()}}))
        click.echo(f"wrote {out}", err=True)
    if telemetry:
        names = scenario.candidate_names
        _write_telemetry(
            telemetry, result.time_s - coast_s, result.omega_measured[k, realisation], offset
        )
        click.echo(
            f"wrote {telemetry} (candidate {k + 1} {names[k]!r}, realisation {realisation})",
            err=True,
        )
    write_json(None, summary)


def _with_coast(scenario: Any, sequence: Any, pre_start_s: float) -> tuple[Any, float]:
    """The sequence with ``pre_start_s`` seconds of no firing before it (whole steps), and
    that span in seconds (the stamps' shift, so that 0 is the sequence start)."""
    import numpy as np

    from ..errors import InputError

    rows = np.asarray(scenario.check_sequence(sequence))
    step_s = scenario.timing.step_duration_s
    room = 1000 - len(rows)  # the most steps a sequence may have, coast included
    if not math.isfinite(pre_start_s) or pre_start_s > room * step_s:
        raise InputError(
            f"--pre-start {pre_start_s:g} s: at most {room * step_s:g} s (1000 steps of "
            f"{step_s:g} s with the {len(rows)}-step sequence)"
        )
    coast = round(pre_start_s / step_s)
    if abs(coast * step_s - pre_start_s) > 1e-9 * max(step_s, pre_start_s):
        raise InputError(
            f"--pre-start {pre_start_s:g} s is not a whole number of the scenario's "
            f"{step_s:g} s steps"
        )
    coasting = np.zeros((coast, rows.shape[1]), dtype=rows.dtype)
    return np.concatenate([coasting, rows]), coast * step_s


def _candidate_index(names: list[str], candidate: str | None, number: int | None) -> int:
    """The position in ``names`` of the candidate ``--candidate`` (a name, or a number
    from 1 as plan tables and an identification's ``candidate_number`` number it) or
    ``--candidate-number`` names; the first when neither is given.

    A name and a number that point at different candidates (a candidate named "3" that
    is not the third) are refused naming both: the name won before, so the third could
    not be named by its number, and the number it showed in plan tables flew another.
    """
    from ..errors import InputError

    if number is not None:
        if number > len(names):
            raise InputError(
                f"--candidate-number {number}: the scenario has {len(names)} candidates, "
                f"numbered 1..{len(names)}"
            )
        return number - 1
    if candidate is None:
        return 0
    # ASCII digits only: "²".isdigit() is True, and int() refuses it.
    digits = candidate.isascii() and candidate.isdigit()
    by_name = names.index(candidate) if candidate in names else None
    by_number = int(candidate) - 1 if digits and 1 <= int(candidate) <= len(names) else None
    if by_name is not None and by_number is not None and by_name != by_number:
        raise InputError(
            f"--candidate {candidate!r} is both the name of candidate {by_name + 1} and the "
            f"number of candidate {by_number + 1} ({names[by_number]!r}): give "
            f"--candidate-number {by_name + 1} for the one named {candidate!r}, or "
            f"--candidate-number {by_number + 1} for number {candidate}"
        )
    if by_name is not None:
        return by_name
    if by_number is not None:
        return by_number
    zero = (
        f" (candidates are numbered from 1, as plan tables and identify number them: the "
        f"first is 1, {names[0]!r})"
        if digits and int(candidate) == 0
        else ""
    )
    raise InputError(
        f"candidate {candidate!r} is neither a number 1..{len(names)} nor one of {names}{zero}"
    )


def _at_rate(scenario: Any, rate_hz: float) -> Any:
    """``scenario`` with its gyro at ``rate_hz``: the integration step becomes the longest
    no longer than the scenario's that divides the sample period, the actuation step and
    the disturbance interval (whole nanoseconds)."""
    from ..errors import InputError

    timing, unc = scenario.timing, scenario.uncertainty
    if not math.isfinite(rate_hz) or rate_hz < 0.01:
        raise InputError(f"--sample-rate {rate_hz:g} Hz: give a rate from 0.01 Hz to 10 kHz")
    ns = [round(1e9 * v) for v in (1 / rate_hz, timing.step_duration_s, unc.disturbance_interval_s)]
    if abs(ns[0] - 1e9 / rate_hz) > 1e-3:
        raise InputError(f"--sample-rate {rate_hz:g} Hz: its period is not whole nanoseconds")
    common = math.gcd(*ns)
    h = round(1e9 * timing.integration_step_s)
    divisor = max(1, -(-common // h))
    while common % divisor:
        divisor += 1
    step = common // divisor
    if step < 10_000:  # 10 µs: the sample period shares no practical step with the rest
        raise InputError(
            f"--sample-rate {rate_hz:g} Hz shares no integration step of at least 10 µs with "
            f"the actuation step {timing.step_duration_s:g} s and the disturbance interval "
            f"{unc.disturbance_interval_s:g} s"
        )
    data = scenario.model_dump()
    data["timing"] = {
        **data["timing"],
        "sample_rate_hz": rate_hz,
        "integration_step_s": step * 1e-9,
    }
    return type(scenario).model_validate(data)


def _write_telemetry(path: str, time_s: Any, omega: Any, offset: float | str | None) -> None:
    """Telemetry CSV: time_s (plus a numeric offset) or time_utc (from an ISO start)."""
    header, stamps = _telemetry_stamps(time_s, offset)
    lines = [f"{header},wx_rad_s,wy_rad_s,wz_rad_s"]
    lines += [
        f"{s},{w[0]:.10g},{w[1]:.10g},{w[2]:.10g}" for s, w in zip(stamps, omega, strict=True)
    ]
    write_output(path, "\n".join(lines) + "\n")


#: How far a written stamp may lie from its time, as a fraction of the sample period.
STAMP_TOLERANCE = 0.01


def _telemetry_stamps(time_s: Any, offset: float | str | None) -> tuple[str, list[str]]:
    """The telemetry's time column, its header and stamps, for times ``time_s`` (s from
    the sequence start) and ``--time-offset``; an offset whose stamps cannot hold those
    times is an :class:`~inertia_id.errors.InputError` naming it.

    Stamps are written with 15 significant digits (1 µs at mission times below 1e9 s),
    else with as many as the float holds. At 1e12 s 15 digits are 10 ms, and 200 Hz
    stamps were written twice each (identify refused the file); at 1e16 s a float is 2 s
    and every 20 Hz stamp was the same. An ISO start whose stamps leave years 1 to 9999
    was a traceback (OverflowError).
    """
    from datetime import UTC, datetime, timedelta

    import numpy as np

    from ..errors import InputError

    times = np.asarray(time_s, dtype=float)
    if isinstance(offset, str):
        # In UTC, as the column's name says, whatever offset the start was given with.
        origin = datetime.fromisoformat(offset).astimezone(UTC)
        try:
            stamps = [
                (origin + timedelta(microseconds=round(1e6 * t))).isoformat().replace("+00:00", "Z")
                for t in times
            ]
        except OverflowError:
            raise InputError(
                f"--time-offset {offset!r}: the telemetry's stamps, {times[0]:g} s to "
                f"{times[-1]:g} s from it, leave the years 1 to 9999 an ISO-8601 stamp "
                "can write"
            ) from None
        return "time_utc", stamps
    base = 0.0 if offset is None else float(offset)
    if len(times) < 2:
        return "time_s", [f"{base + t:.15g}" for t in times]
    limit = STAMP_TOLERANCE * float(np.min(np.diff(times)))
    error = 0.0
    for write in (lambda stamp: f"{stamp:.15g}", repr):
        stamps = [write(base + float(t)) for t in times]
        # What identify reads back, less the start it is given (the same offset).
        error = float(np.max(np.abs(np.array([float(s) for s in stamps]) - base - times)))
        if error <= limit:
            return "time_s", stamps
    raise InputError(
        f"--time-offset {base:g} s: stamps that large are off their times by up to "
        f"{error:.3g} s (a float's precision there), more than {STAMP_TOLERANCE:.0%} of the "
        f"{limit / STAMP_TOLERANCE:g} s sample period: give seconds from a nearer epoch"
    )


def _fly_basilisk(
    scenario: Any,
    sequence: Any,
    *,
    coast_s: float,
    k: int,
    seed: int,
    process_noise: float,
    measurement_noise: float,
    sample_rate_hz: float | None,
    out: str | None,
    telemetry: str | None,
    offset: float | str | None,
) -> None:
    """One series flown by Basilisk: the --telemetry one (candidate ``k`` from 0,
    realisation 0 of --seed)."""
    import numpy as np

    from ..errors import InputError

    if telemetry is None or out is not None:
        raise InputError("--engine basilisk flies one series: give --telemetry (and not --out)")
    try:
        from ..physics.engines.basilisk import BasiliskUnavailableError, simulate_basilisk
    except ImportError as exc:  # pragma: no cover - the module imports Basilisk lazily
        raise click.ClickException(f"Basilisk is not available: {exc}") from None
    try:
        flown = simulate_basilisk(
            scenario,
            sequence,
            k,
            np.random.default_rng(seed),
            sample_rate_hz=sample_rate_hz,
            process_noise_scale=process_noise,
            measurement_noise_scale=measurement_noise,
        )
    except BasiliskUnavailableError as exc:
        raise click.ClickException(str(exc)) from None
    except ValueError as exc:
        raise InputError(str(exc)) from None
    _write_telemetry(telemetry, flown.time_s - coast_s, flown.omega_measured, offset)
    click.echo(f"wrote {telemetry} ({flown.candidate}, Basilisk)", err=True)
    write_json(
        None,
        {
            "engine": "basilisk",
            "candidate": flown.candidate,
            "series_shape": list(flown.omega_measured.shape),
            "sample_rate_hz": flown.sample_rate_hz,
            "hub_step_s": flown.hub_step_s,
            "final_rate_rad_s": flown.omega_true[-1].tolist(),
        },
    )
