"""Classifier fit time and F1 per metric: our InertiaClassifier against tslearn defaults.

Data: the paper preset, K = 5 candidates x 20 realisations, 4-step sequences (the
hand-designed good sequence and one random sequence), measured rates in rad/s.

- ours: InertiaClassifier(metric, random_state=seed).fit(X, y) with its defaults
  (n_init=5, series scaled to unit RMS, auto gamma and DTW inertia for soft-DTW);
- tslearn defaults: TimeSeriesKMeans(n_clusters=5, metric=metric,
  random_state=seed).fit(X) on the raw rad/s series (n_init=1, gamma=1).

F1 is the macro F1 of the clustering under the best cluster-to-candidate matching
(inertia_id.match_clusters). Both are then refitted over --restarts random_state values
on the good sequence, to show how often a single initialisation lands in a poor local
optimum. numba's JIT compilation is done on a tiny problem before anything is timed.

Run: python bench/classifier_fit.py [--metrics dtw,softdtw,euclidean] [--restarts 5]
"""

from __future__ import annotations

import argparse
import warnings
from typing import Any

import numpy as np
from _common import (
    GOOD_SEQUENCE,
    add_realisations,
    add_steps,
    base_parser,
    begin,
    print_table,
    random_sequence,
    sequence_text,
    summary,
    timed,
    warm_up_numba,
    write_json,
)

from inertia_id import METRICS, InertiaClassifier, Scenario, match_clusters, simulate

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from tslearn.clustering import TimeSeriesKMeans

OURS = "ours (InertiaClassifier)"
TSLEARN = "tslearn defaults"


def metric_list(text: str) -> list[str]:
    metrics = [m.strip() for m in text.split(",") if m.strip()]
    bad = [m for m in metrics if m not in METRICS]
    if not metrics or bad:
        raise argparse.ArgumentTypeError(f"metrics must be among {list(METRICS)}, got {text!r}")
    return metrics


def fit_ours(
    X: np.ndarray, y: np.ndarray, metric: str, random_state: int
) -> tuple[float, float, dict[str, float]]:
    model = InertiaClassifier(metric, random_state=random_state)
    seconds, model = timed(lambda: model.fit(X, y))
    f1 = match_clusters(y, model.labels_, model.n_candidates_).f1
    return seconds, f1, {"gamma": model.gamma_, "inertia": model.inertia_}


def fit_tslearn(
    X: np.ndarray, y: np.ndarray, metric: str, random_state: int
) -> tuple[float, float, dict[str, float]]:
    n_clusters = int(y.max()) + 1
    kmeans = TimeSeriesKMeans(n_clusters=n_clusters, metric=metric, random_state=random_state)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seconds, kmeans = timed(lambda: kmeans.fit(X))
    f1 = match_clusters(y, kmeans.labels_, n_clusters).f1
    return seconds, f1, {"inertia": float(kmeans.inertia_)}


FITTERS = {OURS: fit_ours, TSLEARN: fit_tslearn}


