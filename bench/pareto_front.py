"""The Pareto front on the paper preset, and whether its best member that ends near rest
on no more impulse than the hand-designed sequence matches that sequence's accuracy.

1. For each --lengths L: NSGA-II (the defaults) on accuracy at the default design noise
   (6x process, 6x gyro), final rate and impulse, with the operator's constraints
   (--max-final-rate rad/s, --max-impulse N m s), then the same search without them;
   the wall time of each (search and fresh re-scoring: the rates on a fresh draw, the
   accuracy measured with the noise model's Bayes classifier on 200 fresh series per
   candidate and condition, the prediction beside it; the first member measured again
   on 1,000 other series per candidate, since it is first by its own series' luck in
   part).
2. The constrained front's best member at each L (the most accurate on the front's own
   measurement) and the baselines of the issue (hand-designed L = 4, fire then brake,
   fire-coast-brake L = 8): the default classifier (marginal likelihood, 100
   realisations per candidate) tested at 6x process and at 6x gyro noise on --n-test
   series a point (spread over the 5 candidates) simulated from one seed for every
   sequence, with the Wilson
   interval, the prediction the search used, and the ceiling (2,000 realisations)
   beside it.

    python bench/pareto_front.py            # about 5 minutes on the 2-core machine
"""

from __future__ import annotations

import time

import numpy as np
from _common import base_parser, begin, int_list, write_json

from inertia_id import preset, run_sweep, simulate, train_classifier
from inertia_id.search import OperatorSettings, pareto_search
from inertia_id.search.noise_model import LinearNoiseModel

