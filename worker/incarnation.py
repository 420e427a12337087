"""Which worker process holds a name: its *incarnation*, and whether an earlier one lives.

A worker started again under a name it had (docker keeps a container's hostname across a
restart, and ``celery -n w1@host`` names it outright) is a new incarnation: a fresh id,
made once in the worker's main process before it forks its task processes, stamped on
each job its runs claim (``jobs.worker_incarnation``) and on its ``workers`` row.

Whether the incarnation a job was claimed by is still alive is answered by a lock that
the incarnation holds for as long as its main process lives and that the operating
system lets go of when it dies, however it dies (``kill -9`` included): a PostgreSQL
session advisory lock (its connection closes with the process), or, for SQLite (the
workers share the database's machine), an ``flock`` on a file beside the database. So a
worker restarted at once finds its earlier incarnation's lock free and takes that one's
jobs within two beats (see :class:`Witness`), while two *live* workers started under
one name by mistake each find the other's lock held and leave the other's jobs alone. A
database where neither can be held (an in-memory SQLite) reports every earlier
incarnation alive: the reaper's heartbeat timeout stays the backstop.

A lock can be lost while its process lives: the PostgreSQL session that holds it ends
(the server restarts, ``pg_terminate_backend``, ``idle_session_timeout``), or its file
is removed. Others then find it free and could judge the live process dead and run its
jobs again. So the worker's monitor checks its lock at every beat and takes it again
(:meth:`Life.keep`); until it holds it again its task processes claim no job
(:meth:`Life.may_claim`); and a lock found free is believed only when found free again
two beats later, its run silent meanwhile (:class:`Witness`).

Written here rather than taken from a library: the lock has to be tied to the database
the workers share (its server, or its file), which no lock library we use knows of.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import mmap
import os
import threading
import time
from collections.abc import Callable, Iterable
from datetime import datetime
from pathlib import Path
from typing import Any

from sqlalchemy.engine import make_url
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import Session

from service.store.incarnations import LockUnreadable, lock_held
from service.store.incarnations import lock_file as _lock_file
from service.store.incarnations import lock_key as _key
from service.store.models import new_id, utcnow

from .cut import SocketCut
from .episode import Episode

__all__ = ["LOCK_ANSWER_S", "Life", "LockSilent", "Witness", "alive", "current"]

logger = logging.getLogger(__name__)

#: Seconds the lock's PostgreSQL session is given to answer a statement (the beat's
#: check, the take, a stop's unlock), and to connect (libpq's ``connect_timeout``,
#: whole seconds). A server whose packets go unanswered (a silent network: no refusal,
#: no reset) otherwise held the beat, and a stop, for as long: the kernel acknowledges
#: what is sent, and a query waits on its answer for ever (behind a SIGSTOPped proxy,
#: release(), lost() and hold() each still waited after 30 s; a stop would wait past
#: serve's 10 s grace, which then kills the worker).
LOCK_ANSWER_S = 3.0

# Made at import, in the worker's main process, before the pool forks: its task
# processes (and those started in place of dead ones) inherit it.
_CURRENT = new_id()


def current() -> str:
    """This worker's incarnation id (the same in its main and its task processes)."""
    return _CURRENT


class LockSilent(TimeoutError):
    """The lock's database session gave no answer in time (see :data:`LOCK_ANSWER_S`);
    its connection was cut, so the server drops the session, and the lock with it, when
    it sees it end."""


class HeldElsewhere(RuntimeError):
    """The lock is held by another database session (a twin's probe, or a session that
    kept it): a condition to wait out, not a fault."""


