"""Do the least-squares estimate's standard errors cover the truth?

For each series, z = (estimate - true parameter) / stated standard error, per parameter
(Ixx, Iyy, Izz, Ixy, Ixz, Iyz). Honest errors give an RMS of z near 1 and about 5 % of
|z| beyond 2. Printed for the reported figure (``parameter_std_kg_m2``, the sandwich
covariance) and the textbook one that assumes independent equation errors
(``independent_std_kg_m2``), and the bias, which no standard error covers (above about
0.5 the RMS of z says more about the bias): the mean z over every series, the mean
error in percent (of the true moment; a product of inertia's of the true mean moment)
and the worst candidate's |mean error| / spread of the errors.

1. Our simulator, ``--realisations`` (100) series per candidate, at 1x, 6x process
   noise and 6x gyro noise: the paper preset (at rest) and paper-in-orbit (an initial
   rate and a gyro bias), under an 8-step sequence that turns every axis (a reviewer's,
   helper-132) and under the hand-designed ``[[4,4,4,0,0,0]]*4``, whose one torque
   direction leaves the tensor to the gyroscopic term (condition number about 110: the
   estimate's diagonal is biased by tens of percent, README). Then the paper preset
   with one source alone, every other off: the duty jitter (both sequences fire at full
   duty, where the clipped jitter leaves a mean thrust shortfall the estimate must
   allow for) and the gyro noise (in the regressor, which biased the estimate light
   until its expected share came out of the normal equations).
2. ``--basilisk N`` (default 2, 0 skips; needs the ``basilisk`` extra): N passes per
   candidate flown by Basilisk on paper-in-orbit at 10 Hz with 30 s before the start,
   resampled as ``identify`` does (the grid times a sample measures): z of the true
   value per pass.

Run: python bench/estimate_coverage.py [--realisations 100] [--basilisk 2] [--json PATH]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, add_realisations, base_parser, begin, write_json

from inertia_id import simulate
from inertia_id.evaluation.telemetry import Telemetry, resample_covered
from inertia_id.physics.estimate import (
    PARAMETER_NAMES,
    estimate_inertia,
    parameters_from_tensor,
    tensor_from_parameters,
)
from inertia_id.physics.presets import NOISE_OFF, preset

# Every axis torqued, alone and in pairs, over eight steps (helper-132's review).
TURNING_SEQUENCE = [
    [4, 4, 4, 0, 0, 0],
    [0, 0, 0, 0, 4, 0],
    [0, 0, 0, 4, 4, 0],
    [0, 0, 0, 0, 0, 4],
    [0, 0, 0, 0, 0, 4],
    [0, 0, 0, 0, 0, 0],
    [0, 4, 0, 0, 0, 0],
    [4, 0, 4, 4, 0, 0],
]
# Each noise row: the simulator's noise scales, and the one source kept at 1x with every
# other switched off (None: all kept), which tells the biases apart: the duty jitter's
# clip at full duty and the noisy rates in the regressor.
NOISES: dict[str, tuple[dict[str, float], str | None]] = {
    "1x": ({}, None),
    "6x process": ({"process_noise_scale": 6.0}, None),
    "6x gyro": ({"measurement_noise_scale": 6.0}, None),
    "jitter alone": ({}, "duty_jitter_sigma"),
    "gyro noise alone": ({}, "gyro_noise_sigma_rad_s"),
}


def _row(z: np.ndarray) -> str:
    rms = np.sqrt(np.mean(z**2, axis=0))
    beyond = np.mean(np.abs(z) > 2.0, axis=0)
    return "  ".join(f"{r:5.2f} {100 * b:3.0f}%" for r, b in zip(rms, beyond, strict=True))


def _relative_error(error: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(n, 6) errors as fractions: a moment's of its true value, a product of inertia's
    of the true mean moment (a product may be 0)."""
    scale = np.full(6, np.trace(tensor_from_parameters(truth)) / 3.0)
    scale[:3] = truth[:3]
    return error / scale


