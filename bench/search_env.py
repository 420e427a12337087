"""Search-environment steps per second and F1: the fast SequenceSearchEnv against the plain step.

For each sequence length L, on Scenario.paper() with --realisations (20) realisations per
candidate and metric dtw, --sequences (50) seeded random (L, 6) sequences of level indices
0..4 are drawn, and every step of an episode scores the prefix played so far:

- plain: inertia_id.search.reference.plain_prefix_score, which re-simulates the whole prefix one
  series at a time (Python RK4) and clusters it with tslearn's
  TimeSeriesKMeans(n_clusters=5, metric="dtw", random_state=0) with its defaults;
- fast: SequenceSearchEnv(scenario, sequence_length=L, seed=SEED, n_realisations=R),
  reset() then step(row) per row (batched simulation extending the parent prefix,
  band-constrained numba DTW k-means warm-started from the parent, cached prefixes).

Both use the same noise: the plain step gets the noise of a PrefixScorer built with the
same seed, i.e. the env's own draw (common random numbers, one draw for all sequences),
so they see literally the same data; the largest difference between their final rates is
printed to show it. Throughput: the plain step is slow (seconds), so only the first
--plain-episodes sequences are played with it; the fast env plays all of them, and its
figures on the same first few episodes are reported too (like for like). F1 of the full
sequence on all sequences: fast = info["f1"] of the last step; plain = tslearn's
defaults on the full sequence's series from the batched simulator with the same noise
(the same data as the per-series loop to about 1e-12, which the throughput part checks),
since re-running the per-series loop for every sequence would only cost time. numba is
warmed up before anything is timed.

Run: python bench/search_env.py [--lengths 4,10] [--sequences 50] [--json PATH]
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
import warnings
from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    add_realisations,
    base_parser,
    int_list,
    positive_int,
    print_header,
    print_table,
    random_sequence,
    sequence_text,
    summary,
    warm_up_numba,
    write_json,
)

from inertia_id import Scenario, Simulator, match_clusters
from inertia_id.search.env import SequenceSearchEnv
from inertia_id.search.reference import plain_prefix_score
from inertia_id.search.scorer import PrefixScorer, ScorerSettings

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from tslearn.clustering import TimeSeriesKMeans

METRIC = "dtw"
TSLEARN_RANDOM_STATE = 0  # plain_prefix_score's default
TIE = 1e-9  # "fast >= plain" allows this much rounding


def default_plain_episodes(length: int) -> int:
    """Plain episodes per length when none are given: about half a minute to a minute."""
    return 3 if length <= 4 else 2


def plain_episodes_for(args: argparse.Namespace) -> dict[int, int]:
    """Plain episodes per length: one value for all, one per length, or the defaults."""
    given = args.plain_episodes
    if given is None:
        counts = [default_plain_episodes(length) for length in args.lengths]
    elif len(given) == 1:
        counts = given * len(args.lengths)
    elif len(given) == len(args.lengths):
        counts = list(given)
    else:
        raise SystemExit(
            f"--plain-episodes takes one value or one per length ({len(args.lengths)}), "
            f"got {len(given)}"
        )
    return {length: min(c, args.sequences) for length, c in zip(args.lengths, counts, strict=True)}


def tslearn_f1(X: np.ndarray, y: np.ndarray, n_clusters: int) -> float:
    """Macro F1 of tslearn's TimeSeriesKMeans(metric="dtw") with its defaults."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = TimeSeriesKMeans(
            n_clusters=n_clusters, metric=METRIC, random_state=TSLEARN_RANDOM_STATE
        )
        clusters = model.fit_predict(X)
    return match_clusters(y, clusters, n_clusters).f1


def play_plain(
    scenario: Scenario, sequence: np.ndarray, scorer: PrefixScorer
) -> tuple[list[float], list[float], list[float]]:
    """One plain episode: score every prefix; return per-step seconds, F1s and rates."""
    seconds, f1s, rates = [], [], []
    for k in range(1, len(sequence) + 1):
        start = time.perf_counter()
        f1, rate = plain_prefix_score(
            scenario, sequence[:k], scorer.noise, random_state=TSLEARN_RANDOM_STATE
        )
        seconds.append(time.perf_counter() - start)
        f1s.append(f1)
        rates.append(rate)
    return seconds, f1s, rates


