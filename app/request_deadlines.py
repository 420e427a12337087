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

The request head has limits too, which uvicorn lacks: httptools (llhttp) takes any
number of header fields of any size, and h11 refuses only a head still incomplete past
``h11_max_incomplete_event_size`` (16 KiB; a larger head that arrives in one read is
taken whole, and the refusal is a 400). Measured (``bench/header_limits.py``): 10,000
header fields, or one of 16 MB sent at once, were answered 200 by httptools, ten such
16 MB heads at once adding 181 MB to the API process. Here a head with more than
``request_header_max_count`` fields, or more than ``request_header_max_bytes`` bytes (its
target and header fields), is answered **431** (Request Header Fields Too Large, RFC
6585), and a request target (URL) alone longer than ``request_header_max_bytes`` is
answered **414** (URI Too Long, RFC 9110 15.5.15), with a body naming the limit, and the
connection closed; no part of the app sees it. One limit on bytes, not one for the
target and another for the fields: it bounds the memory a head holds, of which the
target is part (a second setting would be a second knob on the same memory).

A head still arriving is counted by the bytes received for it (besides the method,
version and line ends, at most :data:`REQUEST_LINE_FRAMING` bytes, which a complete head
is not charged), a head that began after another request in the same read included, and
a complete head that came in one read is held to the same bound (h11 takes a method of
any length): memory held for a head stays within the limit, :data:`REQUEST_LINE_FRAMING`
and the :data:`HEAD_FEED_BYTES` it may take to see it past them, where it once was the
limit and a whole read of the socket (about 256 KB, uncounted). The refusal is the one
line logged for the request (not uvicorn's "Invalid HTTP request received." besides,
which stays for heads its parser refuses).