def simulated(args: Any) -> dict[str, Any]:
    figures: dict[str, Any] = {}
    header = "  ".join(f"{n:>10}" for n in PARAMETER_NAMES)
    print(f"RMS z and share |z| > 2 per parameter:\n{'':44}{header}")
    for preset_name in ("paper", "paper-in-orbit"):
        for seq_name, sequence in (
            ("8-step", TURNING_SEQUENCE),
            ("[[4,4,4,0,0,0]]*4", GOOD_SEQUENCE),
        ):
            for noise, (scales, alone) in NOISES.items():
                if alone is not None and preset_name != "paper":
                    continue  # every other source off, paper-in-orbit is the paper preset
                scenario = preset(preset_name)
                if alone is not None:
                    kept = getattr(scenario.uncertainty, alone)
                    scenario = scenario.with_uncertainty(**{**NOISE_OFF, alone: kept})
                sim = simulate(
                    scenario,
                    sequence,
                    args.realisations,
                    np.random.default_rng(args.seed),
                    **scales,
                )
                reported, independent, bias, relative = [], [], [], []
                for k in range(scenario.n_candidates):
                    estimate = estimate_inertia(scenario, sequence, sim.omega_measured[k])
                    truth = parameters_from_tensor(scenario.inertia_array[k])
                    error = estimate.parameters_kg_m2 - truth
                    reported.append(error / estimate.parameter_std_kg_m2)
                    independent.append(error / estimate.independent_std_kg_m2)
                    bias.append(np.abs(error.mean(axis=0)) / error.std(axis=0))
                    relative.append(_relative_error(error, truth))
                label = f"{preset_name}, {seq_name}, {noise}"
                z_reported, z_independent = np.concatenate(reported), np.concatenate(independent)
                print(f"{label:<44}")
                print(f"{'  reported (sandwich)':<44}{_row(z_reported)}")
                print(f"{'  independent-error':<44}{_row(z_independent)}")
                mean_z = z_reported.mean(axis=0)
                mean_relative = np.concatenate(relative).mean(axis=0)
                print(f"{'  mean z (reported)':<44}" + "  ".join(f"{m:+10.2f}" for m in mean_z))
                print(
                    f"{'  mean error, % (products: of mean moment)':<44}"
                    + "  ".join(f"{100 * m:+10.2f}" for m in mean_relative)
                )
                worst_bias = np.max(np.asarray(bias), axis=0)
                print(
                    f"{'  |bias| / spread, worst candidate':<44}"
                    + "  ".join(f"{b:10.2f}" for b in worst_bias)
                )
                figures[label] = {
                    "rms_z_reported": np.sqrt(np.mean(z_reported**2, axis=0)),
                    "beyond_2_reported": np.mean(np.abs(z_reported) > 2, axis=0),
                    "rms_z_independent": np.sqrt(np.mean(z_independent**2, axis=0)),
                    "beyond_2_independent": np.mean(np.abs(z_independent) > 2, axis=0),
                    "worst_bias_over_spread": worst_bias,
                    "mean_z_reported": mean_z,
                    "mean_relative_error": mean_relative,
                }
    return figures


def basilisk(args: Any) -> dict[str, Any]:
    from inertia_id.physics.engines.basilisk import simulate_basilisk

    scenario = preset("paper-in-orbit")
    sequence = TURNING_SEQUENCE
    pre = 30
    grid = scenario.sample_times(len(sequence))
    rows: dict[str, Any] = {}
    print("\nBasilisk, paper-in-orbit, 8-step sequence, 10 Hz, 30 s before the start:")
    print(f"{'pass':<28}" + "  ".join(f"{n:>16}" for n in PARAMETER_NAMES))
    for k in range(scenario.n_candidates):
        for i in range(args.basilisk):
            rng = np.random.default_rng([args.seed, k, i])
            flown = simulate_basilisk(
                scenario,
                [[0] * 6] * pre + sequence,
                k,
                rng,
                sample_rate_hz=10.0,
                start_time_s=-float(pre),
            )
            telemetry = Telemetry(
                time_s=flown.time_s.tolist(),
                omega_rad_s=flown.omega_measured.tolist(),
                sequence_start=0.0,
            )
            resampled = resample_covered(telemetry, grid, marginalise_gaps=True)
            estimate = estimate_inertia(
                scenario, sequence, resampled.series, covered=resampled.observed
            )
            truth = parameters_from_tensor(scenario.inertia_array[k])
            error = estimate.parameters_kg_m2 - truth
            z = error / estimate.parameter_std_kg_m2
            z_old = error / estimate.independent_std_kg_m2
            name = f"candidate {k}, pass {i}"
            print(
                f"{name:<28}"
                + "  ".join(
                    f"{p:6.1f}±{s:4.1f} z{v:+5.1f}"
                    for p, s, v in zip(
                        estimate.parameters_kg_m2, estimate.parameter_std_kg_m2, z, strict=True
                    )
                )
            )
            print(f"{'  independent-error z':<28}" + "  ".join(f"{v:+16.1f}" for v in z_old))
            rows[name] = {"z_reported": z, "z_independent": z_old, "truth": truth}
    z_all = np.array([r["z_reported"] for r in rows.values()])
    z_old_all = np.array([r["z_independent"] for r in rows.values()])
    print(
        f"all passes: RMS z reported {np.sqrt(np.mean(z_all**2)):.2f} "
        f"({100 * np.mean(np.abs(z_all) > 2):.0f} % beyond 2), independent-error "
        f"{np.sqrt(np.mean(z_old_all**2)):.2f} ({100 * np.mean(np.abs(z_old_all) > 2):.0f} %)"
    )
    return rows


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    add_realisations(parser, default=100)
    parser.add_argument("--basilisk", type=int, default=2, help="Basilisk passes per candidate")
    args = begin(parser, "Least-squares estimate: coverage of the stated standard errors")
    figures = {"simulated": simulated(args)}
    if args.basilisk > 0:
        figures["basilisk"] = basilisk(args)
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
