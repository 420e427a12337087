"""Start-up cost: ``import inertia_id`` and the ``inertia-id`` command's quick answers.

Prints, for one source tree (this checkout, or another one with ``--repo``):

- ``python -X importtime -c "import inertia_id"``: the total and the top-level imports
  that cost most (cumulative microseconds, as ``-X importtime`` reports them), and which
  heavy packages the import pulled in;
- the wall time of ``inertia-id --help`` and of
  ``inertia-id scenario --preset paper --out FILE``, each run in a fresh process.

Every figure is a fresh interpreter, so the operating system's file cache is warm after
the first run: one unmeasured run comes first, then ``--repeats`` measured ones (median
and best printed). ``--repo`` points ``PYTHONPATH`` at another checkout, e.g. the tree
before the redesign (``git worktree add /tmp/before 9a0a415``), so both are measured
with the same interpreter and packages::

    python bench/import_time.py
    python bench/import_time.py --repo /tmp/before
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import base_parser, positive_int, print_table, write_json

#: Packages whose presence after ``import inertia_id`` the issue asks about.
HEAVY = ("torch", "tslearn", "stable_baselines3", "sklearn", "numba", "scipy", "plotly")

_IMPORTTIME = re.compile(r"^import time:\s+(\d+)\s+\|\s+(\d+)\s+\|\s*(\S+)")
_CLI = "import sys; from inertia_id.cli import main; sys.argv[0] = 'inertia-id'; main()"


#: This checkout, measured when no --repo is given.
_HERE = Path(__file__).resolve().parent.parent


def _environment(repo: Path | None) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(repo or _HERE), *filter(None, [env.get("PYTHONPATH", "")])]
    )
    return env


def import_profile(repo: Path | None) -> tuple[int, list[tuple[str, int]], list[str], str]:
    """Total microseconds of ``import inertia_id``, the costliest top-level imports below
    it, the heavy packages loaded, and the file ``inertia_id`` was imported from."""
    probe = (
        "import sys, inertia_id; "
        f"print(inertia_id.__file__); print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", probe],
        capture_output=True,
        text=True,
        env=_environment(repo),
        cwd=repo or _HERE,
        check=True,
    )
    rows = []
    for line in done.stderr.splitlines():
        match = _IMPORTTIME.match(line)
        if match:
            rows.append((match.group(3), int(match.group(2))))
    total = next(cumulative for name, cumulative in rows if name == "inertia_id")
    # A package is often first imported through one of its modules (tslearn through
    # tslearn.clustering): its cost is the largest cumulative row under its root name.
    # Rows nest, so torch's cost is also inside tslearn's when tslearn imports it.
    by_root: dict[str, int] = {}
    for name, cumulative in rows:
        root = name.split(".")[0]
        by_root[root] = max(by_root.get(root, 0), cumulative)
    by_root.pop("inertia_id", None)
    own = [(name, cumulative) for name, cumulative in rows if name.startswith("inertia_id.")]
    offenders = sorted(by_root.items(), key=lambda item: -item[1])[:8]
    offenders += sorted(own, key=lambda item: -item[1])[:6]
    origin, heavy = [*done.stdout.splitlines(), "", ""][:2]
    return total, offenders, [m for m in heavy.split(",") if m], origin


def wall_times(argv: list[str], repo: Path | None, repeats: int) -> list[float]:
    """Seconds of ``inertia-id ARGV`` in fresh processes, after one unmeasured run."""
    command = [sys.executable, "-c", _CLI, *argv]
    env = _environment(repo)
    # `python -c` puts the working directory first on sys.path: run in the tree measured.
    where = repo or _HERE
    subprocess.run(command, capture_output=True, env=env, cwd=where, check=True)
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        subprocess.run(command, capture_output=True, env=env, cwd=where, check=True)
        times.append(time.perf_counter() - started)
    return times


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument(
        "--repo", type=Path, default=None, help="measure this checkout instead of the installed one"
    )
    parser.add_argument("--repeats", type=positive_int, default=5, help="measured runs each")
    args = parser.parse_args()
    repo = args.repo.resolve() if args.repo is not None else None

    total, offenders, heavy, origin = import_profile(repo)
    print(f"import inertia_id from {origin}")
    print(f"python -X importtime -c 'import inertia_id': {total / 1e6:.3f} s cumulative")
    print(f"heavy packages loaded: {', '.join(heavy) if heavy else 'none'}")
    print()
    print_table(
        ["import", "cumulative s"],
        [(name, micro / 1e6) for name, micro in offenders],
        title="costliest packages, then inertia_id's own modules (cumulative)",
    )

    with tempfile.TemporaryDirectory() as scratch:
        commands = {
            "inertia-id --help": ["--help"],
            "inertia-id scenario --preset paper --out FILE": [
                "scenario",
                "--preset",
                "paper",
                "--out",
                str(Path(scratch) / "scenario.json"),
            ],
        }
        figures = {name: wall_times(argv, repo, args.repeats) for name, argv in commands.items()}
    print_table(
        ["command", "median s", "best s", "runs"],
        [
            (name, statistics.median(times), min(times), len(times))
            for name, times in figures.items()
        ],
        title="wall time in a fresh process",
    )
    write_json(
        args.json,
        args,
        {
            "import_total_s": total / 1e6,
            "import_offenders_s": {name: micro / 1e6 for name, micro in offenders},
            "heavy_loaded": heavy,
            "wall_time_s": figures,
        },
    )


if __name__ == "__main__":
    main()