A request asking for a protocol upgrade that is not made (no WebSocket here) is answered
as any other, and the connection goes on in HTTP/1.1 (RFC 9110 7.8): a request pipelined
after it is answered too (uvicorn dropped the rest of the read). On httptools, one that
also has a body, which llhttp does not read after such a head (the app was handed the
request without it), is refused: a 400 naming it, and the connection closed.
"""

from __future__ import annotations

import asyncio
import atexit
import contextlib
import ctypes
import json
import logging
import os
import re
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import Any, Literal, NamedTuple

import h11
import httptools
import uvicorn
from uvicorn.config import HTTPProtocolType
from uvicorn.protocols.http.flow_control import FlowControl
from uvicorn.protocols.http.h11_impl import H11Protocol
from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol
from uvicorn.server import ServerState

from service.config import get_settings

__all__ = [
    "H11WithDeadlines",
    "HeadLimits",
    "HttpToolsWithDeadlines",
    "ServerConfig",
    "protocol_class",
]

logger = logging.getLogger("uvicorn.error")

#: A request body must bring this much more (or end) within each
#: ``request_body_timeout_s``: a byte every few seconds does not keep a connection.
BODY_PROGRESS_BYTES = 1024

#: Bytes a request head has besides its target and header fields (as
#: :attr:`HeadLimits.max_bytes` counts them): the method (13 bytes at most in llhttp's
#: list, ``GET_PARAMETER``), two spaces, ``HTTP/1.1`` and two line ends make at most 27;
#: 64 leaves room for optional whitespace. A head still arriving, counted by the bytes
#: received, is refused past ``max_bytes`` and this, so that a head within the limit is
#: never refused for arriving in pieces.
REQUEST_LINE_FRAMING = 64

#: Most bytes of one read handed to llhttp at once where a request head may begin in
#: them (not in a request body of known length), so that a head still arriving is
#: counted every this many bytes.
HEAD_FEED_BYTES = 4096


class ServerConfig(uvicorn.Config):
    """uvicorn's ``Config`` with the two read deadlines, the limits on a request head and
    the protocol that keeps them.

    A class of its own (not attributes set on a ``Config``) so that it travels whole to
    the API processes of ``--api-workers`` > 1, which receive the config pickled.

    :param request_head_timeout_s: longest wait for a complete request head, from the
        connection's start or the previous response (s).
    :param request_body_timeout_s: longest a request body being read may take to bring
        :data:`BODY_PROGRESS_BYTES` more, or its end (s).
    :param request_header_max_count: most header fields a request head may have (None:
        the settings', ``INERTIA_ID_REQUEST_HEADER_MAX_COUNT``).
    :param request_header_max_bytes: most bytes a request head may have, its target and
        header fields (None: the settings', ``INERTIA_ID_REQUEST_HEADER_MAX_BYTES``).
    :param http: which of uvicorn's HTTP implementations to extend: ``auto`` (httptools,
        as uvicorn picks it when installed), ``httptools`` or ``h11``.
    """

    def __init__(
        self,
        app: Any,
        *,
        request_head_timeout_s: float,
        request_body_timeout_s: float,
        request_header_max_count: int | None = None,
        request_header_max_bytes: int | None = None,
        http: Literal["auto", "h11", "httptools"] = "auto",
        stop_with: int | None = None,
        **options: Any,
    ) -> None:
        for name, value in (
            ("request_head_timeout_s", request_head_timeout_s),
            ("request_body_timeout_s", request_body_timeout_s),
        ):
            if not value > 0:
                raise ValueError(f"{name} must be > 0 s, got {value!r}")
        if request_header_max_count is None:
            request_header_max_count = get_settings().request_header_max_count
        if request_header_max_bytes is None:
            request_header_max_bytes = get_settings().request_header_max_bytes
        self.header_limits = HeadLimits(request_header_max_count, request_header_max_bytes)
        super().__init__(app, http=protocol_class(http), **options)
        self.request_head_timeout_s = float(request_head_timeout_s)
        self.request_body_timeout_s = float(request_body_timeout_s)
        #: The pid of the process (``inertia-id serve``) whose API processes load this
        #: config: each is sent SIGTERM by the kernel when that process dies.
        self.stop_with = stop_with

    def load(self) -> None:
        if self.stop_with is not None and not self.loaded and os.getpid() != self.stop_with:
            # In an API process of --api-workers > 1 (loaded there, not in serve): after
            # serve's kill -9 they served on, holding its port, for ever (ppid 1).
            _stop_when_parent_dies(self.stop_with)
        super().load()

    def get_loop_factory(self) -> Callable[[], asyncio.AbstractEventLoop] | None:
        # uvicorn's Server.run asks for the loop just before it takes the stop signals
        # over; loaded in an API process of --api-workers > 1, not in serve.
        if self.stop_with is not None and os.getpid() != self.stop_with:
            _exit_normally_after_sigterm()
        return super().get_loop_factory()


#: ``prctl`` option: the signal this process gets when its parent dies.
_PR_SET_PDEATHSIG = 1


def _stop_when_parent_dies(parent: int) -> None:
    """Ask the kernel for SIGTERM (uvicorn's graceful stop) when the parent dies (Linux;
    nothing elsewhere); if ``parent`` has gone already, SIGTERM now."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGTERM)


def _exit_on_sigterm(signum: int, _frame: FrameType | None) -> None:
    code = 128 + signum
    # Run first of the interpreter's exit handlers, once multiprocessing's end of the
    # process (its finalizers) is done: the interpreter's own teardown of what the API
    # imported (the core, numba, scikit-learn) took 1.5-2 s more of each stop, which the
    # signal's default action skipped before.
    atexit.register(_exit_now, code)
    raise SystemExit(code)


def _exit_now(code: int) -> None:
    from multiprocessing import util

    # Run already by the end of a process multiprocessing started (a no-op then).
    end = getattr(util, "_exit_function", None)
    if end is not None:
        end()
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            if stream is not None:
                stream.flush()
    os._exit(code)


def _exit_normally_after_sigterm() -> None:
    """In an API process of serve's (its main thread, before uvicorn's server runs):
    SIGTERM raises SystemExit (128 + 15), so that the SIGTERM uvicorn raises again once
    its graceful shutdown is done ends the process through its normal exit rather than
    the signal's default action. uvicorn takes the signal over while it serves and puts
    this handler back after. multiprocessing's finalizers then run: its temp folder
    (``pymp-*`` in TMPDIR, the fork server's socket in it) is removed. Killed by the
    signal, each API process left that folder behind at every stop."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _exit_on_sigterm)


#: The reason phrases of a refused head's answer (400: an upgrade request with a body, on
#: httptools): RFC 9110's (Python 3.11's ``http`` still has RFC 2616's "Request-URI Too
#: Long" for 414).
_REASONS = {
    400: b"Bad Request",
    414: b"URI Too Long",
    431: b"Request Header Fields Too Large",
}


class HeadRefusal(NamedTuple):
    """Why a request head is refused, and the status that says it."""

    #: 414 (the request target is too long) or 431 (the head is).
    status: int
    #: The answer's ``detail``, naming the setting whose limit the head passed.
    why: str


class HeadLimits:
    """The limits on one request head: ``max_count`` header fields, ``max_bytes`` bytes
    (the request target and each field's name and value, and 4 for its ``": "`` and
    CRLF). A target alone over ``max_bytes`` is refused as too long (414), a head past
    either limit otherwise as too large (431)."""

    def __init__(self, max_count: int, max_bytes: int) -> None:
        if not (isinstance(max_count, int) and max_count >= 1):
            raise ValueError(f"request_header_max_count must be >= 1, got {max_count!r}")
        if not (isinstance(max_bytes, int) and max_bytes >= 1):
            raise ValueError(f"request_header_max_bytes must be >= 1, got {max_bytes!r}")
        self.max_count = max_count
        self.max_bytes = max_bytes

    def too_many_bytes(self) -> HeadRefusal:
        return HeadRefusal(
            431,
            f"the request head is over {self.max_bytes} bytes (the limit: "
            f"INERTIA_ID_REQUEST_HEADER_MAX_BYTES={self.max_bytes})",
        )

    def target_too_long(self) -> HeadRefusal:
        return HeadRefusal(
            414,
            f"the request target (URL) is over {self.max_bytes} bytes (the limit on a "
            f"request head: INERTIA_ID_REQUEST_HEADER_MAX_BYTES={self.max_bytes})",
        )

    def target_exceeded(self, size: int) -> HeadRefusal | None:
        """Why a request target of ``size`` bytes is refused (None: it is not)."""
        return self.target_too_long() if size > self.max_bytes else None

    def exceeded(self, count: int, size: int) -> HeadRefusal | None:
        """Why a head of ``count`` fields and ``size`` bytes is refused (None: it is not)."""
        if count > self.max_count:
            return HeadRefusal(
                431,
                f"the request head has more than {self.max_count} header fields (the limit: "
                f"INERTIA_ID_REQUEST_HEADER_MAX_COUNT={self.max_count})",
            )
        if size > self.max_bytes:
            return self.too_many_bytes()
        return None

    def received_exceeded(self, received: int) -> HeadRefusal | None:
        """Why a head still arriving, ``received`` bytes of it so far, is refused (None:
        it is not)."""
        if received > self.max_bytes + REQUEST_LINE_FRAMING:
            return self.too_many_bytes()
        return None


def field_bytes(name: bytes, value: bytes) -> int:
    """What one header field counts towards :attr:`HeadLimits.max_bytes`."""
    return len(name) + len(value) + 4


class _HeadTooLarge(Exception):
    """Raised in a parser callback to stop parsing a head past its limits."""


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
    """The read deadlines and head limits of :class:`ServerConfig` on one of uvicorn's
    HTTP protocols: mixed in before it (``class X(_WithDeadlines, H11Protocol)``), each
    hook calls the protocol's own and then tells the connection's :class:`_Deadlines`."""

    cycle: Any
    transport: asyncio.Transport
    client: tuple[str, int] | None
    server_state: ServerState

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)  # type: ignore[call-arg]
        self.deadlines = _Deadlines(self, config)
        self.head_limits = _head_limits(config)
        #: Why the current request head was refused (None: it was not).
        self.head_refused: HeadRefusal | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:
        super().connection_made(transport)  # type: ignore[misc]
        self.deadlines.connected()

    def data_received(self, data: bytes) -> None:
        cycle = self.cycle
        self.parse(data)
        self.deadlines.received(cycle, len(data))

    def parse(self, data: bytes) -> None:
        """Hand ``data`` to the parser: the protocol's own ``data_received``."""
        super().data_received(data)  # type: ignore[misc]

    def on_response_complete(self) -> None:
        super().on_response_complete()  # type: ignore[misc]
        self.deadlines.answered()

    def connection_lost(self, exc: Exception | None) -> None:
        self.deadlines.stop()
        super().connection_lost(exc)  # type: ignore[misc]

    def refuse_head(self, refusal: HeadRefusal) -> None:
        """Answer ``refusal`` (its status; the body, as the API's errors: ``{"detail":
        why}``), log it, the one line for this request, and close the connection."""
        self.head_refused = refusal
        self.deadlines.stop()
        if self.transport.is_closing():
            return
        peer = f"{self.client[0]}:{self.client[1]}" if self.client else "a client"
        logger.warning("answered %d to %s: %s", refusal.status, peer, refusal.why)
        body = json.dumps({"detail": refusal.why}).encode()
        head = [b"HTTP/1.1 %d %s\r\n" % (refusal.status, _REASONS[refusal.status])]
        for name, value in self.server_state.default_headers:
            head.append(name + b": " + value + b"\r\n")
        head.append(b"content-type: application/json\r\n")
        head.append(b"content-length: %d\r\nconnection: close\r\n\r\n" % len(body))
        self.transport.write(b"".join(head) + body)
        self.transport.close()


# (uvicorn types connection_made's transport narrower than asyncio's BaseProtocol does.)
class H11WithDeadlines(_WithDeadlines, H11Protocol):  # type: ignore[misc]
    """uvicorn's h11 protocol with the read deadlines and head limits of
    :class:`ServerConfig`.

    h11 refuses a head still incomplete past its ``max_incomplete_event_size``: set here
    to the byte limit and :data:`REQUEST_LINE_FRAMING` (whatever
    ``h11_max_incomplete_event_size`` says), its refusal becomes a 414 (the request
    target is what runs on) or a 431; a complete head (one that came in one read) is
    checked as parsed, and by its bytes as received."""

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)
        self.conn = _LimitedH11Connection(self)


