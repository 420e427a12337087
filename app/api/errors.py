"""Bad input is a 422 whose message names the rule and quotes the value; a bug is a 500.

The caller's faults are the core's :class:`inertia_id.InputError` and pydantic's
``ValidationError`` (the request models, the scenario's rules): 422, all with one shape,
``{"detail": [{"loc", "msg", "type"}, ...]}``. The input itself is not echoed (it may be
200 000 telemetry rows, or hold NaN, which JSON cannot carry); it is quoted in the
message instead, a list or object by its first items (at most 120 characters).

Anything else raised while serving a request is our fault: a 500 whose body says only
that, with the request's id (``X-Request-ID``), and a traceback in the log under the same
id. Internals (messages, paths, SQL) never reach the client. The 500 ends that request
only: the connection stays open for the client's next one (:class:`InternalErrors`).
"""

from __future__ import annotations

import logging
import re
import reprlib
import uuid
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import sqlalchemy.exc
from fastapi import FastAPI, Request, status
from fastapi.exception_handlers import http_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, Response
from pydantic import ValidationError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match, Mount
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from inertia_id.checks import DuplicateKeyError
from inertia_id.errors import InputError
from service.store.refusals import why_cannot_store

from ..security import asked_with, scope_header
from ..watched_send import WatchedSend
from .deps import unprocessable

__all__ = ["duplicate_key_errors", "format_errors", "install_error_handlers", "refused_at"]

log = logging.getLogger(__name__)

_MAX_QUOTE = 120
# Built-in pydantic messages say the rule but not the value.
_NO_QUOTE = {"missing", "value_error", "assertion_error", "union_tag_not_found"}


def _text(value: str) -> str:
    """``value`` safe to encode as UTF-8 (lone surrogates escaped)."""
    return value.encode("utf-8", "backslashreplace").decode("utf-8")


# A list or object is quoted by its first items and levels (a body may be 200 000 rows:
# its whole repr would be built only to be cut).
_BRIEF = reprlib.Repr()
_BRIEF.maxlevel, _BRIEF.maxlist, _BRIEF.maxdict = 3, 6, 4
_BRIEF.maxstring = _BRIEF.maxother = _MAX_QUOTE


def _quote(value: Any) -> str:
    text = _BRIEF.repr(value) if isinstance(value, list | dict) else repr(value)
    if len(text) > _MAX_QUOTE:
        text = text[: _MAX_QUOTE - 3] + "..."
    return text


def _format_error(error: Mapping[str, Any], prefix: Sequence[str | int]) -> dict[str, Any]:
    kind = str(error.get("type", "value_error"))
    message = str(error.get("msg", ""))
    if kind == "value_error":
        message = message.removeprefix("Value error, ")
    elif kind == "json_invalid":
        reason = (error.get("ctx") or {}).get("error")
        if reason:
            message = f"{message}: {reason}"
    elif kind not in _NO_QUOTE and "input" in error:
        value = error["input"]
        if value is None or isinstance(value, bool | int | float | str | list | dict):
            message = f"{message}, got {_quote(value)}"
    loc = [*prefix, *error.get("loc", ())]
    return {
        "loc": [_text(p) if isinstance(p, str) else p for p in loc],
        "msg": _text(message),
        "type": kind,
    }


def format_errors(
    errors: Iterable[Mapping[str, Any]], prefix: Sequence[str | int] = ()
) -> list[dict[str, Any]]:
    return [_format_error(error, prefix) for error in errors]


# No document given (``None`` is a JSON body of its own: ``null``).
_NOT_SENT: Any = object()
# Below a key the client did not send (a model's own "before" validator put it there).
_UNSEEN: Any = object()


@contextmanager
def refused_at(loc: tuple[str | int, ...], sent: Any = _NOT_SENT) -> Iterator[None]:
    """What the models or the core refuse inside the block, as a 422 located at ``loc`` of
    the request (the handlers below can only say ``[]``: they do not know where the value
    came from). ``sent``, the document validated in the block as the client sent it,
    locates each refusal where the client put the value (:func:`_located`)."""
    try:
        yield
    except ValidationError as exc:
        errors: Iterable[Mapping[str, Any]] = exc.errors(include_url=False)
        if sent is not _NOT_SENT:
            errors = _located(({**e, "loc": ("body", *e["loc"])} for e in errors), sent)
            errors = ({**e, "loc": tuple(e["loc"])[1:]} for e in errors)
        raise RequestValidationError(format_errors(errors, loc)) from None
    except InputError as exc:
        unprocessable(loc, str(exc))


