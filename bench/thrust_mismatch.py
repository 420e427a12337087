"""Thrusters weaker than the scenario says: does the verdict stay honest?

Torque and inertia enter the dynamics as their ratio, so a thrust shortfall the scenario
does not state looks like a heavier body. Data: the paper preset and the hand-designed
sequence; the default classifier (marginal likelihood, 100 realisations per candidate)
trained on the scenario as stated, then --series telemetry series per candidate flown
with every thruster's torque scaled by each of --scales (the same seed for every scale),
each judged by ``identify``: identified right, identified wrong (at the required
confidence, 0.99), ambiguous, or matches none / not this sequence. Twice: trained with
the preset's thrust-scale sigma (0, thrust known exactly), and with the scenario stating
--stated-sigma per thruster.

Run: python bench/thrust_mismatch.py [--series 40] [--scales 1,0.95,0.9]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _common import GOOD_SEQUENCE, base_parser, begin, float_list, print_table, write_json

from inertia_id import Scenario, simulate, train_classifier
from inertia_id.evaluation.identify import identify
from inertia_id.evaluation.telemetry import Telemetry


def weaker(scenario: Scenario, scale: float) -> Scenario:
    document = scenario.model_dump()
    matrix = np.asarray(document["thrusters"]["torque_matrix_nm"]) * scale
    document["thrusters"]["torque_matrix_nm"] = matrix.tolist()
    return Scenario.model_validate(document)


def verdicts(model: Any, flown: Scenario, series: int, seed: int) -> dict[str, Any]:
    result = simulate(flown, GOOD_SEQUENCE, series, np.random.default_rng(seed))
    times = flown.sample_times(len(GOOD_SEQUENCE)).tolist()
    counts = {"right": 0, "wrong": 0, "ambiguous": 0, "none": 0}
    wrong_confidence: list[float] = []
    for k in range(flown.n_candidates):
        for i in range(series):
            verdict = identify(
                model, Telemetry(time_s=times, omega_rad_s=result.omega_measured[k, i].tolist())
            )
            if verdict.status == "identified":
                right = verdict.candidate_index == k
                counts["right" if right else "wrong"] += 1
                if not right:
                    wrong_confidence.append(float(verdict.confidence))
            elif verdict.status == "ambiguous":
                counts["ambiguous"] += 1
            else:
                counts["none"] += 1
    return {**counts, "wrong_confidence_min": min(wrong_confidence, default=None)}


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=40, help="telemetry series per candidate")
    parser.add_argument("--scales", type=float_list, default=[1.0, 0.95, 0.9])
    parser.add_argument("--stated-sigma", type=float, default=0.05, help="thrust_scale_sigma")
    args = begin(parser, "A thrust shortfall the scenario does or does not state")
    paper = Scenario.paper()
    document = paper.model_dump()
    document["uncertainty"]["thrust_scale_sigma"] = args.stated_sigma
    trained_on = {"thrust exact (preset)": paper, "stated": Scenario.model_validate(document)}
    rows, figures = [], {}
    for label, scenario in trained_on.items():
        model = train_classifier(scenario, GOOD_SEQUENCE, 100, np.random.default_rng(args.seed))
        sigma = scenario.uncertainty.thrust_scale_sigma
        for scale in args.scales:
            found = verdicts(model, weaker(paper, scale), args.series, args.seed + 7)
            figures[f"{label} x{scale:g}"] = found
            low = found["wrong_confidence_min"]
            rows.append(
                [
                    f"{label}, sigma {sigma:g}",
                    f"x{scale:g}",
                    found["right"],
                    found["wrong"],
                    "-" if low is None else f"{low:.4f}",
                    found["ambiguous"],
                    found["none"],
                ]
            )
    total = args.series * paper.n_candidates
    print_table(
        ["trained on", "torque flown", "right", "wrong", "wrong, least conf.", "ambiguous", "none"],
        rows,
        title=f"{total} series per row, default classifier, hand-designed sequence",
    )
    write_json(args.json, args, figures)


if __name__ == "__main__":
    main()
