"""``inertia-id serve``: the whole service on one machine, nothing to install.

``python -m app.serve [--host 127.0.0.1] [--port 8000] [--data-dir DIR] [--workers 1]``

1. points the settings at ``--data-dir`` (SQLite file and filesystem broker inside it,
   unless ``DATABASE_URL`` / ``BROKER_URL`` say otherwise), creates it and migrates the
   database;
2. builds the API (:func:`app.main.create_app`), which makes sure an API key exists, and
   prints the URL and the key when it was generated now (only then: it is stored hashed);
3. starts ``--workers`` real ``celery worker`` processes (one job at a time each, each
   named uniquely), logging to ``DIR/logs/``, and restarts one that dies;
4. serves the API with uvicorn (``--api-workers`` processes; a connection that does not
   send its request in time is closed: :mod:`app.request_deadlines`) until Ctrl-C or
   SIGTERM. At that signal the workers are told to stop, while uvicorn gives the
   requests in flight their grace (:data:`API_GRACE_S`): each hands its running job back
   to the queue at once (it costs the job no attempt) and exits; once the API has
   stopped, serve waits for them, and one still there after a grace period is killed.

If serve itself dies (``kill -9``), its workers are told to stop by the kernel
(``PR_SET_PDEATHSIG``): they hand their jobs back and exit, and nothing is orphaned.

On its way out serve leaves no process behind: it is its descendants' *subreaper*
(``PR_SET_CHILD_SUBREAPER``), so any of them orphaned (the API's fork server and verdict
process, multiprocessing's resource tracker, a worker's task process) is its child, and
once the workers and the API have stopped it stops every child left (the fork server and
the resource tracker by closing their pipes, the others by SIGTERM; SIGKILL for any still
there after :data:`LEFTOVER_GRACE_S`), reaps them, and logs how each ended.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import logging
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType
from typing import IO, TYPE_CHECKING, Any

from pydantic import ValidationError

from service.config import Settings, get_settings, setting_problems
from service.queue import worker_command

from .temp_folders import (
    SERVE_PREFIX,
    LockedFolder,
    make_locked,
    remove_stale,
    use_for_multiprocessing,
    worker_prefix,
)

if TYPE_CHECKING:
    from service.store.session import Database

__all__ = ["WorkerPool", "main", "tcp_socket"]

#: The worker package's name for serve's pid in its workers' environment
#: (``worker.process.PARENT_PID_ENV``; not imported, the API does not import the worker).
PARENT_PID_ENV = "INERTIA_ID_PARENT_PID"
#: ...and for the folder serve makes for a worker's multiprocessing temp files
#: (``worker.process.TEMP_DIR_ENV``), removed once that worker is gone.
WORKER_TEMP_DIR_ENV = "INERTIA_ID_WORKER_TEMP_DIR"
#: Seconds uvicorn waits for requests in flight when asked to stop.
API_GRACE_S = 5.0

logger = logging.getLogger("inertia_id.serve")

#: Seconds a stopping worker gets to finish its job before it is killed.
STOP_GRACE_S = 10.0
#: A worker that dies is restarted, but not more often than this (s).
RESTART_DELAY_S = 5.0

PROJECT_ROOT = Path(__file__).resolve().parent.parent

#: Seconds the processes left at shutdown get to exit once asked, before SIGKILL.
LEFTOVER_GRACE_S = 3.0
#: serve's own database connections (its start's migration and key, its workers'
#: announced rows, its stop's hand-back check; PostgreSQL) give up a connect, or a server
#: whose machine stopped acknowledging, after about this many seconds, as the API's do
#: (app.main.DATABASE_SILENT_S; see service.store.session.Database). Before, a silent
#: database held serve's start for ever, printing nothing, and its stop too.
DATABASE_SILENT_S = 5.0
#: ...and a statement of theirs still unanswered this many seconds after it was sent
#: has its connection cut (service.store.answers.AnswerDeadline): behind a proxy that
#: acknowledges for a server that does not answer (frozen), nothing else ends the wait.
#: Short, where the API's requests get INERTIA_ID_DATABASE_ANSWER_TIMEOUT_S: these are
#: one-row statements, and none is needed (a row left unannounced is written by the
#: worker's first beat; a hand-back left unconfirmed waits out the stop's grace).
DATABASE_ANSWER_S = 5.0
#: ``prctl`` option: orphaned descendants are re-parented to this process, not to init.
_PR_SET_CHILD_SUBREAPER = 36


def become_subreaper() -> bool:
    """Make this process the subreaper of its descendants (Linux; False elsewhere or on
    failure), so that :func:`stop_children` finds the ones whose parent has gone."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return bool(libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0)
    except (OSError, AttributeError):
        return False


