"""Deadlines on reading a request, so that slow clients (slowloris) cannot hold connections.

uvicorn (0.55) has no timeout on receiving a request. ``timeout_keep_alive`` closes a
connection left idle *between* requests, and any byte received cancels it; a new
connection has no timer at all. A client that connects and sends nothing, or sends its
request head (or its body) a byte every few seconds, held its connection, a file
descriptor and a little memory, for as long as it liked: 15,000 of them held 15,000 fds
of the API process (``bench/slow_clients.py``), and at a soft limit of 1,024 open files
a thousand of them locked every other client out. The option was proposed upstream
(``--timeout-request-start``, https://github.com/Kludex/uvicorn/issues/157) and its pull
request closed unmerged (https://github.com/Kludex/uvicorn/pull/1685), so the protocol
classes here add it to uvicorn's own (``Config(http=...)`` takes a class):

- **head**: a connection's request head must be complete within
  ``request_head_timeout_s`` of the connection's start, or of the previous response on
  a kept-alive connection, whatever the client trickles meanwhile;
- **body**: while a request's body is being read, each ``request_body_timeout_s`` must
  bring at least :data:`BODY_PROGRESS_BYTES` of it (or its end): a slow but steady
  upload is never cut, a byte every few seconds is. The clock stops while uvicorn itself
  has paused reading (the application has not yet taken the body it has): the client
  cannot send then, and is not the slow one.

A connection past either deadline is closed (nothing sent: a 408 on an idle kept-alive
connection may be read by the client as the answer to the request it is sending just
then). A request whose body is cut short sees ``http.disconnect``, as when a client goes
away. Nothing changes once a request has been received: a slow computation or a slow
reader of the response is not timed here.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any, Literal

import uvicorn
from uvicorn.config import HTTPProtocolType
from uvicorn.protocols.http.flow_control import FlowControl
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
from uvicorn.server import ServerState

from service.config import get_settings

__all__ = ["H11WithDeadlines", "HttpToolsWithDeadlines", "ServerConfig", "protocol_class"]

logger = logging.getLogger("uvicorn.error")

#: A request body must bring this much more (or end) within each
#: ``request_body_timeout_s``: a byte every few seconds does not keep a connection.
BODY_PROGRESS_BYTES = 1024


class ServerConfig(uvicorn.Config):
    """uvicorn's ``Config`` with the two read deadlines and the protocol that keeps them.

    A class of its own (not attributes set on a ``Config``) so that it travels whole to
    the API processes of ``--api-workers`` > 1, which receive the config pickled.

    :param request_head_timeout_s: longest wait for a complete request head, from the
        connection's start or the previous response (s).
    :param request_body_timeout_s: longest a request body being read may take to bring
        :data:`BODY_PROGRESS_BYTES` more, or its end (s).
    :param http: which of uvicorn's HTTP implementations to extend: ``auto`` (httptools,
        as uvicorn picks it when installed), ``httptools`` or ``h11``.
    """

    def __init__(
        self,
        app: Any,
        *,
        request_head_timeout_s: float,
        request_body_timeout_s: float,
        http: Literal["auto", "h11", "httptools"] = "auto",
        **options: Any,
    ) -> None:
        for name, value in (
            ("request_head_timeout_s", request_head_timeout_s),
            ("request_body_timeout_s", request_body_timeout_s),
        ):
            if not value > 0:
                raise ValueError(f"{name} must be > 0 s, got {value!r}")
        super().__init__(app, http=protocol_class(http), **options)
        self.request_head_timeout_s = float(request_head_timeout_s)
        self.request_body_timeout_s = float(request_body_timeout_s)


class _ResumableFlow(FlowControl):
    """uvicorn's flow control, telling the deadlines when reading resumes."""

    def __init__(self, transport: asyncio.Transport, on_resume: Callable[[], None]) -> None:
        super().__init__(transport)
        self._on_resume = on_resume

    def resume_reading(self) -> None:
        paused = self.read_paused
        super().resume_reading()
        if paused:
            self._on_resume()


def _body_expected(cycle: Any) -> bool:
    """Whether the request ``cycle`` still waits for body data."""
    return cycle is not None and bool(cycle.more_body) and not cycle.response_complete


