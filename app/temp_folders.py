"""Temp folders of serve's processes that a later serve can tell from a live one's.

multiprocessing keeps a process's temp files (the fork server's socket, billiard's shared
memory) in a folder it makes in ``TMPDIR`` (``pymp-*``) and removes at the process's
normal exit. A process killed (``kill -9`` of serve; a worker killed with it) runs no
exit: its folder stayed for good, and nothing told it from the folder of a process
still running (another serve beside, any other Python program).

serve makes its own folder (``pymp-XXXXXXXX``, as multiprocessing names it: the fork
server's socket goes in it, and a longer name would leave less of AF_UNIX's 107 bytes
to ``TMPDIR``) and each of its workers' (``inertia-id-worker<i>-XXXXXXXX``), and in each
a file :data:`MARKER` that says whose it is. It locks each folder (``flock``), before the
file is written, with a descriptor that the processes using the folder hold open for
their lives: serve its own, and a worker the one it inherits (serve keeps its copy until
it removes the folder). The kernel lets a lock go when the last process holding it
ends, however it ends. At its start serve removes every folder of those names, of its
user, that holds the file and that no process holds locked (:func:`remove_stale`): a
dead process's. A live one's (another serve beside, or the worker of a killed serve
still handing its job back) is locked; another user's is theirs; a folder without the
file is another program's (a ``pymp-*`` of any Python process, a worker folder of a
serve from before these locks): all are kept.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "MARKER",
    "SERVE_PREFIX",
    "LockedFolder",
    "make_locked",
    "remove_stale",
    "use_for_multiprocessing",
    "worker_prefix",
]

#: serve's own folder: ``<TMPDIR>/pymp-XXXXXXXX``.
SERVE_PREFIX = "pymp-"
#: The file in each folder made here that marks it as serve's.
MARKER = "inertia-id-serve"
#: The names of the folders made here (``tempfile.mkdtemp``'s 8 characters last).
_NAME = re.compile(r"(?:pymp|inertia-id-worker[0-9]+)-[a-z0-9_]{8}")


def worker_prefix(index: int) -> str:
    """The name of worker ``index``'s folder, less its random end."""
    return f"inertia-id-worker{index}-"


@dataclass(frozen=True)
class LockedFolder:
    """A folder made by :func:`make_locked`, and the descriptor open on it that holds
    its lock (close-on-exec: handed to a worker through ``Popen(pass_fds=...)``)."""

    path: str
    fd: int

    def remove(self) -> None:
        """Remove the folder, then let its lock go (its users have ended)."""
        shutil.rmtree(self.path, ignore_errors=True)
        with contextlib.suppress(OSError):
            os.close(self.fd)


def _lock(path: str) -> int | None:
    """A descriptor open on the folder ``path`` holding its lock, or None where another
    process holds it. OSError: it cannot be opened or locked (gone, not a folder, a file
    system without locks)."""
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            return None
        raise
    return fd


def make_locked(prefix: str, base: str | None = None, *, owner: str) -> LockedFolder:
    """A new folder ``<base>/<prefix>XXXXXXXX`` (base: ``TMPDIR``), mode 0700, locked and
    marked (:data:`MARKER`, which names ``owner``); OSError where none can be made or
    locked (then none is left). No other serve removes it meanwhile: it looks only at
    folders marked, and the mark comes after the lock."""
    path = tempfile.mkdtemp(prefix=prefix, dir=base)
    try:
        fd = _lock(path)
        if fd is None:  # no one else knows of it: not expected
            raise OSError(errno.EWOULDBLOCK, f"{path} is locked already")
    except OSError:
        shutil.rmtree(path, ignore_errors=True)
        raise
    folder = LockedFolder(path, fd)
    try:
        with open(os.path.join(path, MARKER), "x", encoding="utf-8") as marker:
            marker.write(
                f"{owner}: multiprocessing's temp files, made by inertia-id serve (pid "
                f"{os.getpid()}); a later serve removes this folder once no process holds "
                "it locked (flock)\n"
            )
    except OSError:
        folder.remove()
        raise
    return folder


def remove_stale(bases: Iterable[str]) -> list[str]:
    """Remove the folders of :func:`make_locked` in ``bases`` (their names, their
    :data:`MARKER`) that belong to this user and that no process holds locked: those of
    processes that have ended. The paths removed. Nothing raises: a folder that cannot
    be looked at is left."""
    uid = os.geteuid()
    removed = []
    for base in dict.fromkeys(bases):
        try:
            entries = list(os.scandir(base))
        except OSError:
            continue
        for entry in entries:
            if not _NAME.fullmatch(entry.name):
                continue
            try:
                if not entry.is_dir(follow_symlinks=False):
                    continue
                if entry.stat(follow_symlinks=False).st_uid != uid:
                    continue  # another user's: theirs to remove
                marker = os.lstat(os.path.join(entry.path, MARKER))
                if not stat.S_ISREG(marker.st_mode):
                    continue
                fd = _lock(entry.path)
            except OSError:
                continue
            if fd is None:
                continue  # held: a live process's
            try:
                shutil.rmtree(entry.path, ignore_errors=True)
            finally:
                os.close(fd)
            if not os.path.lexists(entry.path):
                removed.append(entry.path)
    return removed


def use_for_multiprocessing(folder: LockedFolder) -> bool:
    """Take ``folder`` as this process's multiprocessing temp folder (where it would make
    ``pymp-*``), removed at this process's normal exit as that one is; whether it was
    taken (not where multiprocessing has a folder already)."""
    from multiprocessing import process, util

    # What multiprocessing.util.get_temp_dir does with the folder it makes (private
    # names of CPython's, read with getattr: without them nothing is taken).
    config = getattr(process.current_process(), "_config", None)
    remove = getattr(util, "_remove_temp_dir", None)
    if not isinstance(config, dict) or remove is None or config.get("tempdir") is not None:
        return False
    config["tempdir"] = folder.path
    util.Finalize(None, remove, args=(shutil.rmtree, folder.path), exitpriority=-100)
    return True
