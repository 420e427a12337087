"""The Pareto front on the paper preset, and whether its best low-rate, low-impulse member
matches the hand-designed sequence with the default classifier.

For L = 4, 6, 8: NSGA-II (defaults: population 64, 30 generations) on accuracy at the
default design noise (6x process, 6x gyro), final rate and impulse; the time to find and
re-score the front. Then, among every front's members with a final rate <= 0.01 rad/s and
an impulse <= 24 N m s, the most accurate on its fresh scores is trained with the default
classifier (marginal likelihood, 100 realisations per candidate) and tested at 6x process
and at 6x gyro noise on 400 series simulated from the same seeds as the hand-designed
sequence's and the issue's rows (fire then brake L = 4, 6; fire, coast, brake L = 8),
with the ceiling (2,000 realisations per candidate) beside each.

    python bench/pareto_front.py            # about 5 minutes on the 2-core machine
"""

from __future__ import annotations

import time

import numpy as np

from inertia_id import preset, run_sweep, train_classifier
from inertia_id.search import pareto_search

FIRE, BRAKE, OFF = [4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4], [0] * 6


def _flag(names: list[str]) -> str:
    return f"  dominated by {','.join(names)}" if names else ""


def main() -> None:
    scenario = preset("paper")
    candidates = []
    for length in (4, 6, 8):
        started = time.perf_counter()
        result = pareto_search(scenario, sequence_length=length, seed=0)
        elapsed = time.perf_counter() - started
        front = result.front or {}
        members = front.get("members", [])
        print(
            f"L = {length}: {len(members)} members from {result.episodes} sequences evaluated "
            f"in {elapsed:.1f} s (wall, search + fresh re-scoring); flagged: "
            f"{front.get('dominated_by_baseline')}"
        )
        print("  #   acc 6x proc / 6x gyro  final rad/s (deg/s)   impulse  sequence")
        for member in members:
            s = member["scores"]
            print(
                f"  {member['index']:<3d} {s['accuracy_by_noise'][0]:.3f} / "
                f"{s['accuracy_by_noise'][1]:.3f}        {s['final_rate_rad_s']:.4f} "
                f"({s['final_rate_deg_s']:.2f})    {s['impulse_nms']:5.1f}    "
                f"{member['sequence']}{_flag(member['dominated_by'])}"
            )
            if s["final_rate_rad_s"] <= 0.01 and s["impulse_nms"] <= 24.0:
                candidates.append((s["accuracy"], length, member["sequence"]))
        for name, base in front.get("baselines", {}).items():
            if "scores" in base:
                s = base["scores"]
                print(
                    f"  baseline {name:16s} {s['accuracy_by_noise'][0]:.3f} / "
                    f"{s['accuracy_by_noise'][1]:.3f}  {s['final_rate_rad_s']:.4f}  "
                    f"{s['impulse_nms']:5.1f}  dominates {base['dominates']}"
                )
    rows = {
        "hand-designed (L=4)": [FIRE] * 4,
        "fire then brake L=4": [FIRE] * 2 + [BRAKE] * 2,
        "fire then brake L=6": [FIRE] * 3 + [BRAKE] * 3,
        "fire, coast, brake L=8": [FIRE] * 2 + [OFF] * 4 + [BRAKE] * 2,
    }
    if candidates:
        _, length, sequence = max(candidates, key=lambda c: c[0])
        rows[f"front's best, rate <= 0.01, impulse <= 24 (L={length})"] = sequence
    else:
        print("no front member has final rate <= 0.01 rad/s and impulse <= 24 N m s")
    print(
        "\nsequence | final rate rad/s (deg/s) | impulse | acc 6x process | acc 6x gyro | "
        "ceiling 6x process / gyro"
    )
    for label, sequence in rows.items():
        model = train_classifier(scenario, sequence, 100, np.random.default_rng(1))
        sweep = run_sweep(model, multiples=(6,), n_test=400, ceiling_realisations=2000, seed=7)
        points = {p.noise: p for p in sweep.points}
        ceiling = {p.noise: p for p in sweep.ceiling}
        from inertia_id import simulate

        rate = simulate(scenario, sequence, 100, np.random.default_rng(3)).mean_final_rate_rad_s
        print(
            f"{label} {sequence} | {rate:.4f} ({np.degrees(rate):.2f}) | "
            f"{scenario.impulse_nms(sequence):.1f} | {points['process'].accuracy:.3f} "
            f"[{points['process'].ci_low:.3f}, {points['process'].ci_high:.3f}] | "
            f"{points['measurement'].accuracy:.3f} [{points['measurement'].ci_low:.3f}, "
            f"{points['measurement'].ci_high:.3f}] | {ceiling['process'].accuracy:.3f} / "
            f"{ceiling['measurement'].accuracy:.3f}"
        )


if __name__ == "__main__":
    main()