def play_fast(
    env: SequenceSearchEnv, sequence: np.ndarray
) -> tuple[list[float], list[float], list[float], int]:
    """One fast episode (reset, then a step per row); per-step seconds, F1s and rates.

    Also counts the steps answered from the scorer's cache.
    """
    env.reset()
    seconds, f1s, rates = [], [], []
    cached = 0
    for row in sequence:
        hits = env.scorer.hits
        start = time.perf_counter()
        _, _, _, _, info = env.step(row)
        seconds.append(time.perf_counter() - start)
        cached += env.scorer.hits > hits
        f1s.append(info["f1"])
        rates.append(info["final_rate_rad_s"])
    return seconds, f1s, rates, cached


def warm_up_env(scenario: Scenario, realisations: int, seed: int) -> float:
    """One tiny fast episode on other noise, so the env's numba kernels are compiled."""
    start = time.perf_counter()
    env = SequenceSearchEnv(
        scenario, sequence_length=2, seed=seed, n_realisations=realisations, metric=METRIC
    )
    env.reset()
    for row in random_sequence(
        np.random.default_rng(seed), 2, scenario.n_thrusters, scenario.n_levels
    ):
        env.step(row)
    return time.perf_counter() - start


def rate_record(name: str, episodes: int, length: int, seconds: float) -> dict[str, Any]:
    steps = episodes * length
    return {
        "implementation": name,
        "episodes": episodes,
        "steps": steps,
        "seconds": seconds,
        "steps_per_s": steps / seconds,
    }


def paired(fast: list[float], plain: list[float]) -> dict[str, float]:
    """Paired comparison of F1s: fraction fast >= plain, mean difference and its 95% CI."""
    diffs = [f - p for f, p in zip(fast, plain, strict=True)]
    n = len(diffs)
    mean = statistics.fmean(diffs)
    half = 1.96 * statistics.stdev(diffs) / math.sqrt(n) if n > 1 else math.nan
    return {
        "n": n,
        "fraction_fast_ge_plain": sum(d >= -TIE for d in diffs) / n,
        "mean_difference": mean,
        "ci95_low": mean - half,
        "ci95_high": mean + half,
    }


