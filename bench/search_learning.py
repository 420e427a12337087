"""Does PPO learn? PPO against random search at the same number of environment steps.

Both search the paper preset for a 4-step sequence in the same environment (same seed,
so the same noise draw scores both), PPO at the paper's hyperparameters. Printed per
rollout (2048 steps): each method's mean episode reward and mean F1 over the episodes of
that rollout, and its best F1 so far; then the steps and wall time each took to first
reach F1 = 1, and each best sequence re-scored on fresh draws (independent seed).

The two run side by side in two processes (one core each), so the wall times are
comparable with each other; run nothing else meanwhile.

    python bench/search_learning.py [--rollouts 10] [--seed 0] [--json out.json]
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from _common import add_length, base_parser, begin, positive_int, print_table, write_json


def _run(method: str, timesteps: int, seed: int, length: int) -> dict[str, Any]:
    from inertia_id import Scenario
    from inertia_id.search import SearchProgress, search

    first_hit: dict[str, float] = {}
    started = time.perf_counter()

    def progress(report: SearchProgress) -> None:
        if report.best is not None and report.best.f1 >= 1.0 and "episode" not in first_hit:
            first_hit["episode"] = report.best.episode
            first_hit["timesteps_by"] = report.timesteps
            first_hit["wall_s_by"] = time.perf_counter() - started

    result = search(
        method,
        Scenario.paper(),
        sequence_length=length,
        total_timesteps=timesteps,
        seed=seed,
        patience_episodes=None,
        progress=progress,
    )
    doc = result.to_dict()
    doc["first_f1_1"] = first_hit
    return doc


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--rollouts", type=positive_int, default=10, help="PPO rollouts")
    add_length(parser)
    args = begin(parser, "PPO vs random search at equal environment steps (paper preset)")
    timesteps = args.rollouts * 2048
    with ProcessPoolExecutor(max_workers=2) as pool:
        futures = {
            m: pool.submit(_run, m, timesteps, args.seed, args.length) for m in ("ppo", "random")
        }
        results = {m: f.result() for m, f in futures.items()}
    ppo, rnd = results["ppo"], results["random"]
    rows = []
    for p, r in zip(ppo["curve"], rnd["curve"], strict=False):
        rows.append(
            [
                p["timesteps"],
                p["mean_episode_reward"],
                r["mean_episode_reward"],
                p["mean_f1"],
                r["mean_f1"],
                p["best_f1"],
                r["best_f1"],
            ]
        )
    print_table(
        [
            "env steps",
            "PPO mean reward",
            "random mean reward",
            "PPO mean F1",
            "random mean F1",
            "PPO best F1",
            "random best F1",
        ],
        rows,
        title="Learning curve (means over the episodes of each 2048-step rollout)",
    )
    summary_rows = []
    for name, doc in (("ppo", ppo), ("random", rnd)):
        hit = doc["first_f1_1"]
        summary_rows.append(
            [
                name,
                doc["best"]["f1"],
                doc["fresh"]["f1_mean"],
                doc["fresh"]["f1_min"],
                doc["best"]["final_rate_rad_s"],
                doc["best"]["fuel_nms"],
                hit.get("episode", None) and hit["episode"] * args.length,
                hit.get("wall_s_by"),
                doc["timesteps"],
                doc["wall_time_s"],
                str(doc["best"]["sequence"]),
            ]
        )
    print_table(
        [
            "method",
            "best F1 (search draw)",
            "fresh F1 mean",
            "fresh F1 min",
            "final rate rad/s",
            "fuel N m s",
            "steps to F1=1",
            "wall s to F1=1 (by)",
            "steps",
            "wall s",
            "best sequence",
        ],
        summary_rows,
        title="Best sequences ('steps to F1=1': env steps when the first F1 = 1 sequence "
        "ended; '-': never)",
    )
    write_json(args.json, args, {"ppo": ppo, "random": rnd})


if __name__ == "__main__":
    main()
