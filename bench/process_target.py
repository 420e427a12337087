"""The default classifier's process component: shrunk towards the identity, or towards
the covariance the scenario's disturbance writes out?

Data: the paper preset; the hand-designed sequence (L = 4), fire-coast-brake (L = 8) and
the L = 8 Pareto front's best member of the README (fire 2 s, coast 2 s, brake x, then
y and z). For each, the marginal-likelihood classifier is trained twice on the same
--realisations per candidate (the same draws), once with ``process_target="isotropic"``
(the rule before) and once with the default ``"disturbance model"``, and both are tested
on the same --n-test series a point at 6x and 8x process noise and at 6x and 8x gyro
noise, beside the ceiling (``run_sweep``). Also the fit time of each.

    python bench/process_target.py          # about 4 minutes on the 2-core machine
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from _common import add_sweep_sizes, base_parser, begin, print_table, warm_up_numba, write_json

from inertia_id import Scenario, run_sweep, train_classifier

FIRE, OFF = [4, 4, 4, 0, 0, 0], [0] * 6
BRAKE, BRAKE_X, BRAKE_YZ = [0, 0, 0, 4, 4, 4], [0, 0, 0, 4, 0, 0], [0, 0, 0, 0, 4, 4]
SEQUENCES = {
    "hand-designed L=4": [FIRE] * 4,
    "fire, coast, brake L=8": [FIRE, FIRE, OFF, OFF, OFF, OFF, BRAKE, BRAKE],
    "front's best L=8 (README)": [FIRE, FIRE, OFF, OFF, BRAKE_X, BRAKE_X, BRAKE_YZ, BRAKE_YZ],
}
TARGETS = ("isotropic", "disturbance model")
MULTIPLES = (6, 8)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--realisations", type=int, default=100, help="training per candidate")
    add_sweep_sizes(parser)
    parser.set_defaults(n_test=2000)
    args = begin(parser, "Process component: isotropic or disturbance-model target")
    warm_up_numba()
    scenario = Scenario.paper()
    figures: dict[str, Any] = {}
    rows = []
    for name, steps in SEQUENCES.items():
        sequence = scenario.check_sequence(steps)
        models, fit_s = {}, {}
        for target in TARGETS:
            started = time.perf_counter()
            models[target] = train_classifier(
                scenario,
                sequence,
                args.realisations,
                np.random.default_rng(args.seed),
                kind="marginal-likelihood",
                process_target=target,
            )
            fit_s[target] = time.perf_counter() - started
        sweep = run_sweep(
            models["disturbance model"],
            others={"isotropic": models["isotropic"]},
            multiples=MULTIPLES,
            noises=("process", "measurement"),
            n_test=args.n_test,
            ceiling_realisations=args.ceiling_realisations,
            seed=args.seed + 1,
        )
        figures[name] = {"fit_s": fit_s, "intensity": {}}
        for target in TARGETS:
            model = models[target]
            figures[name]["intensity"][target] = float(model.shrinkage_[1])
            cells = []
            for noise in ("process", "measurement"):
                curve = sweep.curve(noise, None if target == "disturbance model" else target)
                cells += [f"{p.accuracy:.4f}" for p in curve]
                figures[name][f"{target} {noise}"] = [p.accuracy for p in curve]
            rows.append([name, target, *cells, f"{model.shrinkage_[1]:g}", f"{fit_s[target]:.1f}"])
        ceiling = []
        for noise in ("process", "measurement"):
            points = [p for p in sweep.ceiling if p.noise == noise]
            ceiling += [f"{p.accuracy:.4f}" for p in points]
            figures[name][f"ceiling {noise}"] = [p.accuracy for p in points]
        rows.append([name, "the ceiling", *ceiling, "-", "-"])
    print_table(
        [
            "sequence",
            "process target",
            "6x process",
            "8x process",
            "6x gyro",
            "8x gyro",
            "intensity",
            "fit s",
        ],
        rows,
        title=f"Marginal likelihood, {args.realisations} realisations per candidate; the "
        f"same {args.n_test} test series a point for both targets",
    )
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
