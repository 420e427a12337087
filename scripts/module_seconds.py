"""Write ``tests/module_seconds.json``: each test module's seconds in a measured run of
the suite, which ``tests/conftest.py`` uses to hand the longest modules out first.

Usage, from a full run on two workers (the way ``scripts/test.sh`` runs it)::

    bash scripts/test.sh --junitxml=/tmp/suite.xml -o junit_family=xunit1
    python scripts/module_seconds.py /tmp/suite.xml [OUTPUT]   # default: tests/module_seconds.json

A module's seconds are the sum of its tests' (set-up and tear-down included), as
pytest's JUnit XML gives them. Stale figures cost only balance, never a test.
"""

from __future__ import annotations

import json
import sys
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TARGET = ROOT / "tests" / "module_seconds.json"


def module_of(classname: str) -> str:
    """The test module's path (``tests/api/test_jobs.py``) of a JUnit ``classname``
    (``tests.api.test_jobs``, or ``tests.api.test_jobs.TestClass`` for a method)."""
    parts = classname.split(".")
    for end in range(len(parts), 0, -1):
        path = "/".join(parts[:end]) + ".py"
        if (ROOT / path).is_file():
            return path
    raise SystemExit(f"no test module for the JUnit classname {classname!r}")


def main(argv: list[str]) -> int:
    if len(argv) not in (1, 2):
        raise SystemExit("usage: python scripts/module_seconds.py JUNIT_XML [OUTPUT]")
    target = Path(argv[1]) if len(argv) == 2 else TARGET
    seconds: Counter[str] = Counter()
    for case in ET.parse(argv[0]).getroot().iter("testcase"):
        seconds[module_of(case.get("classname", ""))] += float(case.get("time", 0.0))
    document = {
        "about": "seconds each test module took in a full run on two workers; written by "
        "scripts/module_seconds.py, read by tests/conftest.py",
        "seconds": {name: round(value, 1) for name, value in seconds.most_common()},
    }
    target.write_text(json.dumps(document, indent=1) + "\n")
    print(f"{target}: {len(seconds)} modules, {sum(seconds.values()):.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