FIRE, BRAKE, OFF = [4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4], [0] * 6
DESIGN = ((6.0, 1.0), (1.0, 6.0))


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int_list, default=[4, 6, 8], help="sequence lengths")
    parser.add_argument("--max-final-rate", type=float, default=0.01, help="rad/s")
    parser.add_argument("--max-impulse", type=float, default=24.0, help="N m s")
    parser.add_argument(
        "--n-test", type=int, default=2000, help="test series a point, spread over the candidates"
    )
    args = begin(parser, "Pareto front, paper preset")
    scenario = preset("paper")
    constraints = {"max_final_rate_rad_s": args.max_final_rate, "max_impulse_nms": args.max_impulse}
    rows: dict[str, list[list[int]]] = {
        "hand-designed (L=4)": [FIRE] * 4,
        "fire then brake L=4": [FIRE] * 2 + [BRAKE] * 2,
        "fire then brake L=6": [FIRE] * 3 + [BRAKE] * 3,
        "fire, coast, brake L=8": [FIRE] * 2 + [OFF] * 4 + [BRAKE] * 2,
    }
    fronts: list[dict] = []
    measured: list[dict] = []
    for length in args.lengths:
        for label, given in (("constrained", constraints), ("unconstrained", {})):
            started = time.perf_counter()
            result = pareto_search(
                scenario,
                sequence_length=length,
                seed=args.seed,
                operator=OperatorSettings(constraints=given),
            )
            elapsed = time.perf_counter() - started
            front = result.front or {}
            members = front.get("members", [])
            fronts.append(
                {
                    "length": length,
                    "constraints": given,
                    "seconds": elapsed,
                    "sequences_evaluated": result.episodes,
                    "members": members,
                    "dominated_by_baseline": front.get("dominated_by_baseline"),
                    "confirmation": front.get("confirmation"),
                }
            )
            print(
                f"L = {length} {label}: {len(members)} members, {result.episodes} sequences "
                f"evaluated, {elapsed:.1f} s (search + fresh re-scoring); a baseline "
                f"dominates a member: {front.get('dominated_by_baseline')}"
            )
            if label == "unconstrained" or not members:
                continue
            print(
                "  #   measured 6x proc / 6x gyro (predicted)  residual rad/s (deg/s) mean, worst  "
                "impulse  sequence"
            )
            for member in members[:8]:
                s = member["scores"]
                p = s["predicted_accuracy_by_noise"]
                print(
                    f"  {member['index']:<3d} {s['accuracy_by_noise'][0]:.4f} / "
                    f"{s['accuracy_by_noise'][1]:.4f} ({p[0]:.4f} / {p[1]:.4f})  "
                    f"{s['final_rate_rad_s']:.4f} "
                    f"({s['final_rate_deg_s']:.2f}), {s['final_rate_max_rad_s']:.4f}  "
                    f"{s['impulse_nms']:5.1f}  "
                    f"{member['sequence']}"
                )
            confirmation = front.get("confirmation")
            if confirmation:
                shown = " / ".join(
                    f"{a:.4f} [{low:.4f}, {high:.4f}]"
                    for a, (low, high) in zip(
                        confirmation["accuracy_by_noise"],
                        confirmation["interval_by_noise"],
                        strict=True,
                    )
                )
                print(
                    f"  #0 again on {confirmation['test_series']} other series per candidate "
                    f"(not those that ranked it first): {shown}"
                )
                for name, figures in (confirmation.get("baselines") or {}).items():
                    print(
                        f"     {name} on the same series: "
                        + " / ".join(f"{a:.4f}" for a in figures["accuracy_by_noise"])
                        + (" (dominates #0)" if figures["dominates_member_0"] else "")
                    )
            rows[f"front's best, L={length}"] = members[0]["sequence"]
    print(
        f"\nDefault classifier, {args.n_test} test series a point "
        "(one seed for every sequence); [Wilson 95 %]; predicted = the search's figure"
    )
    print(
        "sequence | residual rate rad/s (deg/s), worst candidate | impulse N m s | 6x process | "
        "6x gyro | "
        "predicted process / gyro | ceiling process / gyro"
    )
    for label, sequence in rows.items():
        sequence_array = np.asarray(sequence)
        model = train_classifier(scenario, sequence_array, 100, np.random.default_rng(1))
        sweep = run_sweep(
            model, multiples=(6,), n_test=args.n_test, ceiling_realisations=2000, seed=7
        )
        points = {p.noise: p for p in sweep.points}
        ceiling = {p.noise: p for p in sweep.ceiling}
        predicted = (
            1.0
            - LinearNoiseModel(scenario, len(sequence_array)).predicted_error(
                sequence_array[None], DESIGN
            )[0]
        )
        rate = simulate(scenario, sequence_array, 100, np.random.default_rng(3))
        settled = rate.settled_rate_rad_s(scenario)  # (K, n): once the lag is empty
        final, worst = float(settled.mean()), float(settled.mean(axis=1).max())
        process, gyro = points["process"], points["measurement"]
        measured.append(
            {
                "label": label,
                "sequence": np.asarray(sequence).tolist(),
                "final_rate_rad_s": final,
                "final_rate_max_rad_s": worst,
                "impulse_nms": scenario.impulse_nms(sequence_array),
                "accuracy_6x_process": process.accuracy,
                "accuracy_6x_gyro": gyro.accuracy,
                "predicted": predicted.tolist(),
                "ceiling": [ceiling["process"].accuracy, ceiling["measurement"].accuracy],
            }
        )
        print(
            f"{label} {sequence} | {final:.4f} ({np.degrees(final):.2f}), worst {worst:.4f} | "
            f"{scenario.impulse_nms(sequence_array):.1f} | {process.accuracy:.4f} "
            f"[{process.ci_low:.4f}, {process.ci_high:.4f}] | {gyro.accuracy:.4f} "
            f"[{gyro.ci_low:.4f}, {gyro.ci_high:.4f}] | {predicted[0]:.4f} / {predicted[1]:.4f} | "
            f"{ceiling['process'].accuracy:.4f} / {ceiling['measurement'].accuracy:.4f}",
            flush=True,
        )

    write_json(args.json, args, {"fronts": fronts, "measured": measured})


if __name__ == "__main__":
    main()
