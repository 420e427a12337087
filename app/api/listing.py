"""What the list endpoints (jobs, classifiers, scenarios) share: their filters by id and
tag, their sort direction, and the one page of rows they answer with."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, Literal, TypeVarTuple

from sqlalchemy import ColumnElement, Row, Select
from sqlalchemy.orm import Session

from .deps import Paging, checked_tags, job_tagged, plausible_id

__all__ = ["id_filters", "one_page", "search_text", "sort_order", "tag_filters"]

Columns = TypeVarTuple("Columns")


def id_filters(
    pairs: Iterable[tuple[Any, str | None]],
) -> list[ColumnElement[bool]] | None:
    """``column == value`` for each ``(column, value)`` whose value is given; None when a
    value could name no row, so the list is empty without asking the database (which
    refuses to bind the NUL bytes and lone surrogates such a value may hold)."""
    conditions: list[ColumnElement[bool]] = []
    for column, value in pairs:
        if value is None:
            continue
        if not plausible_id(value):
            return None
        conditions.append(column == value)
    return conditions


def tag_filters(job_id: Any, tags: list[str] | None) -> list[ColumnElement[bool]]:
    """The job ``job_id`` (a column) carries every one of ``tags`` (``?tag=``, checked by
    :func:`~app.api.deps.checked_tags`)."""
    return [job_tagged(job_id, tag=tag) for tag in checked_tags(tags)]


def search_text(q: str | None) -> str | None:
    """A ``?q=`` as it is matched: stripped and in lower case; None when blank."""
    if q is None or not q.strip():
        return None
    return q.strip().lower()


def sort_order(key: Any, order: Literal["asc", "desc"]) -> Any:
    """``key`` in the ``?order=`` direction, rows without it last either way."""
    return (key.asc() if order == "asc" else key.desc()).nulls_last()


def one_page(
    session: Session, query: Select[*Columns], *, count: Select[Any], page: Paging
) -> tuple[Sequence[Row[*Columns]], int]:
    """The rows of the ordered ``query`` on ``page``, and how many ``count`` finds in all."""
    total = session.scalar(count) or 0
    rows = session.execute(query.limit(page.limit).offset(page.offset)).all()
    return rows, total
