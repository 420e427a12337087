"""Dependencies shared by the routers: settings, database session, API key, paging."""

from __future__ import annotations

import re
import types
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Annotated, Any, Literal, NoReturn, TypeVar, Union, get_args, get_origin

from celery import Celery
from fastapi import Depends, HTTPException, Query, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.security import APIKeyHeader
from sqlalchemy import ColumnElement, func, select
from sqlalchemy.orm import Session

from inertia_id.checks import number_as_written
from service.config import Settings
from service.store.models import MAX_TAG_LENGTH, JobTagRow
from service.store.session import Database

from ..schemas import TagText
from ..security import API_KEY_HEADER, KeyVerifier, key_refusal

__all__ = [
    "UNAUTHORIZED",
    "ApiKeyDep",
    "CeleryDep",
    "DatabaseDep",
    "OrderQuery",
    "Paging",
    "PagingDep",
    "SessionDep",
    "SettingsDep",
    "TagText",
    "checked_tags",
    "get_or_404",
    "job_tagged",
    "no_such",
    "not_found",
    "numbers_as_written",
    "plausible_id",
    "quoted",
    "quoted_id",
    "sort_query",
    "text_query",
    "unknown_sort",
    "unprocessable",
]

Row = TypeVar("Row")

# Row ids are uuid4 hex strings; anything else cannot name a row. Checking before the
# query keeps NUL bytes and lone surrogates (which SQLite and PostgreSQL refuse to bind)
# away from the database.
_ID = re.compile(r"[0-9A-Za-z_-]{1,64}")


def plausible_id(value: str) -> bool:
    return _ID.fullmatch(value) is not None


def get_settings(request: Request) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def get_database(request: Request) -> Database:
    database: Database = request.app.state.db
    return database


def get_celery(request: Request) -> Celery:
    celery: Celery = request.app.state.celery
    return celery


def get_session(database: Annotated[Database, Depends(get_database)]) -> Iterator[Session]:
    """A session for one request: committed when the endpoint returns, else rolled back."""
    with database.session() as session:
        yield session


SettingsDep = Annotated[Settings, Depends(get_settings)]
DatabaseDep = Annotated[Database, Depends(get_database)]
CeleryDep = Annotated[Celery, Depends(get_celery)]
# scope="function": commit before the response is sent, so a client that reads right
# after a write sees it.
SessionDep = Annotated[Session, Depends(get_session, scope="function")]

_api_key_header = APIKeyHeader(
    name=API_KEY_HEADER,
    auto_error=False,
    description="Needed by every write endpoint (POST, DELETE). Printed by `inertia-id serve` "
    "when generated on the first run, or set with INERTIA_ID_API_KEY.",
)


async def require_api_key(
    request: Request,
    key: Annotated[str | None, Depends(_api_key_header)],
) -> None:
    """401 unless the request carries an accepted key (never echoed back).

    Holds no database connection for the request (see :class:`app.security.KeyVerifier`).
    A remembered key is answered on the event loop; only a lookup goes to a thread (a
    sync dependency cost every request a thread hand-off, 0.2 ms of /identify's 4).
    """
    verify: KeyVerifier = request.app.state.verify_key
    problem = await key_refusal(verify, key)
    if problem is not None:
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED,
            detail=problem,
            headers={"WWW-Authenticate": API_KEY_HEADER},
        )


ApiKeyDep = Depends(require_api_key)

#: What the schema says of a write endpoint's 401 (see :func:`require_api_key`).
UNAUTHORIZED: dict[int | str, dict[str, Any]] = {401: {"description": "missing or wrong API key"}}


def no_such(what: str) -> dict[int | str, dict[str, Any]]:
    """What the schema says of the 404 (:func:`not_found`) of an endpoint naming a ``what``."""
    return {404: {"description": f"no such {what}"}}


@dataclass(frozen=True)
class Paging:
    limit: int
    offset: int


def paging(
    settings: SettingsDep,
    limit: Annotated[
        int, Query(ge=1, description="page size, at most INERTIA_ID_MAX_PAGE_SIZE (200)")
    ] = 50,
    offset: Annotated[int, Query(ge=0, le=2**31 - 1)] = 0,
) -> Paging:
    if limit > settings.max_page_size:
        unprocessable(
            ("query", "limit"),
            f"page size must be at most {settings.max_page_size}, got {limit}",
        )
    return Paging(limit=limit, offset=offset)


