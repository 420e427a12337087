"""``inertia-id scenario`` and ``inertia-id simulate``: the spacecraft and its responses."""

from __future__ import annotations

import json
from pathlib import Path

import click

from .options import (
    DEFAULT_SEQUENCE_TEXT,
    friendly_errors,
    load_scenario,
    parse_sequence,
    realisations_option,
    scenario_options,
    seed_option,
    sequence_option,
    write_json,
)

__all__ = ["scenario_cmd", "simulate_cmd"]


@click.command("scenario")
@scenario_options
@click.option("--out", type=click.Path(dir_okay=False), help="Write here instead of stdout.")
@friendly_errors
def scenario_cmd(preset_name: str, scenario_path: str | None, out: str | None) -> None:
    """Print a scenario as JSON (a starting point to edit), after validating it."""
    scenario = load_scenario(preset_name, scenario_path)
    write_json(out, scenario.model_dump(mode="json"))


@click.command("simulate")
@scenario_options
@sequence_option(DEFAULT_SEQUENCE_TEXT)
@realisations_option("Noisy realisations per candidate.")
@click.option(
    "--process-noise",
    default=1.0,
    show_default=True,
    type=click.FloatRange(0),
    help="Multiple of the scenario's disturbance torque.",
)
@click.option(
    "--measurement-noise",
    default=1.0,
    show_default=True,
    type=click.FloatRange(0),
    help="Multiple of the scenario's gyro noise.",
)
@seed_option
@click.option(
    "--out", type=click.Path(dir_okay=False), help="Write every series: .npz (arrays) or .json."
)
@click.option(
    "--telemetry",
    type=click.Path(dir_okay=False),
    help="Write one series as telemetry CSV (time_s,wx_rad_s,wy_rad_s,wz_rad_s) for `identify`.",
)
@click.option(
    "--candidate",
    default="0",
    show_default=True,
    help="Candidate (index or name) whose series --telemetry writes.",
)
@click.option(
    "--realisation",
    default=0,
    show_default=True,
    type=click.IntRange(0),
    help="Which realisation --telemetry writes.",
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
    candidate: str,
    realisation: int,
) -> None:
    """Simulate every candidate's gyro response to a sequence."""
    import numpy as np

    from ..errors import InputError
    from ..physics.simulate import simulate

    scenario = load_scenario(preset_name, scenario_path)
    result = simulate(
        scenario,
        parse_sequence(sequence_text),
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
            "time_s": result.time_s,
            "omega_measured_rad_s": result.omega_measured,
            "omega_true_rad_s": result.omega_true,
            "applied_torque_nm": result.applied_torque_nm,
            "sequence": result.sequence,
        }
        if out.endswith(".npz"):
            np.savez_compressed(out, **arrays)  # type: ignore[arg-type]
        else:
            Path(out).write_text(
                json.dumps({**summary, **{k: v.tolist() for k, v in arrays.items()}}),
                encoding="utf-8",
            )
        click.echo(f"wrote {out}", err=True)
    if telemetry:
        names = scenario.candidate_names
        if candidate in names:
            k = names.index(candidate)
        elif candidate.isdigit() and int(candidate) < len(names):
            k = int(candidate)
        else:
            raise InputError(
                f"candidate {candidate!r} is neither an index 0..{len(names) - 1} nor one of "
                f"{names}"
            )
        if realisation >= realisations:
            raise InputError(f"--realisation {realisation} but only {realisations} simulated")
        rows = np.column_stack([result.time_s, result.omega_measured[k, realisation]])
        np.savetxt(
            telemetry,
            rows,
            delimiter=",",
            header="time_s,wx_rad_s,wy_rad_s,wz_rad_s",
            comments="",
            fmt="%.10g",
        )
        click.echo(f"wrote {telemetry} ({names[k]}, realisation {realisation})", err=True)
    write_json(None, summary)
