"""Words for messages: a count and its noun in agreement ("1 column", "3 columns")."""

from __future__ import annotations

__all__ = ["counted"]


def counted(n: int, singular: str, plural: str | None = None) -> str:
    """``n`` and the noun in its number: "1 identified verdict", "2 identified verdicts".

    :param n: the count.
    :param singular: the noun for one (with any adjective before it).
    :param plural: the noun for any other count; ``singular`` + "s" when not given.
    """
    return f"{n} {singular if n == 1 else (plural if plural is not None else singular + 's')}"
