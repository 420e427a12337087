"""How long loading a classifier document takes and how much memory it needs: as shipped
(``registry.load_classifier``: a document laid out as canonical JSON verified by hashing
its payload's text as read, and the parsed document let go before the covariances are
factored) against before (the load as ``--classifier`` did it: the parsed payload
re-encoded as canonical JSON to be hashed, and held while the covariances were factored).
Give documents this code wrote (``inertia-id train``): one written before is laid out
otherwise, and both variants re-encode it.

Each load runs in a fresh Python process (so that its peak memory is its own), best of
``--repeats`` for the time; a second pass under tracemalloc gives the load's peak traced
memory, and the process's peak resident memory less its resident memory after the
imports is printed beside it. Both variants then score the same fixed telemetry
(``--realisations`` seeded series per candidate of the document's own scenario and
sequence at 1x); the largest difference of their log-likelihoods and whether every
verdict agrees are printed. The documents are any ``inertia-id train`` wrote (the
default kind, marginal likelihood, is the one whose load factors covariances), e.g.
``python -m inertia_id.cli train --sequence '...' --out c8.json``.

Run: python bench/classifier_load.py --classifier c4.json c8.json [--repeats 1]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
from _common import base_parser, positive_int, print_header, print_table, write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

VARIANTS = ("shipped", "before")


def _rss_mb() -> float:
    """This process's resident memory now, MB (Linux)."""
    with open("/proc/self/statm", encoding="ascii") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def child(variant: str, path: str, repeats: int, realisations: int, seed: int, out: str) -> None:
    """One variant's figures for one document, written as JSON to ``out``."""
    from inertia_id import simulate
    from inertia_id.classifiers import documents, registry

    rss_imports = _rss_mb()

    def load() -> Any:
        if variant == "before":
            # The caller holds the parsed document while the classifier is built, and
            # hands over no text: the payload is re-encoded to be hashed.
            return registry.classifier_from_json(
                documents.parse(documents.read_file(path), unique_keys=True)
            )
        return registry.load_classifier(path)

    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        model = load()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
        del model
    rss_peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    tracemalloc.start()
    model = load()
    traced_peak = tracemalloc.get_traced_memory()[1] / 1e6
    tracemalloc.stop()
    if model.scenario_ is None or model.sequence_ is None:
        raise SystemExit(f"{path}: the document holds no scenario and sequence to simulate")
    X, _ = simulate(
        model.scenario_, model.sequence_, realisations, np.random.default_rng(seed)
    ).dataset()
    figures = {
        "wall_s": walls,
        "cpu_s": cpus,
        "traced_peak_mb": traced_peak,
        "rss_peak_mb": rss_peak,
        "rss_imports_mb": rss_imports,
        "log_likelihood": model.log_likelihood(X).tolist(),
        "predict": model.predict(X).tolist(),
    }
    Path(out).write_text(json.dumps(figures))


def run_child(variant: str, path: str, args: Any) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "figures.json")
        command = [sys.executable, __file__, "--child", variant, path, out]
        command += ["--repeats", str(args.repeats), "--realisations", str(args.realisations)]
        command += ["--seed", str(args.seed)]
        subprocess.run(command, check=True)
        result: dict[str, Any] = json.loads(Path(out).read_text())
        return result


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--classifier", nargs="+", default=[], help="classifier documents (JSON) to load"
    )
    parser.add_argument("--repeats", type=positive_int, default=1, help="timed loads, best of")
    parser.add_argument(
        "--realisations",
        type=positive_int,
        default=4,
        help="telemetry series per candidate both variants score",
    )
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        variant, path, out = args.child
        child(variant, path, args.repeats, args.realisations, args.seed, out)
        return
    del args.child
    print_header("Classifier load: time and peak memory, shipped vs before", args)
    if not args.classifier:
        parser.error("give --classifier FILE ... (documents inertia-id train wrote)")
    rows, figures = [], {}
    for path in args.classifier:
        size_mb = os.path.getsize(path) / 1e6
        results = {variant: run_child(variant, path, args) for variant in VARIANTS}
        shipped, before = results["shipped"], results["before"]
        difference = float(
            np.max(np.abs(np.subtract(shipped["log_likelihood"], before["log_likelihood"])))
        )
        same = shipped["predict"] == before["predict"]
        for variant in VARIANTS:
            r = results[variant]
            rows.append(
                [
                    Path(path).name,
                    size_mb,
                    variant,
                    min(r["wall_s"]),
                    min(r["cpu_s"]),
                    r["traced_peak_mb"],
                    r["rss_peak_mb"] - r["rss_imports_mb"],
                    difference,
                    same,
                ]
            )
        figures[path] = {"size_mb": size_mb, **results, "max_log_likelihood_difference": difference}
    print_table(
        [
            "document",
            "MB",
            "variant",
            "load s (wall)",
            "load s (cpu)",
            "traced peak MB",
            "RSS over imports MB",
            "max |Δ log-lik|",
            "same verdicts",
        ],
        rows,
    )
    write_json(args.json, args, {"documents": figures})


if __name__ == "__main__":
    main()
