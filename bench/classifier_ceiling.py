"""How close is each classifier to the ceiling, on the searched and the hand-designed sequences?

Data: the paper preset. For each sequence (one given with --searched, e.g. the best a
search found, and the two baselines: the positive-axis thrusters at full duty every
step, and one axis at a time), every classifier kind is trained at 1x noise on the same
--n-train realisations per candidate, then scored on the same fresh test series (--n-test
per point, spread over the 5 candidates) at process-noise and measurement-noise
multiples 1, 2, 4, 6, 8 (the other noise at 1x):

- clustering dtw: the paper's method (time-series k-means, DTW, InertiaClassifier);
- marginal likelihood: the shipped default, the likelihood marginalised over the
  unknown noise level (trained on 100 realisations per candidate, its default);
- clustering euclidean, nearest-centroid and 1-NN (dtw, euclidean), MiniRocket;
- likelihood (1x): the Gaussian matched filter trained at 1x like the others;
- least squares: integral-form inertia estimate, nearest candidate;
- the ceiling (:mod:`inertia_id.evaluation.ceiling`): per-candidate Gaussians fitted at
  each point's own noise level on --ceiling-realisations per candidate (it knows the
  simulator, noise included), what the others are measured against; a classifier above
  its Wilson interval's upper end is counted and printed (it would mean the ceiling is
  none; earlier versions of this bench measured against a pooled-covariance "limit"
  that the default classifier beat).

Each sequence's row also gives its fuel (commanded impulse), mean final rate, and the
clustering F1 on 5 fresh draws (what a search reports as its fresh F1).

Run: python bench/classifier_ceiling.py [--searched "[[...], ...]"] [--n-test 500]
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np
from _common import (
    add_sweep_sizes,
    base_parser,
    begin,
    print_table,
    sequence_text,
    warm_up_numba,
    write_json,
)

from inertia_id import Scenario, run_sweep, simulate, train_classifier
from inertia_id.classifiers.registry import default_realisations, parse_spec
from inertia_id.physics.sequences import axis_in_turn, hand_designed
from inertia_id.search import ScorerSettings, evaluate_sequence

CLASSIFIERS = [
    "clustering:dtw",
    "marginal-likelihood",
    "clustering:euclidean",
    "nearest-centroid:dtw",
    "nearest-centroid:euclidean",
    "1nn:dtw",
    "1nn:euclidean",
    "minirocket",
    "likelihood",
    "least-squares",
]
# "likelihood" above is trained at 1x like the rest; the ceiling is fitted at each point.
MULTIPLES = (1, 2, 4, 6, 8)
# The best sequence of the documented PPO run (README, "The search").
PPO_SEQUENCE = [[2, 0, 0, 3, 4, 4], [0, 0, 0, 4, 4, 4], [4, 2, 2, 2, 3, 0], [0, 0, 0, 2, 1, 1]]


def sequence_row(scenario: Scenario, name: str, sequence: np.ndarray, seed: int) -> list[Any]:
    fresh = evaluate_sequence(scenario, sequence, ScorerSettings(), seed=seed + 1000, n_draws=5)
    result = simulate(scenario, sequence, 20, np.random.default_rng(seed))
    return [
        name,
        len(sequence),
        f"{result.impulse_nms:.1f}",
        f"{result.mean_final_rate_rad_s:.3f}",
        f"{np.mean(fresh.f1):.3f}",
        f"{np.min(fresh.f1):.3f}",
        sequence_text(sequence),
    ]


def accuracy_tables(
    scenario: Scenario, sequence: np.ndarray, args: argparse.Namespace
) -> dict[str, Any]:
    models = {}
    fit_s = {}
    for spec in CLASSIFIERS:
        kind, options = parse_spec(spec)
        started = time.perf_counter()
        # Every kind sees the same training draw (the marginal likelihood a larger one).
        n_train = max(args.n_train, default_realisations(kind))
        models[spec] = train_classifier(
            scenario, sequence, n_train, np.random.default_rng(args.seed), kind=kind, **options
        )
        fit_s[spec] = time.perf_counter() - started
    main, *rest = CLASSIFIERS
    sweep = run_sweep(
        models[main],
        others={spec: models[spec] for spec in rest},
        multiples=MULTIPLES,
        n_test=args.n_test,
        ceiling_realisations=args.ceiling_realisations,
        seed=args.seed + 1,
    )
    tables: dict[str, Any] = {"fit_s": fit_s}
    for noise in ("process", "measurement"):
        rows = []
        for spec in CLASSIFIERS:
            points = sweep.curve(noise, None if spec == main else spec)
            rows.append([spec, *(f"{p.accuracy:.3f}" for p in points), f"{fit_s[spec]:.2f}"])
        ceiling = [p for p in sweep.ceiling if p.noise == noise]
        rows.append(["the ceiling", *(f"{p.accuracy:.3f}" for p in ceiling), "-"])
        gaps, above = {}, {}
        for spec in CLASSIFIERS:
            points = sweep.curve(noise, None if spec == main else spec)
            gaps[spec] = max(c.accuracy - p.accuracy for c, p in zip(ceiling, points, strict=True))
            above[spec] = [
                p.multiple for c, p in zip(ceiling, points, strict=True) if p.accuracy > c.ci_high
            ]
        tables[noise] = {
            "rows": rows,
            "largest_gap_to_ceiling": gaps,
            "above_ceiling_interval": above,
            "ceiling_covariance": sweep.ceiling_covariance,
        }
    half = max((p.ci_high - p.ci_low) / 2 for p in sweep.points)
    tables["largest_interval_half_width"] = half
    return tables


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--searched", default=json.dumps(PPO_SEQUENCE), help="JSON sequence")
    parser.add_argument("--searched-name", default="PPO (README run)")
    parser.add_argument(
        "--n-train", type=int, default=20, help="training realisations per candidate"
    )
    add_sweep_sizes(parser)
    args = begin(parser, "Classifiers against the ceiling, paper preset")
    warm_up_numba()
    scenario = Scenario.paper()
    sequences = {
        args.searched_name: scenario.check_sequence(json.loads(args.searched)),
        "hand-designed": hand_designed(scenario, 4),
        "axis-in-turn": axis_in_turn(scenario, 4),
    }
    print_table(
        ["sequence", "steps", "fuel N m s", "final rate rad/s", "fresh F1 mean", "min", "levels"],
        [sequence_row(scenario, name, seq, args.seed) for name, seq in sequences.items()],
        title="Sequences (fresh F1: clustering dtw on 5 fresh draws, independent seed)",
    )
    figures: dict[str, Any] = {}
    for name, sequence in sequences.items():
        tables = accuracy_tables(scenario, sequence, args)
        figures[name] = tables
        for noise in ("process", "measurement"):
            print_table(
                ["classifier", *(f"x{m}" for m in MULTIPLES), "fit s"],
                tables[noise]["rows"],
                title=f"{name}: accuracy vs {noise}-noise multiple "
                f"({args.n_test} test series per point; 95 % half-width up to "
                f"{tables['largest_interval_half_width']:.3f})",
            )
            gaps = tables[noise]["largest_gap_to_ceiling"]
            print(
                "largest shortfall from the ceiling: "
                + ", ".join(f"{spec} {gap:+.3f}" for spec, gap in gaps.items())
            )
            above = {s: m for s, m in tables[noise]["above_ceiling_interval"].items() if m}
            print(
                "above the ceiling's Wilson upper end: "
                + (
                    ", ".join(f"{spec} at x{m}" for spec, m in above.items())
                    if above
                    else "no classifier at any multiple"
                )
            )
            print(flush=True)
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