class Life:
    """The lock ``incarnation`` holds while its process lives (see the module's notes)."""

    def __init__(self, database_url: str, incarnation: str) -> None:
        self.database_url = database_url
        self.incarnation = incarnation
        self._connection: Any = None
        self._fd: int | None = None
        self._path: Path | None = None
        #: try_hold's failures, logged once an episode (see worker.episode).
        self._hold_failing = Episode(logger)
        #: Since when this process's task processes have claimed no job (the lock let
        #: go of, or never taken; UTC), until the monitor has sent again what they left
        #: meanwhile (see worker.reaper.resend_left); None otherwise.
        self.claims_stopped_at: datetime | None = None
        # One shared byte, 1 while this process may claim jobs (see may_claim): mapped
        # before the worker forks its task processes, so they read what the main
        # process writes.
        self._claims = mmap.mmap(-1, 1)
        #: Set by release(): no lock is taken from then on. A beat (keep()) still under
        #: way as a stop released the lock (its statements each take up to
        #: LOCK_ANSWER_S, and the stop waits for the beat only so long) took it again
        #: after the release, and held it until the process exited. Read, and what
        #: holds the lock swapped, under _guard; the network waits are outside it.
        self._closed = False
        self._guard = threading.Lock()

    @property
    def held(self) -> bool:
        return self._connection is not None or self._fd is not None

    def may_claim(self) -> bool:
        """Whether a job claimed now is safe from a twin (another live process of the
        same worker name): the lock is held, or the database has none (an in-memory
        SQLite, where :func:`alive` judges no incarnation dead). Read by the task
        processes before each claim; a job they may not claim stays queued for
        another worker, or for this one once its lock is taken again."""
        return self._claims[0] == 1

    def hold(self) -> bool:
        """Take the lock (once); whether it is held (never after :meth:`release`)."""
        if self.held:
            return True
        if self._closed:
            return False
        url = make_url(self.database_url)
        if url.drivername.startswith("postgresql"):
            import psycopg

            conninfo = url.set(drivername="postgresql").render_as_string(hide_password=False)
            # Named, so an operator sees it in pg_stat_activity for what it is, and
            # so that this process knows its own earlier sessions (see below).
            name = f"inertia-id lock {self.incarnation}"
            connection = psycopg.connect(
                conninfo,
                autocommit=True,
                application_name=name,
                connect_timeout=max(2, round(LOCK_ANSWER_S)),
            )
            try:
                # Not pg_advisory_lock: a session holding the key (an alive() probe
                # stuck mid-way) would block the monitor's beat for as long.
                key = _key(self.incarnation)
                take = "SELECT pg_try_advisory_lock(%s)"
                taken = _ask(connection, take, (key,))
                if not (taken and taken[0]) and _end_own_sessions(connection, name, key):
                    taken = _ask(connection, take, (key,))
                if not (taken and taken[0]):
                    raise HeldElsewhere(
                        f"the lock of incarnation {self.incarnation} is held by another "
                        "database session"
                    )
            except BaseException:
                connection.close()
                raise
            with self._guard:
                if not self._closed:
                    self._connection = connection
                    self._claims[0] = 1
                    return True
            _close_session(connection, self.incarnation)  # released meanwhile
            return False
        path = _lock_file(self.database_url, self.incarnation)
        if path is None:
            with self._guard:
                if not self._closed:
                    self._claims[0] = 1  # nothing to guard: alive() judges none dead
            return False
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = _open_locked(path)
        with self._guard:
            taken = not self._closed
            if taken:
                self._fd, self._path = fd, path
                self._claims[0] = 1
        if not taken:  # released meanwhile: as release() leaves it
            with contextlib.suppress(OSError):
                path.unlink()
            os.close(fd)
            return False
        _sweep(path.parent, keep=path)
        return True

    def lost(self) -> str | None:
        """Why the lock this process took is not held any more, or None (held, or never
        taken): its database session ended (a server restart, ``pg_terminate_backend``,
        ``idle_session_timeout``), or its file was removed (others then find no lock
        and judge this live process dead)."""
        if self._connection is not None:
            key = _key(self.incarnation)
            # pg_locks names a bigint advisory key in two unsigned 32-bit halves.
            high, low = (key >> 32) & 0xFFFFFFFF, key & 0xFFFFFFFF
            try:
                row = _ask(
                    self._connection,
                    "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory'"
                    " AND pid = pg_backend_pid() AND granted AND objsubid = 1"
                    " AND classid = %s::bigint::oid AND objid = %s::bigint::oid",
                    (high, low),
                )
            except LockSilent as exc:
                return f"its database session gave {exc} (its connection is closed now)"
            except Exception as exc:
                return f"its database session ended ({type(exc).__name__}: {exc})"
            return None if row and row[0] else "its database session no longer holds it"
        if self._fd is not None and self._path is not None:
            try:
                same = os.fstat(self._fd).st_ino == os.stat(self._path).st_ino
            except OSError:
                same = False
            return None if same else f"its file {self._path} was removed"
        return None

    def keep(self) -> bool:
        """At each of the monitor's beats: take the lock again if it was lost (see
        :meth:`lost`), or take it at last; whether it is held. Until it is, the task
        processes claim no job (:meth:`may_claim`). The check also keeps the lock's
        session from idling past the server's ``idle_session_timeout``."""
        if self._closed:
            return False
        reason = self.lost()
        if reason is not None:
            logger.warning("this worker's incarnation lock was lost: %s; taking it again", reason)
            self._let_go()
            if self.try_hold():
                logger.info("took this worker's incarnation lock again")
                return True
            return False
        return self.held or self.try_hold()

    def _let_go(self, *, remove_file: bool = False, confirm: bool = True) -> None:
        """Close what held the lock (claims stop at once); with ``remove_file``, the lock
        file too (a clean exit: a lost lock's path may be another's by now); without
        ``confirm``, the lock's session closed without asking the server to unlock first
        (see :func:`_close_session`)."""
        # Taken out under the guard, so that a beat and a stop letting go at once each
        # close what they took, and nothing twice.
        with self._guard:
            if self._claims[0] == 1 and self.claims_stopped_at is None:
                self.claims_stopped_at = utcnow()
            self._claims[0] = 0
            connection, self._connection = self._connection, None
            fd, path, self._fd, self._path = self._fd, self._path, None, None
        if connection is not None:
            _close_session(connection, self.incarnation, confirm=confirm)
        if fd is not None:
            if remove_file and path is not None:
                with contextlib.suppress(OSError):
                    path.unlink()
            os.close(fd)

    def try_hold(self) -> bool:
        """:meth:`hold`, its failure logged rather than raised: once an episode (when
        it starts, for each new reason, then as a rare reminder; see
        :class:`worker.episode.Episode`), the traceback only for a failure that is no
        outage (a database or file that cannot be reached says all in its message).
        The monitor retries every beat: a data dir where the lock file cannot be made
        logged a traceback every 5 s, and a second outage later was never logged."""
        try:
            held = self.hold()
        except Exception as exc:
            if self._claims[0] == 0 and self.claims_stopped_at is None:
                self.claims_stopped_at = utcnow()  # never taken: its jobs are left from now
            self._hold_failing.seen(
                _reason(exc),
                "could not take this worker's incarnation lock (%s); will retry at every beat",
                exc_info=not _outage(exc),
            )
            return False
        self._hold_failing.cleared("took this worker's incarnation lock (after %.0f s)")
        return held

    def release(self, *, confirm: bool = True) -> None:
        """Let go of the lock (a clean exit), for good: a beat still under way takes it
        no more (see :attr:`_closed`); its file, if any, is removed. Without
        ``confirm`` (a stop whose database gave no answer already), its PostgreSQL
        session is closed at once, not asked to unlock first (up to
        :data:`LOCK_ANSWER_S` more)."""
        with self._guard:
            self._closed = True
        self._let_go(remove_file=True, confirm=confirm)

    def forget_after_fork(self) -> None:
        """In a forked task process: drop the PostgreSQL connection's socket without a
        word to the server (a goodbye sent from here would end the parent's session, and
        its lock with it). The ``flock`` file stays open: it is the parent's lock, and the
        task process dies with its parent."""
        if self._connection is None:
            return
        devnull = os.open(os.devnull, os.O_RDWR)
        try:
            os.dup2(devnull, self._connection.fileno())
        finally:
            os.close(devnull)


