"""Gzip-compressed input, known by its magic bytes and decompressed up to a limit.

Ground systems hand over a long pass gzip-compressed (a 100 Hz pass of ten minutes is
megabytes of CSV). A gzip stream is recognised by its first two bytes, whatever its name,
and decompressed through :class:`gzip.GzipFile` (streaming, members concatenated, CRC
checked) reading at most ``limit + 1`` bytes: a stream that holds more is refused after
that many, so a decompression bomb (a megabyte of gzip holding a gigabyte of zeros) costs
``limit`` bytes of memory and the time to inflate them, never its whole content.
"""

from __future__ import annotations

import gzip
import io
import zlib
from typing import BinaryIO

from .errors import InputError

__all__ = ["GZIP_MAGIC", "DecompressedTooLarge", "gunzip", "is_gzip", "without_gz_suffix"]

#: The first two bytes of every gzip stream (RFC 1952, ID1 ID2). No UTF-8 text starts
#: with them (0x8b is a continuation byte), so telemetry text is never taken for gzip.
GZIP_MAGIC = b"\x1f\x8b"


class DecompressedTooLarge(InputError):
    """A gzip stream holds more than the limit (the API answers it 413, as a body over
    its limit).

    :param what: the stream, as the message names it (a file's name, "request body").
    :param limit: the most bytes it may hold once decompressed.
    """

    def __init__(self, what: str, limit: int) -> None:
        self.what = what
        self.limit = limit
        super().__init__(
            f"{what} is gzip whose decompressed size exceeds the limit of {limit} bytes "
            f"(it holds more than {limit} bytes once decompressed); send less data, e.g. "
            "fewer telemetry samples"
        )


def is_gzip(head: bytes) -> bool:
    """``head`` (a stream's first bytes) begins a gzip stream."""
    return head[:2] == GZIP_MAGIC


def gunzip(source: bytes | BinaryIO, *, limit: int, what: str) -> bytes:
    """What the gzip stream ``source`` holds, at most ``limit`` bytes of it.

    :param source: the compressed bytes, or a binary stream positioned at them.
    :param limit: the most bytes it may hold once decompressed; past them
        :class:`DecompressedTooLarge`, after inflating ``limit + 1`` bytes only.
    :param what: the stream as a message names it.
    :raises InputError: a stream that is no gzip, corrupt or truncated, naming ``what``.
    """
    stream = io.BytesIO(source) if isinstance(source, bytes) else source
    try:
        with gzip.GzipFile(fileobj=stream, mode="rb") as compressed:
            data = compressed.read(limit + 1)
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:
        # EOFError: truncated; BadGzipFile: a bad header, CRC or length, or trailing bytes
        # that are no gzip member; zlib.error: a corrupt deflate stream.
        raise InputError(f"{what} is not a valid gzip stream: {exc}") from None
    if len(data) > limit:
        raise DecompressedTooLarge(what, limit)
    if is_gzip(data):
        # Compressed twice (gzip of a .gz): read as text it was "not UTF-8 (byte 0x8b at
        # position 1)", which did not say why. No telemetry text starts with the magic.
        raise InputError(
            f"{what} is gzip holding gzip again (compressed twice): compress the telemetry once"
        )
    return data


def without_gz_suffix(name: str) -> str:
    """``pass.csv.gz`` -> ``pass.csv``: the name of what a gzip file holds (unchanged
    without the suffix)."""
    return name[:-3] if name.lower().endswith(".gz") else name
