"""Ending a PostgreSQL statement that gets no answer: its socket shut down from another
thread.

psycopg has no client-side deadline for a statement, and a server-side one
(``statement_timeout``) needs a server that hears the statement; libpq's and the kernel's
bounds (``tcp_user_timeout``, keepalives: see service.store.session.Database) do not fire
while something still acknowledges what is sent (a frozen proxy). Shutting the socket
down ends the wait of the thread in the statement at once, on an error; the server ends
the session when it sees the connection end.

- :class:`SocketCut` (service.store.answers'): one connection's socket, held so that it
  can be cut later (the incarnation lock's statements: worker.incarnation._ask).
- :class:`StopCut`: a run's database (worker.runner): once its worker is stopping, a
  statement unanswered for :data:`STOP_ANSWER_S` has every connection of the run cut,
  and no new one opened; the run then gives itself up (see
  worker.context.JobContext.check_now).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from sqlalchemy import event

from service.store import Database
from service.store.answers import SocketCut
from service.store.refusals import database_label

__all__ = ["STOP_ANSWER_S", "SocketCut", "StopCut"]

logger = logging.getLogger(__name__)

#: Seconds a statement of a stopping worker's run may wait for its answer before the
#: run's connections are cut (see :class:`StopCut`). A database that answers does so in
#: milliseconds, and the stop's hand-back ends the run at its next cancel poll
#: (worker.context.CANCEL_POLL_S); behind a frozen proxy the run's cancel poll waited for
#: ever, and Celery, waiting for its task, kept a plain ``celery worker`` running (76 s
#: after SIGTERM, then killed). The worker's main process waits for its own hand-back
#: worker.monitor.STOP_WAIT_S (5 s) meanwhile; this is well inside it.
STOP_ANSWER_S = 2.0
#: Seconds between two looks at a stopping run's connections.
STOP_LOOK_S = 0.1


class StopCut:
    """A run's database (``db``), watched once its worker is ``stopping()``: a
    statement (a ping, a commit) still waiting for its answer :data:`STOP_ANSWER_S`
    after the stop, or after it was sent if later, has every connection of ``db`` cut
    (:class:`SocketCut`) and no new one opened (a connect fails at once). The database
    is then :attr:`given_up`: the run's statements fail at once, and the run gives
    itself up (worker.context.JobContext.check_now) to the stop's hand-back, or, where
    that did not reach the database either, to the reaper.

    Only PostgreSQL: an SQLite file does not go silent. Watched on a daemon thread from
    :meth:`start` to :meth:`stop`.
    """

    def __init__(self, db: Database, stopping: Callable[[], bool]) -> None:
        self.db = db
        self.stopping = stopping
        self.given_up = False
        self._guard = threading.Lock()
        #: Each open connection's socket, by the connection's id.
        self._sockets: dict[int, tuple[Any, SocketCut]] = {}
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._watched = db.engine.dialect.name == "postgresql"
        if self._watched:
            event.listen(db.engine, "do_connect", self._refuse_once_given_up)
            event.listen(db.engine, "connect", self._opened)
            event.listen(db.engine, "close", self._closed)
            event.listen(db.engine, "close_detached", self._closed_detached)

    def start(self) -> StopCut:
        if self._watched:
            self._thread = threading.Thread(target=self._watch, name="stop cut", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop watching, and let go of the sockets held."""
        self._done.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        with self._guard:
            held, self._sockets = list(self._sockets.values()), {}
        for _connection, cut in held:
            cut.close()

    def _refuse_once_given_up(self, *_args: Any) -> Any:
        if self.given_up:
            import psycopg

            raise psycopg.OperationalError(
                "this worker is stopping and its database gave no answer: "
                "no new connection is opened"
            )
        return None  # SQLAlchemy connects as usual

    def _opened(self, connection: Any, _record: Any) -> None:
        cut = SocketCut(connection)
        with self._guard:
            self._sockets[id(connection)] = (connection, cut)
            late = self.given_up
        if late:  # opened as the run gave up (a connect already under way)
            cut.cut()

    def _closed(self, connection: Any, _record: Any) -> None:
        self._closed_detached(connection)

    def _closed_detached(self, connection: Any) -> None:
        with self._guard:
            held = self._sockets.pop(id(connection), None)
        if held is not None:
            held[1].close()

    def _waiting(self) -> list[Any]:
        """The connections whose statement waits for its answer now."""
        from psycopg.pq import TransactionStatus

        with self._guard:
            connections = [connection for connection, _cut in self._sockets.values()]
        waiting = []
        for connection in connections:
            with contextlib.suppress(Exception):
                if connection.pgconn.transaction_status == TransactionStatus.ACTIVE:
                    waiting.append(connection)
        return waiting

    def _watch(self) -> None:
        stopped_at: float | None = None
        # Since when each connection's statement has been seen waiting, without a break.
        waiting_since: dict[int, float] = {}
        while not self._done.wait(STOP_LOOK_S):
            if not self.stopping():
                continue
            now = time.monotonic()
            if stopped_at is None:
                stopped_at = now
            waiting = {id(connection) for connection in self._waiting()}
            waiting_since = {key: waiting_since.get(key, now) for key in waiting}
            if any(
                now - max(since, stopped_at) >= STOP_ANSWER_S for since in waiting_since.values()
            ):
                self._give_up()
                return

    def _give_up(self) -> None:
        with self._guard:
            self.given_up = True
            held = [cut for _connection, cut in self._sockets.values()]
        logger.warning(
            "this worker is stopping and its database %s gave its run no answer within "
            "%g s: the run's connections are cut and the run given up (the stop's "
            "hand-back, or else the reaper, re-queues its job)",
            database_label(self.db.url),
            STOP_ANSWER_S,
        )
        for cut in held:
            cut.cut()
