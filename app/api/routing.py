"""The route class of every router: a JSON body with a key given twice is refused.

FastAPI parses a JSON body with Starlette's ``Request.json``, that is ``json.loads``, which
keeps the last of two values for one key without a word: ``{"scenario": {...},
"scenario": {...}}`` was stored as the second. :class:`UniqueKeysRoute` hands the route a
request whose ``json`` is :func:`inertia_id.checks.loads_unique_keys` (the same one parse,
its hook counting each object's keys); FastAPI turns the
:class:`~inertia_id.checks.DuplicateKeyError` into a 400 caused by it, which
:mod:`app.api.errors` answers as a 422 at the object that holds the key.
"""

from __future__ import annotations

import codecs
from collections.abc import Callable, Coroutine
from email.message import Message
from typing import Any

from fastapi import HTTPException, Request, Response, params, status
from fastapi.routing import APIRoute

from inertia_id.checks import loads_unique_keys

from .deps import quoted

__all__ = ["UniqueKeysRoute", "content_codings", "refuse_json_charset"]


def content_codings(request: Request) -> list[str]:
    """The body's content codings (``Content-Encoding``, every header, lower case),
    ``identity`` left out."""
    codings = [
        coding.strip().lower()
        for header in request.headers.getlist("content-encoding")
        for coding in header.split(",")
    ]
    return [c for c in codings if c not in ("", "identity")]


class _UniqueKeysRequest(Request):
    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            codings = content_codings(self)
            if codings:
                # The header was ignored: a gzip body was "not acceptable JSON: 'utf-8'
                # codec can't decode byte 0x8b", and a plain one labelled gzip or br was
                # stored. Only /identify and /identify/partial read gzip (their own body).
                raise HTTPException(
                    status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
                    detail=f"Content-Encoding {quoted(', '.join(codings))} is not supported "
                    "on this route: send the JSON body as is (only POST /identify and "
                    "/identify/partial read a gzip body)",
                )
            self._json = loads_unique_keys(await self.body())
        return self._json


def refuse_json_charset(content_type: str) -> None:
    """A 415 naming the charset when a JSON body's ``Content-Type`` states one other than
    UTF-8 (``utf-8``, ``UTF8``: any of Python's names for it) or ASCII (``us-ascii``,
    ``ascii``), which is a subset of UTF-8: an ASCII body read as UTF-8 is read as sent.

    JSON exchanged between systems MUST be UTF-8 (RFC 8259, 8.1), and the body is read as
    UTF-8 whatever the header says: ``application/json; charset=latin-1`` was accepted,
    and its ``Ã©`` stored as ``é`` (a byte outside UTF-8 was a 422 about the 'utf-8'
    codec that named neither the header nor the fix). Refused rather than decoded as
    stated: the other routes of the same client, the CLI's files and the stored documents
    are UTF-8 only, and a charset is no parameter of application/json (RFC 8259, 11).
    """
    message = Message()
    message["content-type"] = content_type
    charset = message.get_content_charset()
    if charset is None:
        return
    try:
        readable = codecs.lookup(charset).name in ("utf-8", "ascii")
    except LookupError:
        readable = False
    if not readable:
        raise HTTPException(
            status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
            detail=f"charset {charset[:40]!r} is not supported: a JSON body is read as UTF-8 "
            "(RFC 8259: JSON exchanged between systems must be UTF-8); send it encoded in "
            "UTF-8, as application/json or application/json; charset=utf-8",
        )


def _is_json(content_type: str) -> bool:
    message = Message()
    message["content-type"] = content_type
    subtype = message.get_content_subtype()
    return message.get_content_maintype() == "application" and (
        subtype == "json" or subtype.endswith("+json")
    )


class UniqueKeysRoute(APIRoute):
    """An API route whose JSON body may not give a key twice in one object, and whose
    JSON body sent as another media type is a 415 naming it: FastAPI handed such a body
    to the model as bytes, and ``curl -d '{"preset": "paper"}'`` (curl's default type,
    application/x-www-form-urlencoded) was a 422 "Input should be a valid dictionary or
    object to extract fields from" that named neither the header nor the fix."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        takes_json = self.body_field is not None and not isinstance(
            self.body_field.field_info, params.Form
        )

        async def unique_keys_handler(request: Request) -> Response:
            request = _UniqueKeysRequest(request.scope, request.receive)
            content_type = request.headers.get("content-type")
            if takes_json and not (content_type and _is_json(content_type)):
                if await request.body():
                    sent = f"not {quoted(content_type)}" if content_type else "with no type"
                    raise HTTPException(
                        status.HTTP_415_UNSUPPORTED_MEDIA_TYPE,
                        detail=f"send the JSON body as application/json, {sent} (curl -d "
                        "sends application/x-www-form-urlencoded: add -H 'Content-Type: "
                        "application/json')",
                    )
            if takes_json and content_type:
                refuse_json_charset(content_type)
            return await handler(request)

        return unique_keys_handler
