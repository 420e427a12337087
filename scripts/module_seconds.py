"""Write tests/module_seconds.json from a JUnit XML report of a test run.

``tests/xdist_order.py`` hands the test modules to pytest-xdist's workers longest first by
these figures. Refresh them after a run that changed them much::

    bash scripts/test.sh --junitxml=/tmp/run.xml -o junit_family=xunit1
    .venv/bin/python scripts/module_seconds.py /tmp/run.xml
"""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "module_seconds.json"


def _module(case: ET.Element) -> str | None:
    """The test module of a test case: its ``file`` (xunit1), else, for a test that
    another package generates (schemathesis' name its own file), its ``classname``'s
    longest prefix that is a module under tests/."""
    module = case.get("file") or ""
    if module.startswith("tests/") and module.endswith(".py"):
        return module
    parts = (case.get("classname") or "").split(".")
    for end in range(len(parts), 0, -1):
        candidate = "/".join(parts[:end]) + ".py"
        if candidate.startswith("tests/") and (ROOT / candidate).is_file():
            return candidate
    return None


def module_seconds(report: Path) -> dict[str, int]:
    """Seconds each test module's tests took, summed (``file`` per test case: xunit1)."""
    seconds: dict[str, float] = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        module = _module(case)
        if module is not None:
            seconds[module] = seconds.get(module, 0.0) + float(case.get("time") or 0.0)
    if not seconds:
        raise SystemExit(f"{report}: no test case names its file (run with -o junit_family=xunit1)")
    return {module: round(s) for module, s in sorted(seconds.items())}


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python scripts/module_seconds.py REPORT.xml")
    OUT.write_text(json.dumps(module_seconds(Path(sys.argv[1])), indent=1) + "\n", encoding="utf-8")
    print(f"wrote {OUT}")
