"""Files written whole or not at all."""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Callable
from typing import BinaryIO

__all__ = ["NotWritten", "write_whole"]


class NotWritten(OSError):
    """A write that failed, leaving the path as it was: one line naming the path (its
    ``filename``) and the reason, however far up it is caught (the CLI prints it as it
    is; ``[Errno 27] File too large: 'classifier.json'`` said neither that the write
    failed nor what became of the file)."""

    def __str__(self) -> str:
        return (
            f"could not write {self.filename}: {self.strerror}; nothing was written there "
            "(a file it held before is left as it was)"
        )


def write_whole(
    path: str | os.PathLike[str], data: str | bytes | Callable[[BinaryIO], None]
) -> None:
    """Write ``data`` (text as UTF-8, bytes, or a function that writes to the open file)
    to ``path`` whole or not at all: into a file beside it, flushed, then renamed over it.

    Written in place, a write that failed part-way (a full disk, a file-size limit) left a
    truncated file under the name asked for: a command plan cut after its first 2 KiB, a
    classifier document cut mid-JSON. Now the path keeps what it held before (nothing, or
    the earlier file). A device or pipe (``/dev/stdout``) is written directly: renaming
    over it would replace the device. The standard library has no atomic write, and
    ``atomicwrites``, the package that had one, is archived.

    :raises NotWritten: the write failed; its ``filename`` is ``path``.
    :raises OSError: a device's write failed.
    """
    if os.path.exists(path) and not os.path.isfile(path):
        with open(path, "wb") as handle:
            _write_to(handle, data)
        return
    # Through a symbolic link, the file it names is replaced, not the link.
    target = os.path.realpath(path)
    folder, name = os.path.split(target)
    part = os.path.join(folder, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.part")
    try:
        # Mode 0o666 less the umask, as open() gives the file itself.
        fd = os.open(part, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        with os.fdopen(fd, "wb") as handle:
            _write_to(handle, data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(part, target)
    except OSError as exc:
        with contextlib.suppress(OSError):
            os.remove(part)
        raise NotWritten(exc.errno, exc.strerror or str(exc), os.fspath(path)) from None


def _write_to(handle: BinaryIO, data: str | bytes | Callable[[BinaryIO], None]) -> None:
    if isinstance(data, str):
        handle.write(data.encode("utf-8"))
    elif isinstance(data, bytes):
        handle.write(data)
    else:
        data(handle)
