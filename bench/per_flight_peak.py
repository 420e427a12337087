"""A peak-rate bound on the mean flight, and on 95 % of flights, checked on flights the
search never saw.

``max_peak_rate_deg_s`` bounds, for the candidate that spins fastest, the larger of its
mean speed's fastest instant over the scorer's realisations and the command plan's
noise-free peak. A single flight's peak is its own fastest instant, and it spreads
around that (the disturbance and the duty jitter), so a member at the bound leaves some
flights above it. ``max_peak_rate_p95_deg_s`` bounds a peak rate at least 95 % of the
flights stay under with 95 % confidence (the residual's ``max_final_rate_p95``, read the
same way: a proxy from the realisations while searching, the order statistic of 200
flights of its own on the front).

For each --lengths L, NSGA-II (defaults: accuracy at 6x process and 6x gyro noise, final
rate, impulse) runs once with each peak bound at --peak deg/s, beside the residual rate
at most --bound rad/s and the impulse at most --max-impulse N m s. Every member is flown
--flights times per candidate on an independent draw at the scenario's own noise; a
flight's peak is its largest true |ω| at any sample or once the lag has delivered the
torque still in it. Printed: for the member nearest the bound, its figures and its
fastest candidate's share of flights above the bound; over the front, the largest such
share, the members whose own p95 figure more than 5 % of flights exceed, and member 0's
confirmed accuracy (what the tighter bound costs).

    python bench/per_flight_peak.py            # about 2.5 minutes on the 2-core machine
"""

from __future__ import annotations

import numpy as np
from _common import add_flight_bounds, base_parser, begin, constrained_front, write_json

from inertia_id import preset
from inertia_id.physics.simulate import Simulator

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
    add_flight_bounds(parser)
    parser.add_argument("--peak", type=float, default=4.0, help="peak rate bound, deg/s")
    args = begin(parser, "Peak-rate bound on the mean flight, on single flights")
    scenario = preset("paper")
    bound = args.peak / _DEG
    rows = []
    print(
        "L | bound | members | s | nearest member: mean figure, p95 figure deg/s | its "
        "flights above the bound | most flights above, any member | members whose own p95 "
        "figure > 5 % of flights exceed | #0 confirmed 6x process / 6x gyro"
    )
    for length in args.lengths:
        for name in ("max_peak_rate_deg_s", "max_peak_rate_p95_deg_s"):
            constraints = {
                name: args.peak,
                "max_final_rate_rad_s": args.bound,
                "max_impulse_nms": args.max_impulse,
            }
            front, members, elapsed, confirmed = constrained_front(
                scenario, length, args.seed, constraints
            )
            if not members:
                print(f"{length} | {name} | 0 | {elapsed:.1f} | no member")
                continue
            sequences = np.array([m["sequence"] for m in members])
            mean = np.array([m["scores"]["peak_rate_rad_s"] for m in members])
            p95 = np.array([m["scores"]["peak_rate_p95_rad_s"] for m in members])
            peaks = flight_peaks(scenario, sequences, args.flights, args.seed + 99)
            above = (peaks > bound).mean(axis=2).max(axis=1)  # (P,): fastest candidate's
            own = (peaks > p95[:, None, None]).mean(axis=2).max(axis=1)
            nearest = int(np.argmax(p95 if "p95" in name else mean))
            print(
                f"{length} | {name} <= {args.peak:g} | {len(members)} | {elapsed:.1f} | "
                f"#{nearest}: {mean[nearest] * _DEG:.3f}, {p95[nearest] * _DEG:.3f} | "
                f"{above[nearest]:.1%} | {above.max():.1%} (#{int(np.argmax(above))}) | "
                f"{int((own > 0.05).sum())} of {len(members)} (most {own.max():.1%}) | "
                f"{confirmed}"
            )
            rows.append(
                {
                    "length": length,
                    "constraint": name,
                    "members": len(members),
                    "seconds": elapsed,
                    "nearest": nearest,
                    "peak_rate_rad_s_by_member": mean.tolist(),
                    "peak_rate_p95_rad_s_by_member": p95.tolist(),
                    "share_above_by_member": above.tolist(),
                    "share_above_own_p95_by_member": own.tolist(),
                    "confirmation": front.get("confirmation"),
                }
            )
    write_json(
        args.json, args, {"flights": args.flights, "peak_bound_deg_s": args.peak, "rows": rows}
    )


if __name__ == "__main__":
    main()
