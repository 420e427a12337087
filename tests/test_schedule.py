"""The order in which pytest-xdist's workers take the test modules (tests/conftest.py):
longest first, by the figures in tests/module_seconds.json."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import pytest
from conftest import longest_modules_first

ROOT = Path(__file__).resolve().parent.parent


def _items(*nodeids: str) -> list[pytest.Item]:
    return [cast(pytest.Item, SimpleNamespace(nodeid=nodeid)) for nodeid in nodeids]


def test_modules_go_longest_first_an_unmeasured_one_before_all_each_in_its_order() -> None:
    items = _items(
        "tests/a.py::test_1",
        "tests/a.py::test_2[x]",
        "tests/b.py::test_1",
        "tests/c.py::Case::test_1",
        "tests/c.py::Case::test_2",
        "tests/new.py::test_1",
        "tests/a.py::test_3",  # a module's tests kept together, in their order
    )
    seconds = {"tests/a.py": 5.0, "tests/b.py": 50.0, "tests/c.py": 20.0}
    ordered = [item.nodeid for item in longest_modules_first(items, seconds)]
    assert ordered == [
        "tests/new.py::test_1",
        "tests/b.py::test_1",
        "tests/c.py::Case::test_1",
        "tests/c.py::Case::test_2",
        "tests/a.py::test_1",
        "tests/a.py::test_2[x]",
        "tests/a.py::test_3",
    ]


def test_without_figures_the_order_is_the_collections() -> None:
    items = _items("tests/a.py::test_1", "tests/b.py::test_1", "tests/a.py::test_2")
    assert [i.nodeid for i in longest_modules_first(items, {})] == [
        "tests/a.py::test_1",
        "tests/a.py::test_2",
        "tests/b.py::test_1",
    ]


def test_the_figures_name_only_test_modules_that_exist() -> None:
    document: dict[str, Any] = json.loads((ROOT / "tests" / "module_seconds.json").read_text())
    seconds = document["seconds"]
    assert seconds and all(value >= 0 for value in seconds.values())
    missing = [name for name in seconds if not (ROOT / name).is_file()]
    assert not missing, f"tests/module_seconds.json names modules that are gone: {missing}"


def test_the_figures_are_written_from_a_junit_report(tmp_path: Path) -> None:
    report = tmp_path / "suite.xml"
    report.write_text(
        '<testsuites><testsuite name="pytest">'
        '<testcase classname="tests.test_checks" name="test_is_number" time="1.25"/>'
        '<testcase classname="tests.test_checks" name="test_is_integer" time="0.5"/>'
        '<testcase classname="tests.api.test_jobs" name="test_x" time="3"/>'
        "</testsuite></testsuites>"
    )
    target = tmp_path / "module_seconds.json"
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "module_seconds.py"), str(report), str(target)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    written = json.loads(target.read_text())["seconds"]
    assert written == {"tests/api/test_jobs.py": 3.0, "tests/test_checks.py": 1.8}