def child_processes(parent: int | None = None) -> dict[int, tuple[str, str]]:
    """The processes whose parent is ``parent`` (this one by default), by pid: each one's
    state (``Z`` a zombie) and command line (its name in brackets when it has none, as a
    zombie or a process that is exiting has not), from ``/proc``."""
    parent = os.getpid() if parent is None else parent
    found: dict[int, tuple[str, str]] = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return found
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as stat:
                head, _, tail = stat.read().rpartition(b")")
            fields = tail.split()
            if int(fields[1]) != parent:
                continue
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                command = cmdline.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except (OSError, IndexError, ValueError):
            continue  # gone meanwhile
        name = head.partition(b"(")[2].decode(errors="replace")
        found[int(entry)] = (fields[0].decode(), command or f"[{name}]")
    return found


def reap_orphans(keep: set[int]) -> int:
    """Reap this process's ended children but those in ``keep`` (the ones a
    :class:`subprocess.Popen` waits for), multiprocessing's helpers and the processes it
    started (uvicorn's API processes with ``--api-workers`` above 1), which it waits for
    itself: orphans adopted as subreaper (a killed worker's task process) would otherwise
    stay zombies until serve ends. The number reaped."""
    from multiprocessing import forkserver, process, resource_tracker

    keep = keep | {
        getattr(forkserver._forkserver, "_forkserver_pid", None) or 0,
        getattr(resource_tracker._resource_tracker, "_pid", None) or 0,
    }
    # Reaped here, a process multiprocessing started had no exit code for its owner
    # (uvicorn could not tell a startup failure from a crash) and its pid, free for the
    # kernel to reuse, was sent SIGKILL. Copied: the main thread adds and removes them.
    while True:
        try:
            started = list(process._children)  # type: ignore[attr-defined]
            break
        except RuntimeError:  # changed size while copied
            continue
    keep |= {getattr(child, "pid", None) or 0 for child in started}
    reaped = 0
    for pid, (state, _command) in child_processes().items():
        if pid in keep or state != "Z":
            continue
        with contextlib.suppress(ChildProcessError):
            if os.waitpid(pid, os.WNOHANG)[0] == pid:
                reaped += 1
    return reaped


def _role(pid: int, command: str) -> str:
    from multiprocessing import forkserver, resource_tracker

    if pid == getattr(forkserver._forkserver, "_forkserver_pid", None):
        return "fork server"
    if pid == getattr(resource_tracker._resource_tracker, "_pid", None):
        return "resource tracker"
    if "multiprocessing.forkserver" in command:
        # An API process's fork server (--api-workers above 1) or a verdict process.
        return "fork server or verdict process"
    if "celery" in command:
        return "worker process"
    return f"process {command[:80]!r}"


def _ask_multiprocessing_helpers_to_stop() -> None:
    """Close this process's ends of the fork server's and the resource tracker's pipes:
    each exits at the end of its pipe (what they would do when this process exits)."""
    from multiprocessing import forkserver, resource_tracker

    server: Any = forkserver._forkserver
    if getattr(server, "_forkserver_alive_fd", None) is not None:
        with contextlib.suppress(OSError):
            os.close(server._forkserver_alive_fd)
        server._forkserver_alive_fd = None
    tracker: Any = resource_tracker._resource_tracker
    if getattr(tracker, "_fd", None) is not None:
        with contextlib.suppress(OSError):
            os.close(tracker._fd)
        tracker._fd = None


def _reap(pid: int) -> bool:
    """Collect ``pid``'s exit status if it has ended; True once it is gone."""
    try:
        done, _status = os.waitpid(pid, os.WNOHANG)
    except ChildProcessError:
        return True  # not a child (any more): reaped elsewhere
    return done == pid


def stop_children(grace_s: float = LEFTOVER_GRACE_S) -> list[str]:
    """Stop every process still a child of this one, reaped; one line each saying what it
    was and how it ended (asked and exited, or killed after ``grace_s``)."""
    from multiprocessing import forkserver, resource_tracker, util

    left = child_processes()
    if not left:
        return []
    roles = {pid: _role(pid, command) for pid, (_state, command) in left.items()}
    _ask_multiprocessing_helpers_to_stop()
    for pid, role in roles.items():
        # The resource tracker ignores SIGTERM and exits at the end of its pipe, having
        # cleaned up; the fork server holds nothing, and its own exit once its pipe is
        # closed (the interpreter's teardown of what it preloaded) took over 3 s.
        if role != "resource tracker":
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    waiting = set(left)
    while waiting and time.monotonic() < deadline:
        waiting = {pid for pid in waiting if not _reap(pid)}
        if waiting:
            time.sleep(0.05)
    lines = []
    for pid in sorted(left):
        how = "exited" if left[pid][0] == "Z" else "exited when asked"
        if pid in waiting:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)
            how = f"killed (still there {grace_s:g} s after being asked to stop)"
        lines.append(f"{roles[pid]} (pid {pid}) {how}")
    # The helpers are gone: a later start in this process (tests) starts new ones.
    server: Any = forkserver._forkserver
    if getattr(server, "_forkserver_pid", None) in left:
        address = server._forkserver_address
        server._forkserver_pid = None
        server._forkserver_address = None
        if address and not util.is_abstract_socket_namespace(address):
            with contextlib.suppress(OSError):
                os.unlink(address)
    tracker: Any = resource_tracker._resource_tracker
    if getattr(tracker, "_pid", None) in left:
        tracker._pid = None
    return lines


