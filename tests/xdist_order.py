"""The order in which pytest-xdist's workers are handed the test modules: longest first.

``scripts/test.sh`` runs ``--dist loadscope --no-loadscope-reorder``: each module whole
on one worker, in the order collected. xdist's own order (the modules with the most
tests first) left the modules of a few long tests to the end (the fault tests: 2 to 4
tests of 40 to 135 s each), and one worker ran them alone while the others had finished.
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: Seconds each test module's tests took in a recent run, summed
#: (``python scripts/module_seconds.py REPORT.xml`` writes it).
MODULE_SECONDS = Path(__file__).parent / "module_seconds.json"


def module_seconds(path: Path = MODULE_SECONDS) -> dict[str, float]:
    """The figures of :data:`MODULE_SECONDS`; none when the file is missing."""
    if not path.is_file():
        return {}
    return {str(k): float(v) for k, v in json.loads(path.read_text(encoding="utf-8")).items()}


def longest_modules_first(items: list[Any], seconds: Mapping[str, float] | None = None) -> None:
    """Sort ``items`` (pytest's, in place) by their module's seconds, longest first.

    A module with no figure (a new one) counts as the median. The order within a module
    is kept (the sort is stable and a module's tests are collected together)."""
    seconds = module_seconds() if seconds is None else seconds
    if not seconds:
        return
    unknown = statistics.median(seconds.values())
    items.sort(key=lambda item: -seconds.get(item.nodeid.partition("::")[0], unknown))