class _LimitedH11Connection(h11.Connection):
    """h11's server side, refusing heads past the limits of ``protocol``.

    A refused head is answered here, and ``NEED_DATA`` returned (uvicorn's
    ``handle_events`` stops on it), not raised: uvicorn would log its generic "Invalid
    HTTP request received." for it besides our line, and answer a 400.

    A complete head is also held to the bound on a head still arriving (its bytes as
    received, past ``max_bytes`` and :data:`REQUEST_LINE_FRAMING`): h11 takes a method of
    any length and any amount of whitespace around a value, which the target and the
    fields it hands over do not show (a 100 KB method in one read reached the app, a 405;
    40 KB of spaces before a value, a 200). Its bytes are what left h11's receive buffer
    for it, seen through the public ``trailing_data`` (a copy: taken once as a head
    begins, and once as it is parsed; the bytes received in between are added up here).
    """

    def __init__(self, protocol: H11WithDeadlines) -> None:
        super().__init__(
            h11.SERVER,
            max_incomplete_event_size=protocol.head_limits.max_bytes + REQUEST_LINE_FRAMING,
        )
        self._protocol = protocol
        #: Bytes in h11's receive buffer while it waits for a request head (None: not
        #: waiting for one, or not counted yet).
        self._buffered_for_head: int | None = None

    def receive_data(self, data: bytes) -> None:
        super().receive_data(data)
        if self._buffered_for_head is not None:
            self._buffered_for_head += len(data)

    def next_event(self) -> Any:
        limits = self._protocol.head_limits
        in_head = self.their_state is h11.IDLE
        if in_head and self._buffered_for_head is None:
            self._buffered_for_head = len(self.trailing_data[0])
        try:
            event = super().next_event()
        except h11.RemoteProtocolError as exc:
            if not (in_head and exc.error_status_hint == 431):
                raise
            # h11's "Receive buffer too long": the head so far is what is too long.
            self._buffered_for_head = None
            self._protocol.refuse_head(_unfinished_head_refusal(limits, self.trailing_data[0]))
            return h11.NEED_DATA
        if isinstance(event, h11.Request):
            received = (self._buffered_for_head or 0) - len(self.trailing_data[0])
            self._buffered_for_head = None
            size = len(event.target) + sum(field_bytes(n, v) for n, v in event.headers)
            refusal = (
                limits.target_exceeded(len(event.target))
                or limits.exceeded(len(event.headers), size)
                or limits.received_exceeded(received)
            )
            if refusal is not None:
                self._protocol.refuse_head(refusal)
                return h11.NEED_DATA
        return event


