"""A request cut off by the server's shutdown is answered 503, not logged as a crash.

When uvicorn stops it gives the requests in flight their grace (``timeout_graceful_shutdown``,
:data:`app.serve.API_GRACE_S` under ``inertia-id serve``), then cancels the task of each
one left: a slow upload half sent at SIGTERM, say. The cancellation came out of the app
as an exception, so uvicorn logged "Exception in ASGI application" with a traceback and
answered "500 Internal Server Error", as for a bug, on an ordinary stop. :class:`StopCut`
answers such a request 503 instead (the service is stopping: ``Connection: close`` and
``Retry-After``), and logs nothing more than uvicorn's own line about the tasks it cancelled.
"""

from __future__ import annotations

import asyncio
import json

from starlette.types import ASGIApp, Receive, Scope, Send

from .watched_send import WatchedSend

__all__ = ["RETRY_AFTER_S", "StopCut"]

#: Seconds a client cut off by the shutdown is told to wait before trying again (a
#: restart: ``docker compose up``, systemd's ``Restart=``).
RETRY_AFTER_S = 5

_DETAIL = (
    "the service is stopping and this request did not finish within its shutdown grace; "
    "nothing was done with it: send it again"
)


class StopCut:
    """Answer 503 to a request whose task the server cancels (its shutdown grace ran
    out), rather than letting the cancellation out to the server as an error.

    Only a cancellation of the request's own task from outside (``Task.cancelling()``:
    uvicorn's shutdown) is taken; one the app raises inside itself goes on out. Once the
    response has started there is nothing to answer: the request ends and uvicorn closes
    the connection."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        watched = WatchedSend(send)
        try:
            await self.app(scope, receive, watched.send)
        except asyncio.CancelledError:
            task = asyncio.current_task()
            if task is None or task.cancelling() == 0:
                raise
            # The server's cancel, taken here: the task ends without an error.
            task.uncancel()
            if watched.started:
                return
            body = json.dumps({"detail": _DETAIL}).encode()
            await send(
                {
                    "type": "http.response.start",
                    "status": 503,
                    "headers": [
                        (b"content-type", b"application/json"),
                        (b"content-length", str(len(body)).encode()),
                        (b"connection", b"close"),
                        (b"retry-after", str(RETRY_AFTER_S).encode()),
                    ],
                }
            )
            await send({"type": "http.response.body", "body": body, "more_body": False})
