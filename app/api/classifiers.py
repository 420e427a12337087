"""Trained classifiers: list, inspect, download the checksummed JSON document."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from sqlalchemy import func, select

from service.store.models import ClassifierRow

from ..schemas import ClassifierOut, ClassifierPage
from .deps import PagingDep, SessionDep, get_or_404, plausible_id

__all__ = ["router"]

router = APIRouter(prefix="/classifiers", tags=["classifiers"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"description": "no such classifier"}}


@router.get("")
def list_classifiers(
    session: SessionDep,
    page: PagingDep,
    scenario_id: Annotated[str | None, Query(max_length=64)] = None,
    job_id: Annotated[str | None, Query(max_length=64)] = None,
) -> ClassifierPage:
    """Classifiers, newest first, optionally of one scenario or one job."""
    conditions = []
    for column, value in ((ClassifierRow.scenario_id, scenario_id), (ClassifierRow.job_id, job_id)):
        if value is None:
            continue
        if not plausible_id(value):
            return ClassifierPage(items=[], total=0, limit=page.limit, offset=page.offset)
        conditions.append(column == value)
    total = session.scalar(select(func.count()).select_from(ClassifierRow).where(*conditions))
    rows = session.scalars(
        select(ClassifierRow)
        .where(*conditions)
        .order_by(ClassifierRow.created_at.desc(), ClassifierRow.id)
        .limit(page.limit)
        .offset(page.offset)
    ).all()
    return ClassifierPage(
        items=[ClassifierOut.model_validate(r) for r in rows],
        total=total or 0,
        limit=page.limit,
        offset=page.offset,
    )


@router.get("/{classifier_id}", responses=_NOT_FOUND)
def get_classifier(classifier_id: str, session: SessionDep) -> ClassifierOut:
    """Kind, sequence, metric, F1, accuracy, confusion matrix, candidate names, provenance."""
    return ClassifierOut.model_validate(
        get_or_404(session, ClassifierRow, classifier_id, "classifier")
    )


@router.get(
    "/{classifier_id}/download",
    response_class=Response,
    responses={
        200: {
            "content": {"application/json": {"schema": {"type": "object"}}},
            "description": "the classifier document (inertia-id/classifier, with its sha256)",
        },
        **_NOT_FOUND,
    },
)
def download_classifier(classifier_id: str, session: SessionDep) -> Response:
    """The stored checksummed JSON document, as written by the classifier's ``to_json``."""
    row = get_or_404(session, ClassifierRow, classifier_id, "classifier")
    return Response(
        content=row.document,
        media_type="application/json",
        headers={
            "Content-Disposition": f'attachment; filename="classifier-{row.id}.json"',
            "ETag": f'"{row.sha256}"',
        },
    )
