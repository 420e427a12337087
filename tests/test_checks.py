"""The core's number tests (inertia_id.checks): what counts as an integer or a number."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from inertia_id.checks import is_integer, is_number


@pytest.mark.parametrize(
    ("value", "options", "expected"),
    [
        (3, {}, True),
        (True, {}, False),  # a bool given for a count is a mistake, not 1
        (np.int64(3), {}, True),
        (np.int64(3), {"numpy": False}, False),  # stored as given: a Python int only
        (3.0, {}, False),
        ("3", {}, False),
        (0, {"minimum": 1}, False),
        (1, {"minimum": 1}, True),
        (5, {"maximum": 4}, False),
        (4, {"minimum": 1, "maximum": 4}, True),
    ],
)
def test_is_integer(value: Any, options: dict[str, Any], expected: bool) -> None:
    assert is_integer(value, **options) is expected


@pytest.mark.parametrize(
    ("value", "options", "expected"),
    [
        (0.5, {"minimum": 0.0}, True),
        (0, {"minimum": 0.0}, True),
        (0, {"minimum": 0.0, "exclusive": True}, False),
        (False, {"minimum": 0.0}, False),
        (float("nan"), {"minimum": 0.0}, False),
        (float("inf"), {"minimum": 0.0}, False),
        (-1e-9, {"minimum": 0.0}, False),
        ("1", {"minimum": 0.0}, False),
    ],
)
def test_is_number(value: Any, options: dict[str, Any], expected: bool) -> None:
    assert is_number(value, **options) is expected
