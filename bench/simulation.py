"""Simulation throughput: the batched simulator against a plain per-series RK4 loop.

Throughput is measured in series·steps per second, where series·steps = number of
series x number of RK4 integration steps per series (substeps_per_step x L). Both
simulators get the same pre-drawn noise (drawing it is not timed), and the largest
difference between their outputs is printed to show they compute the same thing.

Run: python bench/simulation.py [--realisations 20,200] [--repeats 7] [--json PATH]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from _common import (
    add_steps,
    base_parser,
    begin,
    best_of,
    int_list,
    positive_int,
    print_table,
    random_sequence,
    sequence_text,
    write_json,
)

from inertia_id import Scenario, Simulator
from inertia_id.physics.reference import simulate_per_series


def throughput_record(
    implementation: str,
    realisations: int,
    series: int,
    rk4_steps: int,
    times: list[float],
    best: float,
) -> dict[str, Any]:
    """One row of the throughput table: series x RK4 steps per second at the best time."""
    return {
        "implementation": implementation,
        "realisations_per_candidate": realisations,
        "series": series,
        "rk4_steps_per_series": rk4_steps,
        "series_steps": series * rk4_steps,
        "repeats": len(times),
        "times_s": times,
        "best_s": best,
        "series_steps_per_s": series * rk4_steps / best,
    }


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--realisations",
        type=int_list,
        default=[20, 200],
        help="realisations per candidate for the batched simulator (comma-separated)",
    )
    parser.add_argument(
        "--loop-realisations",
        type=positive_int,
        default=20,
        help="realisations per candidate for the per-series loop (and the "
        "size at which the speed-up and agreement are measured)",
    )
    add_steps(parser)
    parser.add_argument(
        "--repeats",
        type=positive_int,
        default=7,
        help="timed repeats of the batched simulator (best is kept)",
    )
    parser.add_argument(
        "--loop-repeats",
        type=positive_int,
        default=2,
        help="timed repeats of the per-series loop (best is kept)",
    )
    args = begin(parser, "Simulation throughput: batched simulator vs per-series RK4 loop")

    scenario = Scenario.paper()
    timing = scenario.timing
    rng = np.random.default_rng(args.seed)
    sequence = random_sequence(rng, args.steps, scenario.n_thrusters, scenario.n_levels)
    rk4_steps = timing.substeps_per_step * args.steps
    k = scenario.n_candidates
    print(
        f"scenario: {scenario.name}, {k} candidates, {scenario.n_thrusters} thrusters, "
        f"{scenario.n_levels} levels; RK4 dt = {timing.integration_step_s} s, "
        f"{timing.substeps_per_step} RK4 steps per actuation step"
    )
    print(
        f"sequence (seed {args.seed}, {args.steps} steps): {sequence_text(sequence)}; "
        f"{rk4_steps} RK4 steps per series"
    )
    print("noise is drawn once per size, outside the timed region; best-of-N wall time")
    print(flush=True)

    sizes = sorted(set(args.realisations) | {args.loop_realisations})
    rows = []
    records = []
    batched_at_loop_size = None
    for n in sizes:
        simulator = Simulator(scenario, n)
        noise = simulator.draw_noise(np.random.default_rng([args.seed, n]), args.steps)
        best, times, result = best_of(lambda s=simulator, z=noise: s.run(sequence, z), args.repeats)
        record = throughput_record("batched Simulator.run", n, k * n, rk4_steps, times, best)
        if n == args.loop_realisations:
            batched_at_loop_size = (record, noise, result)
        if n in args.realisations or n == args.loop_realisations:
            records.append(record)

    # The per-series loop, only at its own size (measured, never extrapolated).
    record_b, noise, result = batched_at_loop_size  # type: ignore[misc]
    n = args.loop_realisations
    best, times, loop_out = best_of(
        lambda: simulate_per_series(scenario, sequence, noise), args.loop_repeats
    )
    series = k * n
    max_diff = float(np.max(np.abs(loop_out - result.omega_measured)))
    max_rate = float(np.max(np.abs(result.omega_measured)))
    loop_record = throughput_record(
        "per-series loop (reference)", n, series, rk4_steps, times, best
    )
    records.append(loop_record)
    loop_rate = loop_record["series_steps_per_s"]
    for rec in records:
        rec["speedup_vs_loop"] = rec["series_steps_per_s"] / loop_rate

    records.sort(
        key=lambda r: (
            r["implementation"].startswith("per-series"),
            r["realisations_per_candidate"],
        )
    )
    for rec in records:
        rows.append(
            [
                rec["implementation"],
                rec["realisations_per_candidate"],
                rec["series"],
                rec["series_steps"],
                f"{rec['repeats']}",
                rec["best_s"] * 1e3,
                f"{rec['series_steps_per_s']:,.0f}",
                f"{rec['speedup_vs_loop']:.1f}x",
            ]
        )
    print_table(
        [
            "simulator",
            "real./cand.",
            "series",
            "series·steps",
            "repeats",
            "best ms",
            "series·steps/s",
            "speed-up",
        ],
        rows,
        title=f"Throughput ({rk4_steps} RK4 steps per series; speed-up = throughput ratio "
        "to the loop)",
    )
    print_table(
        [
            "compared at",
            "series",
            "max |batched - loop| (rad/s)",
            "max |omega| (rad/s)",
            "speed-up (same work)",
        ],
        [
            [
                f"{n} realisations/candidate",
                series,
                max_diff,
                max_rate,
                f"{loop_record['best_s'] / record_b['best_s']:.1f}x",
            ]
        ],
        title="Agreement (same noise for both)",
    )
    write_json(
        args.json,
        args,
        {
            "benchmark": "simulation",
            "scenario": scenario.name,
            "sequence": sequence.tolist(),
            "rk4_steps_per_series": rk4_steps,
            "results": records,
            "agreement": {
                "realisations_per_candidate": n,
                "series": series,
                "max_abs_difference_rad_s": max_diff,
                "max_abs_rate_rad_s": max_rate,
            },
            "speedup_same_work": loop_record["best_s"] / record_b["best_s"],
        },
    )


if __name__ == "__main__":
    main()