def _close_session(connection: Any, incarnation: str, *, confirm: bool = True) -> None:
    """Let go of the lock ``incarnation``'s session ``connection`` holds, and close it.

    Unlocked before the goodbye (with ``confirm``): closing alone leaves the lock to the
    server process's exit, which ends after close() returns; another session reading
    pg_locks meanwhile saw this released lock held (in 20 of 200 releases on the loaded
    2-core machine), and /health a stopped worker alive. A lost session's unlock fails,
    and is let be: its lock went with it. One that gets no answer in time is cut (see
    _ask): released, unconfirmed."""
    try:
        if confirm:
            _ask(connection, "SELECT pg_advisory_unlock(%s)", (_key(incarnation),))
    except LockSilent as exc:
        logger.warning(
            "could not confirm the release of this worker's incarnation lock (%s): "
            "its session's connection is closed, and the server lets go of the lock "
            "as it sees that session end",
            exc,
        )
    except Exception:
        pass
    with contextlib.suppress(Exception):
        connection.close()


#: The refusals to end this process's earlier lock session (see _end_own_sessions).
_COULD_NOT_END: list[str] = []


def _end_own_sessions(connection: Any, name: str, key: int) -> bool:
    """End the server sessions that hold the lock ``key`` under this process's own lock
    session name ``name`` (its incarnation's, unique to this process) other than
    ``connection``'s; whether one was ended (within half of :data:`LOCK_ANSWER_S`: the
    server's locks go before it counts a session as ended).

    Such a session is one this process let go of without the server hearing of it: its
    connection cut when it did not answer (see :func:`_ask`), the goodbye lost in a
    silent network. The server ends it only when its TCP keepalive gives up (hours, by
    default), and each beat meanwhile found the lock "held by another database
    session": the live worker claimed no job. A probe of another process (``alive()``)
    holding the key a moment has another name, and is waited out as before.
    """
    try:
        row = _ask(
            connection,
            "SELECT count(*) FILTER (WHERE pg_terminate_backend(l.pid, %s))"
            " FROM pg_locks l JOIN pg_stat_activity a ON a.pid = l.pid"
            " WHERE l.locktype = 'advisory' AND l.granted AND l.objsubid = 1"
            " AND l.classid = %s::bigint::oid AND l.objid = %s::bigint::oid"
            " AND l.database = (SELECT oid FROM pg_database WHERE datname = current_database())"
            " AND a.application_name = %s AND l.pid <> pg_backend_pid()",
            (
                max(1, int(LOCK_ANSWER_S * 500)),
                (key >> 32) & 0xFFFFFFFF,
                key & 0xFFFFFFFF,
                name,
            ),
        )
    except LockSilent:
        raise
    except Exception as exc:  # no right to end it, or a server before 14: wait it out
        # Once a process at WARNING (it comes back at each beat while the key is held):
        # otherwise an operator saw only "held by another database session", for hours.
        first = not _COULD_NOT_END
        _COULD_NOT_END.append(str(exc))
        logger.log(
            logging.WARNING if first else logging.DEBUG,
            "could not end this worker's earlier incarnation lock session, which the "
            "database server still keeps (%s): the worker claims no job until the server "
            "ends it (its TCP keepalive) or an operator does (pg_terminate_backend)",
            exc,
        )
        return False
    if not (row and row[0]):
        return False
    logger.warning(
        "ended this worker's earlier incarnation lock session, which the database server "
        "still kept (its connection was closed here while the server did not answer)"
    )
    return True


