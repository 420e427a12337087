"""How fast the command line answers ``--help``: ``inertia-id --help`` and every
command's ``inertia-id COMMAND --help``, each in a fresh process.

The installed console script is run (``.venv/bin/inertia-id`` beside this interpreter,
or ``--command``), as a user runs it. One unmeasured run warms the file cache, then
``--repeats`` measured ones; the median and the slowest are printed, in seconds::

    python bench/cli_help.py [--repeats 5] [--json out.json]
"""

from __future__ import annotations

import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from _common import base_parser, begin, positive_int, print_table, write_json

from inertia_id.cli import COMMANDS as _CLI_COMMANDS

#: Every command the CLI has, read from its table: a list kept here by hand left out
#: ``plan``. Importing the CLI here costs the timed runs nothing: each is a fresh process.
COMMANDS = tuple(sorted(_CLI_COMMANDS))


def _script(given: str | None) -> list[str]:
    if given:
        return [given]
    beside = Path(sys.executable).with_name("inertia-id")
    if beside.is_file():
        return [str(beside)]
    found = shutil.which("inertia-id")
    if found:
        return [found]
    return [sys.executable, "-m", "inertia_id.cli"]


def wall_times(argv: list[str], repeats: int) -> list[float]:
    subprocess.run(argv, check=True, capture_output=True)
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        subprocess.run(argv, check=True, capture_output=True)
        times.append(time.perf_counter() - started)
    return times


def main() -> None:
    parser = base_parser(__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=positive_int, default=5, help="measured runs each")
    parser.add_argument("--command", default=None, help="the inertia-id executable to run")
    args = begin(parser, "inertia-id --help: wall time in a fresh process")
    script = _script(args.command)
    rows, figures = [], {}
    for command in (None, *COMMANDS):
        argv = [*script, *([command] if command else []), "--help"]
        times = wall_times(argv, args.repeats)
        label = f"inertia-id {command + ' ' if command else ''}--help"
        figures[label] = {"median_s": statistics.median(times), "max_s": max(times)}
        rows.append([label, f"{statistics.median(times):.3f}", f"{max(times):.3f}"])
    print_table(["command", "median (s)", "slowest (s)"], rows, f"{' '.join(script)}")
    write_json(args.json, args, {"help_wall_time_s": figures})


if __name__ == "__main__":
    main()
