"""Noise calibration of the paper preset at 1x noise: random sequences vs the good one.

For --n-random random 4-step sequences (level indices uniform in 0..M-1 per thruster
per step) a classifier is trained (inertia_id.train, K candidates x --realisations
series at 1x noise) and its F1 recorded; then the hand-designed sequence
[[4, 4, 4, 0, 0, 0]] * 4 over --good-seeds independent seeds. Both are repeated with
duty jitter off on the first --n-jitter-off random sequences (same sequences, same
seeds: every other noise draw is identical) to show that jitter is what limits F1.

Run: python bench/calibration.py [--metric dtw] [--n-random 20] [--json PATH]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    add_realisations,
    add_steps,
    base_parser,
    begin,
    positive_int,
    print_table,
    random_sequence,
    sequence_text,
    summary,
    timed,
    warm_up_numba,
    write_json,
)

from inertia_id import METRICS, Scenario, train

UNITS = {
    "duty_jitter_sigma": "fraction of full duty",
    "lowpass_time_constant_s": "s",
    "thrust_scale_sigma": "relative",
    "disturbance_torque_sigma_nm": "N m",
    "disturbance_interval_s": "s",
    "gyro_noise_sigma_rad_s": "rad/s",
    "gyro_bias_rad_s": "rad/s",
    "gyro_bias_sigma_rad_s": "rad/s",
    "initial_rate_sigma_rad_s": "rad/s",
    "step_duration_s": "s",
    "integration_step_s": "s",
    "sample_rate_hz": "Hz",
}


def run_one(
    scenario: Scenario, sequence: np.ndarray, seed: tuple[int, ...], args: Any
) -> dict[str, Any]:
    rng = np.random.default_rng(list(seed))
    seconds, model = timed(
        lambda: train(scenario, sequence, args.realisations, rng, metric=args.metric)
    )
    return {
        "sequence": np.asarray(sequence).tolist(),
        "rng_seed": list(seed),
        "f1": model.f1_,
        "accuracy": model.accuracy_,
        "train_s": seconds,
        "impulse_nms": scenario.impulse_nms(sequence),
    }


def show(record: dict[str, Any], label: str) -> None:
    print(
        f"  {label:22s} {sequence_text(record['sequence'])}  F1 {record['f1']:.3f}  "
        f"acc {record['accuracy']:.3f}  ({record['train_s']:.1f} s)",
        flush=True,
    )


def run_random(scenario: Scenario, sequences: list[np.ndarray], args: Any) -> list[dict[str, Any]]:
    """Random sequence i trained on seed (seed, 0, i): the same seed with jitter on and
    off, so that every other noise draw is identical."""
    records = []
    for i, seq in enumerate(sequences):
        records.append(run_one(scenario, seq, (args.seed, 0, i), args))
        show(records[-1], f"random #{i}")
    return records


def run_good(scenario: Scenario, good: np.ndarray, args: Any) -> list[dict[str, Any]]:
    """The hand-designed sequence on --good-seeds seeds (seed, 1, j)."""
    records = []
    for j in range(args.good_seeds):
        records.append(run_one(scenario, good, (args.seed, 1, j), args))
        show(records[-1], f"good, seed #{j}")
    return records


# The columns of a table of training runs, after the run's own label.
RUN_COLUMNS = ["sequence", "impulse N m s", "F1", "accuracy", "train s"]


def run_cells(record: dict[str, Any]) -> list[Any]:
    return [
        sequence_text(record["sequence"]),
        record["impulse_nms"],
        record["f1"],
        record["accuracy"],
        record["train_s"],
    ]


def jitter_cells(label: str, on: dict[str, Any], off: dict[str, Any]) -> list[Any]:
    """One case with duty jitter on and off, and the change in F1."""
    return [
        label,
        sequence_text(on["sequence"]),
        on["f1"],
        off["f1"],
        f"{off['f1'] - on['f1']:+.3f}",
    ]


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--metric",
        choices=METRICS,
        default="dtw",
        help="classifier metric passed to inertia_id.train",
    )
    parser.add_argument(
        "--n-random", type=positive_int, default=20, help="random sequences trained at 1x noise"
    )
    parser.add_argument(
        "--good-seeds",
        type=positive_int,
        default=5,
        help="independent seeds for the hand-designed sequence",
    )
    parser.add_argument(
        "--n-jitter-off",
        type=int,
        default=5,
        help="random sequences repeated with duty jitter off (0 skips the jitter-off part)",
    )
    add_realisations(parser)
    add_steps(parser)
    args = begin(parser, "Noise calibration of the paper preset at 1x noise")

    scenario = Scenario.paper()
    no_jitter = scenario.with_uncertainty(duty_jitter_sigma=0.0)
    settings = {**scenario.uncertainty.model_dump(), **scenario.timing.model_dump()}
    timing = scenario.timing
    rows = [[name, str(value), UNITS.get(name, "")] for name, value in settings.items()]
    rows += [
        ["substeps_per_step (derived)", str(timing.substeps_per_step), "RK4 steps"],
        ["samples_per_step (derived)", str(timing.samples_per_step), "samples"],
    ]
    print_table(
        ["setting (1x noise)", "value", "unit"],
        rows,
        title=f"Scenario '{scenario.name}': {scenario.n_candidates} candidates, "
        f"{scenario.n_thrusters} thrusters, levels {scenario.thrusters.levels}",
    )
    print(
        f"metric {args.metric}; {scenario.n_candidates} x {args.realisations} series per "
        f"train; F1 = macro F1 of the training clustering under the best matching"
    )
    print(
        f"numba warm-up (tiny fits, so train times exclude JIT compilation): "
        f"{warm_up_numba():.1f} s"
    )
    print(flush=True)

    seq_rng = np.random.default_rng(args.seed)
    sequences = [
        random_sequence(seq_rng, args.steps, scenario.n_thrusters, scenario.n_levels)
        for _ in range(args.n_random)
    ]
    good = np.asarray(GOOD_SEQUENCE, dtype=int)

    print("jitter on (1x):")
    random_on = run_random(scenario, sequences, args)
    good_on = run_good(scenario, good, args)

    random_off: list[dict[str, Any]] = []
    good_off: list[dict[str, Any]] = []
    n_off = min(max(args.n_jitter_off, 0), args.n_random)
    if n_off:
        print("duty jitter off (duty_jitter_sigma = 0, all other noise identical):")
        random_off = run_random(no_jitter, sequences[:n_off], args)
        good_off = run_good(no_jitter, good, args)
    print()

    print_table(
        ["#", *RUN_COLUMNS],
        [[i, *run_cells(r)] for i, r in enumerate(random_on)],
        title=f"Random {args.steps}-step sequences, 1x noise (jitter on), metric {args.metric}",
    )
    print_table(
        ["seed #", *RUN_COLUMNS],
        [[j, *run_cells(r)] for j, r in enumerate(good_on)],
        title="Hand-designed sequence [[4,4,4,0,0,0]]*4, 1x noise (jitter on)",
    )
    if n_off:
        print_table(
            ["case", "sequence", "F1 jitter on", "F1 jitter off", "change"],
            [
                jitter_cells(f"random #{i}", on, off)
                for i, (on, off) in enumerate(zip(random_on, random_off, strict=False))
            ]
            + [
                jitter_cells(f"good, seed #{j}", on, off)
                for j, (on, off) in enumerate(zip(good_on, good_off, strict=False))
            ],
            title="Duty jitter on vs off (same sequences, same seeds)",
        )

    groups = [("random sequences", "on", random_on), ("good sequence", "on", good_on)]
    if n_off:
        groups += [
            (f"random sequences #0-{n_off - 1}", "on", random_on[:n_off]),
            (f"random sequences #0-{n_off - 1}", "off", random_off),
            ("good sequence", "off", good_off),
        ]
    summaries = []
    for name, jitter, records in groups:
        stats = summary([r["f1"] for r in records])
        summaries.append(
            {
                "group": name,
                "duty_jitter": jitter,
                "runs": len(records),
                "f1": stats,
                "train_s_median": summary([r["train_s"] for r in records])["median"],
            }
        )
    print_table(
        ["group", "duty jitter", "runs", "F1 median", "F1 min", "F1 max", "median train s"],
        [
            [
                s["group"],
                s["duty_jitter"],
                s["runs"],
                s["f1"]["median"],
                s["f1"]["min"],
                s["f1"]["max"],
                s["train_s_median"],
            ]
            for s in summaries
        ],
        title="Summary",
    )

    write_json(
        args.json,
        args,
        {
            "benchmark": "calibration",
            "scenario": scenario.name,
            "settings_1x": settings,
            "random_jitter_on": random_on,
            "good_jitter_on": good_on,
            "random_jitter_off": random_off,
            "good_jitter_off": good_off,
            "summary": summaries,
        },
    )


if __name__ == "__main__":
    main()