PagingDep = Annotated[Paging, Depends(paging)]

#: ``?order=``: the direction of a list's ``?sort=``.
OrderQuery = Annotated[Literal["asc", "desc"], Query(description="asc or desc")]


def text_query(description: str) -> Any:
    """A list's ``?q=``: free text of at most 200 characters without NUL (which the
    databases refuse to bind); ``description`` says what it matches."""
    return Query(max_length=200, pattern=r"^[^\x00]*$", description=description)


def sort_query(keys: Iterable[str], description: str) -> Any:
    """A list's ``?sort=``: one of ``keys``, which the schema lists as its enum (checked
    by the endpoint, with :func:`unknown_sort`, since some keys are read at run time)."""
    return Query(max_length=64, description=description, json_schema_extra={"enum": list(keys)})


def unknown_sort(what: str, sort: str, keys: Iterable[str]) -> NoReturn:
    """422 for a ``?sort=`` that is none of ``keys``."""
    unprocessable(
        ("query", "sort"), f"cannot sort {what} by {quoted(sort)}; by one of {', '.join(keys)}"
    )


def checked_tags(tags: list[str] | None) -> list[str]:
    """Tags from a query (``?tag=a&tag=b``), stripped; 422 for one no job could carry."""
    out = []
    for raw in tags or []:
        tag = raw.strip()
        if not tag or len(tag) > MAX_TAG_LENGTH or any(ord(c) < 32 for c in tag):
            unprocessable(
                ("query", "tag"),
                f"a tag is 1 to {MAX_TAG_LENGTH} characters without control characters, "
                f"got {quoted(raw)}",
            )
        out.append(tag)
    return out


def job_tagged(
    job_id: Any, *, tag: str | None = None, containing: str | None = None
) -> ColumnElement[bool]:
    """The job ``job_id`` (a column) carries ``tag``, or a tag whose lower case contains
    ``containing`` (already lower case)."""
    condition = (
        JobTagRow.tag == tag
        if containing is None
        else func.lower(JobTagRow.tag).contains(containing, autoescape=True)
    )
    return select(JobTagRow.job_id).where(JobTagRow.job_id == job_id, condition).exists()


def unprocessable(loc: tuple[str | int, ...], message: str) -> NoReturn:
    """Raise a 422 shaped like pydantic's, for rules checked outside the models."""
    raise RequestValidationError([{"loc": loc, "msg": message, "type": "value_error"}])


#: Query parameters a request may repeat (list-valued: every value counts).
REPEATABLE_QUERY = frozenset({"tag"})


_QUERY_NAMES: dict[int, frozenset[str]] = {}


def _route_query_names(route: Any) -> frozenset[str] | None:
    """The query parameters ``route`` reads (its dependencies' too), or None when it is
    not an API route (the dashboard's page and the docs take whatever a browser adds).
    Walked here from the route's dependency tree (FastAPI keeps it
    public as ``route.dependant``; its own flattening helper is internal)."""
    dependant = getattr(route, "dependant", None)
    if dependant is None or not getattr(route, "include_in_schema", False):
        return None
    names = _QUERY_NAMES.get(id(route))
    if names is None:
        found: set[str] = set()
        stack = [dependant]
        while stack:
            current = stack.pop()
            found.update(field.alias for field in current.query_params)
            stack.extend(current.dependencies)
        names = _QUERY_NAMES[id(route)] = frozenset(found)
    return names


def one_value_each(request: Request) -> None:
    """Refuse a query parameter the route does not read, or one given more than once
    unless it is a list.

    FastAPI (Starlette) keeps the last of repeated values, so
    ``?sequence=A&sequence=B`` would plan B alone and ``?format=csv&format=json`` answer
    JSON; and it ignores names it does not know, so ``/jobs?stauts=failed`` listed every
    job: a request must mean one thing. Applied to every route (``app.main``)."""
    known = _route_query_names(request.scope.get("route"))
    if known is not None:
        unknown = [name for name in request.query_params if name not in known]
        if unknown:
            takes = ", ".join(sorted(known)) or "none"
            unprocessable(
                ("query", unknown[0][:40]),
                f"unknown query parameter {unknown[0][:40]!r}; this route takes: {takes}",
            )
    for name in request.query_params:
        if name in REPEATABLE_QUERY:
            continue
        given = request.query_params.getlist(name)
        if len(given) > 1:
            shown = [value[:40] for value in given[:5]]
            unprocessable(
                ("query", name), f"{name} is given {len(given)} times ({shown}); give one"
            )


