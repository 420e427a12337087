"""A residual-rate bound on the mean flight, and on 95 % of flights, checked on flights
the search never saw.

``max_final_rate_rad_s`` bounds each candidate's mean residual rate over the
realisations (and the command plan's prediction), so a front member near the bound
leaves many single flights above it. ``max_final_rate_p95_rad_s`` bounds the rate 95 %
of each candidate's flights stay under, estimated from the search's realisations. For
each --lengths L, NSGA-II (defaults: accuracy at 6x process and 6x gyro noise, final
rate, impulse) runs once with each bound (--bound rad/s, impulse at most --max-impulse
N m s), and every member of each front is flown --flights times per candidate on an
independent draw at the scenario's own noise: the table gives, for the member that
comes closest to the bound, its worst candidate's share of flights above the bound,
and, over the front, the largest such share and member 0's confirmed accuracy (what
the tighter bound costs).

    python bench/per_flight_bound.py            # about 2.5 minutes on the 2-core machine
"""

from __future__ import annotations

import time

import numpy as np
from _common import base_parser, begin, int_list, positive_int, write_json

from inertia_id import preset
from inertia_id.physics.simulate import Simulator
from inertia_id.search import OperatorSettings, pareto_search


def flights_above(scenario, sequences: np.ndarray, bound: float, flights: int, seed: int):
    """(P, K) share of each candidate's flights whose residual rate ends above ``bound``."""
    simulator = Simulator(scenario, flights)
    noise = simulator.draw_noise(np.random.default_rng(seed), sequences.shape[1])
    out = []
    for start in range(0, len(sequences), 8):
        _, end = simulator.population_run(sequences[start : start + 8], noise)
        out.append((simulator.settled(end) > bound).mean(axis=2))
    return np.concatenate(out)


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=int_list, default=[4, 8], help="sequence lengths")
    parser.add_argument("--bound", type=float, default=0.01, help="residual rate, rad/s")
    parser.add_argument("--max-impulse", type=float, default=24.0, help="N m s")
    parser.add_argument(
        "--flights", type=positive_int, default=4000, help="independent flights per candidate"
    )
    args = begin(parser, "Residual-rate bound on the mean flight and on 95 % of flights")
    scenario = preset("paper")
    rows = []
    print(
        "L | bound | members | s | nearest member: reported mean, p95 (worst candidate) | "
        "its flights above the bound | most flights above, any member | #0 confirmed "
        "6x process / 6x gyro"
    )
    for length in args.lengths:
        for name in ("max_final_rate_rad_s", "max_final_rate_p95_rad_s"):
            started = time.perf_counter()
            result = pareto_search(
                scenario,
                sequence_length=length,
                seed=args.seed,
                operator=OperatorSettings(
                    constraints={name: args.bound, "max_impulse_nms": args.max_impulse}
                ),
            )
            elapsed = time.perf_counter() - started
            front = result.front or {}
            members = front.get("members", [])
            if not members:
                print(f"{length} | {name} | 0 | {elapsed:.1f} | no member")
                continue
            sequences = np.array([m["sequence"] for m in members])
            above = flights_above(scenario, sequences, args.bound, args.flights, args.seed + 99)
            worst = above.max(axis=1)  # (P,): the candidate with most flights above
            key = "final_rate_p95_rad_s" if "p95" in name else "final_rate_max_rad_s"
            nearest = int(np.argmax([m["scores"][key] for m in members]))
            scores = members[nearest]["scores"]
            confirmation = front.get("confirmation") or {}
            confirmed = " / ".join(f"{a:.4f}" for a in confirmation.get("accuracy_by_noise", []))
            print(
                f"{length} | {name} <= {args.bound:g} | {len(members)} | {elapsed:.1f} | "
                f"#{nearest}: {scores['final_rate_max_rad_s']:.4f}, "
                f"{scores['final_rate_p95_rad_s']:.4f} | {worst[nearest]:.1%} | "
                f"{worst.max():.1%} (#{int(np.argmax(worst))}) | {confirmed}"
            )
            rows.append(
                {
                    "length": length,
                    "constraint": name,
                    "bound": args.bound,
                    "members": len(members),
                    "seconds": elapsed,
                    "nearest": nearest,
                    "nearest_scores": scores,
                    "nearest_sequence": members[nearest]["sequence"],
                    "share_above_by_member": worst.tolist(),
                    "confirmation": confirmation,
                }
            )
    write_json(args.json, args, {"flights": args.flights, "rows": rows})


if __name__ == "__main__":
    main()
