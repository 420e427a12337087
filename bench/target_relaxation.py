"""What a sequence that ends near rest needs to match the hand-designed one: the front's
best member under each residual-rate and impulse allowance, measured on the same series.

The target of issue 14 (final rate <= 0.01 rad/s on no more than the hand-designed
sequence's 24 N m s, at L <= 8) is not met (``bench/pareto_front.py``,
``bench/rest_ending.py``). This bench measures how far it must be loosened, one
allowance at a time, for the search's best member to match or beat the hand-designed
sequence at 6x process and at 6x gyro noise:

1. For each --max-final-rates allowance at --max-impulse N m s, and each --max-impulses
   allowance at --final-rate rad/s: NSGA-II (the defaults, seed --seed) at --length L
   with those two constraints and no test series (the front's members judged on the
   prediction). Its best member is the one whose smaller predicted margin over the
   hand-designed sequence's prediction is largest.
2. That member and the hand-designed sequence: the default classifier (marginal
   likelihood, 100 realisations per candidate) tested on --n-test series a point simulated
   from one seed for every sequence (seed 7, as ``bench/pareto_front.py``), with the Wilson
   interval. "beats" when both of its accuracies are at least the hand-designed one's.
3. Why the hand-designed sequence is hard to beat: the noise model's prediction for it and
   for the first row's member, with the dynamics as they are and with the gyroscopic term
   ω × Iω removed (the torque alone drives the rates), so the share of the gap that the
   coupling between axes explains is printed, not argued.

    python bench/target_relaxation.py       # about 9 minutes on the 2-core machine, alone
"""

from __future__ import annotations

import time

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    base_parser,
    begin,
    float_list,
    without_gyroscopic_term,
    write_json,
)

from inertia_id import preset, run_sweep, simulate, train_classifier
from inertia_id.search import OperatorSettings, pareto_search
from inertia_id.search.noise_model import LinearNoiseModel

DESIGN = ((6.0, 1.0), (1.0, 6.0))


def predicted(scenario, sequence: np.ndarray) -> np.ndarray:
    model = LinearNoiseModel(scenario, len(sequence))
    return 1.0 - model.predicted_error(sequence[None], DESIGN)[0]