def _unfinished_head_refusal(limits: HeadLimits, received: bytes) -> HeadRefusal:
    """Why an unfinished head, ``received`` so far, past the bytes allowed is refused: a
    414 while its request target is what runs on (the method ended with a space, the
    target has not), a 431 otherwise (a line end came, or the method runs on: h11 takes
    one of any length, and a 30 KB method was answered "the request target is over")."""
    _method, space, rest = received.partition(b" ")
    if space and b"\n" not in received and b" " not in rest:
        return limits.target_too_long()
    return limits.too_many_bytes()


class HttpToolsWithDeadlines(_WithDeadlines, HttpToolsProtocol):  # type: ignore[misc]
    """uvicorn's httptools protocol with the read deadlines and head limits of
    :class:`ServerConfig`.

    llhttp has no limit of its own. The target and each field are counted as the parser
    hands them over (a callback raising stops the parser); a field still arriving, which
    httptools keeps to itself until it is whole, is counted by the bytes received while
    its head is open. A read is handed to the parser in pieces of at most
    :data:`HEAD_FEED_BYTES` where a head may begin in it, each ending at the end of a
    head where one ends in it (a request body of known length goes whole, from the piece
    after its head), so that the bytes of a head are known: all of a piece that began
    between requests and ends inside one head, or began and ended inside it, and for a
    head that begins after a chunked body inside one piece, what follows that body's last
    blank line (:func:`_after_last_blank_line`).

    The parser is fed here, not by uvicorn's ``data_received`` (which feeds a read
    whole), its errors handled as uvicorn handles them but for a head past the limits:
    answered 414 or 431 with one line logged."""

    def __init__(
        self,
        config: uvicorn.Config,
        server_state: ServerState,
        app_state: dict[str, Any],
        _loop: asyncio.AbstractEventLoop | None = None,
    ) -> None:
        super().__init__(config, server_state, app_state, _loop)
        #: Heads begun on this connection; whether the last one is still open; whether
        #: a request is being parsed (its head or its body).
        self._heads = 0
        self._head_open = False
        self._in_message = False
        #: The current head's fields and bytes as parsed, and the bytes received for it.
        self._head_count = 0
        self._head_bytes = 0
        self._head_received = 0
        #: Bytes of the current request's body still to come, where its length is known.
        self._body_left: int | None = None
        #: A refusal waiting for the answers to the requests pipelined before its head.
        self._refusal_waits: HeadRefusal | None = None
        #: The last (up to 3) bytes handed to the parser: a blank line may begin in them.
        self._fed_tail = b""

    def refuse_head(self, refusal: HeadRefusal) -> None:
        """Answer ``refusal`` now, or, where requests pipelined before the refused head
        are still being answered, after them: answers go out in the order of their
        requests (RFC 9112 9.3.2), and the close that follows the refusal would cut them
        off. (h11 parses no head before the request ahead of it is answered.)"""
        cycle = self.cycle
        if cycle is not None and not cycle.response_complete and not self.transport.is_closing():
            self.head_refused = self._refusal_waits = refusal
            self.deadlines.stop()
            return
        super().refuse_head(refusal)

    def on_response_complete(self) -> None:
        super().on_response_complete()
        refusal = self._refusal_waits
        if refusal is not None and (self.cycle is None or self.cycle.response_complete):
            self._refusal_waits = None
            super().refuse_head(refusal)

    def parse(self, data: bytes) -> None:
        if self._refusal_waits is not None:
            return  # past a refused head: nothing more is parsed (its answer waits)
        self._unset_keepalive_if_required()
        view = memoryview(data)
        start = 0
        while start < len(view):
            piece = view[start : start + self._piece_bytes(data, start)]
            start += len(piece)
            heads, was_open, was_idle = self._heads, self._head_open, not self._in_message
            try:
                self.parser.feed_data(piece)
            except httptools.HttpParserUpgrade as upgrade:
                if self._should_upgrade():
                    self.handle_websocket_upgrade()
                    return
                self._unsupported_upgrade_warning()
                # Not upgraded, the connection goes on in HTTP/1.1 (RFC 9110 7.8), and
                # httptools parses on after the request: from where it stopped (uvicorn
                # dropped the rest of the read, a request pipelined after it unanswered).
                start += upgrade.args[0] - len(piece)
                self._fed_tail = _last_bytes(self._fed_tail, piece[: upgrade.args[0]])
                continue
            except httptools.HttpParserError:
                if self.head_refused is not None:
                    self.refuse_head(self.head_refused)
                else:
                    msg = "Invalid HTTP request received."
                    self.logger.warning(msg)
                    self.send_400_response(msg)
                return
            before, self._fed_tail = self._fed_tail, _last_bytes(self._fed_tail, piece)
            if not self._head_open:
                continue
            if self._heads == heads and was_open:
                self._head_received += len(piece)  # all of it inside the head
            elif self._heads == heads + 1 and was_idle:
                self._head_received = len(piece)  # the head began it (blank lines aside)
            else:
                # The head began after the end of another request inside this piece.
                self._head_received = _after_last_blank_line(before, piece)
            refusal = self.head_limits.received_exceeded(self._head_received)
            if refusal is not None:
                self.refuse_head(refusal)
                return

    def _piece_bytes(self, data: bytes, start: int) -> int:
        """How much of ``data`` from ``start`` on to hand the parser next: the rest of a
        request body of known length (no head can begin in it); where a head may be open
        or begin, up to the end of the first blank line within :data:`HEAD_FEED_BYTES`
        (the end of a head), so that what follows a head (a body of known length, or the
        next head) begins a piece of its own; else :data:`HEAD_FEED_BYTES` (a chunked
        body, whose end is a blank line that :func:`_after_last_blank_line` finds).

        (A piece that went on past a head into its body of known length and the head
        after it charged that head the body too: a head within the limit, pipelined after
        a POST of 4,030 bytes in one send, was refused 431.)"""
        if self._in_message and not self._head_open:
            return self._body_left or HEAD_FEED_BYTES
        stop = start + HEAD_FEED_BYTES
        if self._head_open:
            # Its blank line may begin in the bytes already fed (at most 3 of it).
            tail = len(self._fed_tail)
            end = (self._fed_tail + data[start : start + 3]).find(b"\r\n\r\n")
            if end >= 0:
                return end + 4 - tail
            begin = start
        else:
            # The line ends llhttp skips before a request, as many as come, are no head:
            # a piece cut at each blank line of them (a piece of 2 bytes for each CRLF)
            # took 8 s of the event loop for 5 MB of CRLFs, where 4 KiB pieces take 0.01 s.
            begin = start
            if data[start] in b"\r\n":
                if not data[start:stop].translate(None, b"\r\n"):
                    return HEAD_FEED_BYTES  # line ends only (translate: the fast test)
                first = _NOT_LINE_END.search(data, start, stop)
                begin = first.start() if first is not None else stop
        end = data.find(b"\r\n\r\n", begin, stop)
        return HEAD_FEED_BYTES if end < 0 else end + 4 - start

    def on_message_begin(self) -> None:
        super().on_message_begin()
        self._heads += 1
        self._head_open = self._in_message = True
        self._head_count = self._head_bytes = self._head_received = 0
        self._body_left = None
        self.head_refused = None

    def on_url(self, url: bytes) -> None:
        super().on_url(url)
        self._head_bytes += len(url)
        self._refuse(self.head_limits.target_exceeded(len(self.url)))
        self._refuse(self.head_limits.exceeded(self._head_count, self._head_bytes))

    def on_header(self, name: bytes, value: bytes) -> None:
        super().on_header(name, value)
        self._head_count += 1
        self._head_bytes += field_bytes(name, value)
        self._refuse(self.head_limits.exceeded(self._head_count, self._head_bytes))

    def on_headers_complete(self) -> None:
        self._head_open = False
        # llhttp has checked the framing (one Content-Length, not with Transfer-Encoding).
        lengths = [value for name, value in self.headers if name == b"content-length"]
        chunked = any(name == b"transfer-encoding" for name, _ in self.headers)
        self._body_left = int(lengths[0]) if lengths and not chunked else None
        if (
            self.parser.should_upgrade()
            and not self._should_upgrade()
            and (chunked or self._body_left)
        ):
            # llhttp takes what follows such a head for the other protocol, the body
            # too (the app was handed none): nothing after it could be read as HTTP.
            upgrade = dict(self.headers).get(b"upgrade", b"")[:100].decode("latin-1")
            method = self.parser.get_method().decode("ascii")
            asked = method if method == "CONNECT" else f"Upgrade: {upgrade}"
            why = (
                f"a request with a body cannot ask for a protocol upgrade here ({asked}): "
                "none is made, and its body is not read"
            )
            self._refuse(HeadRefusal(400, why))
        super().on_headers_complete()

    def on_body(self, body: bytes) -> None:
        if self._body_left is not None:
            self._body_left -= len(body)
        super().on_body(body)

    def on_message_complete(self) -> None:
        self._in_message = False
        self._body_left = None
        super().on_message_complete()

    def _refuse(self, refusal: HeadRefusal | None) -> None:
        if refusal is not None:
            self.head_refused = refusal
            raise _HeadTooLarge(refusal.why)