def run_length(
    scenario: Scenario, length: int, plain_episodes: int, args: argparse.Namespace
) -> dict[str, Any]:
    k = scenario.n_candidates
    rng = np.random.default_rng([args.seed, length])
    sequences = [
        random_sequence(rng, length, scenario.n_thrusters, scenario.n_levels)
        for _ in range(args.sequences)
    ]
    settings = ScorerSettings(n_realisations=args.realisations, metric=METRIC)
    scorer = PrefixScorer(scenario, length, settings, seed=args.seed)  # the plain side's noise
    env = SequenceSearchEnv(
        scenario,
        sequence_length=length,
        seed=args.seed,
        n_realisations=args.realisations,
        metric=METRIC,
    )
    print(
        f"L = {length}: {args.sequences} random sequences (first: "
        f"{sequence_text(sequences[0])}); plain plays {plain_episodes}, fast all "
        f"{args.sequences}",
        flush=True,
    )

    # Throughput, plain: the first few sequences as episodes.
    plain_eps = []
    for i in range(plain_episodes):
        secs, f1s, rates = play_plain(scenario, sequences[i], scorer)
        plain_eps.append({"seconds": secs, "f1": f1s, "final_rate_rad_s": rates})
        print(
            f"  plain episode {i + 1}/{plain_episodes}: {sum(secs):.1f} s "
            f"({length} steps, last step {secs[-1]:.2f} s), F1 {f1s[-1]:.3f}",
            flush=True,
        )

    # Throughput, fast: every sequence, in order, in one fresh env (its cache starts
    # empty, so the first episodes are exactly comparable with the plain ones).
    fast_eps = []
    for seq in sequences:
        secs, f1s, rates, cached = play_fast(env, seq)
        fast_eps.append(
            {"seconds": secs, "f1": f1s, "final_rate_rad_s": rates, "cached_steps": cached}
        )
    hits, misses = env.scorer.hits, env.scorer.misses
    cached_steps = sum(e["cached_steps"] for e in fast_eps)
    fast_all_s = sum(sum(e["seconds"]) for e in fast_eps)
    fast_same_s = sum(sum(e["seconds"]) for e in fast_eps[:plain_episodes])
    plain_s = sum(sum(e["seconds"]) for e in plain_eps)
    print(
        f"  fast: {args.sequences} episodes in {fast_all_s:.2f} s "
        f"(cache hits {hits}, misses {misses}; {cached_steps} of "
        f"{args.sequences * length} steps answered from the cache)",
        flush=True,
    )
    plain_rec = rate_record("plain (per-series RK4 + tslearn)", plain_episodes, length, plain_s)
    same_rec = rate_record("fast env, same episodes", plain_episodes, length, fast_same_s)
    all_rec = rate_record("fast env, all episodes", args.sequences, length, fast_all_s)
    for rec in (plain_rec, same_rec, all_rec):
        rec["speedup_vs_plain"] = rec["steps_per_s"] / plain_rec["steps_per_s"]

    # Same data: the final rates of every like-for-like step.
    rate_diff = max(
        abs(p - f)
        for pe, fe in zip(plain_eps, fast_eps, strict=False)
        for p, f in zip(pe["final_rate_rad_s"], fe["final_rate_rad_s"], strict=True)
    )
    max_rate = max(max(e["final_rate_rad_s"]) for e in plain_eps)

    # F1 of the full sequence on every sequence; plain via the batched simulator.
    simulator = Simulator(scenario, args.realisations)
    plain_f1 = []
    start = time.perf_counter()
    for i, seq in enumerate(sequences):
        X, y = simulator.run(seq, scorer.noise).dataset()
        plain_f1.append(tslearn_f1(X, y, k))
        if (i + 1) % 10 == 0 or i + 1 == len(sequences):
            print(f"  plain F1: {i + 1}/{len(sequences)} sequences", flush=True)
    plain_f1_s = time.perf_counter() - start
    fast_f1 = [e["f1"][-1] for e in fast_eps]
    episode_f1_diff = max(
        abs(e["f1"][-1] - plain_f1[i]) for i, e in enumerate(plain_eps)
    )  # the episode's plain F1 against the batched-data plain F1

    # The hand-designed sequence as a reference (not timed).
    good = np.asarray([GOOD_SEQUENCE[0]] * length, dtype=int)
    _, good_fast, _, _ = play_fast(env, good)
    X, y = simulator.run(good, scorer.noise).dataset()
    good_plain = tslearn_f1(X, y, k)
    print(flush=True)

    steps = list(range(1, length + 1))
    step_ms = {
        "plain": [
            1e3 * statistics.fmean(e["seconds"][j] for e in plain_eps) for j in range(length)
        ],
        "fast_same": [
            1e3 * statistics.fmean(e["seconds"][j] for e in fast_eps[:plain_episodes])
            for j in range(length)
        ],
        "fast_all": [
            1e3 * statistics.fmean(e["seconds"][j] for e in fast_eps) for j in range(length)
        ],
    }
    return {
        "length": length,
        "sequences": [s.tolist() for s in sequences],
        "plain_episodes": plain_episodes,
        "throughput": [plain_rec, same_rec, all_rec],
        "step_ms_by_prefix_length": {"prefix_length": steps, **step_ms},
        "cache": {
            "hits": hits,
            "misses": misses,
            "steps_answered_from_cache": cached_steps,
            "steps": args.sequences * length,
            "cached_prefixes": env.scorer.cache_size,
        },
        "agreement": {
            "max_abs_final_rate_difference_rad_s": rate_diff,
            "max_final_rate_rad_s": max_rate,
            "max_abs_plain_f1_episode_vs_batched": episode_f1_diff,
        },
        "f1": {
            "plain": plain_f1,
            "fast": fast_f1,
            "plain_summary": summary(plain_f1),
            "fast_summary": summary(fast_f1),
            "paired": paired(fast_f1, plain_f1),
            "plain_fit_s": plain_f1_s,
        },
        "good_sequence": {
            "sequence": good.tolist(),
            "plain_f1": good_plain,
            "fast_f1": good_fast[-1],
        },
        "plain_episode_records": plain_eps,
        "fast_episode_records": fast_eps,
    }


