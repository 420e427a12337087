"""Worker processes that start warm and never outlive their parents.

- **Warm task processes**: a Celery worker's task process imports the science core
  (torch, numba, tslearn: seconds) once, when it starts, and then runs job after job;
  a job pays no import (:func:`worker.runner.warm_up` on ``worker_process_init``).
- **No orphans**: a task process is killed when its worker dies (``PR_SET_PDEATHSIG``),
  and a worker started by ``inertia-id serve`` is told to stop (SIGTERM: it hands its
  job back) when serve dies, even by ``kill -9``. serve names itself in
  :data:`PARENT_PID_ENV`; a worker whose parent is already gone at start stops at once.
- **Unique names**: a worker left with Celery's default name, ``celery@<host>`` (the
  docker-compose command gives none), gets a token in it, like serve's workers: two
  workers on one host, or a container restarted in place, never share a ``workers`` row,
  so each is counted, and a dead one's job is reaped as soon as its own name goes quiet.
- **A stopping worker starts nothing**: once told to stop, a worker's consumer may still
  hand its task process a message (Celery leaves its loop only after the current poll;
  the job it just handed back, re-sent, is the likeliest). :func:`stopping`, a flag the
  main process raises and its task processes read, makes them leave such a job to
  another worker instead of running it until they are killed.
- **No temp folder left**: the folder of multiprocessing's temp files (billiard's pool
  makes one for its shared memory when it starts the task process) is one that serve
  made for this worker (:data:`TEMP_DIR_ENV`, :func:`use_launcher_temp_dir`): serve
  kills its worker once its job is handed back, so the worker's own exit, which would
  remove the folder, never runs; serve removes it once the worker is gone.
"""

from __future__ import annotations

import ctypes
import logging
import mmap
import os
import secrets
import shutil
import signal
import struct
import sys
import time
from typing import Any

from billiard.pool import DEATH as _DEATH
from celery.signals import celeryd_init, worker_process_init, worker_ready
from celery.utils.nodenames import default_nodename

__all__ = [
    "PARENT_PID_ENV",
    "TEMP_DIR_ENV",
    "cold_since",
    "die_with_parent",
    "mark_starting",
    "mark_stopping",
    "mark_warm",
    "stop_with_launcher",
    "stopping",
    "unique_name",
    "use_launcher_temp_dir",
    "warm",
]

logger = logging.getLogger(__name__)

#: Set by ``inertia-id serve`` to its pid in the environment of the workers it starts.
PARENT_PID_ENV = "INERTIA_ID_PARENT_PID"
#: Set by ``inertia-id serve`` to a folder it made for the worker: multiprocessing's temp
#: folder in the worker's main process (see :func:`use_launcher_temp_dir`).
TEMP_DIR_ENV = "INERTIA_ID_WORKER_TEMP_DIR"

_PR_SET_PDEATHSIG = 1

# One shared byte, mapped when the worker's main process imports this module: the task
# processes it forks later share the page, so a flag raised by the main process is seen
# by them at once.
_STOPPING = mmap.mmap(-1, 1)
# The pid of each warm task process, in its pool slot (billiard's process index), written
# by the task process once it has imported the core: the worker's row then says it is
# warm, and the re-sender counts it idle. Before, a job sent to it would wait for the
# imports, and the re-sender would take it for a worker that lost a message. A pid, not a
# flag: a task process killed outright (kill -9, the kernel's OOM killer) cannot lower a
# flag, and its replacement warms up for seconds; meanwhile the worker can run no job and
# must not be reported as able to.
_WARM_SLOTS = 64
_PID = struct.Struct("i")
_WARM = mmap.mmap(-1, _PID.size * _WARM_SLOTS)
# Since when (s since the epoch; 0: not) the worker has had no warm task process: set by
# a task process that starts while none is warm (the last one retired after its jobs or
# its memory limit, or was killed), kept by another that starts in its place before
# warming up (Celery kills one that takes too long), cleared by the first to be warm. The
# main process beats only every few seconds: a warm-up, a job and the next warm-up can
# all fall between two beats, and each warm-up is then dated from its own start, not
# from the beat that first saw the worker warming.
_SINCE = struct.Struct("d")
_COLD_SINCE = mmap.mmap(-1, _SINCE.size)


