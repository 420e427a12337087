"""Files written whole or not at all."""

from __future__ import annotations

import contextlib
import io
import os
import secrets
import stat
from collections.abc import Callable
from typing import Any, BinaryIO, cast

__all__ = ["NotWritten", "write_whole"]


class NotWritten(OSError):
    """A write that failed: one line naming the path (its ``filename``), the reason and
    what became of the path, however far up it is caught (the CLI prints it as it is;
    ``[Errno 27] File too large: 'classifier.json'`` said neither that the write failed
    nor what became of the file).

    A file is written beside the path and renamed over it, so a failed write leaves it as
    it was. A device or pipe is written directly (``written`` is then the bytes it took
    before the write failed, ``size`` the bytes meant for it): a pipe whose reader stops
    after 100 bytes has taken a pipe buffer's worth, which no message may call nothing.
    """

    #: What the path is, for a device or pipe written directly ("a pipe", "a device"); None
    #: for a file written beside it and renamed.
    direct: str | None = None
    written = 0
    size = 0

    def __str__(self) -> str:
        head = f"could not write {self.filename}: {self.strerror}"
        if self.direct is None:
            return f"{head}; nothing was written there (a file it held before is left as it was)"
        if self.written == 0:
            return f"{head}; nothing was written to it ({self.direct}, written directly)"
        return (
            f"{head}; the first {self.written} of {self.size} bytes went to it before the "
            f"write failed ({self.direct}, written directly): what it got is incomplete"
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

    :raises NotWritten: the write failed; its ``filename`` is ``path``, and for a device
        or pipe, how many bytes it took.
    """
    if os.path.exists(path) and not os.path.isfile(path):
        _write_directly(path, data)
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
    except BaseException:
        # Any other stop (Ctrl-C, a writer function that raised) leaves nothing beside
        # the path either: it had left the part file, as large as what was written.
        with contextlib.suppress(OSError):
            os.remove(part)
        raise


#: The most bytes held at once on the way to a device or pipe, and the size of each piece
#: of text encoded for any file: a write had encoded the whole text (a classifier document
#: of hundreds of MB) and, for a device or pipe, copied it once more into a buffer first.
CHUNK_BYTES = 1 << 20


class _DirectWriter(io.RawIOBase):
    """A device or pipe's descriptor as a file, written in the pieces it is handed,
    counting the bytes it takes (a buffered file object does not tell). After a failed
    write it takes the rest without sending it, only counting, so that the failure can say
    how many of how many bytes went."""

    def __init__(self, fd: int) -> None:
        super().__init__()
        self.fd = fd
        self.written = 0
        self.size = 0
        self.failure: OSError | None = None
        # Set when the data's maker raised: what is still buffered is not sent.
        self.stopped = False

    def writable(self) -> bool:
        return True

    def write(self, data: Any) -> int:
        with memoryview(data) as view, view.cast("B") as piece:
            self.size += len(piece)
            sent = 0
            while self.failure is None and not self.stopped and sent < len(piece):
                try:
                    sent += os.write(self.fd, piece[sent:])
                except OSError as exc:
                    self.failure = exc
            self.written += sent
            return len(piece)


def _write_directly(
    path: str | os.PathLike[str], data: str | bytes | Callable[[BinaryIO], None]
) -> None:
    """Write ``data`` to a device or pipe as it is made, in pieces of at most
    :data:`CHUNK_BYTES`, counting the bytes it takes, so that a failure says how many
    went. It had been made whole in memory first, then written: ``--out /dev/stdout``
    held a classifier document twice over (its text and its bytes) before a byte went."""
    kind = "a device or pipe"
    writer: _DirectWriter | None = None
    try:
        fd = os.open(path, os.O_WRONLY)
        try:
            mode = os.fstat(fd).st_mode
            kind = "a pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else kind
            kind = "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else kind
            writer = _DirectWriter(fd)
            buffered = io.BufferedWriter(writer, CHUNK_BYTES)
            try:
                _write_to(cast(BinaryIO, buffered), data)
                buffered.flush()
            except BaseException as exc:
                # The data's maker raised (a writer function, Ctrl-C): the rest is not
                # sent, and what went already is said beside the error, which told nothing
                # of the bytes a pipe had taken.
                writer.stopped = True
                if writer.written and not isinstance(exc, OSError):
                    exc.add_note(
                        f"the first {writer.written} bytes went to {os.fspath(path)} before "
                        f"it ({kind}, written directly): what it got is incomplete"
                    )
                raise
            finally:
                buffered.close()
            if writer.failure is not None:
                raise writer.failure
        finally:
            os.close(fd)
    except OSError as exc:
        failed = NotWritten(exc.errno, exc.strerror or str(exc), os.fspath(path))
        failed.direct = kind
        if writer is not None:
            failed.written, failed.size = writer.written, writer.size
        raise failed from None


def _write_to(handle: BinaryIO, data: str | bytes | Callable[[BinaryIO], None]) -> None:
    if isinstance(data, str):
        # In pieces: the whole text encoded at once is a second copy of it.
        for start in range(0, len(data), CHUNK_BYTES):
            handle.write(data[start : start + CHUNK_BYTES].encode("utf-8"))
    elif isinstance(data, bytes):
        handle.write(data)
    else:
        data(handle)