def _leave_no_process() -> None:
    """Stop the children left at shutdown and reap them, saying so in the log."""
    lines = stop_children()
    if lines:
        for line in lines:
            logger.info("shutdown: %s", line)
    logger.info("shutdown complete: no process of this service is left")


class WorkerPool:
    """``count`` ``celery worker`` subprocesses named ``worker<i>-<token>@<host>``.

    The token is new at every start, so a worker restarted after a crash, or started by
    a later serve while an old one lingers, never shares a name with another: the
    ``workers`` table counts each once, and a dead worker's job is reaped as soon as its
    own name goes quiet. Each runs in its own session, so a Ctrl-C in the terminal
    reaches only this process, which then stops the workers in order (warm shutdown
    first, then SIGKILL); each also stops when this process dies.

    :param count: how many workers (each ``--concurrency=1``).
    :param log_dir: where ``worker<i>.log`` files go.
    :param log_level: Celery log level.
    """

    def __init__(
        self,
        count: int,
        log_dir: Path,
        *,
        log_level: str = "INFO",
        settings: Settings | None = None,
    ) -> None:
        self.count = count
        self.log_dir = log_dir
        self.log_level = log_level
        #: Where the workers beat: each is announced there as starting (see _announce).
        self._database: Database | None = None
        if settings is not None:
            self._database = _database(settings)
        self._broker_label = "" if settings is None else _broker_label(settings.broker_url)
        self.processes: dict[int, subprocess.Popen[bytes]] = {}
        self.names: dict[int, str] = {}
        #: Each worker process's temp folder (multiprocessing's, in TMPDIR), by pid:
        #: removed once that process has ended (see worker.process.use_launcher_temp_dir).
        self._temp_dirs: dict[int, LockedFolder] = {}
        #: The workers whose last process ended before its first beat (see _forget):
        #: their restarts are not announced, so /health keeps saying no worker is seen.
        self._died_unbeaten: set[int] = set()
        #: The pids whose end was handled (their announced row forgotten).
        self._ended: set[int] = set()
        self._logs: dict[int, IO[bytes]] = {}
        #: serve is its descendants' subreaper: reap the orphans that end meanwhile.
        self.adopts_orphans = False
        self._stopping = threading.Event()
        #: The database gave no answer while the workers stop: the rows of the workers
        #: stopped after are left (each try cost a connect's DATABASE_SILENT_S more).
        self._unanswered_in_stop = False
        #: The pids told to stop (SIGTERM), by the supervisor or by stop(), under its lock.
        self._told: set[int] = set()
        self._told_lock = threading.Lock()
        #: When the first worker was told to stop (monotonic s): stop()'s grace runs from it.
        self._stop_began: float | None = None
        self._supervisor = threading.Thread(
            target=self._supervise, name="inertia-id worker supervisor", daemon=True
        )
        # The starting workers' rows kept on a thread of their own: a database that did
        # not answer held the supervisor there (up to DATABASE_ANSWER_S, then a connect's
        # DATABASE_SILENT_S), and the workers were told to stop that much later.
        self._row_keeper = threading.Thread(
            target=self._keep_rows, name="inertia-id worker rows", daemon=True
        )

    def command(self, index: int) -> list[str]:
        return worker_command(self.names.get(index, f"worker{index}"), log_level=self.log_level)

    def log_path(self, index: int) -> Path:
        return self.log_dir / f"worker{index}.log"

    def start(self) -> None:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        for index in range(1, self.count + 1):
            self._spawn(index)
        if self.count:
            self._supervisor.start()
            self._row_keeper.start()

    def _spawn(self, index: int) -> None:
        self.names[index] = f"worker{index}-{secrets.token_hex(3)}"
        env = dict(os.environ)
        env[PARENT_PID_ENV] = str(os.getpid())
        # The workers import app/ and worker/ from this checkout even when the project
        # is not installed (python -m app.serve run from the repository).
        if (PROJECT_ROOT / "worker").is_dir():
            env["PYTHONPATH"] = os.pathsep.join(
                filter(None, [str(PROJECT_ROOT), env.get("PYTHONPATH")])
            )
        old = self._logs.pop(index, None)
        if old is not None:
            old.close()
        temp_dir = self._make_temp_dir(index)
        if temp_dir is not None:
            env[WORKER_TEMP_DIR_ENV] = temp_dir.path
        log = open(self.log_path(index), "ab")  # closed in stop()
        self._logs[index] = log
        try:
            self.processes[index] = subprocess.Popen(
                self.command(index),
                env=env,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                # The folder's lock, held by the worker as long as it lives: a later
                # serve keeps the folder of a worker that outlives this one.
                pass_fds=() if temp_dir is None else (temp_dir.fd,),
            )
        except BaseException:
            if temp_dir is not None:
                temp_dir.remove()
            raise
        if temp_dir is not None:
            self._temp_dirs[self.processes[index].pid] = temp_dir
        logger.info(
            "worker%d started (pid %d, name %s)",
            index,
            self.processes[index].pid,
            self.names[index],
        )
        self._announce(index)

    def _make_temp_dir(self, index: int) -> LockedFolder | None:
        """A new folder in TMPDIR for worker ``index``'s multiprocessing temp files,
        locked (:mod:`app.temp_folders`: a later serve removes it once no process holds
        it), or None (logged) where none can be made: the worker then makes its own."""
        try:
            return make_locked(worker_prefix(index), owner=f"worker{index}")
        except OSError as exc:
            logger.warning(
                "could not make a temp folder for worker%d (%s): it makes its own, which "
                "is left in %s when serve stops it",
                index,
                exc,
                tempfile.gettempdir(),
            )
            return None

    def _remove_temp_dir(self, process: subprocess.Popen[bytes]) -> None:
        """Remove the temp folder of ``process``, a worker that has ended: its task
        process, in its group, dies with it (PR_SET_PDEATHSIG, or serve's SIGKILL to the
        group), and what either left in the folder (files unlinked at once) is no one's."""
        folder = self._temp_dirs.pop(process.pid, None)
        if folder is not None:
            folder.remove()

    def node_name(self, index: int) -> str:
        """Worker ``index``'s Celery node name, its ``workers`` row's key."""
        return f"{self.names[index]}@{socket.gethostname()}"

    def _announce(self, index: int) -> None:
        """Record worker ``index`` as starting (warming since now): its main process
        imports Celery for seconds before its first beat (4 s after the API first
        answered, measured), and meanwhile /health said "no worker seen". Housekeeping:
        a failure is logged, and the worker's own first beat writes the row anyway."""
        if self._database is None or index in self._died_unbeaten:
            # Its last process crashed before its first beat (in its imports): this one
            # most likely will too, and a row announced for each restart (each under a
            # name of its own) kept /health "ok" with a worker warming for ever.
            return
        from service.store.jobs import announce_worker

        try:
            with self._database.session() as session:
                announce_worker(session, self.node_name(index), self._broker_label)
        except Exception as exc:
            _housekeeping_failed(
                f"could not record worker{index} as starting", exc, self._database.url
            )

    def _forget(self, index: int) -> None:
        """Worker ``index``'s process has ended: remove its announced row if it never
        beat (crashed while importing), so /health says at once that no worker is seen
        instead of "warming" (the reason is in serve's log and the worker's)."""
        process = self.processes[index]
        if process.pid in self._ended:
            return
        self._ended.add(process.pid)
        if self._database is None or self._unanswered_in_stop:
            return
        from service.store.jobs import forget_announced_worker

        try:
            with self._database.session() as session:
                beat = forget_announced_worker(session, self.node_name(index))
        except Exception as exc:
            unanswered = _housekeeping_failed(
                f"could not remove worker{index}'s row", exc, self._database.url
            )
            self._unanswered_in_stop |= unanswered and self._stopping.is_set()
            return
        if not beat and (self._stopping.is_set() or process.pid in self._told):
            # Told to stop (serve's SIGTERM or Ctrl-C) while it still imported Celery: a
            # stop asked for, not a crash (it was logged at ERROR as one).
            logger.info(
                "worker%d (pid %d) stopped before its first beat, as serve stops",
                index,
                process.pid,
            )
        elif not beat:
            self._died_unbeaten.add(index)
            logger.error(
                "worker%d (pid %d) exited with status %s before its first beat; /health "
                "lists it no more (log: %s)",
                index,
                process.pid,
                process.returncode,
                self.log_path(index),
            )
        else:
            self._died_unbeaten.discard(index)

    def _keep_announced(self) -> None:
        """Keep the rows of workers that live but have not beaten yet in the silence
        window (an import past 15 s on a loaded machine); a worker that died before its
        first beat is let go of, and leaves the list once its row is older."""
        if self._database is None:
            return
        names = [self.node_name(i) for i, p in self.processes.items() if p.poll() is None]
        if not names:
            return
        from service.store.jobs import keep_announced_workers

        try:
            with self._database.session() as session:
                keep_announced_workers(session, names)
        except Exception:
            logger.debug("could not refresh the starting workers' rows", exc_info=True)

    def _keep_rows(self) -> None:
        while not self._stopping.wait(1.0):
            self._keep_announced()

    def request_stop(self) -> None:
        """Have the workers told to stop now, without waiting: safe in a signal handler
        (it sets an event; the supervisor thread sends the signals and logs).

        serve calls it at its first stop signal, so that the workers wind down (each
        hands its job back, then Celery takes seconds to close its pool) while uvicorn
        gives the API's requests their grace: the workers were told only after it, and
        serve took 7-14 s to stop under /identify load. Safe to overlap: no request of
        the API waits for a worker (a job submitted meanwhile stays queued, and is sent
        again when a worker starts)."""
        self._stopping.set()

    def _tell_to_stop(self) -> int:
        """SIGTERM to every live worker not told yet; how many were told now."""
        told = 0
        with self._told_lock:
            if self._stop_began is None:
                self._stop_began = time.monotonic()
            for process in self.processes.values():
                if process.poll() is not None or process.pid in self._told:
                    continue
                try:
                    process.send_signal(signal.SIGTERM)
                except ProcessLookupError:
                    continue
                self._told.add(process.pid)
                told += 1
        return told

    def _supervise(self) -> None:
        try:
            self._watch()
        finally:
            if self._stopping.is_set():
                told = self._tell_to_stop()
                if told:
                    logger.info(
                        "told %d worker(s) to stop (a running job goes back to the queue), "
                        "while the API finishes its requests",
                        told,
                    )

    def _watch(self) -> None:
        started = {index: time.monotonic() for index in self.processes}
        while not self._stopping.wait(1.0):
            if self.adopts_orphans:
                reap_orphans({p.pid for p in self.processes.values()})
            for index, process in list(self.processes.items()):
                code = process.poll()
                if code is None or self._stopping.is_set():
                    continue
                self._forget(index)
                self._remove_temp_dir(process)
                if time.monotonic() - started[index] < RESTART_DELAY_S:
                    continue
                logger.warning(
                    "worker%d exited with status %s; restarting it (log: %s)",
                    index,
                    code,
                    self.log_path(index),
                )
                started[index] = time.monotonic()
                try:
                    self._spawn(index)
                except OSError:
                    logger.exception("could not restart worker%d", index)

    def stop(
        self,
        grace_s: float = STOP_GRACE_S,
        *,
        settled: Callable[[list[str]], bool] | None = None,
    ) -> None:
        """Warm shutdown for every worker, then SIGKILL for those still there.

        :param settled: ``names -> bool``: whether those workers have handed their jobs
            back (marked stopping, running nothing). A Celery worker takes 7 to 8 s to
            wind down its pool even when idle; once its job is back in the queue there is
            nothing left to wait for, and the rest of the grace is skipped.
        """
        self._stopping.set()
        if self._supervisor.is_alive():
            # It tells the workers as it leaves its loop (at once: the event is set).
            self._supervisor.join(5)
        running = {i: p for i, p in self.processes.items() if p.poll() is None}
        self._tell_to_stop()
        # The grace runs from the first worker told: by request_stop, at serve's signal.
        assert self._stop_began is not None
        deadline = self._stop_began + grace_s
        names = [self.node_name(i) for i in running]
        while time.monotonic() < deadline and any(p.poll() is None for p in running.values()):
            # Checked before the first pause: told at serve's signal, the workers have
            # mostly handed their jobs back by the time the API has stopped.
            if settled is not None and names:
                try:
                    if settled(names):
                        break
                except Exception as exc:  # the database is away: wait out the grace instead
                    where = None if self._database is None else self._database.url
                    self._unanswered_in_stop = _housekeeping_failed(
                        "could not check the workers' hand-back", exc, where
                    )
                    settled = None
            time.sleep(0.2)
        for index, process in self.processes.items():
            # The whole group: the worker and its task process, if either is left.
            try:
                os.killpg(process.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass
            try:
                process.wait(5)
            except subprocess.TimeoutExpired:
                logger.error("worker%d (pid %d) did not die", index, process.pid)
            else:
                self._forget(index)  # one stopped while importing was listed warming
                self._remove_temp_dir(process)
        for log in self._logs.values():
            log.close()
        self._logs.clear()
        if self._database is not None:
            self._database.dispose()


def _database(settings: Settings) -> Database:
    """serve's own connection to the service's database, bounded (see
    :data:`DATABASE_SILENT_S`, :data:`DATABASE_ANSWER_S`)."""
    from service.store.session import Database

    return Database(
        settings.resolved_database_url,
        silent_after_s=DATABASE_SILENT_S,
        answer_within_s=DATABASE_ANSWER_S,
    )


def _housekeeping_failed(what: str, exc: Exception, url: str | None) -> bool:
    """Log a failed housekeeping statement: one line naming the database and what the
    driver said where it could not be reached (a connect given up, a statement left
    unanswered and cut); with its traceback otherwise (a defect). Whether it was not
    reached."""
    from service.store.refusals import database_label, driver_said, unreachable

    if unreachable(exc):
        where = "" if url is None else f" {database_label(url)}"
        logger.warning("%s: the database%s did not answer (%s)", what, where, driver_said(exc))
        return True
    logger.warning(what, exc_info=exc)
    return False


def _broker_label(broker_url: str) -> str:
    """The broker URL as the workers' rows show it: any password masked."""
    from kombu.utils.url import maybe_sanitize_url

    return str(maybe_sanitize_url(broker_url))


def _whole_number(text: str) -> int:
    """An option's whole number as written: ``int`` also takes ``80_80`` as 8080."""
    from inertia_id.checks import parse_whole

    try:
        return parse_whole(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="inertia-id serve",
        description="Run the inertia-id web service (API, dashboard) and its workers on "
        "this machine. Data (SQLite database, broker folders, policies, logs) goes in "
        "--data-dir; DATABASE_URL and BROKER_URL point at PostgreSQL and Redis instead.",
    )
    parser.add_argument(
        "--host",
        default=os.environ.get("INERTIA_ID_HOST", "127.0.0.1"),
        help="Address to bind (default 127.0.0.1, or INERTIA_ID_HOST: 127.0.0.1 is this "
        "machine only; 0.0.0.0 opens it to the network).",
    )
    parser.add_argument(
        "--port",
        type=_whole_number,
        default=None,
        help="TCP port (default 8000, or INERTIA_ID_PORT).",
    )
    parser.add_argument(
        "--data-dir",
        default=os.environ.get("INERTIA_ID_DATA_DIR", "inertia-id-data"),
        help="Folder for the database, broker, policies and logs (default ./inertia-id-data, "
        "or INERTIA_ID_DATA_DIR).",
    )
    parser.add_argument(
        "--workers",
        type=_whole_number,
        default=1,
        help="Worker processes to start, each running one job at a time (default 1; 0 "
        "when workers run elsewhere).",
    )
    parser.add_argument(
        "--api-workers",
        type=_whole_number,
        default=None,
        help="API processes (default 1, or INERTIA_ID_API_WORKERS), each with a verdict "
        "process of its own that computes /identify: on a machine with more cores, more API "
        "processes serve more requests at once (on 2 cores, 2 did worse than 1).",
    )
    parser.add_argument(
        "--log-level",
        default="info",
        choices=["critical", "error", "warning", "info", "debug"],
        help="Log level of the server and workers (default info).",
    )
    return parser


def _settings_for(data_dir: Path, host: str, port: int) -> Settings:
    # Through the environment, so the worker subprocesses read the same settings.
    os.environ["INERTIA_ID_DATA_DIR"] = str(data_dir)
    os.environ["INERTIA_ID_HOST"] = host
    os.environ["INERTIA_ID_PORT"] = str(port)
    get_settings.cache_clear()
    return get_settings()


def _key_line(settings: Settings, generated: str | None) -> str:
    if generated:
        return (
            f"API key:   {generated}\n"
            "           (generated now and stored hashed: it is not shown again; send it as "
            "the X-API-Key header)"
        )
    if settings.api_key:
        return "API key:   the one in INERTIA_ID_API_KEY"
    return (
        "API key:   generated on an earlier run and shown then (stored hashed); to choose "
        "one, set INERTIA_ID_API_KEY"
    )


def _configure_logging(level: str) -> None:
    from uvicorn.logging import DefaultFormatter

    # The same look as uvicorn's own lines ("INFO:     ..."), which follow ours.
    handler = logging.StreamHandler()
    handler.setFormatter(DefaultFormatter("%(levelprefix)s %(message)s"))
    logging.basicConfig(level=level.upper(), handlers=[handler])
    logging.getLogger("alembic").setLevel(logging.WARNING)


def _port_problem(host: str, port: int) -> str | None:
    """Why ``host:port`` cannot be bound, or None. Checked before anything is started or
    a key generated, so a busy port costs nothing."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except OSError as exc:
        return f"cannot resolve --host {host!r}: {exc}"
    family, kind, proto, _name, address = infos[0]
    with socket.socket(family, kind, proto) as sock:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(address)
        except OSError as exc:
            return f"cannot listen on {host}:{port}: {exc.strerror or exc}"
    return None


def _handed_back(settings: Settings) -> Callable[[list[str]], bool]:
    """``names -> bool``: each worker is marked stopping and runs no job any more."""

    def settled(names: list[str]) -> bool:
        from sqlalchemy import func, select

        from service.store.models import JobRow, WorkerRow

        database = _database(settings)
        try:
            with database.session() as session:
                stopping = session.scalar(
                    select(func.count())
                    .select_from(WorkerRow)
                    .where(WorkerRow.name.in_(names), WorkerRow.stopping_since.is_not(None))
                )
                running = session.scalar(
                    select(func.count())
                    .select_from(JobRow)
                    .where(JobRow.worker.in_(names), JobRow.status == "running")
                )
        finally:
            database.dispose()
        return stopping == len(names) and running == 0

    return settled


def tcp_socket(sock: socket.socket) -> socket.socket:
    """``sock`` as a socket object of protocol TCP (``IPPROTO_TCP``, not 0).

    uvicorn makes the listening socket it shares between API processes with protocol 0;
    the connections accepted on it inherit that, and asyncio sets ``TCP_NODELAY`` only
    on sockets whose protocol is TCP. Without it every response (headers and body are
    two writes) waited on the client's delayed ACK: about 40 ms a request with two API
    processes, and none with one (where asyncio makes the socket itself).
    """
    if (
        sock.family in (socket.AF_INET, socket.AF_INET6)
        and sock.type == socket.SOCK_STREAM
        and sock.proto != socket.IPPROTO_TCP
    ):
        inheritable = sock.get_inheritable()
        sock = socket.socket(sock.family, sock.type, socket.IPPROTO_TCP, fileno=sock.detach())
        sock.set_inheritable(inheritable)
    return sock


def _serve_one(config: Any, on_stop: Callable[[], None]) -> None:
    """One API process, this one: uvicorn's server, ``on_stop`` called at its first stop
    signal (SIGTERM, Ctrl-C), before uvicorn gives the requests in flight their grace."""
    import uvicorn

    class Server(uvicorn.Server):
        def handle_exit(self, sig: int, frame: FrameType | None) -> None:
            on_stop()
            super().handle_exit(sig, frame)

    Server(config).run()


def _serve_processes(count: int, options: dict[str, Any], on_stop: Callable[[], None]) -> None:
    """``count`` API processes on one listening socket (uvicorn's multiprocess mode).

    Each process builds its app from the environment :func:`_settings_for` wrote;
    ``on_stop`` is called when the supervisor takes a stop signal, as it tells them to stop.
    """
    from uvicorn.supervisors import Multiprocess

    from .request_deadlines import ServerConfig

    # A ServerConfig reaches each process pickled, its read deadlines with it.
    config = ServerConfig(
        "app.main:create_app", factory=True, workers=count, stop_with=os.getpid(), **options
    )

    class Supervisor(Multiprocess):
        terminated = False

        def handle_term(self) -> None:
            self.terminated = True
            on_stop()
            super().handle_term()

        def handle_int(self) -> None:
            on_stop()
            super().handle_int()

    supervisor = Supervisor(config, sockets=[tcp_socket(config.bind_socket())])
    supervisor.run()
    if supervisor.terminated:
        # uvicorn's supervisor takes SIGTERM itself and returns: serve exited 0 where one
        # API process made it 128 + 15 (uvicorn raises the signal again on its way out).
        raise SystemExit(128 + signal.SIGTERM)


def _temp_folders(*, own: bool) -> LockedFolder | None:
    """Remove the temp folders left by serve processes that are gone (killed: no exit of
    theirs removed them) and their workers; where ``own`` (the API runs in this process),
    make this process's multiprocessing temp folder, the fork server's socket's, locked
    so that a later serve removes it if this one is killed (:mod:`app.temp_folders`).
    The folder, or None: not ``own``, or none made (multiprocessing makes its own)."""
    from .verdicts import SHORT_TEMP_BASES, has_socket_room, say_moved

    temp = tempfile.gettempdir()
    removed = remove_stale([temp, *SHORT_TEMP_BASES])
    if removed:
        logger.info(
            "removed %d temp folder(s) left by serve processes that are gone: %s",
            len(removed),
            ", ".join(removed),
        )
    if not own:
        return None
    # The fork server's socket must fit: where TMPDIR is too long, the folder goes in
    # /tmp (as the verdict process's own would: app.verdicts).
    name = f"{SERVE_PREFIX}XXXXXXXX"
    bases = [temp] if has_socket_room(os.path.join(temp, name)) else []
    bases = bases or [b for b in SHORT_TEMP_BASES if has_socket_room(os.path.join(b, name))]
    problem: OSError | None = None
    for base in bases:
        try:
            folder = make_locked(SERVE_PREFIX, base, owner="serve")
        except OSError as exc:
            problem = problem or exc
            continue
        if not use_for_multiprocessing(folder):
            folder.remove()  # multiprocessing has one already
            return None
        if base != temp:
            say_moved(temp, folder.path)
        return folder
    if problem is not None:
        logger.warning(
            "could not make serve's temp folder (%s): multiprocessing makes its own, which "
            "is left in %s if serve is killed",
            problem,
            temp,
        )
    return None


def _raise_on_sigterm(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def _already_stopping(signum: int, _frame: FrameType | None) -> None:
    """A second SIGTERM or Ctrl-C while serve stops: said, not acted on. Raised out of
    the cleanup, it cut the shutdown short: serve exited with its workers and fork server
    still running (ppid 1) and their jobs not yet handed back."""
    logger.warning(
        "%s while stopping: already stopping (the workers get at most %g s, the processes "
        "left %g s more); kill -9 to force",
        signal.Signals(signum).name,
        STOP_GRACE_S,
        LEFTOVER_GRACE_S,
    )


def _env_whole_numbers(args: argparse.Namespace) -> list[str]:
    """Fill ``--port`` and ``--api-workers`` left out from the environment (or their
    defaults); the problems of values there, one line each naming the variable and the
    value. Read here, not as the parser's defaults: ``INERTIA_ID_PORT=x`` was a
    traceback from building the parser, even with ``--port`` given."""
    problems = []
    for option, name, default in (
        ("port", "INERTIA_ID_PORT", 8000),
        ("api_workers", "INERTIA_ID_API_WORKERS", 1),
    ):
        if getattr(args, option) is not None:
            continue
        text = os.environ.get(name)
        setattr(args, option, default)
        if text is None:
            continue
        try:
            setattr(args, option, _whole_number(text))
        except argparse.ArgumentTypeError as exc:
            problems.append(f"inertia-id serve: {name}={text!r}: {exc}")
    return problems


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    problems = _env_whole_numbers(args)
    if problems:
        print("\n".join(problems), file=sys.stderr)
        return 1
    if args.workers < 0:
        _parser().error(f"--workers must be >= 0, got {args.workers}")
    if args.api_workers < 1:
        _parser().error(f"--api-workers must be >= 1, got {args.api_workers}")
    if not 0 < args.port < 65536:
        _parser().error(f"--port must be 1..65535, got {args.port}")
    problem = _port_problem(args.host, args.port)
    if problem:
        print(f"inertia-id serve: {problem}", file=sys.stderr)
        return 1
    _configure_logging(args.log_level)

    data_dir = Path(args.data_dir).expanduser().resolve()
    try:
        settings = _settings_for(data_dir, args.host, args.port)
    except ValidationError as exc:
        # A setting from the environment that is no value of its type or range: one line
        # each, naming the variable and the value, before anything is created.
        for line in setting_problems(exc):
            print(f"inertia-id serve: {line}", file=sys.stderr)
        return 1
    from service.store.refusals import unusable_database

    problem = unusable_database(settings.resolved_database_url)
    if problem:
        # Before anything starts: a traceback from the first connection before.
        print(f"inertia-id serve: {problem}", file=sys.stderr)
        return 1
    data_dir.mkdir(parents=True, exist_ok=True)

    # SIGTERM (systemd, docker stop) ends like Ctrl-C: through the finally below.
    signal.signal(signal.SIGTERM, _raise_on_sigterm)
    # Orphans among our descendants become our children, stopped at the end.
    subreaper = become_subreaper()

    from sqlalchemy.exc import InterfaceError, OperationalError

    from service.store.refusals import database_label, driver_said
    from service.store.session import DatabaseNewerThanCode, upgrade

    from .main import create_app
    from .request_deadlines import ServerConfig
    from .security import ensure_api_key

    # Once, here, before any API process starts: several would race to generate a key.
    doing = "to migrate it"
    try:
        upgrade(settings.resolved_database_url, silent_after_s=DATABASE_SILENT_S)
        doing = "to check its API key"
        database = _database(settings)
        try:
            generated = ensure_api_key(database, settings)
        finally:
            database.dispose()
    except DatabaseNewerThanCode as exc:
        print(f"inertia-id serve: {exc}", file=sys.stderr)
        return 1
    except (OperationalError, InterfaceError) as exc:
        # One line, nothing started: a traceback before (a refused connection), or no
        # end at all (a silent database).
        print(
            f"inertia-id serve: cannot reach the database "
            f"{database_label(settings.resolved_database_url)} {doing}: {driver_said(exc)}",
            file=sys.stderr,
        )
        return 1

    # Its descriptor (the lock) stays open until this process ends.
    _temp_folders(own=args.api_workers == 1)
    shown_host = f"[{args.host}]" if ":" in args.host else args.host
    url = f"http://{shown_host}:{args.port}"
    pool = WorkerPool(
        args.workers, data_dir / "logs", log_level=args.log_level.upper(), settings=settings
    )
    print(
        f"\ninertia-id service\n"
        f"URL:       {url}   (dashboard; API docs: {url}/docs)\n"
        f"{_key_line(settings, generated)}\n"
        f"Data:      {data_dir}\n"
        f"Workers:   {args.workers} (logs in {pool.log_dir}); API processes: "
        f"{args.api_workers}\n",
        flush=True,
    )
    if args.host not in ("127.0.0.1", "localhost", "::1"):
        logger.warning("listening on %s: reachable from other machines", args.host)
    pool.adopts_orphans = subreaper
    try:
        pool.start()
        # No limit_concurrency: uvicorn counts open connections against it, so slow
        # clients would get every other client a 503; they are closed by the read
        # deadlines instead. The listen backlog stays uvicorn's 2,048.
        options = {
            "host": args.host,
            "port": args.port,
            "log_level": args.log_level,
            "timeout_graceful_shutdown": API_GRACE_S,
            "request_head_timeout_s": settings.request_head_timeout_s,
            "request_body_timeout_s": settings.request_body_timeout_s,
            "request_header_max_count": settings.request_header_max_count,
            "request_header_max_bytes": settings.request_header_max_bytes,
        }
        # The workers are told to stop at the signal, while uvicorn gives the API's
        # requests their grace (API_GRACE_S); the finally below waits for them.
        if args.api_workers == 1:
            _serve_one(ServerConfig(create_app(settings), **options), pool.request_stop)
        else:
            _serve_processes(args.api_workers, options, pool.request_stop)
    except KeyboardInterrupt:
        pass
    finally:
        # Bounded from here on (STOP_GRACE_S, then LEFTOVER_GRACE_S): a second signal
        # must not raise out of it.
        signal.signal(signal.SIGTERM, _already_stopping)
        signal.signal(signal.SIGINT, _already_stopping)
        if args.workers:
            print("stopping workers (a running job goes back to the queue) ...", flush=True)
        pool.stop(settled=_handed_back(settings))
        if args.workers:
            print("workers stopped", flush=True)
        if subreaper:
            _leave_no_process()
    return 0


if __name__ == "__main__":
    sys.exit(main())
