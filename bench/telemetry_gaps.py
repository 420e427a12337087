"""Telemetry with a dropout: accuracy of the default classifier on passes with a hole
against the same passes without one.

The paper-in-orbit preset (initial rates and gyro biases drawn) flown with the paper's
hand-designed step ``[4, 4, 4, 0, 0, 0]`` repeated ``--steps`` times (12 s by default:
a 5 s hole must leave half the sequence), the default classifier (marginal likelihood,
its default realisations) trained at 1x noise. Test series: ``--series`` per candidate
at ``--process`` times the process noise, sent at ``--rate`` Hz (every n-th sample of
the 20 Hz simulation), from the sequence start (no telemetry before it). Each series is
judged whole, and with each ``--holes`` length lost (every sample strictly inside the
hole), the hole starting at one of ``--hole-starts`` in turn; ``identify`` judges it on
the grid times its samples cover (the exact Gaussian marginal).

Per row: accuracy of the most probable candidate (with its 95 % Wilson interval), the
fraction "identified" at 0.99 and the errors among them, genuine series called matches
none (false alarms), and the mean part of the sequence covered.

Run: python bench/telemetry_gaps.py [--series 20] [--holes 0.5,2,5] [--process 6]
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, float_list, print_header, print_table, write_json

from inertia_id.classifiers.registry import default_realisations, train_classifier
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.sweep import wilson_interval
from inertia_id.evaluation.telemetry import Telemetry
from inertia_id.physics.presets import preset
from inertia_id.physics.simulate import simulate


def _telemetry(t: np.ndarray, omega: np.ndarray, hole: tuple[float, float] | None) -> Telemetry:
    keep = np.ones(len(t), dtype=bool)
    if hole is not None:
        keep = ~((t > hole[0] + 1e-9) & (t < hole[1] - 1e-9))
    return Telemetry(time_s=t[keep].tolist(), omega_rad_s=omega[keep].tolist())


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=12, help="steps of 1 s in the sequence")
    parser.add_argument("--series", type=int, default=20, help="test series per candidate")
    parser.add_argument("--process", type=float, default=6.0, help="process noise multiple")
    parser.add_argument("--rate", type=float, default=10.0, help="telemetry rate, Hz")
    parser.add_argument("--holes", type=float_list, default=[0.5, 2.0, 5.0], help="hole lengths, s")
    parser.add_argument(
        "--hole-starts", type=float_list, default=[1.0, 3.5, 6.0], help="hole starts, s"
    )
    parser.add_argument("--realisations", type=int, default=None, help="training realisations")
    args = parser.parse_args()
    print_header("Telemetry with a hole: accuracy against the same series whole", args)
    rng = np.random.default_rng(args.seed)
    scenario = preset("paper-in-orbit")
    sequence = GOOD_SEQUENCE[:1] * args.steps
    realisations = args.realisations or default_realisations("marginal-likelihood")
    started = time.perf_counter()
    classifier: Any = train_classifier(scenario, sequence, realisations, rng)
    print(
        f"trained {classifier.kind} on {realisations} realisations in "
        f"{time.perf_counter() - started:.1f} s",
        flush=True,
    )
    result = simulate(scenario, sequence, args.series, rng, process_noise_scale=args.process)
    every = round(scenario.timing.sample_rate_hz / args.rate)
    t = np.asarray(result.time_s)[every - 1 :: every]
    omega = result.omega_measured[:, :, every - 1 :: every]
    cases: list[tuple[str, float | None]] = [("none", None), *((f"{h:g} s", h) for h in args.holes)]
    rows, figures = [], {}
    for name, length in cases:
        right = identified = wrong = flagged = refused = 0
        covered: list[float] = []
        started = time.perf_counter()
        for k in range(scenario.n_candidates):
            for i in range(args.series):
                hole = None
                if length is not None:
                    begin = args.hole_starts[(k * args.series + i) % len(args.hole_starts)]
                    hole = (begin, begin + length)
                try:
                    verdict = identify(classifier, _telemetry(t, omega[k, i], hole))
                except ValueError as exc:
                    refused += 1
                    print(f"  refused ({name}): {exc}")
                    continue
                right += verdict.candidate_index == k
                named = verdict.status == "identified"
                identified += named
                wrong += named and verdict.candidate_index != k
                flagged += verdict.matches_none
                covered.append(verdict.sequence_covered_fraction)
        total = scenario.n_candidates * args.series
        low, high = wilson_interval(right, total)
        seconds = time.perf_counter() - started
        figures[name] = {
            "series": total,
            "accuracy": right / total,
            "accuracy_interval": [low, high],
            "identified": identified / total,
            "errors_among_identified": wrong / max(identified, 1),
            "false_alarms": flagged / total,
            "refused": refused,
            "mean_covered_fraction": float(np.mean(covered)) if covered else None,
            "seconds": seconds,
        }
        rows.append(
            [
                name,
                total,
                right / total,
                f"{low:.3f}-{high:.3f}",
                identified / total,
                wrong / max(identified, 1),
                flagged / total,
                refused,
                float(np.mean(covered)) if covered else None,
                seconds,
            ]
        )
    print_table(
        [
            "hole",
            "series",
            "accuracy",
            "95% interval",
            "identified",
            "wrong|identified",
            "false alarms",
            "refused",
            "covered",
            "s",
        ],
        rows,
        title=f"{args.rate:g} Hz telemetry, {args.process:g}x process noise, "
        f"{args.steps}-step sequence",
    )
    write_json(args.json, args, {"rows": figures})


if __name__ == "__main__":
    main()