def _number_kind(annotation: Any) -> bool | None:
    """True when a parameter of type ``annotation`` is a whole number (``int``, ``int |
    None``, ``list[int]``), False for a decimal one (``float``), None for any other (text,
    a choice, a bool)."""
    members = get_args(annotation) if get_origin(annotation) in (Union, types.UnionType) else ()
    found: set[Any] = set()
    for member in members or (annotation,):
        if get_origin(member) in (list, tuple, set, frozenset):
            found.update(get_args(member))
        else:
            found.add(member)
    if str in found or bool in found:
        return None
    if int in found:
        return True
    return False if float in found else None


_NUMBER_PARAMETERS: dict[int, tuple[tuple[str, str, bool], ...]] = {}


def _route_numbers(route: Any) -> tuple[tuple[str, str, bool], ...]:
    """The number parameters of ``route`` (its dependencies' too): (``query`` or
    ``path``, name, whether whole), read from its dependency tree as
    :func:`_route_query_names` reads it."""
    dependant = getattr(route, "dependant", None)
    if dependant is None:
        return ()
    numbers = _NUMBER_PARAMETERS.get(id(route))
    if numbers is None:
        found: list[tuple[str, str, bool]] = []
        stack = [dependant]
        while stack:
            current = stack.pop()
            for where, fields in (("query", current.query_params), ("path", current.path_params)):
                for field in fields:
                    whole = _number_kind(field.field_info.annotation)
                    if whole is not None:
                        found.append((where, field.alias, whole))
            stack.extend(current.dependencies)
        numbers = _NUMBER_PARAMETERS[id(route)] = tuple(found)
    return numbers


def numbers_as_written(request: Request) -> None:
    """Refuse a number in the query or the path that is not written as the command line
    takes one (:func:`inertia_id.checks.number_as_written`): ASCII digits with an
    optional sign (and point and exponent for a decimal), spaces around allowed.

    Pydantic's lax mode, which reads every query and path parameter (text is all a URL
    holds), also reads ``?seed=1_0`` as 10; its own grammar is not the command line's, so
    each number parameter is read here first with the core's readers, on every route
    (``app.main``), and then by pydantic for its range."""
    for where, name, whole in _route_numbers(request.scope.get("route")):
        if where == "query":
            given = request.query_params.getlist(name)
        else:
            value = request.path_params.get(name)
            given = [] if value is None else [str(value)]
        for text in given:
            try:
                number_as_written(text, name, whole=whole)
            except ValueError as exc:
                unprocessable((where, name), str(exc))


#: The characters of a sent value (an id, a header, a query) that a message quotes; a
#: longer one is cut, and the cut said.
_QUOTE = 80


def quoted(text: str) -> str:
    """``text``, a value the client sent, quoted for a message: whole, or its first
    :data:`_QUOTE` characters with "…" and its length (cut silently, a value of 5,000
    characters read as another of 80, one the client could have sent)."""
    if len(text) <= _QUOTE:
        return repr(text)
    return f"{text[:_QUOTE]!r}… ({len(text)} characters)"


def quoted_id(row_id: str) -> str:
    """``row_id`` quoted for a message (:func:`quoted`): an id of 5,000 characters cut
    silently read as another id of 80, one that could exist."""
    return quoted(row_id)


def not_found(what: str, row_id: str) -> HTTPException:
    """The 404 for a ``what`` (job, classifier, ...) that no row ``row_id`` is."""
    return HTTPException(status.HTTP_404_NOT_FOUND, detail=f"{what} {quoted_id(row_id)} not found")


def get_or_404(session: Session, model: type[Row], row_id: str, what: str) -> Row:
    row = session.get(model, row_id) if plausible_id(row_id) else None
    if row is None:
        raise not_found(what, row_id)
    return row
