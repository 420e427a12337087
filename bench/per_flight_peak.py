"""A peak-rate bound on the mean flight, checked on flights the search never saw.

``max_peak_rate_rad_s`` / ``_deg_s`` bound, for the candidate that spins fastest, the
larger of its mean peak |ω| over the scorer's realisations and the command plan's
noise-free peak. A single flight's peak spreads around that mean (the disturbance and
the duty jitter), so a member at the bound leaves some flights above it. This measures
by how much, to tell whether a per-flight peak bound (as ``max_final_rate_p95`` is for
the residual rate) is worth its cost.

For each --lengths L, NSGA-II (defaults: accuracy at 6x process and 6x gyro noise, final
rate, impulse) runs with the peak rate at most --peak deg/s, the residual rate at most
--bound rad/s and the impulse at most --max-impulse N m s. Every member is flown
--flights times per candidate on an independent draw at the scenario's own noise, and a
flight's peak is its largest true |ω| at any sample or once the lag has delivered the
torque still in it. Printed: for the member nearest the bound, its figure and its
fastest candidate's share of flights above the bound; over the front, the largest share
of flights above the bound, and the largest ratio of a member's 95th-percentile flight
peak (and its fastest flight) to its own figure.

    python bench/per_flight_peak.py            # about 2 minutes on the 2-core machine
"""

from __future__ import annotations

import time

import numpy as np
from _common import base_parser, begin, int_list, positive_int, write_json

from inertia_id import preset
from inertia_id.physics.simulate import Simulator
from inertia_id.search import OperatorSettings, pareto_search

_DEG = 180.0 / np.pi


def flight_peaks(scenario, sequences: np.ndarray, flights: int, seed: int) -> np.ndarray:
    """(P, K, flights) each flight's peak |ω|, rad/s: at any sample, or once settled."""
    simulator = Simulator(scenario, flights)
    noise = simulator.draw_noise(np.random.default_rng(seed), sequences.shape[1])
    out = []
    for start in range(len(sequences)):  # one at a time: K x flights x T x 3 rates
        rates, end = simulator.population_run(sequences[start : start + 1], noise)
        during = np.linalg.norm(rates, axis=-1).max(axis=-1)  # (P, K, n)
        out.append(np.maximum(during, simulator.settled(end)))
    return np.concatenate(out)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int_list, default=[4, 8], help="sequence lengths")
    parser.add_argument("--peak", type=float, default=4.0, help="peak rate bound, deg/s")
    parser.add_argument("--bound", type=float, default=0.01, help="residual rate, rad/s")
    parser.add_argument("--max-impulse", type=float, default=24.0, help="N m s")
    parser.add_argument(
        "--flights", type=positive_int, default=4000, help="independent flights per candidate"
    )
    args = begin(parser, "Peak-rate bound on the mean flight, on single flights")
    scenario = preset("paper")
    bound = args.peak / _DEG
    rows = []
    print(
        "L | members | s | nearest member: figure deg/s | its flights above the bound | "
        "most flights above, any member | largest p95 flight peak / own figure | "
        "largest fastest flight / own figure"
    )
    for length in args.lengths:
        started = time.perf_counter()
        result = pareto_search(
            scenario,
            sequence_length=length,
            seed=args.seed,
            operator=OperatorSettings(
                constraints={
                    "max_peak_rate_deg_s": args.peak,
                    "max_final_rate_rad_s": args.bound,
                    "max_impulse_nms": args.max_impulse,
                }
            ),
        )
        elapsed = time.perf_counter() - started
        members = (result.front or {}).get("members", [])
        if not members:
            print(f"{length} | 0 | {elapsed:.1f} | no member")
            continue
        sequences = np.array([m["sequence"] for m in members])
        figures = np.array([m["scores"]["peak_rate_rad_s"] for m in members])
        peaks = flight_peaks(scenario, sequences, args.flights, args.seed + 99)
        above = (peaks > bound).mean(axis=2).max(axis=1)  # (P,): fastest candidate's share
        p95 = np.quantile(peaks, 0.95, axis=2).max(axis=1) / figures
        fastest = peaks.max(axis=(1, 2)) / figures
        nearest = int(np.argmax(figures))
        print(
            f"{length} | {len(members)} | {elapsed:.1f} | #{nearest}: "
            f"{figures[nearest] * _DEG:.4f} | {above[nearest]:.1%} | "
            f"{above.max():.1%} (#{int(np.argmax(above))}) | {p95.max():.4f} | "
            f"{fastest.max():.4f}"
        )
        rows.append(
            {
                "length": length,
                "members": len(members),
                "seconds": elapsed,
                "figures_rad_s": figures.tolist(),
                "share_above_by_member": above.tolist(),
                "p95_over_figure_by_member": p95.tolist(),
                "fastest_over_figure_by_member": fastest.tolist(),
            }
        )
    write_json(
        args.json, args, {"flights": args.flights, "peak_bound_deg_s": args.peak, "rows": rows}
    )


if __name__ == "__main__":
    main()
