"""Identify in a process of its own, beside the API's event loop.

A verdict is about 1.6 ms of small numpy work that holds the GIL; the HTTP side of the
same request (parsing, validation, the key check, the response) is about 2 ms more. In
one process the two take turns on one core: with the event loop and the computation
sharing the GIL, one API process served about 200 requests a second at 20 clients
(queued 100 ms deep). Here the computation runs in a child process, so the API's two
halves use two cores.

The child is a :class:`concurrent.futures.ProcessPoolExecutor` of one process, forked
from multiprocessing's fork server (not from the API process, which has threads): the
fork server, started with the first verdict process, imports the core and compiles its
kernels once (:mod:`app.verdict_preload`), so a replacement child is ready in a fraction
of a second rather than after another 3 s of imports. It keeps its own classifier cache by
(id, checksum) and reads a classifier's document from the database itself on a miss;
the API sends it the id, the checksum it looked up, the validated telemetry and the
:class:`VerdictOptions`, and gets back the verdict as a dict. If the child dies, the next request
starts another (that request is answered 503 with Retry-After). It ends with the API process:
a watchdog thread exits it when the API process is gone, however it ended (``kill -9``
included); the fork server itself exits when the API process's end of its pipe closes.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from inertia_id.evaluation.telemetry import Telemetry
    from service.store.session import Database

    from .classifier_cache import ClassifierCache

__all__ = [
    "SHORT_TEMP_BASES",
    "NotFound",
    "VerdictOptions",
    "VerdictProcess",
    "has_socket_room",
    "say_moved",
]

log = logging.getLogger("inertia_id.api")

#: How often the child checks that the API process is still there.
_WATCH_S = 0.5

#: The module the fork server imports before it forks any verdict process.
_PRELOAD = "app.verdict_preload"


class NotFound(LookupError):
    """The classifier id names no stored classifier (the child's answer; the API says 404)."""


@dataclass(frozen=True)
class VerdictOptions:
    """What a request asks of its verdict, as ``identify`` and ``identify_online`` take it.

    :param confidence: posterior the top candidate needs (default 0.99); for a partial
        verdict the stop rule's ``alpha`` is ``1 - confidence`` (default 0.001).
    :param pre_start_window_s: seconds of telemetry before the start that measure the
        rate plus gyro bias there (default 30; 0 ignores them).
    :param estimate_start_within_s: search the starts within this many seconds of the
        stated one for the best fit (full verdicts only); None: the stated start.
    """

    confidence: float | None = None
    pre_start_window_s: float | None = None
    estimate_start_within_s: float | None = None

    def keywords(self, *, partial: bool) -> dict[str, Any]:
        from inertia_id.evaluation.identify import (
            DEFAULT_ALPHA,
            DEFAULT_CONFIDENCE,
            DEFAULT_PRE_START_WINDOW_S,
        )

        window = self.pre_start_window_s
        out: dict[str, Any] = {
            "pre_start_window_s": DEFAULT_PRE_START_WINDOW_S if window is None else window
        }
        if partial:
            out["alpha"] = DEFAULT_ALPHA if self.confidence is None else 1.0 - self.confidence
        else:
            out["confidence"] = DEFAULT_CONFIDENCE if self.confidence is None else self.confidence
            out["estimate_start_within_s"] = self.estimate_start_within_s
        return out


# --------------------------------------------------------------------------- the child

_cache: ClassifierCache | None = None
_database: Database | None = None


def _api_gone(api: int, fork_server: int) -> bool:
    """True once the API process has ended: the fork server this process was forked
    from has gone (it ends when the API does, so this process is adopted elsewhere), or
    the API process itself no longer exists."""
    if os.getppid() != fork_server:
        return True
    try:
        os.kill(api, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # a process of another user took the number: ours is gone
        return True
    return False


def _watch_api(api: int, fork_server: int) -> None:
    while True:
        time.sleep(_WATCH_S)
        if _api_gone(api, fork_server):
            os._exit(0)


def _initialise(database_url: str, cache_size: int, api: int) -> None:
    global _cache, _database
    # Ctrl-C reaches the whole process group: the API shuts this process down itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_api, args=(api, os.getppid()), daemon=True).start()
    # One BLAS thread: the process computes one verdict at a time, on one core.
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    from service.store.session import Database

    from .classifier_cache import ClassifierCache

    _cache = ClassifierCache(cache_size)
    _database = Database(database_url)  # connects on the first cold classifier
    # The classifier kinds (scikit-learn) and numba's kernels, before the first request
    # (loaded already by the fork server's preload; this is the fallback should it fail).
    from inertia_id import warm_up
    from inertia_id.classifiers import registry  # noqa: F401

    warm_up()


def _document(classifier_id: str) -> str:
    from sqlalchemy import select

    from service.store.models import ClassifierRow

    assert _database is not None, "the verdict process was not initialised"
    with _database.session() as session:
        document = session.scalar(
            select(ClassifierRow.document).where(ClassifierRow.id == classifier_id)
        )
    if document is None:
        raise NotFound(classifier_id)
    return str(document)


def _verdict(
    classifier_id: str,
    checksum: str,
    telemetry: Telemetry,
    options: VerdictOptions,
    partial: bool,
) -> dict[str, Any]:
    from inertia_id.classifiers.registry import classifier_from_json
    from inertia_id.evaluation.identify import identify, identify_online

    assert _cache is not None, "the verdict process was not initialised"
    classifier = _cache.get(
        (classifier_id, checksum), lambda: classifier_from_json(_document(classifier_id))
    )
    judge = identify_online if partial else identify
    return judge(classifier, telemetry, **options.keywords(partial=partial)).model_dump()


def _ready() -> bool:
    return _cache is not None


def _loads() -> int:
    return _cache.loads if _cache is not None else 0


# --------------------------------------------------------------------------- the API side


#: Longest path an AF_UNIX socket may be bound at (Linux's ``sun_path`` is 108 bytes,
#: its terminating NUL included; BSDs' 104).
_SOCKET_PATH_MAX = 107 if sys.platform.startswith("linux") else 103
#: The fork server's socket, as multiprocessing names it in its temp folder
#: (``<TMPDIR>/pymp-XXXXXXXX/listener-XXXXXXXX``).
_SOCKET_NAME = "/listener-XXXXXXXX"
#: Where a short temp folder is made instead when TMPDIR is too long for it: the folders
#: CPython 3.14's multiprocessing falls back to in that case (gh-132124).
SHORT_TEMP_BASES = ("/tmp", "/var/tmp", "/usr/tmp")


def has_socket_room(folder: str) -> bool:
    """Whether the fork server's socket fits in the temp folder ``folder`` (a folder of
    mkdtemp's: its random end as long as ``XXXXXXXX``)."""
    return len(os.fsencode(folder)) + len(_SOCKET_NAME) <= _SOCKET_PATH_MAX


def say_moved(base: str, folder: str) -> None:
    """Log that this process's temp folder is ``folder`` rather than one in ``base``
    (``TMPDIR``), too long for the fork server's socket."""
    log.warning(
        "TMPDIR is too long for the verdict process's fork server socket (%d bytes: "
        "its socket's path would pass AF_UNIX's %d): its temp folder is %s instead "
        "(TMPDIR=%s)",
        len(os.fsencode(base)),
        _SOCKET_PATH_MAX,
        folder,
        base,
    )


def _socket_ready_temp_dir() -> str | None:
    """Make multiprocessing's temp folder of this process one where the fork server's
    socket fits, if TMPDIR is too long for it; the folder made, or None (none needed, or
    none could be made: logged).

    The fork server listens on an AF_UNIX socket in multiprocessing's temp folder, made
    in TMPDIR; past about 75 characters of TMPDIR its path passes what AF_UNIX takes and
    no verdict process could start (``OSError: AF_UNIX path too long``: every
    ``/identify`` was a 500). As Python 3.14 does (3.11 does not), the folder is made in
    ``/tmp`` then, said in the log, and removed at this process's exit as
    multiprocessing's own is (its finalizer); nothing else of this process's temp files
    moves. Nothing is done where the folder already in use, or the one TMPDIR gives,
    has room for the socket (the tests' processes, a usual TMPDIR).
    """
    from multiprocessing import process, util

    config = getattr(process.current_process(), "_config", None)
    remove = getattr(util, "_remove_temp_dir", None)
    if not isinstance(config, dict) or remove is None:
        return None  # not CPython's multiprocessing as we know it: left as it is
    current = config.get("tempdir")
    base = os.path.dirname(current) if current else tempfile.gettempdir()
    if has_socket_room(current or os.path.join(base, "pymp-XXXXXXXX")):
        return None
    for short_base in SHORT_TEMP_BASES:
        if not has_socket_room(os.path.join(short_base, "pymp-XXXXXXXX")):
            continue
        try:
            folder = tempfile.mkdtemp(prefix="pymp-", dir=short_base)
        except OSError:
            continue
        # What multiprocessing.util.get_temp_dir does with the folder it makes. One made
        # in TMPDIR already stays with its own finalizer: what is in it is still used.
        config["tempdir"] = folder
        util.Finalize(None, remove, args=(shutil.rmtree, folder), exitpriority=-100)
        say_moved(base, folder)
        return folder
    log.error(
        "TMPDIR is too long for the verdict process's fork server socket (%d bytes) and "
        "no temp folder could be made in %s: /identify cannot start its verdict process "
        "(set TMPDIR to a shorter folder; TMPDIR=%s)",
        len(os.fsencode(base)),
        " or ".join(SHORT_TEMP_BASES),
        base,
    )
    return None


def _fork_server() -> multiprocessing.context.ForkServerContext:
    """multiprocessing's forkserver context with :mod:`app.verdict_preload` preloaded.

    The fork server is one per API process, started with the first verdict process and
    reused by every later one (and by every app a test process builds). Its socket goes
    in a short temp folder where TMPDIR is too long for it (:func:`_socket_ready_temp_dir`).
    """
    _socket_ready_temp_dir()
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([_PRELOAD])
    return context


class VerdictProcess:
    """The child process that computes verdicts, started on first use or by :meth:`start`.

    :param database_url: where the child reads classifier documents.
    :param cache_size: classifiers the child keeps.
    :param timeout_s: longest wait for one verdict; past it the child is killed (a hung
        child would otherwise hold its requests, and every later one, for good).
    """

    def __init__(self, database_url: str, cache_size: int, *, timeout_s: float = 30.0) -> None:
        self.database_url = database_url
        self.cache_size = cache_size
        self.timeout_s = timeout_s
        self._pool: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()
        self._closed = False
        self.restarts = 0

    def _executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._closed:
                raise RuntimeError("the verdict process was closed with the API")
            if self._pool is None:
                self._pool = ProcessPoolExecutor(
                    max_workers=1,
                    mp_context=_fork_server(),
                    initializer=_initialise,
                    initargs=(self.database_url, self.cache_size, os.getpid()),
                )
            return self._pool

    def start(self) -> None:
        """Spawn the child and warm it (imports, kernels) in the background; nothing once
        the API has closed it (a warm-up thread may come late)."""
        # RuntimeError: closed (or the interpreter is exiting); nothing to start then.
        with contextlib.suppress(RuntimeError):
            self._executor().submit(_ready)

    async def verdict(
        self,
        classifier_id: str,
        checksum: str,
        telemetry: Telemetry,
        options: VerdictOptions,
        partial: bool = False,
    ) -> dict[str, Any]:
        """The verdict as :func:`~inertia_id.evaluation.identify.identify` (or
        ``identify_online``) dumps it; :class:`NotFound` for an unknown id; a child that
        died is replaced and the request answered 503."""
        from .capacity import Overloaded

        try:
            pool = self._executor()
        except RuntimeError:
            raise Overloaded("the service is stopping", 1.0) from None
        loop = asyncio.get_running_loop()
        try:
            return await asyncio.wait_for(
                loop.run_in_executor(
                    pool, _verdict, classifier_id, checksum, telemetry, options, partial
                ),
                self.timeout_s,
            )
        except TimeoutError:
            log.error("a verdict took over %g s: the verdict process is killed", self.timeout_s)
            self._replace(pool, kill=True)
            raise Overloaded(
                f"the verdict took over {self.timeout_s:g} s; the verdict process is restarting",
                2.0,
            ) from None
        except BrokenProcessPool:
            log.error("the verdict process died; a new one is starting")
            self._replace(pool)
            raise Overloaded("the verdict process is restarting", 2.0) from None

    def _replace(self, pool: ProcessPoolExecutor, *, kill: bool = False) -> None:
        """Drop ``pool`` (killing its process first if asked: the executor cannot stop a
        running call) and start the next one, once however many requests saw it fail."""
        with self._lock:
            if self._pool is not pool:
                return
            self._pool = None
            self.restarts += 1
        if kill:
            for process in list(getattr(pool, "_processes", {}).values()):
                with contextlib.suppress(ProcessLookupError):
                    os.kill(process.pid, signal.SIGKILL)
        pool.shutdown(wait=False, cancel_futures=True)
        self.start()

    def pid(self) -> int:
        """The child's process id (starting it if need be)."""
        return int(self._executor().submit(os.getpid).result())

    def loads(self) -> int:
        """Classifier documents the child has loaded (one per cold classifier)."""
        return self._executor().submit(_loads).result()

    def close(self) -> None:
        with self._lock:
            pool, self._pool = self._pool, None
            self._closed = True
        if pool is not None:
            # Joined, so that no verdict process outlives the API's shutdown (a verdict
            # takes milliseconds; a child still warming up finishes that first).
            pool.shutdown(wait=True, cancel_futures=True)