def _slot_offset() -> int:
    from billiard.process import current_process

    index = getattr(current_process(), "index", 0)
    return _PID.size * (int(index or 0) % _WARM_SLOTS)


def mark_starting() -> None:
    """In a task process, before its warm-up: the worker is cold from now unless a warm
    task process is left, or it was cold already."""
    if not warm() and _SINCE.unpack_from(_COLD_SINCE)[0] == 0.0:
        _SINCE.pack_into(_COLD_SINCE, 0, time.time())


def mark_warm() -> None:
    """In a task process: the core is imported and the kernels compiled."""
    _PID.pack_into(_WARM, _slot_offset(), os.getpid())
    _SINCE.pack_into(_COLD_SINCE, 0, 0.0)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except (ProcessLookupError, PermissionError):
        return False
    return True


def warm() -> bool:
    """Whether a live task process of this worker has warmed up."""
    return any(pid and _alive(pid) for (pid,) in _PID.iter_unpack(_WARM))


def cold_since() -> float | None:
    """When (s since the epoch) this worker's task process now warming up, or the first
    of those that started in turn, started, as none was warm; None when there is a warm
    one, or when the replacement has not started yet."""
    if warm():
        return None
    since = float(_SINCE.unpack_from(_COLD_SINCE)[0])
    return since or None


def mark_stopping() -> None:
    """In the worker's main process: this worker was told to stop."""
    _STOPPING[0] = 1


def stopping() -> bool:
    """Whether this worker (the main process, or the one that forked this task process)
    was told to stop."""
    return _STOPPING[0] == 1


def die_with_parent(sig: int) -> bool:
    """Have the kernel send ``sig`` to this process when its parent dies (Linux only).

    Returns whether that could be arranged.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return bool(libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0)
    except (OSError, AttributeError):
        return False


def stop_with_launcher() -> None:
    """In a worker's main process started by serve: SIGTERM ourselves when serve dies."""
    expected = os.environ.get(PARENT_PID_ENV)
    if not expected:
        return
    die_with_parent(signal.SIGTERM)
    # serve may have died between starting us and the prctl above.
    if str(os.getppid()) != expected:
        logger.warning("the serve process %s is gone; stopping", expected)
        os.kill(os.getpid(), signal.SIGTERM)


def use_launcher_temp_dir() -> bool:
    """In a worker's main process started by serve: take the folder serve made for it
    (:data:`TEMP_DIR_ENV`) as multiprocessing's temp folder, the one it would otherwise
    make as ``pymp-*`` in ``TMPDIR``; whether it was taken.

    serve kills the worker (SIGKILL to its group) once its job is handed back rather
    than wait seconds for Celery to wind its pool down, so the worker's exit, which
    removes that folder, never ran: every stop left an empty ``pymp-*`` folder. serve
    knows this one and removes it once the worker is gone. A worker that exits by
    itself (serve killed, and this worker told to stop by the kernel) removes it as
    multiprocessing removes its own, at a normal exit. Nothing is removed here: the
    process that takes the folder is the one whose exit, or death, ends its use.
    """
    folder = os.environ.pop(TEMP_DIR_ENV, None)
    if not folder or not os.path.isdir(folder):
        return False
    from multiprocessing import process, util

    # What multiprocessing.util.get_temp_dir does with the folder it makes (private
    # names of CPython's, read with getattr: without them, multiprocessing makes its own
    # folder, as before, and serve removes the empty one it made).
    config = getattr(process.current_process(), "_config", None)
    remove = getattr(util, "_remove_temp_dir", None)
    if not isinstance(config, dict) or remove is None or config.get("tempdir") is not None:
        return False
    config["tempdir"] = folder
    util.Finalize(None, remove, args=(shutil.rmtree, folder), exitpriority=-100)
    return True


def unique_name(name: str) -> str:
    """``name``, or Celery's default ``celery@<host>`` made unique: ``celery-3fa2c1@<host>``."""
    if name != default_nodename(None):
        return name
    prefix, _, host = name.partition("@")
    return f"{prefix}-{secrets.token_hex(3)}@{host}"


