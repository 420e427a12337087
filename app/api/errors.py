"""Bad input is a 422 whose message names the rule and quotes the value; a bug is a 500.

The caller's faults are the core's :class:`inertia_id.InputError` and pydantic's
``ValidationError`` (the request models, the scenario's rules): 422, all with one shape,
``{"detail": [{"loc", "msg", "type"}, ...]}``. The input itself is not echoed (it may be
200 000 telemetry rows, or hold NaN, which JSON cannot carry); a scalar input is quoted
in the message instead.

Anything else raised while serving a request is our fault: a 500 whose body says only
that, with the request's id (``X-Request-ID``), and a traceback in the log under the same
id. Internals (messages, paths, SQL) never reach the client.
"""

from __future__ import annotations

import logging
import re
import uuid
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import sqlalchemy.exc
from fastapi import FastAPI, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from inertia_id.errors import InputError

from ..security import scope_header
from .deps import unprocessable

__all__ = ["format_errors", "install_error_handlers", "refused_at"]

log = logging.getLogger(__name__)

_MAX_QUOTE = 120
# Built-in pydantic messages say the rule but not the value.
_NO_QUOTE = {"missing", "value_error", "assertion_error", "union_tag_not_found"}


def _text(value: str) -> str:
    """``value`` safe to encode as UTF-8 (lone surrogates escaped)."""
    return value.encode("utf-8", "backslashreplace").decode("utf-8")


def _quote(value: Any) -> str:
    text = repr(value)
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
        if value is None or isinstance(value, bool | int | float | str):
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


@contextmanager
def refused_at(loc: tuple[str | int, ...]) -> Iterator[None]:
    """What the models or the core refuse inside the block, as a 422 located at ``loc`` of
    the request (the handlers below can only say ``[]``: they do not know where the value
    came from)."""
    try:
        yield
    except ValidationError as exc:
        raise RequestValidationError(format_errors(exc.errors(include_url=False), loc)) from None
    except InputError as exc:
        unprocessable(loc, str(exc))


def _unprocessable(detail: list[dict[str, Any]]) -> JSONResponse:
    return JSONResponse(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, content={"detail": detail}
    )


async def _request_validation(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    return _unprocessable(format_errors(exc.errors()))


async def _validation_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, ValidationError)
    return _unprocessable(format_errors(exc.errors(include_url=False)))


async def _input_error(_request: Request, exc: Exception) -> JSONResponse:
    return _unprocessable([{"loc": [], "msg": _text(str(exc)), "type": "value_error"}])


async def _internal_error(request: Request, exc: Exception) -> JSONResponse:
    request_id = request_id_of(request)
    log.error(
        "request %s (%s %s) failed: %s",
        request_id,
        request.method,
        request.url.path,
        type(exc).__name__,
        exc_info=exc,
    )
    return JSONResponse(
        status_code=status.HTTP_500_INTERNAL_SERVER_ERROR,
        content={
            "detail": f"internal error: a defect of the service, not of the request "
            f"(request id {request_id}; the server's log has the details)"
        },
        headers={REQUEST_ID_HEADER: request_id},
    )


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


async def _database_down(_request: Request, exc: Exception) -> JSONResponse:
    log.error("database unreachable: %s", exc)
    return _unavailable("the database cannot be reached; try again shortly", 5)


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _request_validation)
    # The core's rules (scenario physics, sequences, telemetry) raise InputError; the
    # models' rules, pydantic's ValidationError.
    app.add_exception_handler(InputError, _input_error)
    app.add_exception_handler(ValidationError, _validation_error)
    app.add_exception_handler(sqlalchemy.exc.TimeoutError, _database_busy)
    app.add_exception_handler(sqlalchemy.exc.OperationalError, _database_down)
    app.add_exception_handler(sqlalchemy.exc.InterfaceError, _database_down)
    app.add_exception_handler(Exception, _internal_error)
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
