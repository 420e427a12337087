"""Gzip inputs for the tests: a decompression bomb written a megabyte at a time.

Tests import this module as ``gzip_support`` (``tests/`` is on ``sys.path``, see
``service_support``).
"""

from __future__ import annotations

import zlib
from pathlib import Path

#: What the bomb holds once decompressed: 1 GiB of zeros (about 1 MB of gzip).
BOMB_BYTES = 2**30


def write_gzip_bomb(path: Path, size_bytes: int = BOMB_BYTES) -> Path:
    """A gzip file at ``path`` holding ``size_bytes`` zeros, compressed a megabyte at a
    time through one ``zlib.compressobj``: the zeros are never in memory at once."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, 16 + zlib.MAX_WBITS)  # gzip framing
    zeros = bytes(2**20)
    with path.open("wb") as out:
        for _ in range(size_bytes // len(zeros)):
            out.write(compressor.compress(zeros))
        out.write(compressor.flush())
    return path
