"""Writes whole or not at all (:mod:`inertia_id.files`): a device or pipe is written as the
data is made, not collected in memory first."""

from __future__ import annotations

import os
import re
import threading
import tracemalloc
from pathlib import Path
from typing import BinaryIO

import pytest

from inertia_id.files import CHUNK_BYTES, NotWritten, write_whole


def _reader(pipe: Path, limit: int | None, taken: list[int], started: threading.Event) -> None:
    """Read ``pipe`` in 64 KiB pieces, counting (to ``limit`` bytes, then close it), and
    set ``started`` at the first byte."""
    with pipe.open("rb", buffering=0) as handle:
        while limit is None or taken[0] < limit:
            piece = handle.read(65536 if limit is None else min(65536, limit - taken[0]))
            if not piece:
                break
            taken[0] += len(piece)
            started.set()


def _read_in_thread(
    pipe: Path, limit: int | None = None
) -> tuple[threading.Thread, list[int], threading.Event]:
    taken, started = [0], threading.Event()
    thread = threading.Thread(target=_reader, args=(pipe, limit, taken, started), daemon=True)
    thread.start()
    return thread, taken, started


@pytest.fixture
def pipe(tmp_path: Path) -> Path:
    path = tmp_path / "pipe"
    os.mkfifo(path)
    return path


def test_a_pipe_gets_what_is_written_while_the_rest_is_being_made(pipe: Path) -> None:
    # Before: what a writer wrote to a pipe (`--out /dev/stdout | ...`) was collected in
    # memory whole and sent after the writer had finished, so the reader got nothing
    # until then.
    thread, taken, started = _read_in_thread(pipe)
    seen_while_writing: list[bool] = []

    def write(handle: BinaryIO) -> None:
        handle.write(b"x" * (2 * CHUNK_BYTES))
        seen_while_writing.append(started.wait(30))
        handle.write(b"y" * 100)

    write_whole(pipe, write)
    thread.join(30)
    assert seen_while_writing == [True]
    assert taken[0] == 2 * CHUNK_BYTES + 100


@pytest.mark.parametrize("where", ["pipe", "file"])
def test_text_is_written_in_pieces_never_copied_whole(
    tmp_path: Path, pipe: Path, where: str
) -> None:
    # Before: the text was encoded whole (a second copy) and, for a pipe, copied once more
    # into a buffer: 64 MB of text held 128 MB more on its way to a pipe.
    text = "0123456789abcdef" * (4 * 1024 * 1024)  # 64 MiB
    path = pipe if where == "pipe" else tmp_path / "out.json"
    thread, taken, _ = _read_in_thread(pipe) if where == "pipe" else (None, [0], None)
    tracemalloc.start()
    try:
        write_whole(path, text)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    if thread is not None:
        thread.join(30)
        assert taken[0] == len(text)
    else:
        assert path.stat().st_size == len(text)
    assert peak < 4 * CHUNK_BYTES, peak


def test_a_failed_write_to_a_pipe_counts_what_reached_it_of_all_that_was_meant(
    pipe: Path,
) -> None:
    # The reader takes 100 bytes and stops: the pipe took a buffer's worth before the write
    # failed, and the message counts that against every byte the writer meant for it,
    # written after the failure or not.
    thread, _, _ = _read_in_thread(pipe, limit=100)

    def write(handle: BinaryIO) -> None:
        for _ in range(300):
            handle.write(b"z" * 10_000)

    with pytest.raises(NotWritten) as failed:
        write_whole(pipe, write)
    thread.join(30)
    found = re.fullmatch(
        rf"could not write {re.escape(str(pipe))}: Broken pipe; the first (\d+) of 3000000 "
        r"bytes went to it before the write failed \(a pipe, written directly\): what it "
        "got is incomplete",
        str(failed.value),
    )
    assert found is not None, str(failed.value)
    assert 100 <= int(found[1]) < 3_000_000
    assert (failed.value.written, failed.value.size) == (int(found[1]), 3_000_000)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_device_that_takes_nothing_is_said_to_have_got_nothing() -> None:
    with pytest.raises(NotWritten) as failed:
        write_whole("/dev/full", "x" * (3 * CHUNK_BYTES))
    assert str(failed.value) == (
        "could not write /dev/full: No space left on device; nothing was written to it (a "
        "device, written directly)"
    )


@pytest.mark.parametrize("failure", [KeyboardInterrupt, ValueError])
def test_a_write_stopped_by_any_exception_leaves_the_old_file_and_nothing_beside_it(
    tmp_path: Path, failure: type[BaseException]
) -> None:
    # Before: only an OSError removed the part file; Ctrl-C during `train --out` (or a
    # writer function that raised) left the old file intact but a hidden
    # '.name.PID.HEX.part' beside it, as large as what had been written (2 MiB here).
    target = tmp_path / "classifier.json"
    target.write_text("old")

    def stopped(handle: BinaryIO) -> None:
        handle.write(b"x" * (2 * CHUNK_BYTES))
        raise failure("stopped")

    with pytest.raises(failure, match="stopped"):
        write_whole(target, stopped)
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["classifier.json"]


def test_a_writer_that_raises_mid_pipe_says_what_the_pipe_had_taken(pipe: Path) -> None:
    # Written as it is made, a pipe takes the first pieces before the maker fails; the
    # error said nothing of them (before the pieces, nothing had gone), and the piece
    # still buffered was sent after the failure too. Now the rest is held back and the
    # error carries a note counting what went.
    thread, taken, _ = _read_in_thread(pipe)

    def failing(handle: BinaryIO) -> None:
        handle.write(b"a" * (2 * CHUNK_BYTES))
        handle.write(b"b" * 1000)  # buffered when the maker fails: not sent
        raise ValueError("the maker failed")

    with pytest.raises(ValueError, match="the maker failed") as failed:
        write_whole(pipe, failing)
    thread.join(30)
    assert taken[0] == 2 * CHUNK_BYTES
    assert failed.value.__notes__ == [
        f"the first {2 * CHUNK_BYTES} bytes went to {pipe} before it (a pipe, written "
        "directly): what it got is incomplete"
    ]