def measured(scenario, sequence: np.ndarray, n_test: int) -> dict:
    model = train_classifier(scenario, sequence, 100, np.random.default_rng(1))
    sweep = run_sweep(model, multiples=(6,), n_test=n_test, ceiling_realisations=0, seed=7)
    return {p.noise: p for p in sweep.points}


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--length", type=int, default=8, help="sequence steps L")
    parser.add_argument("--max-impulse", type=float, default=24.0, help="N m s, rate rows")
    parser.add_argument(
        "--max-final-rates",
        type=float_list,
        default=[0.01, 0.05, 0.1, 0.12, 0.14, 0.16, 0.2],
        help="rad/s allowances tried at --max-impulse",
    )
    parser.add_argument("--final-rate", type=float, default=0.01, help="rad/s, impulse rows")
    parser.add_argument(
        "--max-impulses",
        type=float_list,
        default=[28.0, 30.0, 32.0, 34.0, 36.0],
        help="N m s allowances tried at --final-rate",
    )
    parser.add_argument("--n-test", type=int, default=2000, help="test series a point")
    args = begin(parser, "What it takes to match the hand-designed sequence, paper preset")
    scenario = preset("paper")
    hand = np.asarray(GOOD_SEQUENCE)
    hand_predicted = predicted(scenario, hand)
    hand_measured = measured(scenario, hand, args.n_test)
    hp, hg = hand_measured["process"], hand_measured["measurement"]
    print(
        f"hand-designed (L=4): final 0.19 rad/s, 24 N m s; 6x process {hp.accuracy:.4f} "
        f"[{hp.ci_low:.4f}, {hp.ci_high:.4f}], 6x gyro {hg.accuracy:.4f} "
        f"[{hg.ci_low:.4f}, {hg.ci_high:.4f}]; predicted {hand_predicted[0]:.4f} / "
        f"{hand_predicted[1]:.4f}\n"
    )
    allowances = [("rate", rate, args.max_impulse) for rate in args.max_final_rates] + [
        ("impulse", args.final_rate, impulse) for impulse in args.max_impulses
    ]
    print(
        f"L = {args.length}; default classifier, {args.n_test} test series a point, the same "
        "series for every sequence; [Wilson 95 %]"
    )
    print(
        "allowance: final rad/s, N m s | search s | member final rad/s (deg/s), N m s | "
        "6x process | 6x gyro | predicted | beats hand-designed"
    )
    first = None
    smallest: dict[str, float] = {}
    rows: list[dict] = []
    for kind, rate, impulse in allowances:
        started = time.perf_counter()
        result = pareto_search(
            scenario,
            sequence_length=args.length,
            seed=args.seed,
            operator=OperatorSettings(
                constraints={"max_final_rate_rad_s": rate, "max_impulse_nms": impulse}
            ),
            # Ranked by the prediction below, against the hand-designed one's: the front's
            # own measurement (other series) is not needed.
            fresh_test_series=0,
        )
        elapsed = time.perf_counter() - started
        members = (result.front or {}).get("members", [])
        if not members:
            print(f"{rate} rad/s, {impulse} N m s | {elapsed:.0f} s | no feasible member")
            continue

        def margin(member: dict) -> float:
            accuracy = member["scores"]["accuracy_by_noise"]  # predicted (no test series)
            return min(accuracy[0] - hand_predicted[0], accuracy[1] - hand_predicted[1])

        sequence = np.asarray(max(members, key=margin)["sequence"])
        first = sequence if first is None else first
        points = measured(scenario, sequence, args.n_test)
        process, gyro = points["process"], points["measurement"]
        settled = simulate(scenario, sequence, 100, np.random.default_rng(3)).settled_rate_rad_s(
            scenario
        )  # (K, n): the residual rate once the lag is empty
        final, worst = float(settled.mean()), float(settled.mean(axis=1).max())
        prediction = predicted(scenario, sequence)
        beats = process.accuracy >= hp.accuracy and gyro.accuracy >= hg.accuracy
        if beats:
            allowance = rate if kind == "rate" else impulse
            smallest[kind] = min(smallest.get(kind, allowance), allowance)
        rows.append(
            {
                "max_final_rate_rad_s": rate,
                "max_impulse_nms": impulse,
                "search_s": elapsed,
                "sequence": sequence.tolist(),
                "final_rate_rad_s": final,
                "final_rate_max_rad_s": worst,
                "impulse_nms": scenario.impulse_nms(sequence),
                "accuracy_6x_process": process.accuracy,
                "accuracy_6x_gyro": gyro.accuracy,
                "predicted": prediction.tolist(),
                "beats_hand_designed": beats,
            }
        )
        print(
            f"{rate} rad/s, {impulse} N m s | {elapsed:.0f} s | {final:.4f} "
            f"({np.degrees(final):.2f}; worst {worst:.4f}), {scenario.impulse_nms(sequence):.1f} | "
            f"{process.accuracy:.4f} [{process.ci_low:.4f}, {process.ci_high:.4f}] | "
            f"{gyro.accuracy:.4f} [{gyro.ci_low:.4f}, {gyro.ci_high:.4f}] | "
            f"{prediction[0]:.4f} / {prediction[1]:.4f} | {'yes' if beats else 'no'} "
            f"{sequence.tolist()}",
            flush=True,
        )
    none = "none of those tried"
    print(
        f"\nsmallest final-rate allowance at {args.max_impulse} N m s whose member beats the "
        f"hand-designed sequence: {smallest.get('rate', none)} rad/s; smallest impulse "
        f"allowance at {args.final_rate} rad/s: {smallest.get('impulse', none)} N m s"
    )
    coupling: dict[str, dict[str, list[float]]] = {}
    if first is not None:
        print("\nThe noise model's prediction (6x process / 6x gyro), with and without ω × Iω:")
        pair = {"hand-designed": hand, "first row": first}
        for label, sequence in pair.items():
            coupling[label] = {"as simulated": predicted(scenario, sequence).tolist()}
        with without_gyroscopic_term():
            for label, sequence in pair.items():
                coupling[label]["without"] = predicted(scenario, sequence).tolist()
        if all(f["without"] == f["as simulated"] for f in coupling.values()):
            raise SystemExit("the ablation of ω × Iω changed no prediction: it did not apply")
        for label, figures in coupling.items():
            a, b = figures["as simulated"], figures["without"]
            print(
                f"{label}: {a[0]:.4f} / {a[1]:.4f} as simulated; {b[0]:.4f} / {b[1]:.4f} without it"
            )
    hand_figures = {"accuracy_6x_process": hp.accuracy, "accuracy_6x_gyro": hg.accuracy}
    write_json(
        args.json,
        args,
        {
            "hand_designed": {**hand_figures, "predicted": hand_predicted.tolist()},
            "rows": rows,
            "smallest": smallest,
            "gyroscopic_ablation": coupling,
        },
    )


if __name__ == "__main__":
    main()