def print_length(rec: dict[str, Any], args: argparse.Namespace) -> None:
    length = rec["length"]
    print_table(
        ["implementation", "episodes", "steps timed", "seconds", "steps/s", "speed-up"],
        [
            [
                t["implementation"],
                t["episodes"],
                t["steps"],
                t["seconds"],
                f"{t['steps_per_s']:,.2f}",
                f"{t['speedup_vs_plain']:.1f}x",
            ]
            for t in rec["throughput"]
        ],
        title=f"L = {length}: environment steps per second ({args.realisations} "
        f"realisations/candidate, metric {METRIC})",
    )
    by_step = rec["step_ms_by_prefix_length"]
    print_table(
        ["prefix length", "plain ms", "fast ms (same episodes)", "fast ms (all episodes)"],
        [
            [p, by_step["plain"][j], by_step["fast_same"][j], by_step["fast_all"][j]]
            for j, p in enumerate(by_step["prefix_length"])
        ],
        title=f"L = {length}: mean time of one step by prefix length",
    )
    agree = rec["agreement"]
    cache = rec["cache"]
    print_table(
        ["check", "value"],
        [
            [
                "max |final rate plain - fast| (rad/s), like-for-like steps",
                agree["max_abs_final_rate_difference_rad_s"],
            ],
            ["max final rate (rad/s), same steps", agree["max_final_rate_rad_s"]],
            [
                "max |plain F1 episode - plain F1 batched data|, full sequence",
                agree["max_abs_plain_f1_episode_vs_batched"],
            ],
            [
                "fast env cache hits / misses (prefixes asked for)",
                f"{cache['hits']} / {cache['misses']}",
            ],
            [
                "fast env steps answered from the cache (no new prefix scored)",
                f"{cache['steps_answered_from_cache']} of {cache['steps']}",
            ],
        ],
        title=f"L = {length}: same data, and the fast env's cache",
    )
    f1 = rec["f1"]
    rows = []
    for name, key in (("plain (tslearn defaults)", "plain"), ("fast env", "fast")):
        s = f1[f"{key}_summary"]
        rows.append(
            [
                name,
                len(f1[key]),
                s["mean"],
                s["median"],
                s["min"],
                s["max"],
                rec["good_sequence"][f"{key}_f1"],
            ]
        )
    print_table(
        ["implementation", "sequences", "F1 mean", "F1 median", "F1 min", "F1 max", "good seq. F1"],
        rows,
        title=f"L = {length}: F1 of the full sequence (good seq. = "
        f"{sequence_text(rec['good_sequence']['sequence'])})",
    )
    p = f1["paired"]
    print_table(
        ["pairs", "fast >= plain", "mean F1 fast - plain", "95% CI"],
        [
            [
                p["n"],
                f"{100 * p['fraction_fast_ge_plain']:.0f}%",
                f"{p['mean_difference']:+.3f}",
                f"[{p['ci95_low']:+.3f}, {p['ci95_high']:+.3f}]",
            ]
        ],
        title=f"L = {length}: paired F1 difference on the same sequences "
        "(CI = mean ± 1.96 sd / sqrt(n))",
    )


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--lengths", type=int_list, default=[4, 10], help="sequence lengths L (comma-separated)"
    )
    parser.add_argument(
        "--sequences", type=positive_int, default=50, help="random sequences per length"
    )
    add_realisations(parser)
    parser.add_argument(
        "--plain-episodes",
        type=int_list,
        default=None,
        help="sequences played with the plain step: one value for every length or one per "
        "length (default: 3 for L <= 4, else 2)",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke run (lengths 2, sequences 4, plain-episodes 1), to check the script works",
    )
    args = parser.parse_args()
    if args.quick:
        args.lengths, args.sequences, args.plain_episodes = [2], 4, [1]
    episodes = plain_episodes_for(args)
    print_header("Search environment: fast SequenceSearchEnv vs the plain step", args)

    scenario = Scenario.paper()
    print(
        f"scenario: {scenario.name}, {scenario.n_candidates} candidates, "
        f"{scenario.n_thrusters} thrusters, {scenario.n_levels} levels, "
        f"{scenario.timing.samples_per_step} samples per step; {args.realisations} "
        f"realisations per candidate, metric {METRIC}"
    )
    print(
        "plain step: reference.plain_prefix_score (whole prefix re-simulated series by "
        f"series, then tslearn TimeSeriesKMeans(metric='{METRIC}') defaults, "
        f"random_state={TSLEARN_RANDOM_STATE})"
    )
    print(
        f"fast step: SequenceSearchEnv(seed={args.seed}, n_realisations={args.realisations}) "
        f"with ScorerSettings defaults otherwise; {ScorerSettings().as_dict()}"
    )
    print(
        f"both on the noise of seed {args.seed} (one draw shared by every sequence of a "
        "length); the plain F1 of every sequence is tslearn on the batched simulator's "
        "series (the same data as the per-series loop to ~1e-12, checked below), so the "
        "per-series loop is not re-run for it"
    )
    warm = warm_up_numba()
    warm_env = warm_up_env(scenario, args.realisations, args.seed + 1_000_003)
    print(
        f"numba warm-up: tslearn / classifier kernels {warm:.1f} s, one 2-step env episode "
        f"on other noise {warm_env:.1f} s; JIT compile time is NOT in the figures below."
    )
    print(flush=True)

    records = []
    for length in args.lengths:
        rec = run_length(scenario, length, episodes[length], args)
        print_length(rec, args)
        records.append(rec)

    rows = []
    for rec in records:
        plain_t, same_t, all_t = rec["throughput"]
        f1, p = rec["f1"], rec["f1"]["paired"]
        rows.append(
            [
                rec["length"],
                plain_t["steps"],
                f"{plain_t['steps_per_s']:,.2f}",
                all_t["steps"],
                f"{all_t['steps_per_s']:,.2f}",
                f"{all_t['speedup_vs_plain']:.1f}x",
                f"{same_t['speedup_vs_plain']:.1f}x",
                f1["plain_summary"]["mean"],
                f1["fast_summary"]["mean"],
                f"{p['mean_difference']:+.3f} ± {(p['ci95_high'] - p['ci95_low']) / 2:.3f}",
            ]
        )
    print_table(
        [
            "L",
            "plain steps",
            "plain steps/s",
            "fast steps",
            "fast steps/s",
            "speed-up",
            "speed-up (same ep.)",
            "plain F1 mean",
            "fast F1 mean",
            "F1 fast - plain",
        ],
        rows,
        title=f"Summary ({args.sequences} sequences per length; speed-up = fast steps/s over "
        "all episodes / plain steps/s; 'same ep.' = fast on the plain episodes only)",
    )
    write_json(
        args.json,
        args,
        {
            "benchmark": "search_env",
            "scenario": scenario.name,
            "metric": METRIC,
            "tslearn_random_state": TSLEARN_RANDOM_STATE,
            "scorer_settings": ScorerSettings(
                n_realisations=args.realisations, metric=METRIC
            ).as_dict(),
            "numba_warmup_s": warm + warm_env,
            "numba_warmup_excluded": True,
            "lengths": records,
        },
    )


if __name__ == "__main__":
    main()
