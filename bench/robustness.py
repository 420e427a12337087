"""The confounders a GNC engineer asks about: jitter, thrust-scale error, gyro bias, and
bodies that are none of the candidates.

Data: the paper preset and the hand-designed sequence (the positive-axis thrusters at full
duty, 4 steps). A classifier of each --kinds is trained at 1x on 20 realisations per
candidate; each source of error is then scaled by 0, 1, 2, 4, 8 (the others at 1x; a source
the preset leaves at zero scales a reference level: thrust-scale sigma 2 %, gyro bias sigma
1e-3 rad/s) and accuracy measured on --n-test fresh series per point, with the ceiling
(per-candidate Gaussians fitted at each point's noise on --ceiling-realisations per
candidate, :mod:`inertia_id.evaluation.ceiling`) and least squares on the same series.
Then bodies off the candidates: the first candidate's inertia scaled by 0.6..1.4, and
bodies between the two closest candidates: how often does identify's verdict say "matches
none", name the right or a wrong candidate, or stay ambiguous?

Run: python bench/robustness.py [--kinds nearest-centroid:euclidean,clustering:dtw]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _common import add_sweep_sizes, base_parser, begin, print_table, warm_up_numba, write_json

from inertia_id import Scenario, run_inertia_sweep, run_sweep, train_classifier
from inertia_id.classifiers.registry import parse_spec
from inertia_id.physics.sequences import hand_designed

SOURCES = ("jitter", "thrust_scale", "gyro_bias")
MULTIPLES = (0, 1, 2, 4, 8)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="clustering:dtw,nearest-centroid:euclidean")
    add_sweep_sizes(parser)
    args = begin(parser, "Robustness to confounders, paper preset, hand-designed sequence")
    warm_up_numba()
    scenario = Scenario.paper()
    sequence = hand_designed(scenario, 4)
    figures: dict[str, Any] = {}
    least_squares = train_classifier(
        scenario, sequence, 20, np.random.default_rng(args.seed), kind="least-squares"
    )
    for spec in [s for s in args.kinds.split(",") if s]:
        kind, options = parse_spec(spec)
        model = train_classifier(
            scenario, sequence, 20, np.random.default_rng(args.seed), kind=kind, **options
        )
        sweep = run_sweep(
            model,
            others={"least-squares": least_squares},
            noises=SOURCES,
            multiples=MULTIPLES,
            n_test=args.n_test,
            ceiling_realisations=args.ceiling_realisations,
            seed=args.seed + 1,
        )
        rows = []
        for noise in SOURCES:
            mine = sweep.curve(noise)
            ls = sweep.curve(noise, "least-squares")
            ceiling = [p for p in sweep.ceiling if p.noise == noise]
            for a, b, c in zip(mine, ls, ceiling, strict=True):
                rows.append(
                    [
                        noise,
                        f"x{a.multiple:g}",
                        f"{a.value:.3g} {sweep.units[noise]}",
                        f"{a.accuracy:.3f}",
                        f"[{a.ci_low:.3f}, {a.ci_high:.3f}]",
                        f"{b.accuracy:.3f}",
                        f"{c.accuracy:.3f} [{c.ci_low:.3f}, {c.ci_high:.3f}]",
                    ]
                )
        print_table(
            ["source", "multiple", "level", spec, "95 % interval", "least squares", "ceiling"],
            rows,
            title=f"{spec}: accuracy as each confounder grows ({args.n_test} series per point)",
        )
        inertia = run_inertia_sweep(model, n_test=100, seed=args.seed + 2)
        names = inertia.candidate_names
        print_table(
            [
                "body",
                "parameter",
                "matches none",
                "95 % interval",
                "identified right",
                "identified wrong",
                "ambiguous",
                "most probable candidates",
            ],
            [
                [
                    p.body,
                    f"{p.parameter:g}",
                    f"{p.matches_none_rate:.2f}",
                    f"[{p.ci_low:.2f}, {p.ci_high:.2f}]",
                    f"{p.identified_right_rate:.2f}",
                    f"{p.identified_wrong_rate:.2f}",
                    f"{p.ambiguous_rate:.2f}",
                    ", ".join(f"{names[k]} {c}" for k, c in enumerate(p.predicted) if c),
                ]
                for p in inertia.points
            ],
            title=f"{spec}: bodies off the candidates (scaled: {names[inertia.base]} x "
            f"parameter; between: {names[inertia.pair[0]]} (0) to {names[inertia.pair[1]]} (1)), "
            "100 series each",
        )
        figures[spec] = {"sweep": sweep.model_dump(), "inertia": inertia.model_dump()}
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
