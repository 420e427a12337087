"""Trained classifiers: list, inspect, download the checksummed JSON document."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Response, status
from sqlalchemy import func, or_, select
from sqlalchemy.orm import Session

from service.exports import iso_utc
from service.store.models import ClassifierRow, JobRow

from ..schemas import ClassifierOut, ClassifierPage
from .deps import (
    OrderQuery,
    PagingDep,
    SessionDep,
    TagText,
    get_or_404,
    job_tagged,
    no_such,
    sort_query,
    text_query,
    unknown_sort,
)
from .listing import id_filters, one_page, search_text, sort_order, tag_filters
from .routing import UniqueKeysRoute

__all__ = ["router"]

router = APIRouter(prefix="/classifiers", tags=["classifiers"], route_class=UniqueKeysRoute)

_NOT_FOUND = no_such("classifier")


_SORT_COLUMNS: dict[str, Any] = {
    "created": ClassifierRow.created_at,
    "f1": ClassifierRow.f1,
    "accuracy": ClassifierRow.accuracy,
    "kind": ClassifierRow.kind,
    "metric": ClassifierRow.metric,
    "name": func.lower(JobRow.name),
}


def classifier_out(
    session: Session, row: ClassifierRow, job: JobRow | None = None
) -> ClassifierOut:
    """The row with its training job's name and tags."""
    if job is None and row.job_id is not None:
        job = session.get(JobRow, row.job_id)
    out = ClassifierOut.model_validate(row)
    if job is not None:
        out.job_name, out.tags = job.name, job.tags
    return out


@router.get("")
def list_classifiers(
    session: SessionDep,
    page: PagingDep,
    scenario_id: Annotated[str | None, Query(max_length=64)] = None,
    job_id: Annotated[str | None, Query(max_length=64)] = None,
    kind: Annotated[str | None, Query(max_length=64, pattern=r"^[a-z0-9-]*$")] = None,
    q: Annotated[
        str | None,
        text_query("text in the kind, metric or training job's name or tags, or an id prefix"),
    ] = None,
    tag: Annotated[
        list[TagText] | None,
        Query(description="classifiers whose training job carries this tag"),
    ] = None,
    sort: Annotated[
        str, sort_query(_SORT_COLUMNS, "created, f1, accuracy, kind, metric or name")
    ] = "created",
    order: OrderQuery = "desc",
) -> ClassifierPage:
    """Classifiers, newest first by default, filtered by scenario, job, kind, text and the
    training job's tags, sorted, one page at a time."""
    conditions = id_filters(
        ((ClassifierRow.scenario_id, scenario_id), (ClassifierRow.job_id, job_id))
    )
    if conditions is None:
        return ClassifierPage(items=[], total=0, limit=page.limit, offset=page.offset)
    if kind:
        conditions.append(ClassifierRow.kind == kind)
    needle = search_text(q)
    if needle is not None:
        conditions.append(
            or_(
                ClassifierRow.id.startswith(needle, autoescape=True),
                ClassifierRow.kind.contains(needle, autoescape=True),
                ClassifierRow.metric.contains(needle, autoescape=True),
                func.lower(JobRow.name).contains(needle, autoescape=True),
                job_tagged(ClassifierRow.job_id, containing=needle),
            )
        )
    conditions.extend(tag_filters(ClassifierRow.job_id, tag))
    if sort not in _SORT_COLUMNS:
        unknown_sort("classifiers", sort, _SORT_COLUMNS)
    with_job = JobRow.id == ClassifierRow.job_id
    rows, total = one_page(
        session,
        select(ClassifierRow, JobRow)
        .outerjoin(JobRow, with_job)
        .where(*conditions)
        .order_by(
            sort_order(_SORT_COLUMNS[sort], order),
            ClassifierRow.created_at.desc(),
            ClassifierRow.id,
        ),
        count=select(func.count())
        .select_from(ClassifierRow)
        .outerjoin(JobRow, with_job)
        .where(*conditions),
        page=page,
    )
    return ClassifierPage(
        items=[classifier_out(session, row, job) for row, job in rows],
        total=total,
        limit=page.limit,
        offset=page.offset,
    )


@router.get("/{classifier_id}", responses=_NOT_FOUND)
def get_classifier(classifier_id: str, session: SessionDep) -> ClassifierOut:
    """Kind, sequence, metric, F1, accuracy, confusion matrix, candidate names, provenance,
    and the training job's name and tags."""
    return classifier_out(session, get_or_404(session, ClassifierRow, classifier_id, "classifier"))


@router.get(
    "/{classifier_id}/download",
    response_class=Response,
    responses={
        200: {
            "content": {"application/json": {"schema": {"type": "object"}}},
            "description": "the classifier document (inertia-id/classifier, with its sha256) "
            "and its provenance (classifier_id, job_id, scenario_id, created_at in UTC), "
            "outside the checksummed payload",
        },
        **_NOT_FOUND,
    },
)
def download_classifier(classifier_id: str, session: SessionDep) -> Response:
    """The stored checksummed JSON document, as written by the classifier's ``to_json``,
    with its ``provenance`` beside the payload: the classifier's id, its training job's id,
    its scenario's id and when it was stored (UTC, ending in Z). The file a team keeps
    said nothing of where it came from. The provenance lies outside the checksummed
    payload, so the ``sha256`` (and the ETag) is the stored classifier's and
    ``inertia-id identify --classifier`` loads the file as before; the checksum does not
    cover it."""
    from inertia_id.classifiers.documents import with_provenance

    row = get_or_404(session, ClassifierRow, classifier_id, "classifier")
    provenance = {
        "classifier_id": row.id,
        "job_id": row.job_id,
        "scenario_id": row.scenario_id,
        "created_at": iso_utc(row.created_at),
    }
    # Bytes made in pieces (a memoryview: the response sends it as it is, not a copy).
    return Response(
        content=memoryview(with_provenance(row.document, provenance)),
        media_type="application/json",
        headers={
            "Content-Disposition": f'attachment; filename="classifier-{row.id}.json"',
            "ETag": f'"{row.sha256}"',
        },
    )


@router.get(
    "/{classifier_id}/calibration",
    responses={
        200: {"description": "the calibration report stored in the classifier's document"},
        **_NOT_FOUND,
    },
)
def get_calibration(classifier_id: str, session: SessionDep) -> dict[str, Any]:
    """The posterior's calibration, measured on fresh draws when the classifier was
    trained: temperature, novelty tail, none prior, held-out accuracy, expected
    calibration error (ECE) and the reliability bins (mean confidence, accuracy, count).
    404 for a classifier stored before calibration existed."""
    import json

    row = get_or_404(session, ClassifierRow, classifier_id, "classifier")
    document = json.loads(row.document)
    calibration = (document.get("classifier") or {}).get("calibration")
    if not isinstance(calibration, dict):
        raise HTTPException(
            status.HTTP_404_NOT_FOUND,
            detail=f"classifier {classifier_id[:80]!r} stores no calibration (trained before it)",
        )
    return calibration