def _ask(connection: Any, statement: str, params: tuple[Any, ...]) -> Any:
    """The first row of ``statement`` on the lock's ``connection``, answered within
    :data:`LOCK_ANSWER_S`; else :class:`LockSilent`, the connection cut.

    psycopg has no client-side deadline for a statement, and a server-side one
    (``statement_timeout``) needs a server that hears the statement. So the socket is
    shut down at the deadline: the wait (ours, or that of another thread in the middle
    of a statement on this connection, which holds its lock) ends at once on an error.
    The server ends the session, and lets go of its lock, when it sees the connection
    end; until then others find the lock held, which keeps this process's runs its own.
    """
    guard = threading.Lock()
    state = {"done": False, "cut": False}
    held = SocketCut(connection)

    def cut() -> None:
        with guard:
            if state["done"]:
                return
            state["cut"] = True
        held.cut()

    timer = threading.Timer(LOCK_ANSWER_S, cut)
    timer.daemon = True
    timer.start()
    try:
        row = connection.execute(statement, params).fetchone()
    except Exception as exc:
        with guard:
            state["done"] = True
        if state["cut"]:
            raise LockSilent(f"no answer within {LOCK_ANSWER_S:g} s") from exc
        raise
    finally:
        timer.cancel()
        # A cut under way ends before its descriptor is closed (it does not wait).
        timer.join()
        held.close()
    with guard:
        state["done"] = True
        cut_meanwhile = state["cut"]
    if cut_meanwhile:  # answered as the deadline cut the connection: it is gone now
        raise LockSilent(f"no answer within {LOCK_ANSWER_S:g} s")
    return row


def _open_locked(path: Path) -> int:
    """``path`` opened (made if missing) and ``flock``-ed, as the file at ``path`` now.

    A sweep or :func:`alive` may unlink a file between our open and our lock (it found
    the lock free); a lock on an unlinked file is invisible to the others, so try again.
    """
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if os.fstat(fd).st_ino == os.stat(path).st_ino:
                return fd
        except FileNotFoundError:
            pass
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


def _sweep(folder: Path, *, keep: Path) -> None:
    """Remove the lock files in ``folder`` that no live process holds: those of workers
    killed (``kill -9``, or ``inertia-id serve``'s stop, which kills a worker once its job
    is handed back) before they could remove their own. ``serve`` names each worker
    afresh at every start, so no later incarnation of its name would ever look at them:
    without this, one file was left per worker start. Housekeeping: errors are ignored."""
    with contextlib.suppress(OSError):
        for path in folder.glob("*.lock"):
            if path == keep:
                continue
            try:
                fd = os.open(path, os.O_RDWR)
            except OSError:
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                pass  # held: a live worker's
            else:
                with contextlib.suppress(OSError):
                    path.unlink()
            finally:
                os.close(fd)


