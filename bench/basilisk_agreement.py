"""Basilisk against our simulator: agreement, gyro noise statistics, time per series.

Needs the optional extra: pip install "inertia-id[basilisk]" (PyPI bsk).

1. Noise off (the low-pass on), every candidate of the paper preset under the
   hand-designed sequence [[4,4,4,0,0,0]]*4 and of a scenario with full tensors and
   canted thrusters (inertia_id.physics.engines.canted_full_tensor_scenario): the largest
   |omega_basilisk - omega_ours| over the series, and each engine against an independent
   reference (scipy's DOP853 at rtol 1e-12 with the lag solved in closed form), which
   says whose error the residual is. For scale, Basilisk without the lag against ours.
   The command plan's attitude change at the end (quaternion propagation of our 20 Hz
   rates) against Basilisk's own attitude (its hub's sigma_BN) on a 2 ms hub step, where
   it has converged, and on the scenario's own step: the angle between them.
2. Process noise on, the same draws in both engines (duty jitter, thrust scale,
   disturbance, initial rate, random bias): the same comparison of the true rates.
3. The residual against the step: Basilisk's hub step and our RK4 step shortened.
4. The IMU's noise on a long quiet run: mean and std of (measured - true) against the
   bias and sigma asked for, lag-1 autocorrelation, excess kurtosis.
5. Time per simulated series, both engines.
6. (--identify N) Classifiers trained on our simulator, tested on N series per candidate
   flown by Basilisk and on the same draws flown by ours.

Run: python bench/basilisk_agreement.py [--identify 40] [--json PATH]
"""

from __future__ import annotations

import subprocess
import sys
import time
from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    base_parser,
    best_of,
    print_header,
    print_table,
    write_json,
)
from scipy import stats
from scipy.integrate import solve_ivp

from inertia_id import Scenario, simulate, train_classifier
from inertia_id.physics.attitude import quaternion_multiply, rotation_angle_deg
from inertia_id.physics.engines import (
    CANTED_SEQUENCE,
    basilisk_available,
    basilisk_version,
    canted_full_tensor_scenario,
    simulate_basilisk,
)
from inertia_id.physics.presets import NOISE_OFF
from inertia_id.search.plan import command_plan


def scenarios() -> list[tuple[str, Scenario, list[list[int]]]]:
    return [
        ("paper", Scenario.paper(), GOOD_SEQUENCE),
        ("canted", canted_full_tensor_scenario(), CANTED_SEQUENCE),
    ]


def reference(scenario: Scenario, sequence: Any, k: int, times: np.ndarray) -> np.ndarray:
    """Noise-off rates of candidate k at ``times``: DOP853 at rtol 1e-12, exact lag."""
    inertia = scenario.inertia_array[k]
    inverse = np.linalg.inv(inertia)
    tau = scenario.uncertainty.lowpass_time_constant_s
    duration = scenario.timing.step_duration_s
    omega, torque = np.zeros(3), np.zeros(3)
    out = []
    for j, levels in enumerate(scenario.check_sequence(sequence)):
        command = scenario.torque_matrix @ scenario.level_values[levels]
        t0 = j * duration

        def rates(
            t: float,
            w: np.ndarray,
            c: np.ndarray = command,
            m0: np.ndarray = torque,
            t0: float = t0,
        ) -> np.ndarray:
            m = c + (m0 - c) * np.exp(-(t - t0) / tau) if tau > 0 else c
            return inverse @ (m - np.cross(w, inertia @ w))

        inside = times[(times > t0 + 1e-9) & (times <= t0 + duration + 1e-9)]
        sol = solve_ivp(
            rates,
            (t0, t0 + duration),
            omega,
            method="DOP853",
            rtol=1e-12,
            atol=1e-14,
            t_eval=inside,
        )
        out.append(sol.y.T)
        omega = sol.y[:, -1]
        torque = command + (torque - command) * (np.exp(-duration / tau) if tau > 0 else 0.0)
    return np.concatenate(out)


def _attitude_apart_deg(quaternion: list[float], mrp: np.ndarray) -> float:
    """The angle of the rotation between a (w, x, y, z) quaternion and an MRP attitude."""
    squared = float(mrp @ mrp)
    theirs = np.concatenate([[(1.0 - squared) / (1.0 + squared)], 2.0 * mrp / (1.0 + squared)])
    inverse = np.asarray(quaternion) * np.array([1.0, -1.0, -1.0, -1.0])
    return float(rotation_angle_deg(quaternion_multiply(inverse, theirs)))