@celeryd_init.connect
def _unique_default_name(instance: Any = None, **_kwargs: Any) -> None:
    # Sent before the worker sets up its consumer and pool, which take the name from it.
    if instance is not None and getattr(instance, "hostname", None):
        instance.hostname = unique_name(instance.hostname)


@worker_process_init.connect
def _task_process_started(**_kwargs: Any) -> None:
    # A task process left behind by a worker that was killed would run on unsupervised.
    die_with_parent(signal.SIGKILL)
    mark_starting()
    from .runner import warm_up

    try:
        warm_up()
    except Exception:
        # The job itself then fails with the reason (see runner._broken_handlers).
        logger.exception("could not warm up the task process")
    finally:
        mark_warm()


#: How long the pool's result thread waits for the result queue's lock before it
#: signals a task process that said it is exiting (see below); a few ms in practice.
DEATH_LOCK_WAIT_S = 5.0


@worker_ready.connect
def _signal_an_exiting_task_process_once_it_let_go_of_the_results(
    sender: Any = None, **_kwargs: Any
) -> None:
    # A task process that exits (told to stop: SIGTERM) writes "DEATH" to the pool's result
    # queue holding the queue's write lock, with SIGTERM blocked; the pool's result thread
    # reads it at once and sends the process SIGTERM. billiard blocks the signal in that
    # process's main thread only: the task processes also have threads (the core's
    # numerical libraries start them), the kernel gave the signal to one of those, and
    # its default action ended the whole process before it let go of the lock. On the
    # filesystem broker (billiard's threaded pool) the pool's close then waits on that
    # lock for ever: the worker stayed in "Warm shutdown" with its task process gone (by
    # hand, SIGTERM to the worker's process group, idle: 2 stops of 30 at 2871866, 6 of 30
    # at 1eccec1, 0 of 30 after; strace showed the pool's SIGTERM sent by the
    # worker 4 ms after the first). The result thread now waits for the lock to be free
    # (a few ms) before it signals the process.
    pool = getattr(getattr(sender, "pool", None), "_pool", None)
    handlers = getattr(getattr(pool, "_result_handler", None), "state_handlers", None)
    lock = getattr(getattr(pool, "_outqueue", None), "_wlock", None)
    if not isinstance(handlers, dict) or lock is None or _DEATH not in handlers:
        return
    signal_it = handlers[_DEATH]

    def on_death(pid: int, exitcode: int) -> None:
        if lock.acquire(True, DEATH_LOCK_WAIT_S):
            lock.release()
        signal_it(pid, exitcode)

    handlers[_DEATH] = on_death


def _release_if_held(lock: Any) -> bool:
    """Release ``lock`` (a multiprocessing lock) if someone holds it; whether it was held."""
    if lock.acquire(False):
        lock.release()
        return False
    lock.release()
    return True


@worker_ready.connect
def _free_the_queue_a_killed_task_process_held(sender: Any = None, **_kwargs: Any) -> None:
    # On a broker without an event loop (the filesystem broker), Celery runs billiard's
    # plain pool: its task processes share one job queue, and an idle one waits for a job
    # holding the queue's read lock. Killed outright there (kill -9, the OOM killer), it
    # never releases it, and every task process started in its place waits on the lock
    # for ever: the worker beats but runs no job again. With one task process (the
    # shipped --concurrency=1) a dead one's lock can be held by nobody else, so it is
    # released when the pool sees it dead, before the pool starts the replacement.
    pool = getattr(getattr(sender, "pool", None), "_pool", None)
    lock = getattr(getattr(pool, "_inqueue", None), "_rlock", None)
    if pool is None or lock is None or getattr(pool, "_processes", 0) != 1:
        return
    flush = pool.process_flush_queues

    def process_flush_queues(process: Any) -> None:
        flush(process)
        exitcode = getattr(process, "exitcode", None)
        if exitcode is not None and exitcode < 0 and _release_if_held(lock):
            logger.warning(
                "released the job queue's lock held by killed task process %s", process.pid
            )

    pool.process_flush_queues = process_flush_queues
