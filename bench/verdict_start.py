"""How long a new verdict process takes to be ready: forked from the warm fork server
(as shipped) against spawned afresh (as before).

Each start builds a :class:`app.verdicts.VerdictProcess` on a throwaway SQLite file,
starts it and waits for its first answer (the child's process id, after its initialiser:
imports, numba kernels), then closes it. The fork server is one per process and starts
with the first forked child, so the first forked start includes it; the later ones are
what a replacement child (after a crash or a hung verdict), or every further app a test
process builds, costs. ``--starts`` of each, side by side in one run.

Run: python bench/verdict_start.py [--starts 4]
"""

from __future__ import annotations

import multiprocessing
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _common import base_parser, begin, positive_int, print_table, write_json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import app.verdicts as verdicts


def starts(n: int, url: str) -> list[float]:
    times = []
    for _ in range(n):
        began = time.perf_counter()
        process = verdicts.VerdictProcess(url, 4)
        process.start()
        process.pid()
        times.append(time.perf_counter() - began)
        process.close()
    return times


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--starts", type=positive_int, default=4, help="starts of each kind")
    args = begin(parser, "Verdict process start: forked from the fork server vs spawned")
    with tempfile.TemporaryDirectory() as folder:
        url = f"sqlite:///{folder}/bench.db"
        forked = starts(args.starts, url)
        shipped = verdicts._fork_server
        verdicts._fork_server = lambda: multiprocessing.get_context("spawn")  # type: ignore[assignment]
        try:
            spawned = starts(args.starts, url)
        finally:
            verdicts._fork_server = shipped
    rows = [
        [
            "forked (shipped)",
            f"{forked[0]:.2f}",
            f"{statistics.median(forked[1:] or forked):.2f}",
            f"{max(forked[1:] or forked):.2f}",
        ],
        [
            "spawned (before)",
            f"{spawned[0]:.2f}",
            f"{statistics.median(spawned[1:] or spawned):.2f}",
            f"{max(spawned[1:] or spawned):.2f}",
        ],
    ]
    print_table(["start", "first s", "later: median s", "later: max s"], rows)
    write_json(args.json, args, {"forked_s": forked, "spawned_s": spawned})


if __name__ == "__main__":
    main()