def agreement_noise_off() -> list[dict[str, Any]]:
    rows = []
    for label, scenario, sequence in scenarios():
        quiet = scenario.with_uncertainty(**NOISE_OFF)
        no_lag = quiet.with_uncertainty(lowpass_time_constant_s=0.0)
        ours = simulate(quiet, sequence, 1, np.random.default_rng(0))
        plan = command_plan(quiet, sequence)
        for k, name in enumerate(quiet.candidate_names):
            flown = simulate_basilisk(quiet, sequence, k, np.random.default_rng(0))
            flown_no_lag = simulate_basilisk(no_lag, sequence, k, np.random.default_rng(0))
            fine = simulate_basilisk(quiet, sequence, k, np.random.default_rng(0), hub_step_s=0.002)
            truth = reference(quiet, sequence, k, ours.time_s)
            mine = ours.omega_true[k, 0]
            rows.append(
                {
                    "scenario": label,
                    "candidate": name,
                    "peak_rate_rad_s": float(np.abs(mine).max()),
                    "basilisk_vs_ours": float(np.abs(flown.omega_true - mine).max()),
                    "ours_vs_reference": float(np.abs(mine - truth).max()),
                    "basilisk_vs_reference": float(np.abs(flown.omega_true - truth).max()),
                    "basilisk_no_lag_vs_ours": float(np.abs(flown_no_lag.omega_true - mine).max()),
                    "attitude_change_deg": plan.attitude_change_deg[k],
                    "attitude_plan_vs_basilisk_deg": _attitude_apart_deg(
                        plan.attitude_quaternion[k], fine.attitude_mrp[-1]
                    ),
                    "attitude_plan_vs_basilisk_own_step_deg": _attitude_apart_deg(
                        plan.attitude_quaternion[k], flown.attitude_mrp[-1]
                    ),
                }
            )
    return rows


def agreement_same_draws(n_seeds: int) -> list[dict[str, Any]]:
    rows = []
    for label, scenario, sequence in scenarios():
        if label == "paper":
            scenario = scenario.with_uncertainty(
                thrust_scale_sigma=0.02, initial_rate_sigma_rad_s=5e-3, gyro_bias_sigma_rad_s=2e-3
            )
        worst, peak = 0.0, 0.0
        for seed in range(n_seeds):
            ours = simulate(scenario, sequence, 1, np.random.default_rng(seed))
            for k in range(scenario.n_candidates):
                flown = simulate_basilisk(scenario, sequence, k, np.random.default_rng(seed))
                worst = max(worst, float(np.abs(flown.omega_true - ours.omega_true[k, 0]).max()))
                peak = max(peak, float(np.abs(ours.omega_true[k, 0]).max()))
        rows.append(
            {
                "scenario": label,
                "series": n_seeds * scenario.n_candidates,
                "peak_rate_rad_s": peak,
                "basilisk_vs_ours": worst,
            }
        )
    return rows


def convergence() -> list[dict[str, Any]]:
    rows = []
    for label, scenario, sequence in scenarios():
        quiet = scenario.with_uncertainty(**NOISE_OFF)
        times = quiet.sample_times(len(sequence))
        truth = reference(quiet, sequence, 0, times)
        base = quiet.timing.integration_step_s
        for step in (base, 0.01, 0.002):
            flown = simulate_basilisk(quiet, sequence, 0, np.random.default_rng(0), hub_step_s=step)
            timing = {**quiet.timing.model_dump(), "integration_step_s": step}
            fine = Scenario.model_validate({**quiet.model_dump(), "timing": timing})
            ours = simulate(fine, sequence, 1, np.random.default_rng(0)).omega_true[0, 0]
            rows.append(
                {
                    "scenario": label,
                    "step_s": step,
                    "ours_vs_reference": float(np.abs(ours - truth).max()),
                    "basilisk_vs_reference": float(np.abs(flown.omega_true - truth).max()),
                }
            )
    return rows


