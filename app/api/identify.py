"""Identify a spacecraft's configuration from its gyro telemetry, in the API process.

No queue: one series against K candidates takes milliseconds. A request reads only the
classifier's id, checksum, kind and provenance, in one look-up remembered for a while (the
verdict names them); the verdict is computed in the API's verdict process
(:mod:`app.verdicts`), which loads classifiers from their stored JSON documents
(checksum verified, never unpickled) once and keeps them in a small LRU cache by (id,
checksum) — or, with ``INERTIA_ID_VERDICT_PROCESS=off``, on the API's own
compute thread with the same cache. Either way it runs behind a compute gate
(:class:`app.capacity.ComputeGate`): past capacity a request is answered 503 with
Retry-After, never left to hang.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Query, Request, Response, status
from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError
from sqlalchemy import select
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import FormData, UploadFile

from inertia_id.checks import DuplicateKeyError, loads_unique_keys, parse_decimal
from inertia_id.errors import InputError
from inertia_id.evaluation.identify import (
    identify,
    identify_online,
)
from inertia_id.evaluation.telemetry import (
    Telemetry,
    parse_sequence_start,
    parse_telemetry,
    same_sequence_start,
)
from inertia_id.gzipped import DecompressedTooLarge, gunzip, is_gzip
from service.exports import identify_table, to_csv
from service.store.models import ClassifierRow
from service.store.session import Database

from ..capacity import ComputeGate
from ..classifier_cache import ClassifierCache, StoredClassifier
from ..schemas import (
    MAX_ESTIMATE_START_WITHIN_S,
    MAX_PRE_START_WINDOW_S,
    IdentifyRequest,
    IdentifyResult,
    PartialIdentifyResult,
    finite_or_none,
)
from ..verdicts import NotFound, VerdictOptions, VerdictProcess
from .deps import (
    UNAUTHORIZED,
    ApiKeyDep,
    no_such,
    not_found,
    plausible_id,
    quoted,
    unprocessable,
)
from .errors import duplicate_key_errors, refused_at
from .routing import UniqueKeysRoute, content_codings, refuse_json_charset

if TYPE_CHECKING:
    from inertia_id.classifiers.registry import CandidateClassifier

__all__ = ["openapi_components", "router"]

router = APIRouter(prefix="/identify", tags=["identify"], route_class=UniqueKeysRoute)


def _load(document: str) -> CandidateClassifier:
    # The registry (every kind, scikit-learn) is imported here, not with the API: the
    # API answers /health before it is loaded (app.main imports it in the background).
    from inertia_id.classifiers.registry import classifier_from_json

    return classifier_from_json(document)


def _document(database: Database, classifier_id: str) -> str:
    with database.session() as session:
        document = session.scalar(
            select(ClassifierRow.document).where(ClassifierRow.id == classifier_id)
        )
    if document is None:
        raise not_found("classifier", classifier_id)
    return document


def _stored(database: Database, cache: ClassifierCache, classifier_id: str) -> StoredClassifier:
    """The stored classifier's checksum, kind and provenance: one look-up of those
    columns (not the document, up to megabytes, read on a cache miss only), remembered for
    a while (a classifier row is never changed: a new training is a new row)."""
    remembered = cache.stored_of(classifier_id)
    if remembered is not None:
        return remembered
    row = None
    if plausible_id(classifier_id):
        with database.session() as session:
            row = session.execute(
                select(
                    ClassifierRow.id,
                    ClassifierRow.sha256,
                    ClassifierRow.kind,
                    ClassifierRow.job_id,
                    ClassifierRow.scenario_id,
                    ClassifierRow.created_at,
                ).where(ClassifierRow.id == classifier_id)
            ).first()
    if row is None:
        raise not_found("classifier", classifier_id)
    stored = StoredClassifier(
        classifier_id=row.id,
        sha256=row.sha256,
        kind=row.kind,
        job_id=row.job_id,
        scenario_id=row.scenario_id,
        created_at=row.created_at,
    )
    cache.remember_stored(stored)
    return stored


def _classifier(
    database: Database, cache: ClassifierCache, classifier_id: str
) -> tuple[StoredClassifier, CandidateClassifier]:
    stored = _stored(database, cache, classifier_id)
    key = (stored.classifier_id, stored.sha256)
    return stored, cache.get(key, lambda: _load(_document(database, classifier_id)))


def _judge(
    database: Database,
    cache: ClassifierCache,
    classifier_id: str,
    telemetry: Telemetry,
    options: VerdictOptions,
    partial: bool,
) -> IdentifyResult | PartialIdentifyResult:
    """The verdict on a compute thread (the verdict process off): ``identify``, or
    ``identify_online`` for a partial one."""
    stored, classifier = _classifier(database, cache, classifier_id)
    judge = identify_online if partial else identify
    result = judge(classifier, telemetry, **options.keywords(partial=partial)).model_dump()
    return _answer(result, stored, partial=partial)


def _answer(result: dict[str, Any], stored: StoredClassifier, *, partial: bool) -> Any:
    """The verdict as its response model, naming the classifier that judged (its id, and
    its checksum, kind and provenance: a verdict kept from the API could not tell which
    training made the classifier, the CLI's could). A verdict that does not fit it (a NaN
    posterior, say) is a fault of ours, a 500 with its reason logged, not the client's
    422: the error handlers read a pydantic ValidationError as bad input."""
    model = PartialIdentifyResult if partial else IdentifyResult
    classifier = {
        "sha256": stored.sha256,
        "kind": stored.kind,
        "provenance": {
            "classifier_id": stored.classifier_id,
            "job_id": stored.job_id,
            "scenario_id": stored.scenario_id,
            "created_at": stored.created_at,
        },
    }
    try:
        return model.model_validate(
            {
                **finite_or_none(result),
                "classifier_id": stored.classifier_id,
                "classifier": classifier,
            }
        )
    except ValidationError as exc:
        raise RuntimeError(
            f"the verdict of classifier {stored.classifier_id} does not fit its response "
            f"model: {exc}"
        ) from exc


async def _verdict(
    request: Request,
    classifier_id: str,
    telemetry: Telemetry,
    options: VerdictOptions,
    *,
    partial: bool,
) -> IdentifyResult | PartialIdentifyResult:
    """The verdict from the verdict process (:mod:`app.verdicts`), or, with it off, from
    the compute threads."""
    state = request.app.state
    database: Database = state.db
    cache: ClassifierCache = state.classifier_cache
    process: VerdictProcess | None = state.verdicts
    if process is None:
        gate: ComputeGate = state.compute_gate
        return await gate.run(_judge, database, cache, classifier_id, telemetry, options, partial)
    stored = cache.stored_of(classifier_id)
    if stored is None:
        stored = await run_in_threadpool(_stored, database, cache, classifier_id)
    verdict_gate: ComputeGate = state.verdict_gate
    try:
        result = await verdict_gate.run_async(
            process.verdict, classifier_id, stored.sha256, telemetry, options, partial
        )
    except NotFound:
        raise not_found("classifier", classifier_id) from None
    return _answer(result, stored, partial=partial)


async def _parsed(request: Request, parse: Callable[..., Any], *args: Any) -> Any:
    """``parse(*args)`` on the compute threads, behind their gate: 200,000 rows of
    telemetry take seconds of Python, and on the event loop every other request (``/health``
    included) waited for them."""
    gate: ComputeGate = request.app.state.compute_gate
    return await gate.run(parse, *args)


def _limit(request: Request) -> int:
    """The most bytes a body may hold: compressed as sent, and once decompressed."""
    return int(request.app.state.settings.max_body_bytes)


def _gunzipped(data: bytes, limit: int, what: str, loc: tuple[str, ...]) -> bytes:
    """What the gzip ``data`` holds: past ``limit`` bytes a 413, as a plain body over the
    limit (having inflated no more than ``limit + 1`` bytes); a corrupt or truncated
    stream a 422 at ``loc`` naming ``what``."""
    try:
        return gunzip(data, limit=limit, what=what)
    except DecompressedTooLarge:
        raise HTTPException(
            status.HTTP_413_CONTENT_TOO_LARGE,
            detail=f"{what} is gzip whose decompressed size exceeds the limit of {limit} "
            "bytes (INERTIA_ID_MAX_BODY_BYTES, the limit of a plain body); send less data, "
            "e.g. fewer telemetry samples",
        ) from None
    except InputError as exc:
        unprocessable(loc, str(exc))


async def _from_json(
    request: Request, sequence_start: str | None, *, gzipped: bool
) -> tuple[str, Telemetry, VerdictOptions]:
    body = await request.body()
    start = _query_start(sequence_start)
    limit = _limit(request) if gzipped else None
    return await _parsed(request, _parse_json, body, start, limit)


def _parse_json(
    body: bytes, start: float | str | None, gzip_limit: int | None = None
) -> tuple[str, Telemetry, VerdictOptions]:
    """The request's JSON body; with ``gzip_limit`` (``Content-Encoding: gzip``) the body
    is gzip, decompressed (at most that many bytes) first."""
    if gzip_limit is not None:
        body = _gunzipped(body, gzip_limit, "request body (Content-Encoding: gzip)", ("body",))
    try:
        data = loads_unique_keys(body)
    except DuplicateKeyError as exc:
        raise RequestValidationError(duplicate_key_errors(exc)) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        unprocessable(("body",), f"request body is not valid JSON: {exc}")
    except (ValueError, RecursionError) as exc:
        # An integer of over 4,300 digits, or arrays nested thousands deep.
        unprocessable(("body",), f"request body is not acceptable JSON: {exc}")
    if start is not None and isinstance(data, dict):
        _same_start_as_query(data, start)
        data = {**data, "sequence_start": start}
    with refused_at(("body",), data):
        parsed = IdentifyRequest.model_validate(data)
    options = VerdictOptions(
        parsed.confidence, parsed.pre_start_window_s, parsed.estimate_start_within_s
    )
    return parsed.classifier_id, parsed.telemetry, options


def _same_start_as_query(data: dict[str, Any], start: float | str) -> None:
    """Refuse a body whose start (its own or its telemetry's) names another moment than
    ``?sequence_start=``: which one was meant cannot be told (the form path refuses a
    start given twice in the same way)."""
    inner = data.get("telemetry")
    given = (
        ("sequence_start", data.get("sequence_start")),
        (
            "telemetry.sequence_start",
            inner.get("sequence_start") if isinstance(inner, dict) else None,
        ),
    )
    for name, value in given:
        if isinstance(value, str | int | float) and not isinstance(value, bool):
            if not same_sequence_start(value, start):
                unprocessable(
                    ("query", "sequence_start"),
                    f"?sequence_start={start!r} and the body's {name} = {value!r} differ; "
                    "give the start once",
                )


def _query_start(text: str | None, where: str = "query") -> float | str | None:
    try:
        return parse_sequence_start(text)
    except InputError as exc:
        unprocessable((where, "sequence_start"), str(exc))


def _no_empty_fields(form: FormData) -> None:
    """Refuse a text field sent empty (``confidence=``, ``sequence_start=``,
    ``averaged=``), as an empty query number (``?limit=``) is: it was not the default
    asked for (a form that sends its untouched inputs, a template's blank), and a client
    that meant to send a value learns it did not. A field left out is the default."""
    for name, value in form.multi_items():
        if isinstance(value, str) and value == "":
            why = (
                "it is required"
                if name in _REQUIRED_FORM_FIELDS
                else "leave the field out for the default"
            )
            unprocessable(("body", name), f"{name} is empty; {why}")


def _form_number(name: str, value: Any, rule: str, ok: Callable[[float], bool]) -> float | None:
    if value is None:
        return None
    try:
        # A number as written: float() also takes 1_0 (10) and other scripts' digits.
        number = parse_decimal(value) if isinstance(value, str) else float("nan")
    except ValueError:
        number = float("nan")
    if not ok(number):
        unprocessable(("body", name), f"{name} must be {rule}, got {value!r}")
    return number


def _form_options(form: Any) -> VerdictOptions:
    confidence = _form_number(
        "confidence", form.get("confidence"), "a number in (0, 1)", lambda x: 0.0 < x < 1.0
    )
    window = _form_number(
        "pre_start_window_s",
        form.get("pre_start_window_s"),
        f"a number of seconds in [0, {MAX_PRE_START_WINDOW_S:g}]",
        lambda x: 0.0 <= x <= MAX_PRE_START_WINDOW_S,
    )
    start_window = _form_number(
        "estimate_start_within_s",
        form.get("estimate_start_within_s"),
        f"a number of seconds in [0, {MAX_ESTIMATE_START_WITHIN_S:g}]",
        lambda x: 0.0 <= x <= MAX_ESTIMATE_START_WITHIN_S,
    )
    return VerdictOptions(confidence, window, start_window)


async def _from_form(
    request: Request, sequence_start: str | None
) -> tuple[str, Telemetry, VerdictOptions]:
    start = _query_start(sequence_start)
    # Room for each field twice (a second file too), so that a repeated one is named
    # below rather than refused by Starlette's count as a 400 that names none.
    async with request.form(max_files=2, max_fields=2 * len(_FORM_FIELDS)) as form:
        unknown = sorted(set(form.keys()) - _FORM_FIELDS)
        if unknown:
            # A field the API does not read is refused, as an unknown JSON key is: a start
            # or a unit sent under another name would otherwise be dropped silently.
            unprocessable(
                ("body", unknown[0]),
                f"unknown form field {unknown[0]!r}; the fields are {sorted(_FORM_FIELDS)}",
            )
        _one_value_each(form)
        _no_empty_fields(form)
        classifier_id = form.get("classifier_id")
        upload = form.get("file")
        options = _form_options(form)
        field_start = form.get("sequence_start")
        if isinstance(field_start, str):
            if sequence_start is not None:
                unprocessable(
                    ("body", "sequence_start"),
                    "sequence_start is given both as a form field and in the query; give it once",
                )
            start = _query_start(field_start, "body")
        averaged = form.get("averaged")
        if isinstance(averaged, str) and averaged.lower() not in ("true", "false"):
            unprocessable(("body", "averaged"), f"averaged must be true or false, got {averaged!r}")
        is_averaged = isinstance(averaged, str) and averaged.lower() == "true"
        if not isinstance(classifier_id, str) or not classifier_id:
            unprocessable(("body", "classifier_id"), "form field classifier_id is required")
        if upload is None:
            unprocessable(("body", "file"), "form field file (CSV telemetry) is required")
        raw = await upload.read() if isinstance(upload, UploadFile) else upload.encode()
        name = upload.filename if isinstance(upload, UploadFile) else None
    telemetry = await _parsed(request, _parse_file, raw, start, is_averaged, name, _limit(request))
    return classifier_id, telemetry, options


def _one_value_each(form: FormData) -> None:
    """Refuse a form field given more than once: Starlette's ``form.get`` keeps the last
    value, so ``confidence=0.5`` then ``confidence=0.999`` judged at 0.999 without a word
    (and a second ``file`` was the telemetry read)."""
    given: dict[str, list[str]] = {}
    for name, value in form.multi_items():
        shown = value[:40] if isinstance(value, str) else f"file {value.filename!r}"
        given.setdefault(name, []).append(shown)
    for name, values in given.items():
        if len(values) > 1:
            unprocessable(
                ("body", name),
                f"form field {name!r} is given {len(values)} times ({values}); give it once",
            )


def _parse_file(
    raw: bytes,
    start: float | str | None,
    averaged: bool,
    name: str | None,
    limit: int,
) -> Telemetry:
    """The uploaded telemetry file; gzip (known by its magic bytes, whatever its name) is
    decompressed first, at most ``limit`` bytes (the body's limit), and what it holds read
    as a plain upload is: CSV or JSON, told apart by its text."""
    if is_gzip(raw):
        what = "telemetry file" + (f" {name[:100]!r}" if name else "")
        raw = _gunzipped(raw, limit, what, ("body", "file"))
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        unprocessable(("body", "file"), f"telemetry file is not UTF-8 text: {exc}")
    try:
        with refused_at(("body", "file")):
            return parse_telemetry(text, sequence_start=start, averaged=averaged)
    except csv.Error as exc:
        # The core's CSV reader lets this through, e.g. for a lone carriage return in a row.
        unprocessable(("body", "file"), f"telemetry is not valid CSV: {exc}")


_FORM_FIELDS = frozenset(
    {
        "averaged",
        "classifier_id",
        "file",
        "confidence",
        "estimate_start_within_s",
        "pre_start_window_s",
        "sequence_start",
    }
)

_REQUIRED_FORM_FIELDS = frozenset({"classifier_id", "file"})

_MULTIPART_SCHEMA = {
    "type": "object",
    "required": sorted(_REQUIRED_FORM_FIELDS),
    "properties": {
        "classifier_id": {"type": "string", "minLength": 1, "maxLength": 64},
        "confidence": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1},
        "pre_start_window_s": {"type": "number", "minimum": 0, "maximum": MAX_PRE_START_WINDOW_S},
        "estimate_start_within_s": {
            "type": "number",
            "minimum": 0,
            "maximum": MAX_ESTIMATE_START_WITHIN_S,
            "description": "search the starts within this many seconds of the stated one "
            "for the best fit (POST /identify only); the verdict reports the shift",
        },
        "sequence_start": {
            "type": "string",
            "minLength": 1,
            "description": "start of the sequence in the telemetry's clock: seconds, or "
            "ISO-8601 UTC (or ?sequence_start=, not both)",
        },
        "averaged": {
            "type": "boolean",
            "description": "true when each rate is the mean over one sample period (the "
            "median spacing) before its stamp (an integrating or delta-angle gyro)",
        },
        "file": {
            "type": "string",
            "format": "binary",
            "description": "CSV with columns time_s (seconds) or time_utc (ISO-8601 UTC), wx, "
            "wy, wz (rad/s); a header row is allowed; the sequence start as the field "
            "sequence_start or ?sequence_start=; or the same JSON as the body's telemetry; "
            "either may be gzip-compressed (known by its magic bytes), at most "
            "INERTIA_ID_MAX_BODY_BYTES once decompressed",
        },
    },
}


def openapi_components() -> dict[str, Any]:
    """Schemas the identify request body refers to (it is parsed by hand, see below)."""
    schema = IdentifyRequest.model_json_schema(ref_template="#/components/schemas/{model}")
    components = schema.pop("$defs", {})
    components["IdentifyRequest"] = schema
    return components


async def _read_body(
    request: Request, sequence_start: str | None
) -> tuple[str, Telemetry, VerdictOptions]:
    # Both media types on one path: FastAPI declares one body per route, so the body is
    # read here and validated with the same models.
    full_type = request.headers.get("content-type", "")
    content_type = full_type.split(";")[0].strip().lower()
    gzipped = _gzip_encoded(request)
    if content_type == "multipart/form-data":
        if gzipped:
            raise HTTPException(
                status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
                detail="Content-Encoding: gzip is read for a JSON body only; send the form "
                "as is, with its telemetry file gzip-compressed (pass.csv.gz)",
            )
        return await _from_form(request, sequence_start)
    if content_type == "application/json" or content_type.endswith("+json"):
        refuse_json_charset(full_type)
        return await _from_json(request, sequence_start, gzipped=gzipped)
    raise HTTPException(
        status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
        detail=f"send application/json or multipart/form-data, not {quoted(content_type)}",
    )


#: The content codings a body may come in (RFC 9110 8.4.1: x-gzip is gzip's old name).
_GZIP_CODINGS = frozenset({"gzip", "x-gzip"})


def _gzip_encoded(request: Request) -> bool:
    """Whether the body is gzip (``Content-Encoding: gzip``); any other coding is a 415
    naming it (the header was ignored: a brotli body was refused as malformed JSON, and a
    plain one labelled br was judged)."""
    codings = content_codings(request)
    if not codings:
        return False
    if len(codings) == 1 and codings[0] in _GZIP_CODINGS:
        return True
    raise HTTPException(
        status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
        detail=f"Content-Encoding {quoted(', '.join(codings))} is not supported: send the body "
        "as is or gzip-compressed (Content-Encoding: gzip)",
    )


_SEQUENCE_START = Query(
    max_length=64,
    description="start of the actuation sequence in the telemetry's clock: seconds "
    "(e.g. 810000000.0) or ISO-8601 UTC (2025-03-01T12:00:00Z); needed for a CSV "
    "whose stamps are not seconds from the start; overrides one in the JSON body",
)


_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {"schema": {"$ref": "#/components/schemas/IdentifyRequest"}},
            "multipart/form-data": {"schema": _MULTIPART_SCHEMA},
        },
    }
}


def _refusals(bad_telemetry: str) -> dict[int | str, dict[str, Any]]:
    """What the schema says of both identify endpoints' answers other than a verdict;
    ``bad_telemetry`` says what their 422 refuses."""
    return {
        **UNAUTHORIZED,
        **no_such("classifier"),
        413: {
            "description": "the body, or a gzip body or telemetry file once decompressed, "
            "is larger than INERTIA_ID_MAX_BODY_BYTES",
            "content": {"application/json": {"schema": {"$ref": "#/components/schemas/HTTPError"}}},
        },
        415: {
            "description": "neither JSON nor multipart/form-data, JSON with a charset other "
            "than UTF-8, or a Content-Encoding other than gzip (and gzip for a JSON body only)"
        },
        422: {"description": bad_telemetry},
        503: {"description": "past capacity: try again after Retry-After seconds"},
    }


@router.post(
    "",
    dependencies=[ApiKeyDep],
    response_model=IdentifyResult,
    responses={
        200: {
            "content": {"text/csv": {"schema": {"type": "string"}}},
            "description": "the verdict (JSON), or with format=csv one row per candidate",
        },
        **_refusals("bad telemetry: the rule and the value"),
    },
    openapi_extra=_BODY,
)
async def identify_telemetry(
    request: Request,
    format: Annotated[
        Literal["json", "csv"],
        Query(description="json, or csv: the verdict as a file, one row per candidate"),
    ] = "json",
    sequence_start: Annotated[str | None, _SEQUENCE_START] = None,
) -> Any:
    """Which candidate is the spacecraft? Telemetry after the classifier's sequence.

    Send JSON ``{"classifier_id": ..., "telemetry": {"time_s": [...], "omega_rad_s":
    [[wx, wy, wz], ...]}}`` or a multipart form with ``classifier_id`` and a CSV ``file``.
    Either may be gzip-compressed: the JSON body with ``Content-Encoding: gzip``, the
    file as it is (``pass.csv.gz``); once decompressed it is held to the body's limit.
    Stamps are seconds in any clock or ISO-8601 UTC strings (``time_utc``); the sequence
    start (``sequence_start``: in the body, the telemetry or the query) is needed unless
    they are seconds from the start.
    The answer has the posterior of every candidate and of "none of these", the status
    (identified at ``confidence``, default 0.99; ambiguous; matches-none;
    not-this-sequence), the most probable candidate and its inertia, the distance to
    every candidate and the margin to the runner-up, and the least-squares tensor when
    it is physically valid and well excited.
    """
    classifier_id, telemetry, options = await _read_body(request, sequence_start)
    verdict = await _verdict(request, classifier_id, telemetry, options, partial=False)
    if format == "csv":
        stem = f"identify-{verdict.classifier_id[:8]}"
        return Response(
            content=to_csv(identify_table(verdict.model_dump(mode="json"))),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": f'attachment; filename="{stem}.csv"'},
        )
    # Already validated as IdentifyResult: serialised once here, not validated again by
    # FastAPI's response_model (which still documents it).
    return Response(content=verdict.model_dump_json(), media_type="application/json")


@router.post(
    "/partial",
    dependencies=[ApiKeyDep],
    response_model=PartialIdentifyResult,
    responses=_refusals("bad telemetry, or a kind without a posterior for part of a series"),
    openapi_extra=_BODY,
)
async def identify_partial(
    request: Request, sequence_start: Annotated[str | None, _SEQUENCE_START] = None
) -> Any:
    """The posterior so far, from telemetry covering the sequence's start up to now.

    The same body as ``POST /identify``. The answer has each candidate's posterior after
    every covered grid sample, the current one, and whether the stop rule has decided
    (top posterior >= 1 - alpha, alpha = 1 - confidence, default 0.001) and when. The
    likelihood kinds answer (their Gaussian's leading block is exact); others get 422.
    """
    classifier_id, telemetry, options = await _read_body(request, sequence_start)
    if options.estimate_start_within_s is not None:
        unprocessable(
            ("body", "estimate_start_within_s"),
            "estimate_start_within_s is for POST /identify only, got "
            f"{options.estimate_start_within_s!r}: the posterior over time follows the stated "
            "start (find the start with POST /identify, then send it as sequence_start)",
        )
    return await _verdict(request, classifier_id, telemetry, options, partial=True)