#: Any byte but a line end's.
_NOT_LINE_END = re.compile(rb"[^\r\n]")


def _last_bytes(before: bytes, piece: memoryview) -> bytes:
    """The last 3 bytes of ``before`` followed by ``piece``: where a blank line that ends
    in the next piece may begin."""
    return (before + bytes(piece[-3:]))[-3:]


def _after_last_blank_line(before: bytes, piece: memoryview) -> int:
    """How many bytes of ``piece`` follow the end of its last blank line (``\\r\\n\\r\\n``,
    which may begin in ``before``, the bytes handed to the parser just before it).

    A request that ends inside a piece of the parser's feed (not a head, where a piece
    ends, nor a body of known length, which is fed to its end) ends with a blank line:
    its chunked body's last one, as llhttp requires CRLF line ends. What follows is at
    most 3 bytes of blank lines and the head that began after it, which holds no blank
    line while it is still open: these bytes are the head's share of the piece, and
    llhttp's own place in the piece, which httptools does not tell, is not needed. All of
    ``piece`` where it has no blank line (which the above rules out)."""
    joined = before + bytes(piece)
    end = joined.rfind(b"\r\n\r\n")
    return len(piece) if end < 0 else len(joined) - (end + 4)


def _timeouts(config: uvicorn.Config) -> tuple[float, float]:
    """The head and body timeouts (s): a :class:`ServerConfig`'s, else the settings'
    (``INERTIA_ID_REQUEST_HEAD_TIMEOUT_S``, ``INERTIA_ID_REQUEST_BODY_TIMEOUT_S``), for
    uvicorn's own command line: ``uvicorn --http app.request_deadlines:HttpToolsWithDeadlines``."""
    if isinstance(config, ServerConfig):
        return config.request_head_timeout_s, config.request_body_timeout_s
    settings = get_settings()
    return settings.request_head_timeout_s, settings.request_body_timeout_s


def _head_limits(config: uvicorn.Config) -> HeadLimits:
    """The limits on a request head: a :class:`ServerConfig`'s, else the settings'
    (``INERTIA_ID_REQUEST_HEADER_MAX_COUNT``, ``INERTIA_ID_REQUEST_HEADER_MAX_BYTES``)."""
    if isinstance(config, ServerConfig):
        return config.header_limits
    settings = get_settings()
    return HeadLimits(settings.request_header_max_count, settings.request_header_max_bytes)


def protocol_class(http: HTTPProtocolType | str = "auto") -> type[asyncio.Protocol]:
    """The HTTP protocol with read deadlines over uvicorn's ``http`` implementation
    (``auto``: httptools, a dependency of this project, as uvicorn picks it)."""
    if http == "h11":
        return H11WithDeadlines
    if http in ("auto", "httptools"):
        return HttpToolsWithDeadlines
    raise ValueError(f"http must be auto, h11 or httptools, got {http!r}")
