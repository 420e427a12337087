"""A deadline on PostgreSQL's answers: a statement that gets none is ended from another
thread, by shutting its connection's socket down.

psycopg has no client-side deadline for a statement, and SQLAlchemy none either (its
``pool_timeout`` bounds the wait for a pooled connection, not for an answer). A
server-side one (``statement_timeout``) needs a server that hears the statement and an
answer that comes back. libpq's and the kernel's bounds (``connect_timeout``,
``tcp_user_timeout``, keepalives: see :class:`service.store.session.Database`) do not fire
while something still acknowledges what is sent: a proxy (PgBouncer, socat, a cloud
load balancer) that is frozen or lost its server, the kernel of a stopped server. A
statement there waited for ever, and its thread with it. Shutting the socket down ends
that wait at once, on an error that psycopg and SQLAlchemy take for a lost connection:
the pool discards it, and the server ends the session when it sees the connection end.

- :class:`SocketCut`: one connection's socket, held so that it can be cut later.
- :class:`AnswerDeadline`: every connection of an engine watched; a statement (a pool's
  ping, a query, a commit) unanswered ``answer_s`` after it was sent, and that the server
  does not say it is at work on, has its connection cut.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import socket
import threading
import time
from typing import Any

from sqlalchemy import Engine, event

__all__ = ["AnswerDeadline", "SocketCut"]

logger = logging.getLogger(__name__)


class SocketCut:
    """``connection``'s socket (a psycopg connection's), held to be shut down later
    from any thread (:meth:`cut`) until :meth:`close`.

    A duplicate of its descriptor is taken now and closed only by :meth:`close`: looked
    up at the cut, the number could name another socket by then (the connection closed
    meanwhile, and its number reused by the next connection, or the broker's). Held,
    the socket outlives the connection's own close until :meth:`close`. A closed
    connection has none: its statements fail on their own.
    """

    def __init__(self, connection: Any) -> None:
        try:
            self._own = os.dup(connection.fileno())
        except Exception:
            self._own = -1

    def cut(self) -> None:
        """Shut the socket down, both ways: a wait on it ends at once, on an error."""
        if self._own < 0:
            return
        with contextlib.suppress(Exception):
            with socket.socket(fileno=os.dup(self._own)) as sock:
                sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        if self._own >= 0:
            os.close(self._own)
            self._own = -1


class AnswerDeadline:
    """Every connection ``engine`` opens (PostgreSQL, psycopg) watched while it lives: a
    statement still waiting for its answer ``answer_s`` after it was sent has its
    connection cut (:class:`SocketCut`), and the thread waiting on it gets an
    ``OperationalError`` at once (a lost connection, discarded by the pool), where it
    waited for ever behind a frozen proxy.

    "Waiting for its answer" is psycopg's own state (the connection is ``ACTIVE``: a
    query, a commit, the pool's ping). A statement's start is stamped where SQLAlchemy
    tells of it (each execute, commit, rollback and pool reset); the pool's ping, which
    it does not, is timed from when it is first seen waiting, never from an earlier
    statement's stamp. So no statement is cut before ``answer_s`` have passed since it
    was sent, and none that gets no answer waits much more than ``answer_s`` +
    ``ask_s`` + ``look_s`` (the bound, then the server asked, :meth:`_working`).

    Past the bound, the server is asked over a connection of its own whether it is at
    work on the statement (a long query, a wait for a row lock): then it is slow, not
    unanswered, and it is left to run, asked again after another ``answer_s``. Cut, it
    was a 503 "cannot be reached" from a server that answered, and its backend went on
    (waiting for the lock) with no client.

    One watching thread (a daemon) per engine, running while the engine has a
    connection open: it ends once the last is closed (``engine.dispose()``), and starts
    again with the next.

    :param engine: a PostgreSQL engine (psycopg).
    :param answer_s: seconds a statement may wait for its answer. A server that answers,
        however slowly, within it is never cut.
    :param what: the database as the warning names it (no password).
    :param look_s: seconds between two looks; default ``answer_s`` / 20, at most 1 s.
    :param ask_s: seconds the server has to say what it is at work on (its connect, then
        its query; :meth:`_working`); default ``answer_s``.
    """

    def __init__(
        self,
        engine: Engine,
        answer_s: float,
        *,
        what: str,
        look_s: float | None = None,
        ask_s: float | None = None,
    ) -> None:
        self.answer_s = answer_s
        self.ask_s = answer_s if ask_s is None else ask_s
        self.what = what
        self.look_s = min(1.0, answer_s / 20) if look_s is None else look_s
        self._guard = threading.Lock()
        #: Each open connection and its socket, by the connection's id.
        self._open: dict[int, tuple[Any, SocketCut]] = {}
        #: When each connection's latest statement was sent (monotonic s), by its id.
        self._sent: dict[int, float] = {}
        self._thread: threading.Thread | None = None
        self._dialect = engine.dialect
        self._url = engine.url
        event.listen(engine, "connect", self._opened)
        event.listen(engine, "close", self._closed)
        event.listen(engine, "close_detached", self._closed_detached)
        event.listen(engine, "reset", self._stamp_pooled)
        event.listen(engine, "before_cursor_execute", self._stamp_cursor)
        event.listen(engine, "commit", self._stamp_connection)
        event.listen(engine, "rollback", self._stamp_connection)

    def _opened(self, connection: Any, _record: Any) -> None:
        cut = SocketCut(connection)
        with self._guard:
            self._open[id(connection)] = (connection, cut)
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._watch, name="database answer deadline", daemon=True
                )
                self._thread.start()

    def _closed(self, connection: Any, _record: Any) -> None:
        self._closed_detached(connection)

    def _closed_detached(self, connection: Any) -> None:
        with self._guard:
            held = self._open.pop(id(connection), None)
            self._sent.pop(id(connection), None)
        if held is not None:
            held[1].close()

    def _stamp_pooled(self, connection: Any, *_args: Any) -> None:
        self._sent[id(connection)] = time.monotonic()

    def _stamp_cursor(self, _conn: Any, cursor: Any, *_args: Any) -> None:
        self._sent[id(cursor.connection)] = time.monotonic()

    def _stamp_connection(self, conn: Any) -> None:
        with contextlib.suppress(Exception):
            self._sent[id(conn.connection.dbapi_connection)] = time.monotonic()

    def _waiting(self) -> list[tuple[int, Any]]:
        """The open connections whose statement waits for its answer now."""
        from psycopg.pq import TransactionStatus

        with self._guard:
            connections = [(key, connection) for key, (connection, _cut) in self._open.items()]
        waiting = []
        for key, connection in connections:
            with contextlib.suppress(Exception):
                if connection.pgconn.transaction_status == TransactionStatus.ACTIVE:
                    waiting.append((key, connection))
        return waiting

    def _watch(self) -> None:
        # Since when each connection has been seen waiting, without a look between.
        seen_since: dict[int, float] = {}
        while True:
            time.sleep(self.look_s)
            with self._guard:
                if not self._open:
                    self._thread = None
                    return
            now = time.monotonic()
            waiting = dict(self._waiting())
            seen_since = {key: seen_since.get(key, now) for key in waiting}
            late = {}
            for key, connection in waiting.items():
                since = max(seen_since[key], self._sent.get(key, 0.0))
                if now - since >= self.answer_s:
                    late[key] = (connection, now - since)
            if not late:
                continue
            working = self._working({key: connection for key, (connection, _) in late.items()})
            for key, (connection, waited_s) in late.items():
                seen_since.pop(key, None)
                if key in working:
                    # The server answers, and is at work on it (a lock wait, a long
                    # query): slow, not lost. Asked again after another answer_s.
                    self._sent[key] = time.monotonic()
                else:
                    self._cut(key, connection, waited_s)

    def _working(self, late: dict[int, Any]) -> set[int]:
        """Of ``late`` (connections by key), those whose statement the server says it
        is at work on, asked over a connection of its own: its backend ``active`` in
        pg_stat_activity (running, or waiting on a lock), but not waiting on its client
        (``ClientWrite``: its answer sent, and stuck on the way, as behind a proxy
        frozen on that connection alone). None when the server does not
        answer that question within ``ask_s`` (its connect bounded by libpq's
        ``connect_timeout``, its query by a cut of its socket): the late ones are cut.
        A backend not found (behind a pooling proxy, the pid is not the server's) or
        idle is a statement whose answer was lost: cut too."""
        import psycopg

        pids: dict[int, int] = {}
        for key, connection in late.items():
            with contextlib.suppress(Exception):
                pids[connection.info.backend_pid] = key
        if not pids:
            return set()
        try:
            cargs, cparams = self._dialect.create_connect_args(self._url)
            cparams = {**cparams, "connect_timeout": max(2, math.ceil(self.ask_s))}
            with psycopg.connect(*cargs, autocommit=True, **cparams) as probe:
                cut = SocketCut(probe)
                timer = threading.Timer(self.ask_s, cut.cut)
                timer.start()
                try:
                    rows = probe.execute(
                        "SELECT pid FROM pg_stat_activity WHERE pid = ANY(%s) AND state = 'active'"
                        " AND wait_event_type IS DISTINCT FROM 'Client'",
                        (list(pids),),
                    ).fetchall()
                finally:
                    timer.cancel()
                    cut.close()
        except Exception as exc:
            logger.debug("the database %s did not say what it is at work on: %s", self.what, exc)
            return set()
        return {pids[pid] for (pid,) in rows if pid in pids}

    def _cut(self, key: int, connection: Any, waited_s: float) -> None:
        with self._guard:
            held = self._open.get(key)
        if held is None or held[0] is not connection:
            return  # closed meanwhile
        logger.warning(
            "the database %s gave no answer to a statement within %g s (waited %.1f s): "
            "its connection is cut, and the statement fails as on a lost connection",
            self.what,
            self.answer_s,
            waited_s,
        )
        held[1].cut()