def alive(session: Session, database_url: str, incarnation: str) -> bool:
    """Whether the worker process of ``incarnation`` still lives: its lock is held.

    On PostgreSQL asked through ``session``'s connection (another session than the
    holder's, also in the holder's own process). True where it cannot be told: an
    in-memory SQLite, a lock file that cannot be read (``<database>.incarnations`` is a
    file, or unreadable), or a PostgreSQL probe that fails (the server restarting, the
    session ended, a statement error); logged once an episode (see :func:`_unknown`).
    """
    try:
        held = lock_held(session, database_url, incarnation)
    except LockUnreadable as unreadable:
        # The lock's state is unknown, so the other incarnation is not judged dead (its
        # run stays its own; before, the error left the monitor's beat before its
        # reaper and re-sender).
        return _unknown(unreadable.where, unreadable.error)
    if session.get_bind().dialect.name == "postgresql":
        _readable("on the PostgreSQL server")
    elif (path := _lock_file(database_url, incarnation)) is not None:
        _readable(f"in {path.parent}")
    return held is None or held


#: For each place (a lock folder, the PostgreSQL server), the episodes in which
#: :func:`alive` could not read a lock there, each logged once an episode: the monitor
#: asks at every beat. (Once a process before: a second outage was never logged.)
_UNREADABLE: dict[str, Episode] = {}


def _reason(exc: BaseException) -> str:
    """``exc``'s type and message in one line: an OSError's ``strerror``, or the first
    line (PostgreSQL's errors go on with the statement and a link)."""
    if isinstance(exc, OSError) and exc.strerror:
        return f"{type(exc).__name__}: {exc.strerror}"
    inner = exc.orig if isinstance(exc, DBAPIError) and exc.orig is not None else exc
    return f"{type(inner).__name__}: {(str(inner).strip().splitlines() or [''])[0]}"


def _outage(exc: BaseException) -> bool:
    """Whether ``exc`` says the lock's database or file cannot be reached (its message
    says all), rather than a fault in our code (its traceback is wanted)."""
    import psycopg

    if isinstance(exc, DBAPIError):
        return exc.connection_invalidated or isinstance(exc.orig, psycopg.OperationalError)
    return isinstance(exc, OSError | psycopg.OperationalError | HeldElsewhere)


def _unknown(where: str, exc: BaseException) -> bool:
    """:func:`alive`'s answer for a lock it could not read: alive (see there)."""
    _UNREADABLE.setdefault(where, Episode(logger)).seen(
        _reason(exc),
        f"cannot read the incarnation locks {where} (%s): their workers are taken to be "
        "alive, and their runs left to them, until it can be read",
    )
    return True


def _readable(where: str) -> None:
    """:func:`alive` read a lock ``where``: an episode of :func:`_unknown` there ends."""
    episode = _UNREADABLE.get(where)
    if episode is not None:
        episode.cleared(f"can read the incarnation locks {where} again (after %.0f s)")


class Witness:
    """Judges an earlier incarnation gone only once its lock was found free at two
    probes at least ``confirm_s`` apart (with no probe between that found it held).

    A lock found free once may belong to a live process whose lock's session just
    ended (the database restarted): that process takes it again at its next beat
    (:meth:`Life.keep`), so with ``confirm_s`` longer than a beat a live process is
    found holding it at the second probe. A dead one's lock stays free.

    :param confirm_s: seconds between the first and the deciding probe.
    :param clock: monotonic seconds (a test passes its own).
    """

    def __init__(self, confirm_s: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.confirm_s = confirm_s
        self._clock = clock
        self._free_since: dict[str, float] = {}

    def gone(self, incarnation: str, lock_free: bool) -> bool:
        """Record a probe of ``incarnation``'s lock; whether it is judged gone."""
        if not lock_free:
            self._free_since.pop(incarnation, None)
            return False
        now = self._clock()
        return now - self._free_since.setdefault(incarnation, now) >= self.confirm_s

    def keep_only(self, incarnations: Iterable[str]) -> None:
        """Forget the incarnations not among ``incarnations`` (their runs were taken)."""
        wanted = set(incarnations)
        self._free_since = {k: v for k, v in self._free_since.items() if k in wanted}
