"""How long until a search holds a sequence that clusters perfectly? Objectives and methods.

Each run searches the paper preset for a ``--length`` (4) step sequence with one method
and one objective (``--runs``, default CEM + separability, CEM + F1, PPO + separability at
the paper's hyperparameters, random + separability), seed ``--seed``, ``ScorerSettings``
defaults otherwise, and is stopped as soon as its best sequence has a clustering F1 of
1.0 on the search's own noise draw, or after ``--cap`` (300) seconds. With the F1
objective the search's score is that F1; with the separability objective every new
best sequence is clustered on the same draw (ScorerSettings defaults, objective "f1")
by the benchmark, and that time is taken out of the figures. Printed per run: the wall
time and environment steps to the first F1 = 1 best sequence, then that sequence's F1
on 5 fresh draws (independent seed; the search's own F1 is optimistic), final rate,
fuel and the search's own score for it. The runs go one after the other in this process
(single-threaded); the load average is printed with each, since the machine may be
shared.

    python bench/search_objectives.py [--runs cem:separability,ppo:f1] [--cap 300] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from typing import Any

from _common import (
    GOOD_SEQUENCE,
    add_length,
    base_parser,
    begin,
    positive_int,
    print_table,
    write_json,
)

from inertia_id import Scenario
from inertia_id.search import (
    SCORER_OBJECTIVES,
    SEARCH_METHODS,
    PrefixScorer,
    ScorerSettings,
    SearchTracker,
    search,
)

DEFAULT_RUNS = "cem:separability,cem:f1,ppo:separability,random:separability"


def runs_list(text: str) -> list[tuple[str, str]]:
    """argparse type: method:objective pairs separated by commas."""
    pairs = []
    for part in text.split(","):
        method, _, objective = part.strip().partition(":")
        if method not in SEARCH_METHODS or objective not in SCORER_OBJECTIVES:
            raise argparse.ArgumentTypeError(
                f"expected method:objective with a method in {list(SEARCH_METHODS)} and an "
                f"objective in {list(SCORER_OBJECTIVES)}, got {part!r}"
            )
        pairs.append((method, objective))
    return pairs


class FirstPerfect:
    """Watches every search's tracker for the first best sequence that clusters at F1 = 1.

    Wraps :meth:`SearchTracker.on_step`: when a step brings a new best, its clustering
    F1 on the search's draw is looked up (the search's own score with the F1 objective,
    a clustering by a scorer of the same seed otherwise), the lookup's time set aside.
    """

    def __init__(self, scenario: Scenario, length: int, settings: ScorerSettings, seed: int):
        self.checker = PrefixScorer(scenario, length, replace(settings, objective="f1"), seed=seed)
        self.objective = settings.objective
        self.started = time.perf_counter()
        self.set_aside = 0.0
        self.hit: dict[str, Any] | None = None
        self.checked = 0

    def elapsed(self) -> float:
        return time.perf_counter() - self.started - self.set_aside

    def on_new_best(self, tracker: SearchTracker) -> None:
        if self.hit is not None or tracker.best is None:
            return
        begun = time.perf_counter()
        if self.objective == "f1":
            f1 = tracker.best.f1
        else:
            f1 = self.checker.score(tracker.best.sequence).f1
            self.checked += 1
        self.set_aside += time.perf_counter() - begun
        if f1 >= 1.0:
            self.hit = {
                "wall_s": self.elapsed(),
                "timesteps": tracker.timesteps,
                "episodes": tracker.episodes,
                "sequence": tracker.best.sequence,
                "search_score": tracker.best.f1,
            }


def run(
    scenario: Scenario, method: str, objective: str, args: argparse.Namespace
) -> dict[str, Any]:
    settings = ScorerSettings(objective=objective)
    watch = FirstPerfect(scenario, args.length, settings, args.seed)
    original = SearchTracker.on_step

    def on_step(self: SearchTracker, reward: float, done: bool, info: dict[str, Any]) -> bool:
        improved = original(self, reward, done, info)
        if improved:
            watch.on_new_best(self)
        return improved

    def should_stop() -> bool:
        return watch.hit is not None or watch.elapsed() > args.cap

    load_before = os.getloadavg()
    SearchTracker.on_step = on_step  # type: ignore[method-assign]
    try:
        watch.started = time.perf_counter()
        result = search(
            method,
            scenario,
            sequence_length=args.length,
            total_timesteps=args.timesteps,
            seed=args.seed,
            settings=settings,
            patience_episodes=None,
            should_stop=should_stop,
        )
    finally:
        SearchTracker.on_step = original  # type: ignore[method-assign]
    return {
        "method": method,
        "objective": objective,
        "hit": watch.hit,
        "new_bests_clustered": watch.checked,
        "result": result.to_dict(),
        "load_before": load_before,
        "load_after": os.getloadavg(),
    }


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--runs", type=runs_list, default=runs_list(DEFAULT_RUNS),
                        help="method:objective pairs, comma-separated")  # fmt: skip
    add_length(parser)
    parser.add_argument("--cap", type=float, default=300.0, help="seconds per run at most")
    parser.add_argument(
        "--timesteps", type=positive_int, default=2_000_000, help="step budget per run"
    )
    args = begin(parser, "Time to a perfectly clustering sequence, by search method and objective")
    scenario = Scenario.paper()
    # numba's JIT compile of the DTW k-means, on other noise, before anything is timed.
    PrefixScorer(scenario, 1, ScorerSettings(), seed=args.seed + 1).score(GOOD_SEQUENCE[:1])
    print(f"ScorerSettings defaults: {ScorerSettings().as_dict()}", flush=True)
    print(flush=True)
    records = []
    for method, objective in args.runs:
        record = run(scenario, method, objective, args)
        records.append(record)
        hit, result = record["hit"], record["result"]
        print(
            f"{method} + {objective}: "
            + (
                f"F1 = 1 after {hit['wall_s']:.1f} s, {hit['timesteps']} env steps"
                if hit
                else f"no F1 = 1 within {args.cap:g} s"
            )
            + f"; ran {result['wall_time_s']:.1f} s, {result['timesteps']} steps, stopped "
            f"{result['stopped']}; load average before {record['load_before'][0]:.2f}, "
            f"after {record['load_after'][0]:.2f}",
            flush=True,
        )
    print(flush=True)
    rows = []
    for record in records:
        hit, result = record["hit"], record["result"]
        fresh = result["fresh"]
        rows.append(
            [
                record["method"],
                record["objective"],
                hit["wall_s"] if hit else None,
                hit["timesteps"] if hit else None,
                hit["episodes"] if hit else None,
                fresh["f1_mean"],
                fresh["f1_min"],
                result["best"]["f1"],
                result["best"]["final_rate_rad_s"],
                result["best"]["fuel_nms"],
                str(result["best"]["sequence"]),
            ]
        )
    print_table(
        [
            "method",
            "objective",
            "wall s to F1=1",
            "env steps",
            "episodes",
            "fresh F1 mean",
            "fresh F1 min",
            "search score",
            "final rate rad/s",
            "fuel N m s",
            "sequence (found, or the best at the cap)",
        ],
        rows,
        title=f"First best sequence with clustering F1 = 1 on the search's draw (seed "
        f"{args.seed}, L = {args.length}; '-': none within {args.cap:g} s; fresh F1 on 5 "
        "independent draws; search score = F1 or separability)",
    )
    write_json(args.json, args, {"benchmark": "search_objectives", "runs": records})


if __name__ == "__main__":
    main()