def noise_statistics(seconds: int) -> list[dict[str, Any]]:
    sigma, bias = 1e-3, np.array([5e-3, -3e-3, 2e-3])
    quiet = Scenario.paper().with_uncertainty(**NOISE_OFF)
    rows = []
    for rate, duration in ((20, seconds), (100, seconds), (1000, max(1, seconds // 10))):
        start = time.perf_counter()
        flown = simulate_basilisk(
            quiet,
            [[0] * 6] * duration,
            0,
            np.random.default_rng(rate),
            sample_rate_hz=rate,
            gyro_noise_sigma_rad_s=sigma,
            gyro_bias_rad_s=bias,
            initial_rate_rad_s=(0.01, -0.02, 0.005),
        )
        elapsed = time.perf_counter() - start
        error = flown.omega_measured - flown.omega_true
        centred = error - error.mean(axis=0)
        lag1 = (centred[:-1] * centred[1:]).sum(axis=0) / (centred**2).sum(axis=0)
        rows.append(
            {
                "rate_hz": rate,
                "samples": len(error),
                "bias_asked": bias.tolist(),
                "mean": error.mean(axis=0).tolist(),
                "sigma_asked": sigma,
                "std": error.std(axis=0, ddof=1).tolist(),
                "lag1_autocorrelation": lag1.tolist(),
                "excess_kurtosis": stats.kurtosis(error, axis=0).tolist(),
                "run_s": elapsed,
            }
        )
    return rows


def timing(repeats: int) -> list[dict[str, Any]]:
    rows = []
    for label, scenario, sequence in scenarios():
        k = scenario.n_candidates

        def ours_batched(sc: Scenario = scenario, seq: Any = sequence) -> Any:
            return simulate(sc, seq, 20, np.random.default_rng(0))

        def ours_single(sc: Scenario = scenario, seq: Any = sequence) -> Any:
            return simulate(sc, seq, 1, np.random.default_rng(0))

        best, _, _ = best_of(ours_batched, repeats)
        rows.append(
            {
                "scenario": label,
                "engine": "ours, batched (20 per candidate)",
                "rate_hz": scenario.timing.sample_rate_hz,
                "s_per_series": best / (20 * k),
            }
        )
        best, _, _ = best_of(ours_single, repeats)
        rows.append(
            {
                "scenario": label,
                "engine": "ours, 1 per candidate",
                "rate_hz": scenario.timing.sample_rate_hz,
                "s_per_series": best / k,
            }
        )
        for rate in (None, 200, 1000):

            def flown(sc: Scenario = scenario, seq: Any = sequence, r: Any = rate) -> Any:
                return simulate_basilisk(sc, seq, 0, np.random.default_rng(0), sample_rate_hz=r)

            best, _, result = best_of(flown, repeats)
            rows.append(
                {
                    "scenario": label,
                    "engine": f"basilisk (hub {result.hub_step_s:g} s)",
                    "rate_hz": result.sample_rate_hz,
                    "s_per_series": best,
                }
            )
    return rows


def identification(n: int, seed: int) -> list[dict[str, Any]]:
    rows = []
    for label, scenario, sequence in scenarios():
        kinds: list[tuple[str, int, dict[str, Any]]] = [
            ("nearest-centroid", 20, {"metric": "euclidean"}),
            ("marginal-likelihood", 100, {}),
        ]
        ours_X, bsk_X, y = [], [], []
        for i in range(n):
            ours = simulate(scenario, sequence, 1, np.random.default_rng(seed + 1000 + i))
            for k in range(scenario.n_candidates):
                flown = simulate_basilisk(
                    scenario, sequence, k, np.random.default_rng(seed + 1000 + i)
                )
                bsk_X.append(flown.omega_measured)
                ours_X.append(ours.omega_measured[k, 0])
                y.append(k)
        labels = np.array(y)
        for kind, realisations, options in kinds:
            model = train_classifier(
                scenario, sequence, realisations, np.random.default_rng(seed), kind=kind, **options
            )
            rows.append(
                {
                    "scenario": label,
                    "classifier": kind,
                    "series": len(labels),
                    "accuracy_ours": float(np.mean(model.predict(np.array(ours_X)) == labels)),
                    "accuracy_basilisk": float(np.mean(model.predict(np.array(bsk_X)) == labels)),
                }
            )
    return rows


def import_seconds() -> float:
    """Seconds a fresh interpreter takes to import the Basilisk modules the engine uses."""
    code = (
        "import time; t = time.perf_counter(); "
        "from Basilisk.architecture import messaging, sysModel; "
        "from Basilisk.simulation import extForceTorque, imuSensor, spacecraft; "
        "from Basilisk.utilities import SimulationBaseClass; "
        "print(time.perf_counter() - t)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--seeds", type=int, default=5, help="seeds of the process-noise-on comparison"
    )
    parser.add_argument(
        "--noise-seconds",
        type=int,
        default=600,
        help="length of the quiet runs of the noise check (1 kHz: a tenth)",
    )
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats (best kept)")
    parser.add_argument(
        "--identify",
        type=int,
        default=0,
        metavar="N",
        help="also test classifiers on N Basilisk series per candidate",
    )
    args = parser.parse_args()
    if not basilisk_available():
        raise SystemExit('Basilisk is not installed: pip install "inertia-id[basilisk]"')
    print_header("Basilisk against our simulator", args)
    seconds = import_seconds()
    print(f"bsk {basilisk_version()}; {seconds:.2f} s to import its modules (fresh process)\n")

    figures: dict[str, Any] = {"bsk": basilisk_version(), "import_s": seconds}
    rows = figures["noise_off"] = agreement_noise_off()
    print_table(
        [
            "scenario",
            "candidate",
            "peak |w|",
            "bsk-ours",
            "ours-ref",
            "bsk-ref",
            "bsk no lag-ours",
            "turn deg",
            "plan-bsk 2ms deg",
            "plan-bsk deg",
        ],
        [
            [
                r["scenario"],
                r["candidate"],
                r["peak_rate_rad_s"],
                r["basilisk_vs_ours"],
                r["ours_vs_reference"],
                r["basilisk_vs_reference"],
                f"{r['basilisk_no_lag_vs_ours']:.2e}",
                f"{r['attitude_change_deg']:.3f}",
                f"{r['attitude_plan_vs_basilisk_deg']:.1e}",
                f"{r['attitude_plan_vs_basilisk_own_step_deg']:.1e}",
            ]
            for r in rows
        ],
        "1. Noise off: max |delta omega| over the series, rad/s (ref: DOP853, exact lag);"
        " the plan's attitude change at the end, and its angle from Basilisk's sigma_BN"
        " (on a 2 ms step, converged, and on the scenario's step)",
    )
    rows = figures["same_draws"] = agreement_same_draws(args.seeds)
    print_table(
        ["scenario", "series", "peak |w|", "bsk-ours"],
        [[r["scenario"], r["series"], r["peak_rate_rad_s"], r["basilisk_vs_ours"]] for r in rows],
        "2. Process noise on, same draws: max |delta omega_true|, rad/s",
    )
    rows = figures["convergence"] = convergence()
    print_table(
        ["scenario", "step s", "ours-ref", "bsk-ref"],
        [
            [r["scenario"], r["step_s"], r["ours_vs_reference"], r["basilisk_vs_reference"]]
            for r in rows
        ],
        "3. Against the step (first candidate, noise off): max |delta omega|, rad/s",
    )
    rows = figures["noise"] = noise_statistics(args.noise_seconds)
    print_table(
        [
            "rate Hz",
            "samples",
            "mean - bias (x,y,z)",
            "std / sigma (x,y,z)",
            "lag-1 r",
            "excess kurtosis",
            "run s",
        ],
        [
            [
                r["rate_hz"],
                r["samples"],
                " ".join(f"{m - b:+.1e}" for m, b in zip(r["mean"], r["bias_asked"], strict=True)),
                " ".join(f"{s / r['sigma_asked']:.4f}" for s in r["std"]),
                " ".join(f"{c:+.3f}" for c in r["lag1_autocorrelation"]),
                " ".join(f"{c:+.3f}" for c in r["excess_kurtosis"]),
                r["run_s"],
            ]
            for r in rows
        ],
        "4. IMU noise on a quiet run: sigma 1e-3 rad/s, bias (5, -3, 2)e-3 rad/s asked",
    )
    rows = figures["timing"] = timing(args.repeats)
    print_table(
        ["scenario", "engine", "rate Hz", "ms per series"],
        [[r["scenario"], r["engine"], r["rate_hz"], r["s_per_series"] * 1e3] for r in rows],
        f"5. Time per simulated series (best of {args.repeats})",
    )
    if args.identify:
        rows = figures["identification"] = identification(args.identify, args.seed)
        print_table(
            ["scenario", "classifier", "series", "accuracy, ours", "accuracy, basilisk"],
            [
                [
                    r["scenario"],
                    r["classifier"],
                    r["series"],
                    r["accuracy_ours"],
                    r["accuracy_basilisk"],
                ]
                for r in rows
            ],
            "6. Trained on our simulator at 1x noise; tested on the same draws flown by each",
        )
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