def _unprocessable(detail: list[dict[str, Any]]) -> JSONResponse:
    return JSONResponse(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, content={"detail": detail}
    )


# The key a discriminated union of the request models is told apart by (POST /jobs:
# "search", "train" or "sweep").
_DISCRIMINATOR = "type"


# How pydantic names a plain union's member in ``loc``: a type ("float", "str",
# "list[float]", "function-after[...]"), never a field of ours (snake_case).
_MEMBER_TAG = re.compile(r"(str|int|float|bool|bytes|none)|[a-z]+(-[a-z]+)*\[.*\]")


def _without_union_tags(error: Mapping[str, Any], body: Any) -> tuple[Mapping[str, Any], bool]:
    """``error`` located where the client put the value, and whether a tag was dropped.

    Pydantic puts a union's tags in ``loc``, keys the client never sent: a discriminated
    union's (``["body", "search", "seed"]`` for a search job's seed) and a plain union's
    member types (``["body", "sequence_start", "float"]`` and ``[..., "str"]`` for a start
    of ``float | str`` that is neither). Each tag is dropped, walking ``loc`` down the body
    (the client's own ``type`` says which job it was; a name cannot address into a number,
    a string or a list, so a name below one is a member's tag)."""
    loc = list(error.get("loc", ()))
    if loc[:1] != ["body"]:
        return error, False
    kept: list[Any] = ["body"]
    node = body
    dropped = False
    last = len(loc) - 1
    for at, part in enumerate(loc[1:], start=1):
        if isinstance(node, Mapping):
            # A member's type refused at a key the object does not hold: {"a": 1} as a start.
            refused_member = (
                at == last
                and str(error.get("type", "")).endswith("_type")
                and isinstance(part, str)
                and _MEMBER_TAG.fullmatch(part) is not None
            )
            if (
                isinstance(part, str)
                and part not in node
                and (node.get(_DISCRIMINATOR) == part or refused_member)
            ):
                dropped = True
                continue
            node = node.get(part, _UNSEEN) if isinstance(part, str) else _UNSEEN
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        elif isinstance(part, str) and node is not _UNSEEN:
            dropped = True
            continue
        else:
            node = _UNSEEN
        kept.append(part)
    return {**error, "loc": tuple(kept)}, dropped


# How pydantic's type refusals begin: the second of a union's is joined without it.
_SHOULD = "Input should be "


def _located(errors: Iterable[Mapping[str, Any]], body: Any) -> list[Mapping[str, Any]]:
    """``errors`` located in ``body`` (:func:`_without_union_tags`), the refusals of one
    union's members at one place made one: ``sequence_start: true`` was two errors, "a valid
    number" at ``["body", "sequence_start", "float"]`` and "a valid string" at ``[...,
    "str"]``; it is one at ``["body", "sequence_start"]``, "Input should be a valid number or
    a valid string, got True"."""
    merged: list[Mapping[str, Any]] = []
    members: dict[tuple[Any, ...], int] = {}
    for error in errors:
        located, dropped = _without_union_tags(error, body)
        where = tuple(located["loc"])
        if not dropped:
            merged.append(located)
            continue
        if where not in members:
            members[where] = len(merged)
            merged.append(located)
            continue
        first = merged[members[where]]
        message, other = str(first.get("msg", "")), str(located.get("msg", ""))
        if message.startswith(_SHOULD) and other.startswith(_SHOULD):
            other = other.removeprefix(_SHOULD)
        merged[members[where]] = {**first, "msg": f"{message} or {other}"}
    return merged


async def _request_validation(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    # No body: refused before one was read, or already located (:func:`refused_at`).
    body = getattr(exc, "body", None)
    return _unprocessable(format_errors(_located(exc.errors(), _UNSEEN if body is None else body)))


async def _validation_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ValidationError)
    return _unprocessable(format_errors(exc.errors(include_url=False)))


async def _input_error(_request: Request, exc: Exception) -> JSONResponse:
    return _unprocessable([{"loc": [], "msg": _text(str(exc)), "type": "value_error"}])


# Set in a request's scope to the exception already logged, so that it is logged once.
_LOGGED = "inertia_id.logged_error"


def _log_internal_error(scope: Scope, exc: Exception, note: str = "") -> None:
    """Log ``exc`` with its traceback under the request's id, once per request."""
    if scope.get(_LOGGED) is exc:
        return
    scope[_LOGGED] = exc
    request = Request(scope)
    log.error(
        "request %s (%s %s) failed%s: %s",
        request_id_of(request),
        request.method,
        request.url.path,
        note,
        type(exc).__name__,
        exc_info=exc,
    )


