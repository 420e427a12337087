"""The modules' figures that order pytest-xdist's work (tests/xdist_order.py)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from xdist_order import longest_modules_first, module_seconds

ROOT = Path(__file__).resolve().parent.parent


def test_every_module_with_a_figure_exists_and_every_figure_is_a_duration() -> None:
    seconds = module_seconds()
    assert seconds, "tests/module_seconds.json is missing or empty"
    gone = [m for m in seconds if not (ROOT / m).is_file()]
    assert gone == [], f"refresh tests/module_seconds.json (scripts/module_seconds.py): {gone}"
    assert all(s >= 0 for s in seconds.values()), seconds


def test_modules_go_longest_first_a_new_one_as_the_median_each_in_its_own_order() -> None:
    seconds = {"tests/a.py": 1.0, "tests/b.py": 50.0, "tests/c.py": 10.0, "tests/d.py": 5.0}
    ids = [
        "tests/a.py::t1",
        "tests/a.py::t2",
        "tests/b.py::t[1]",
        "tests/b.py::t[2]",
        "tests/new.py::t",
        "tests/c.py::t",
        "tests/d.py::t2",
        "tests/d.py::t1",
    ]
    items = [SimpleNamespace(nodeid=i) for i in ids]
    longest_modules_first(items, seconds)
    assert [i.nodeid for i in items] == [
        "tests/b.py::t[1]",
        "tests/b.py::t[2]",
        "tests/c.py::t",
        "tests/new.py::t",  # the median of 1, 5, 10 and 50: 7.5
        "tests/d.py::t2",
        "tests/d.py::t1",
        "tests/a.py::t1",
        "tests/a.py::t2",
    ]


def test_without_figures_the_order_is_pytests() -> None:
    items = [SimpleNamespace(nodeid=i) for i in ("tests/z.py::t", "tests/a.py::t")]
    longest_modules_first(items, {})
    assert [i.nodeid for i in items] == ["tests/z.py::t", "tests/a.py::t"]
