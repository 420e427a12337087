"""The tests behind the core's checks of a number parameter, and numbers made JSON-safe.

Each caller raises its own :class:`~inertia_id.errors.InputError`, with its own message
(they name the parameter and the rule in their own words); what they share is the test.
A bool is never a number here, although Python counts it as an ``int``: ``True`` given
for a count is a mistake, not 1.
"""

from __future__ import annotations

import math
from typing import Any, TypeGuard

import numpy as np

__all__ = ["finite_or_none", "is_integer", "is_number"]


def is_integer(
    value: Any,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    numpy: bool = True,
) -> TypeGuard[int | np.integer[Any]]:
    """``value`` is an integer (a bool is not one) in ``minimum..maximum`` (both
    inclusive, None for no bound).

    :param numpy: whether a NumPy integer counts; False where the value is stored or
        sent on as it was given (a JSON document, a settings object), which takes a
        Python ``int`` only.
    """
    kinds = int | np.integer if numpy else int
    if isinstance(value, bool) or not isinstance(value, kinds):
        return False
    return (minimum is None or value >= minimum) and (maximum is None or value <= maximum)


def is_number(value: Any, *, minimum: float, exclusive: bool = False) -> TypeGuard[int | float]:
    """``value`` is a finite real number (a bool is not one) >= ``minimum``, or >
    ``minimum`` when ``exclusive``: the test behind the kinds' checks of a number
    parameter, each with its own message."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return False
    return value > minimum if exclusive else value >= minimum


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None and numpy scalars made
    Python's, through dicts, lists and tuples: strict JSON has no NaN or Infinity."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    return value