def _internal_error_response(request_id: str, *, close: bool = False) -> JSONResponse:
    headers = {REQUEST_ID_HEADER: request_id}
    if close:
        headers["Connection"] = "close"
    return JSONResponse(
        status_code=status.HTTP_500_INTERNAL_SERVER_ERROR,
        content={
            "detail": f"internal error: a defect of the service, not of the request "
            f"(request id {request_id}; the server's log has the details)"
        },
        headers=headers,
    )


async def _internal_error(request: Request, exc: Exception) -> JSONResponse:
    """Starlette's ``ServerErrorMiddleware`` handler, for what :class:`InternalErrors`
    did not catch (an exception raised by a middleware outside it). That middleware
    re-raises after the answer and the server then closes the connection: the answer
    says so (``Connection: close``), so that the client does not send its next request
    on it."""
    _log_internal_error(request.scope, exc)
    return _internal_error_response(request_id_of(request), close=True)


class InternalErrors:
    """Answer an exception that no handler took (a defect) with our 500, its traceback
    logged under the request's id, and end the request there: the connection serves the
    client's next request.

    Left to Starlette's ``ServerErrorMiddleware`` (where an ``Exception`` handler runs),
    the same 500 is sent and the exception raised again, for the server to log; uvicorn,
    seeing an exception after the answer started, closes the connection without a
    ``Connection: close`` in the answer, and a client's next request on that keep-alive
    connection failed ("connection reset").

    Inside :class:`RequestId` (its id in the answer) and outside Starlette's
    ``ExceptionMiddleware`` (so the handlers of :func:`install_error_handlers` still make
    422s and 503s). An exception after the answer was complete (a background task) is
    logged only. One in the middle of an answer is logged and raised again: the server
    must close the connection, as the client cannot tell where the answer ends.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        watched = WatchedSend(send)
        try:
            await self.app(scope, receive, watched.send)
        except Exception as exc:
            if watched.complete:
                _log_internal_error(scope, exc, " after its answer was sent")
                return
            if watched.started:
                _log_internal_error(scope, exc, " in the middle of its answer (connection closed)")
                raise
            _log_internal_error(scope, exc)
            response = _internal_error_response(request_id_of(Request(scope)))
            await response(scope, receive, send)


def _unavailable(detail: str, retry_after_s: int) -> JSONResponse:
    """503: try again after ``retry_after_s`` seconds."""
    return JSONResponse(
        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
        content={"detail": detail},
        headers={"Retry-After": str(retry_after_s)},
    )


async def _database_busy(_request: Request, exc: Exception) -> JSONResponse:
    # Every pooled connection in use for pool_timeout: the service is past capacity.
    log.warning("database connection pool exhausted: %s", exc)
    return _unavailable("the service is past its capacity (no database connection free)", 2)


# What the caller is told for each refusal (service.store.refusals.why_cannot_store).
_CANNOT_STORE = {
    "full": "the database cannot store anything: the disk that holds it is full; free "
    "space there, then try again",
    "read-only": "the database takes no writes: it is read-only; make it writable, then try again",
    "io": "the database could not write to its disk (an I/O error): check the disk that "
    "holds it, then try again",
}


async def _database_down(_request: Request, exc: Exception) -> JSONResponse:
    # A full disk or a read-only database file is reachable: saying "cannot be reached"
    # sent an operator to look at the network, not at the disk (the 503 was the same).
    why = why_cannot_store(exc)
    if why is not None:
        log.error("database cannot store (%s): %s", why, exc)
        return _unavailable(_CANNOT_STORE[why], 30)
    log.error("database unreachable: %s", exc)
    return _unavailable("the database cannot be reached; try again shortly", 5)


async def _database_refused(_request: Request, exc: Exception) -> JSONResponse:
    # PostgreSQL raises a write in a read-only transaction (25006) as an InternalError,
    # which was a 500 "defect" while the database was a standby or set read-only; any
    # other InternalError is still one, answered by InternalErrors as before.
    why = why_cannot_store(exc)
    if why is None:
        raise exc
    log.error("database cannot store (%s): %s", why, exc)
    return _unavailable(_CANNOT_STORE[why], 30)


async def _http_error(request: Request, exc: Exception) -> Response:
    """FastAPI's HTTP errors as they were, but for a JSON body its parser could not take
    past the JSON grammar (an integer of over 4,300 digits, arrays nested thousands deep):
    FastAPI answers those 400 "There was an error parsing the body", naming nothing; they
    are the caller's and a 422 says what was wrong, as ``POST /identify`` does. A key given
    twice in one object (:mod:`app.api.routing`) is located at that object."""
    assert isinstance(exc, StarletteHTTPException)
    cause = exc.__cause__
    if exc.status_code == 400 and isinstance(cause, DuplicateKeyError):
        return _unprocessable(duplicate_key_errors(cause))
    if exc.status_code == 400 and isinstance(cause, ValueError | RecursionError):
        return _unprocessable(
            [
                {
                    "loc": ["body"],
                    "msg": _text(f"request body is not acceptable JSON: {cause}"),
                    "type": "value_error",
                }
            ]
        )
    if exc.status_code == status.HTTP_405_METHOD_NOT_ALLOWED:
        return _method_not_allowed(request)
    return await http_exception_handler(request, exc)


# The methods a route of this API may take (HEAD is answered as GET).
_METHODS = ("GET", "POST", "PUT", "PATCH", "DELETE")


def _method_not_allowed(request: Request) -> JSONResponse:
    """405 with ``Allow`` listing every method the path takes (RFC 9110 §15.5.6), and a
    detail naming the method refused and those. Starlette's router listed the methods of
    the first route matching the path only: ``DELETE /jobs/{id}`` answered ``Allow:
    PATCH``, hiding GET, and ``PUT /scenarios/{id}/plan`` ``Allow: GET``, hiding POST."""
    routes = [route for route in request.app.router.routes if not isinstance(route, Mount)]
    methods = {
        method
        for method in _METHODS
        if any(
            route.matches({**request.scope, "method": method})[0] == Match.FULL for route in routes
        )
    }
    if "GET" in methods:
        methods.add("HEAD")  # answered as GET (app.security.HeadAsGet)
    allowed = ", ".join(sorted(methods))
    return JSONResponse(
        status_code=status.HTTP_405_METHOD_NOT_ALLOWED,
        content={
            "detail": _text(
                f"method {asked_with(request.scope)} is not allowed on {request.url.path}; "
                f"it takes {allowed}"
            )
        },
        headers={"Allow": allowed},
    )


def duplicate_key_errors(
    error: DuplicateKeyError, at: Sequence[str | int] = ("body",)
) -> list[dict[str, Any]]:
    """A key given twice in a JSON request body (or in JSON held ``at`` another part of
    the request), as the 422's errors: located at the object that holds it."""
    loc = [*at, *error.path]
    return [
        {
            "loc": [_text(p) if isinstance(p, str) else p for p in loc],
            "msg": _text(str(error)),
            "type": "value_error",
        }
    ]


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _request_validation)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    # The core's rules (scenario physics, sequences, telemetry) raise InputError; the
    # models' rules, pydantic's ValidationError.
    app.add_exception_handler(InputError, _input_error)
    app.add_exception_handler(ValidationError, _validation_error)
    app.add_exception_handler(sqlalchemy.exc.TimeoutError, _database_busy)
    app.add_exception_handler(sqlalchemy.exc.OperationalError, _database_down)
    app.add_exception_handler(sqlalchemy.exc.InterfaceError, _database_down)
    app.add_exception_handler(sqlalchemy.exc.InternalError, _database_refused)
    app.add_exception_handler(Exception, _internal_error)
    # add_middleware puts the last added outermost: RequestId, then InternalErrors.
    app.add_middleware(InternalErrors)
    app.add_middleware(RequestId)


REQUEST_ID_HEADER = "X-Request-ID"
_REQUEST_ID = re.compile(r"[A-Za-z0-9._-]{8,64}")


def request_id_of(request: Request) -> str:
    """The id the :class:`RequestId` middleware gave the request."""
    return str(request.scope.get("state", {}).get("request_id") or "unknown")


class RequestId:
    """Give every request an id (the client's ``X-Request-ID`` when it is a plausible
    one), echo it in the response, and let logs and error bodies name it."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        given = scope_header(scope, b"x-request-id") or ""
        request_id = given if _REQUEST_ID.fullmatch(given) else uuid.uuid4().hex
        scope.setdefault("state", {})["request_id"] = request_id

        async def with_id(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = [(k, v) for k, v in message.get("headers", []) if k != b"x-request-id"]
                headers.append((b"x-request-id", request_id.encode()))
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, with_id)