def gamma_text(fit: dict[str, Any]) -> str:
    """Soft-DTW gamma of a fit: ours on unit-RMS series, tslearn's default 1 on rad/s."""
    if fit["metric"] != "softdtw":
        return "-"
    if "gamma" in fit:
        return f"{fit['gamma']:.3g} (unit RMS)"
    return "1 (rad/s)"


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--metrics",
        type=metric_list,
        default=list(METRICS),
        help="comma-separated subset of " + ",".join(METRICS),
    )
    add_realisations(parser)
    add_steps(parser)
    parser.add_argument(
        "--restarts",
        type=int,
        default=5,
        help="random_state values (seed, seed+1, ...) each estimator is fitted "
        "with on the good sequence; 0 skips this part",
    )
    args = begin(parser, "Classifier fit: InertiaClassifier vs tslearn TimeSeriesKMeans defaults")

    scenario = Scenario.paper()
    rng = np.random.default_rng(args.seed)
    sequences = {
        "good": np.asarray(GOOD_SEQUENCE, dtype=int),
        "random": random_sequence(rng, args.steps, scenario.n_thrusters, scenario.n_levels),
    }
    data = {}
    for i, (name, seq) in enumerate(sequences.items()):
        result = simulate(scenario, seq, args.realisations, np.random.default_rng([args.seed, i]))
        data[name] = result.dataset()
        X = data[name][0]
        print(
            f"{name:6s} sequence {sequence_text(seq)}: X {X.shape} (series, samples, axes), "
            f"RMS rate {np.sqrt(np.mean(X**2)):.3g} rad/s"
        )

    warm = warm_up_numba()
    print(
        f"numba warm-up: tiny DTW / soft-DTW / euclidean fits of both estimators took "
        f"{warm:.1f} s before timing; JIT compile time is NOT in the figures below."
    )
    print(
        "ours: n_init=5, unit-RMS scaling, gamma='auto' and dtw_inertia for softdtw; "
        "tslearn: n_init=1, raw rad/s, gamma=1 for softdtw. Single-threaded fits."
    )
    print(flush=True)

    fits = []
    for metric in args.metrics:
        for seq_name, (X, y) in data.items():
            for estimator, fitter in FITTERS.items():
                seconds, f1, extra = fitter(X, y, metric, args.seed)
                fits.append(
                    {
                        "metric": metric,
                        "sequence": seq_name,
                        "estimator": estimator,
                        "random_state": args.seed,
                        "fit_s": seconds,
                        "f1": f1,
                        **extra,
                    }
                )
                print(
                    f"  fit {metric:9s} {seq_name:6s} {estimator:25s} "
                    f"{seconds:8.2f} s  F1 {f1:.3f}",
                    flush=True,
                )
    print()

    restarts = []
    if args.restarts > 0:
        X, y = data["good"]
        for metric in args.metrics:
            for estimator, fitter in FITTERS.items():
                f1s, secs = [], []
                for rs in range(args.seed, args.seed + args.restarts):
                    reuse = [
                        f
                        for f in fits
                        if f["metric"] == metric
                        and f["sequence"] == "good"
                        and f["estimator"] == estimator
                        and f["random_state"] == rs
                    ]
                    if reuse:
                        seconds, f1 = reuse[0]["fit_s"], reuse[0]["f1"]
                    else:
                        seconds, f1, _ = fitter(X, y, metric, rs)
                        print(
                            f"  restart {metric:9s} good   {estimator:25s} random_state={rs:<3d}"
                            f"{seconds:8.2f} s  F1 {f1:.3f}",
                            flush=True,
                        )
                    f1s.append(f1)
                    secs.append(seconds)
                restarts.append(
                    {
                        "metric": metric,
                        "estimator": estimator,
                        "random_states": list(range(args.seed, args.seed + args.restarts)),
                        "f1": f1s,
                        "fit_s": secs,
                        "f1_summary": summary(f1s),
                        "fit_s_median": summary(secs)["median"],
                    }
                )
        print()

    print_table(
        ["metric", "sequence", "estimator", "fit s", "F1", "soft-DTW gamma"],
        [
            [f["metric"], f["sequence"], f["estimator"], f["fit_s"], f["f1"], gamma_text(f)]
            for f in fits
        ],
        title=f"Fit time and F1, random_state={args.seed} "
        f"({scenario.n_candidates} candidates x {args.realisations} realisations, "
        f"{args.steps} steps)",
    )
    speed_rows = []
    for metric in args.metrics:
        for seq_name in data:
            pair = {
                f["estimator"]: f
                for f in fits
                if f["metric"] == metric and f["sequence"] == seq_name
            }
            ratio = pair[OURS]["fit_s"] / pair[TSLEARN]["fit_s"]
            speed_rows.append(
                [
                    metric,
                    seq_name,
                    f"{ratio:.2f}x",
                    f"{pair[OURS]['f1'] - pair[TSLEARN]['f1']:+.3f}",
                ]
            )
    print_table(
        ["metric", "sequence", "fit time ours / tslearn", "F1 ours - tslearn"],
        speed_rows,
        title="Ours relative to tslearn defaults",
    )
    if restarts:
        print_table(
            [
                "metric",
                "estimator",
                "runs",
                "F1 min",
                "F1 median",
                "F1 max",
                "F1 per run",
                "median fit s",
            ],
            [
                [
                    r["metric"],
                    r["estimator"],
                    len(r["f1"]),
                    r["f1_summary"]["min"],
                    r["f1_summary"]["median"],
                    r["f1_summary"]["max"],
                    " ".join(f"{v:.2f}" for v in r["f1"]),
                    r["fit_s_median"],
                ]
                for r in restarts
            ],
            title=f"Good sequence over random_state = {args.seed}..{args.seed + args.restarts - 1}"
            " (one fit each; tslearn n_init=1, ours n_init=5)",
        )

    write_json(
        args.json,
        args,
        {
            "benchmark": "classifier_fit",
            "scenario": scenario.name,
            "sequences": {k: v.tolist() for k, v in sequences.items()},
            "numba_warmup_s": warm,
            "numba_warmup_excluded": True,
            "fits": fits,
            "restarts": restarts,
        },
    )


if __name__ == "__main__":
    main()
