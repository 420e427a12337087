"""What the distance kinds pay for comparing series with each axis' mean removed.

The distance kinds (clustering, nearest centroid, 1-NN) remove each axis' mean before
they compare series, so that an initial rate or a gyro bias does not move a verdict. On
a sequence whose mean level carries the signal that costs accuracy where there is no
drift. Data: the paper preset (no initial rate, no bias) and --sequence; each kind
trained on 20 realisations per candidate (seed --seed) with the mean removed (as
shipped) and kept, both scored on the same --n-test series per candidate at 1x noise.

Run: python bench/offset_removal.py [--sequence "[[...]]"] [--n-test 100]
"""

from __future__ import annotations

import json

import numpy as np
from _common import base_parser, begin, print_table, write_json

from inertia_id import Scenario, simulate, train_classifier
from inertia_id.classifiers.registry import kind_class, parse_spec

# The best sequence of the documented PPO run (README, "The search").
PPO_SEQUENCE = [[2, 0, 0, 3, 4, 4], [0, 0, 0, 4, 4, 4], [4, 2, 2, 2, 3, 0], [0, 0, 0, 2, 1, 1]]
KINDS = ("clustering:dtw", "clustering:euclidean", "1nn:euclidean", "nearest-centroid:euclidean")


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--sequence", default=json.dumps(PPO_SEQUENCE), help="JSON sequence")
    parser.add_argument("--n-test", type=int, default=100, help="test series per candidate")
    args = begin(parser, "Distance kinds with and without each axis' mean removed")
    scenario = Scenario.paper()
    sequence = json.loads(args.sequence)
    X, y = simulate(
        scenario, sequence, args.n_test, np.random.default_rng(args.seed + 123)
    ).dataset()
    rows, figures = [], {}
    for spec in KINDS:
        kind, options = parse_spec(spec)
        cls = kind_class(kind)
        shipped = cls.REMOVES_OFFSET
        accuracy = {}
        try:
            for removes in (True, False):
                cls.REMOVES_OFFSET = removes  # the class's rule, read when a fit starts
                model = train_classifier(
                    scenario, sequence, 20, np.random.default_rng(args.seed), kind=kind, **options
                )
                accuracy[removes] = float((model.predict(X) == y).mean())
        finally:
            cls.REMOVES_OFFSET = shipped
        figures[spec] = {"mean_removed": accuracy[True], "mean_kept": accuracy[False]}
        rows.append([spec, f"{accuracy[True]:.3f}", f"{accuracy[False]:.3f}"])
    print_table(
        ["kind", "mean removed (shipped)", "mean kept"],
        rows,
        title=f"accuracy at 1x on {len(y)} series, sequence {sequence}",
    )
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
