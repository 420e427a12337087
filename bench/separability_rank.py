"""Does the separability score rank sequences as the clustering F1 does?

Draws ``--sequences`` (200) random 4-step sequences of the paper preset (every level
index uniform, per thruster and step) and scores each on the same noise draw (seed
``--seed``, ``--realisations`` per candidate) twice: the clustering F1 of the search's
scorer (``ScorerSettings`` defaults: DTW k-means, band 2, objective "f1") and the
separability score (:mod:`inertia_id.search.objectives`) of the very same simulated series,
in several variants: the search's default (shrinkage 1, noise margin 4) and the
Ledoit–Wolf covariance at margins 1 and 3, with and without the correction for the
noise of the estimated means. Printed: Spearman's rank correlation of each variant with
the F1 (95% interval by Fisher's z), and with the mean clustering F1 on
``--fresh-draws`` (2) independent draws; the rank correlation of the one-draw F1 with
that fresh F1 (the F1 of one draw is itself noisy: this says how much); how many
sequences each variant scores at 0.999 or more (hardly distinguishable at the top);
and the time of one score of each kind.

    python bench/separability_rank.py [--sequences 200] [--fresh-draws 2] [--json out.json]
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    add_length,
    add_realisations,
    base_parser,
    begin,
    positive_int,
    print_table,
    random_sequence,
    write_json,
)
from scipy.stats import spearmanr

from inertia_id import Scenario
from inertia_id.search import PrefixScorer, ScorerSettings, evaluate_sequence
from inertia_id.search.objectives import separability_score
from inertia_id.search.records import fresh_seed

BALANCED = [[1] * 6] * 4
DEFAULTS = ScorerSettings()
#: (name, keyword arguments of separability_score).
VARIANTS: list[tuple[str, dict[str, Any]]] = [
    (
        f"search default: shrinkage {DEFAULTS.separability_shrinkage:g}, "
        f"margin {DEFAULTS.separability_margin:g}",
        {
            "shrinkage": DEFAULTS.separability_shrinkage,
            "noise_margin": DEFAULTS.separability_margin,
        },
    ),
    ("shrinkage 1, margin 1", {"shrinkage": 1.0, "noise_margin": 1.0}),
    ("Ledoit-Wolf, margin 1", {"shrinkage": None, "noise_margin": 1.0}),
    ("Ledoit-Wolf, margin 3", {"shrinkage": None, "noise_margin": 3.0}),
    ("Ledoit-Wolf, margin 1, no debias", {"shrinkage": None, "noise_margin": 1.0, "debias": False}),
]


def spearman(x: list[float], y: list[float]) -> tuple[float, float, float]:
    """Spearman's rho with a 95% interval (Fisher's z, se = 1.03 / sqrt(n - 3))."""
    rho = float(spearmanr(x, y)[0])
    half = 1.96 * 1.03 / math.sqrt(len(x) - 3)
    z = math.atanh(max(min(rho, 0.999999), -0.999999))
    return rho, math.tanh(z - half), math.tanh(z + half)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--sequences", type=positive_int, default=200, help="random sequences")
    add_length(parser)
    add_realisations(parser)
    parser.add_argument(
        "--fresh-draws",
        type=int,
        default=2,
        help="independent draws for the fresh clustering F1 (0 = skip it)",
    )
    args = begin(parser, "Separability score against the clustering F1 (paper preset)")
    print(f"load average (1, 5, 15 min) at the start: {os.getloadavg()}")
    scenario = Scenario.paper()
    settings = ScorerSettings(n_realisations=args.realisations)
    rng = np.random.default_rng(args.seed)
    sequences = [
        random_sequence(rng, args.length, scenario.n_thrusters, scenario.n_levels)
        for _ in range(args.sequences)
    ]
    # numba's JIT compile of the DTW k-means, on other noise, before anything is timed.
    PrefixScorer(scenario, 1, settings, seed=args.seed + 1).score(GOOD_SEQUENCE[:1])

    scorer = PrefixScorer(scenario, args.length, settings, seed=args.seed)
    f1: list[float] = []
    scores: dict[str, list[float]] = {name: [] for name, _ in VARIANTS}
    f1_seconds = 0.0
    score_seconds = {name: 0.0 for name, _ in VARIANTS}
    for sequence in sequences:
        start = time.perf_counter()
        f1.append(scorer.score(sequence).f1)
        f1_seconds += time.perf_counter() - start
        omega = scorer.simulator.run(sequence, scorer.noise).omega_measured
        for name, options in VARIANTS:
            start = time.perf_counter()
            scores[name].append(separability_score(omega, **options))
            score_seconds[name] += time.perf_counter() - start
    fresh: list[float] = []
    if args.fresh_draws > 0:
        fresh = [
            evaluate_sequence(
                scenario, s, settings, seed=fresh_seed(args.seed), n_draws=args.fresh_draws
            ).f1_mean
            for s in sequences
        ]

    references = {}
    for label, sequence in (("good", GOOD_SEQUENCE), ("balanced", BALANCED)):
        omega = scorer.simulator.run(np.asarray(sequence), scorer.noise).omega_measured
        references[label] = {
            "f1": scorer.score(sequence).f1,
            **{name: separability_score(omega, **options) for name, options in VARIANTS},
        }

    rows = []
    figures: dict[str, Any] = {"variants": {}}
    for name, _ in VARIANTS:
        rho, low, high = spearman(scores[name], f1)
        row = [name, rho, f"[{low:.3f}, {high:.3f}]"]
        record: dict[str, Any] = {"spearman_f1": rho, "ci95": [low, high]}
        if fresh:
            rho_f, low_f, high_f = spearman(scores[name], fresh)
            row += [rho_f, f"[{low_f:.3f}, {high_f:.3f}]"]
            record.update(spearman_fresh_f1=rho_f, ci95_fresh=[low_f, high_f])
        at_one = sum(s >= 0.999 for s in scores[name])
        ms = 1e3 * score_seconds[name] / len(sequences)
        row += [
            at_one,
            float(np.median(scores[name])),
            references["good"][name],
            references["balanced"][name],
            ms,
        ]
        record.update(
            at_least_0999=at_one,
            median=float(np.median(scores[name])),
            good=references["good"][name],
            balanced=references["balanced"][name],
            ms_per_score=ms,
            scores=scores[name],
        )
        rows.append(row)
        figures["variants"][name] = record
    headers = ["separability variant", "rho vs F1", "95% CI"]
    if fresh:
        headers += [f"rho vs fresh F1 ({args.fresh_draws} draws)", "95% CI"]
    headers += ["# >= 0.999", "median", "good seq.", "balanced seq.", "ms per score"]
    print_table(
        headers,
        rows,
        title=f"Spearman rank correlation over {len(sequences)} random {args.length}-step "
        f"sequences (F1: ScorerSettings defaults, metric {settings.metric}, the same draw)",
    )
    ceiling = []
    if fresh:
        rho, low, high = spearman(f1, fresh)
        ceiling = [["F1 (search draw) vs fresh F1", rho, f"[{low:.3f}, {high:.3f}]"]]
        figures["f1_vs_fresh"] = {"spearman": rho, "ci95": [low, high], "fresh_f1": fresh}
        print_table(
            ["how noisy the F1 itself is", "rho", "95% CI"],
            ceiling,
            title="How noisy the F1 itself is: one draw's F1 against the fresh F1 of the "
            "same sequences",
        )
    f1_summary = f"{np.mean(f1):.3f} / {np.median(f1):.3f} / {np.max(f1):.3f}"
    references_f1 = f"{references['good']['f1']:.3f} / {references['balanced']['f1']:.3f}"
    print_table(
        ["figure", "value"],
        [
            ["clustering F1 mean / median / max", f1_summary],
            ["sequences at F1 = 1", sum(v >= 1.0 for v in f1)],
            ["good sequence F1 / balanced sequence F1", references_f1],
            [
                "ms per clustering F1 of a sequence (its prefixes simulated and clustered)",
                1e3 * f1_seconds / len(sequences),
            ],
        ],
        title="The clustering F1 of the same sequences",
    )
    print(f"load average (1, 5, 15 min) at the end: {os.getloadavg()}")
    write_json(
        args.json,
        args,
        {
            "benchmark": "separability_rank",
            "scorer_settings": settings.as_dict(),
            "sequences": [s.tolist() for s in sequences],
            "f1": f1,
            "references": references,
            **figures,
        },
    )


if __name__ == "__main__":
    main()
