"""Words for messages: a count and its noun in agreement ("1 column", "3 columns"), and a
figure to a few significant digits in plain decimals ("0.0000960")."""

from __future__ import annotations

import math

__all__ = ["counted", "significant"]


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``n`` and the noun in its number: "1 identified verdict", "2 identified verdicts".

    :param n: the count.
    :param singular: the noun for one (with any adjective before it).
    :param plural: the noun for any other count; ``singular`` + "s" when not given.
    """
    return f"{n} {singular if n == 1 else (plural if plural is not None else singular + 's')}"


def significant(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits in plain decimals, as the dashboard
    writes a figure (``quantity`` in frontend/js/ui.js): 9.6039e-05 as "0.0000960",
    0.45715 as "0.457", 0 as "0", 1234.4 as "1234" (a whole number keeps every digit).

    A fixed number of decimals wiped small figures out: a commanded residual of 5.8e-5
    rad/s read "0.0001 rad/s (0.00 deg/s)", rad/s and deg/s disagreeing, and three front
    members that brake (9.6e-5, 5.8e-5 and 0 rad/s) read alike.
    """
    if not math.isfinite(value):
        return str(value)
    if value == 0:
        return "0"
    decimals = digits - 1 - math.floor(math.log10(abs(value)))
    return f"{value:.{max(decimals, 0)}f}"
