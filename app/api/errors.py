"""Every bad input becomes a 422 whose message names the rule and quotes the value.

The core raises ``ValueError`` with such messages; pydantic's ``ValidationError`` is one
too. All 422 bodies have one shape, ``{"detail": [{"loc", "msg", "type"}, ...]}``. The
input itself is not echoed (it may be 200 000 telemetry rows, or hold NaN, which JSON
cannot carry); a scalar input is quoted in the message instead.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import sqlalchemy.exc
from fastapi import FastAPI, Request, status
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError

__all__ = ["format_errors", "install_error_handlers"]

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


def _unprocessable(detail: list[dict[str, Any]]) -> JSONResponse:
    return JSONResponse(
        status_code=status.HTTP_422_UNPROCESSABLE_CONTENT, content={"detail": detail}
    )


async def _request_validation(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, RequestValidationError)
    return _unprocessable(format_errors(exc.errors()))


async def _value_error(_request: Request, exc: Exception) -> JSONResponse:
    if isinstance(exc, ValidationError):
        return _unprocessable(format_errors(exc.errors(include_url=False)))
    return _unprocessable([{"loc": [], "msg": _text(str(exc)), "type": "value_error"}])


async def _arithmetic(_request: Request, exc: Exception) -> JSONResponse:
    return _unprocessable(
        [
            {
                "loc": [],
                "msg": _text(f"a number in the request is out of range: {exc}"),
                "type": "arithmetic_error",
            }
        ]
    )


async def _database_busy(_request: Request, exc: Exception) -> JSONResponse:
    # Every pooled connection in use for pool_timeout: the service is past capacity.
    log.warning("database connection pool exhausted: %s", exc)
    return JSONResponse(
        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
        content={"detail": "the service is past its capacity (no database connection free)"},
        headers={"Retry-After": "2"},
    )


async def _database_down(_request: Request, exc: Exception) -> JSONResponse:
    log.error("database unreachable: %s", exc)
    return JSONResponse(
        status_code=status.HTTP_503_SERVICE_UNAVAILABLE,
        content={"detail": "the database cannot be reached; try again shortly"},
        headers={"Retry-After": "5"},
    )


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _request_validation)
    # The core's rules (scenario physics, sequences, telemetry) raise ValueError.
    app.add_exception_handler(ValueError, _value_error)
    # A last resort for extreme numbers the core's validators do arithmetic on before
    # checking them (a huge JSON integer passed to float(), a subnormal rate whose product
    # underflows to a division by zero); the schemas refuse the cases known to the API
    # with a message naming the field.
    app.add_exception_handler(ArithmeticError, _arithmetic)
    app.add_exception_handler(sqlalchemy.exc.TimeoutError, _database_busy)
    app.add_exception_handler(sqlalchemy.exc.OperationalError, _database_down)
    app.add_exception_handler(sqlalchemy.exc.InterfaceError, _database_down)