class _Deadlines:
    """The read deadline of one connection: one timer, for the head or for the body.

    :param protocol: the connection's uvicorn protocol (httptools or h11); read here for
        its ``transport``, ``flow`` and current request ``cycle`` (both implementations
        name them alike, and mark a body still to come with ``cycle.more_body``).
    """

    def __init__(self, protocol: Any, config: uvicorn.Config) -> None:
        self._protocol = protocol
        self._head_s, self._body_s = _timeouts(config)
        self._waiting_for: Literal["head", "body"] | None = None
        self._timer: asyncio.TimerHandle | None = None
        #: Body bytes received since the body's clock last started.
        self._progress = 0

    def connected(self) -> None:
        protocol = self._protocol
        protocol.flow = _ResumableFlow(protocol.transport, self._resumed)
        self._await_head()

    def received(self, cycle_before: object, size: int) -> None:
        """After the protocol parsed ``size`` bytes; ``cycle_before``: its request cycle
        before them."""
        protocol = self._protocol
        if protocol.transport.is_closing() or protocol.transport.get_protocol() is not protocol:
            # Closed (a 400), or handed over to a WebSocket protocol.
            self.stop()
            return
        same_request = protocol.cycle is cycle_before
        if self._waiting_for == "head" and same_request:
            return  # the head is not complete yet: its deadline stands
        if self._waiting_for == "body" and same_request and self._timer is not None:
            self._progress += size
            if self._progress < BODY_PROGRESS_BYTES and _body_expected(protocol.cycle):
                return  # too little to reset the clock (a byte every few seconds)
        self._await_body()

    def answered(self) -> None:
        """After a response was sent in full."""
        protocol = self._protocol
        if protocol.transport.is_closing():
            self.stop()
        elif protocol.cycle is not None and not protocol.cycle.response_complete:
            self._await_body()  # a pipelined request, its head already received, started
        else:
            self._await_head()

    def stop(self) -> None:
        self._waiting_for = None
        self._cancel()

    def _await_head(self) -> None:
        self._waiting_for = "head"
        self._arm(self._head_s)

    def _await_body(self) -> None:
        if not _body_expected(self._protocol.cycle):
            self.stop()  # the body is in, or no longer wanted
            return
        self._waiting_for = "body"
        self._progress = 0
        if self._protocol.flow.read_paused:
            self._cancel()  # uvicorn is not reading: _resumed starts the clock again
        else:
            self._arm(self._body_s)

    def _resumed(self) -> None:
        if self._waiting_for == "body":
            self._await_body()

    def _arm(self, delay_s: float) -> None:
        self._cancel()
        self._timer = self._protocol.loop.call_later(delay_s, self._expired)

    def _cancel(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None

    def _expired(self) -> None:
        self._timer = None
        protocol = self._protocol
        if protocol.transport.is_closing():
            return
        if self._waiting_for == "head":
            why = f"no complete request head within {self._head_s:g} s"
        else:
            why = (
                f"its request body brought less than {BODY_PROGRESS_BYTES} bytes in "
                f"{self._body_s:g} s"
            )
        client = protocol.client
        peer = f"{client[0]}:{client[1]}" if client else "a client"
        logger.info("closed the connection from %s: %s", peer, why)
        self._waiting_for = None
        protocol.transport.close()


class _WithDeadlines:
    """The read deadlines of :class:`ServerConfig` on one of uvicorn's HTTP protocols:
    mixed in before it (``class X(_WithDeadlines, H11Protocol)``), each hook calls the
    protocol's own and then tells the connection's :class:`_Deadlines`."""

    cycle: Any

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)  # type: ignore[call-arg]
        self.deadlines = _Deadlines(self, config)

    def connection_made(self, transport: asyncio.Transport) -> None:
        super().connection_made(transport)  # type: ignore[misc]
        self.deadlines.connected()

    def data_received(self, data: bytes) -> None:
        cycle = self.cycle
        super().data_received(data)  # type: ignore[misc]
        self.deadlines.received(cycle, len(data))

    def on_response_complete(self) -> None:
        super().on_response_complete()  # type: ignore[misc]
        self.deadlines.answered()

    def connection_lost(self, exc: Exception | None) -> None:
        self.deadlines.stop()
        super().connection_lost(exc)  # type: ignore[misc]


# (uvicorn types connection_made's transport narrower than asyncio's BaseProtocol does.)
class H11WithDeadlines(_WithDeadlines, H11Protocol):  # type: ignore[misc]
    """uvicorn's h11 protocol with the read deadlines of :class:`ServerConfig`."""


class HttpToolsWithDeadlines(_WithDeadlines, HttpToolsProtocol):  # type: ignore[misc]
    """uvicorn's httptools protocol with the read deadlines of :class:`ServerConfig`."""


def _timeouts(config: uvicorn.Config) -> tuple[float, float]:
    """The head and body timeouts (s): a :class:`ServerConfig`'s, else the settings'
    (``INERTIA_ID_REQUEST_HEAD_TIMEOUT_S``, ``INERTIA_ID_REQUEST_BODY_TIMEOUT_S``), for
    uvicorn's own command line: ``uvicorn --http app.request_deadlines:HttpToolsWithDeadlines``."""
    if isinstance(config, ServerConfig):
        return config.request_head_timeout_s, config.request_body_timeout_s
    settings = get_settings()
    return settings.request_head_timeout_s, settings.request_body_timeout_s


def protocol_class(http: HTTPProtocolType | str = "auto") -> type[asyncio.Protocol]:
    """The HTTP protocol with read deadlines over uvicorn's ``http`` implementation
    (``auto``: httptools, a dependency of this project, as uvicorn picks it)."""
    if http == "h11":
        return H11WithDeadlines
    if http in ("auto", "httptools"):
        return HttpToolsWithDeadlines
    raise ValueError(f"http must be auto, h11 or httptools, got {http!r}")
