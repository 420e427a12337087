"""Hostile input to the command line and the core: a clear error naming the bad value,
never a traceback, a silent NaN or a wrong answer (found by a hostile review; each case
failed before its fix)."""

from __future__ import annotations

import json
import os
import re
import resource
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from inertia_id import (
    InertiaClassifier,
    Scenario,
    estimate_inertia,
    load_classifier,
    preset,
    simulate,
    train_classifier,
)
from inertia_id.classifiers import documents
from inertia_id.classifiers.documents import MAX_CLASSIFIER_BYTES
from inertia_id.cli import main
from inertia_id.cli.options import MAX_SCENARIO_BYTES, MAX_SEQUENCE_BYTES
from inertia_id.errors import InputError
from inertia_id.evaluation.sweep import run_inertia_sweep, run_sweep
from inertia_id.evaluation.telemetry import MAX_TELEMETRY_BYTES, load_telemetry
from inertia_id.pipelines import SweepRequest, sweep_with_limit

SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4


def refused(args: list[str]) -> str:
    """``inertia-id ARGS`` exits with a usage or input error (2 or 1), no traceback; its
    message, folded onto one line."""
    result = CliRunner().invoke(main, args)
    assert result.exit_code in (1, 2), (result.exit_code, result.output)
    assert not isinstance(result.exception, Exception) or isinstance(
        result.exception, SystemExit
    ), result.exception
    assert "Traceback" not in result.output
    return " ".join(result.output.split())


@pytest.fixture
def binary(tmp_path: Path) -> Path:
    path = tmp_path / "b.json"
    path.write_bytes(b"\xff\xfe\x00binary")
    return path


@pytest.mark.parametrize("command", ["simulate", "train", "search", "paper"])
def test_a_negative_seed_is_a_usage_error(command: str) -> None:
    assert "'--seed': -1 is not in the range 0<=x<=2147483647" in refused([command, "--seed", "-1"])


@pytest.mark.parametrize("command", ["simulate", "train", "search", "paper", "plan"])
def test_a_seed_the_service_could_not_keep_is_a_usage_error(command: str) -> None:
    # The service keeps seeds in a 32-bit column and refuses 2^31; the command line took
    # it, so a run made there could not be made again as a job.
    message = refused([command, "--seed", str(2**31)])
    assert "'--seed': 2147483648 is not in the range 0<=x<=2147483647" in message


def test_a_file_that_is_not_text_is_named(binary: Path, tmp_path: Path) -> None:
    why = "is not UTF-8 text (byte b'\\xff' at position 0)"
    message = refused(["identify", "--classifier", str(binary), str(binary)])
    assert str(binary) in message and why in message
    assert why in refused(["simulate", "--scenario", str(binary)])
    assert why in refused(["simulate", "--sequence", str(binary)])
    for load in (load_classifier, load_telemetry):
        with pytest.raises(InputError, match="is not UTF-8 text"):
            load(binary)


def test_a_gzip_bomb_or_a_broken_gzip_is_refused_naming_the_file(
    tmp_path: Path, gzip_bomb: Path
) -> None:
    """1 GiB of zeros in 1 MB of gzip: refused after inflating the limit (100 MB), not
    the gigabyte; a truncated gzip names the file and what is wrong with it."""
    import gzip

    classifier = tmp_path / "c.json"
    train_classifier(
        Scenario.paper(), SEQUENCE, 3, np.random.default_rng(0), metric="euclidean"
    ).save(classifier)
    message = refused(["identify", "--classifier", str(classifier), str(gzip_bomb)])
    assert "decompressed size exceeds the limit of" in message
    from inertia_id.evaluation.telemetry import MAX_GZIP_TELEMETRY_BYTES

    assert f"{str(gzip_bomb)!r} is gzip whose decompressed size exceeds the limit of " in message
    assert f"the limit of {MAX_GZIP_TELEMETRY_BYTES} bytes" in message
    truncated = tmp_path / "pass.csv.gz"
    truncated.write_bytes(gzip.compress(b"time_s,wx,wy,wz\n0.05,0,0,0\n" * 100)[:-20])
    message = refused(["identify", "--classifier", str(classifier), str(truncated)])
    assert f"{str(truncated)!r} is not a valid gzip stream" in message
    assert "Compressed file ended before the end-of-stream marker" in message


@pytest.mark.parametrize("size", [MAX_TELEMETRY_BYTES + 1, 2**40], ids=["limit+1", "1TiB"])
def test_a_plain_telemetry_file_over_the_byte_limit_is_refused_unread(
    tmp_path: Path, size: int
) -> None:
    """A plain file had only the 200,000-row cap, checked after the whole file was read
    into memory; it is held to the gzip file's byte limit, by its size, unread (a
    sparse file: a terabyte of it costs no disk, and reading it would fail for memory)."""
    classifier = tmp_path / "c.json"
    train_classifier(
        Scenario.paper(), SEQUENCE, 3, np.random.default_rng(0), metric="euclidean"
    ).save(classifier)
    big = tmp_path / "pass.csv"
    with big.open("wb") as file:
        file.truncate(size)
    message = refused(["identify", "--classifier", str(classifier), str(big)])
    assert message == (
        f"Error: {str(big)!r} is {size} bytes, over the limit of {MAX_TELEMETRY_BYTES} bytes "
        "for telemetry as CSV or JSON; give less data (fewer samples), or gzip it"
    )


def test_a_named_pipe_is_read_no_further_than_the_limit(tmp_path: Path) -> None:
    """A pipe has no size to check: it is refused one byte past the limit."""
    import os
    import threading

    from inertia_id.checks import read_text

    pipe = tmp_path / "pass.csv"
    os.mkfifo(pipe)
    written: list[int] = []

    def write() -> None:
        # Unbuffered: nothing is left to flush on a pipe the reader has closed.
        with pipe.open("wb", buffering=0) as file:
            try:
                for _ in range(1000):
                    file.write(b"0.05,0,0,0\n" * 100)
                    written.append(1)
            except BrokenPipeError:
                pass

    # A daemon: a reader that never opens the pipe leaves it blocked, not the test run.
    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    with pytest.raises(
        InputError,
        match=r"'.*pass\.csv' holds more than 5000 bytes, over the limit of 5000 bytes for ",
    ):
        read_text(pipe, "telemetry", limit=5000)
    writer.join(10)
    assert not writer.is_alive() and len(written) < 1000
    exact = tmp_path / "exact.csv"
    exact.write_text("0.05,0,0,0\n" * 10)
    assert read_text(exact, "telemetry", limit=110) == "0.05,0,0,0\n" * 10


def _sparse(path: Path, size: int) -> Path:
    """A file of ``size`` bytes that takes no disk (reading it would take the memory)."""
    with path.open("wb") as file:
        file.truncate(size)
    return path


def _pipe_of(path: Path, data: bytes) -> threading.Thread:
    """A named pipe at ``path`` that serves ``data`` once, from a daemon thread."""
    os.mkfifo(path)

    def write() -> None:
        with path.open("wb", buffering=0) as file:
            try:
                file.write(data)
            except BrokenPipeError:
                pass

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    return writer


def test_a_classifier_file_over_the_byte_limit_is_refused_unread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A classifier file was read whole, whatever its size (telemetry alone had a limit):
    one past MAX_CLASSIFIER_BYTES is refused by its size, a pipe one byte past it."""
    big = _sparse(tmp_path / "c.json", MAX_CLASSIFIER_BYTES + 1)
    telemetry = tmp_path / "pass.csv"
    telemetry.write_text("time_s,wx,wy,wz\n0.05,0,0,0\n0.1,0,0,0\n")
    message = refused(["identify", "--classifier", str(big), str(telemetry)])
    assert message == (
        f"Error: {str(big)!r} is {MAX_CLASSIFIER_BYTES + 1} bytes, over the limit of "
        f"{MAX_CLASSIFIER_BYTES} bytes for a classifier's JSON document; is it a "
        "classifier (inertia-id train writes one)?"
    )
    for load in (load_classifier, InertiaClassifier.load):
        with pytest.raises(InputError, match=f"is {MAX_CLASSIFIER_BYTES + 1} bytes, over the"):
            load(big)
    # At the limit a classifier loads; a pipe is refused one byte past it.
    fitted = train_classifier(
        Scenario.paper(), SEQUENCE, 3, np.random.default_rng(0), metric="euclidean"
    )
    document = fitted.to_json().encode()
    monkeypatch.setattr(documents, "MAX_CLASSIFIER_BYTES", len(document))
    exact = tmp_path / "exact.json"
    exact.write_bytes(document)
    assert load_classifier(exact).candidate_names_ == fitted.candidate_names_
    writer = _pipe_of(tmp_path / "piped.json", document + b" ")
    with pytest.raises(
        InputError, match=rf"piped\.json' holds more than {len(document)} bytes, over the limit"
    ):
        load_classifier(tmp_path / "piped.json")
    writer.join(10)


@pytest.mark.parametrize("option", ["--scenario", "--sequence"])
def test_a_scenario_or_sequence_file_over_the_byte_limit_is_refused_unread(
    tmp_path: Path, option: str
) -> None:
    """They were read whole, whatever their size: a megabyte is a wrong file, refused by
    its size (one byte past it; at the limit, padded JSON is read as ever)."""
    limit, what, advice = {
        "--scenario": (
            MAX_SCENARIO_BYTES,
            "a scenario's JSON",
            "is it a scenario (inertia-id scenario writes one)?",
        ),
        "--sequence": (
            MAX_SEQUENCE_BYTES,
            "a sequence: a JSON list of rows",
            "is it a sequence (rows of level indices)?",
        ),
    }[option]
    other = ["--sequence", "4,4,4,0,0,0"] if option == "--scenario" else []
    big = _sparse(tmp_path / "big.json", limit + 1)
    message = refused(["plan", *other, option, str(big)])
    assert message == (
        f"Error: {str(big)!r} is {limit + 1} bytes, over the limit of {limit} bytes for "
        f"{what}; {advice}"
    )
    document = (
        Scenario.paper().model_dump_json() if option == "--scenario" else json.dumps(SEQUENCE)
    )
    exact = tmp_path / "exact.json"
    exact.write_text(document + " " * (limit - len(document)))
    assert exact.stat().st_size == limit
    out = tmp_path / "plan.json"
    result = CliRunner().invoke(main, ["plan", *other, option, str(exact), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())


def _endless_pipe(path: Path, piece: bytes, most: int) -> tuple[threading.Thread, list[int]]:
    """A named pipe at ``path`` that serves ``piece`` over and over, ``most`` bytes at
    most, from a daemon thread; the list counts the bytes written."""
    os.mkfifo(path)
    written = [0]

    def write() -> None:
        with path.open("wb", buffering=0) as file:
            try:
                while written[0] < most:
                    written[0] += file.write(piece)
            except BrokenPipeError:
                pass

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    return writer, written


def test_a_classifier_stream_that_never_ends_is_refused_at_a_gigabyte(tmp_path: Path) -> None:
    """``--classifier <(printf '{'; cat /dev/zero)`` begins as a JSON object does, so
    only the byte limit stops it: it was 4 GB, held before the refusal (peak RSS 4.1 GB,
    13 s). The limit is 1 GB now, above the paper preset's largest classifier the service
    trains (773 MB) and the 64-step one (425 MB); the message names the file and it."""
    assert MAX_CLASSIFIER_BYTES == 1_000_000_000
    endless = tmp_path / "endless"
    # A brace and blanks, a mebibyte at a time: the reader stops at the limit, whatever
    # follows the first brace.
    writer, written = _endless_pipe(endless, b"{" + b" " * ((1 << 20) - 1), 2 * 10**9)
    telemetry = tmp_path / "pass.csv"
    telemetry.write_text("time_s,wx,wy,wz\n0.05,0,0,0\n0.1,0,0,0\n")
    message = refused(["identify", "--classifier", str(endless), str(telemetry)])
    assert message == (
        f"Error: {str(endless)!r} holds more than 1000000000 bytes, over the limit of "
        "1000000000 bytes for a classifier's JSON document; is it a classifier "
        "(inertia-id train writes one)?"
    )
    writer.join(10)
    assert not writer.is_alive() and written[0] < MAX_CLASSIFIER_BYTES + (4 << 20)


def test_a_stream_that_is_no_json_object_is_refused_as_it_begins(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--classifier /dev/zero`` was read to the byte limit before it was refused: 4 GB
    of memory (peak RSS 4.2 GB). A stream has no size to check, so a classifier, scenario
    or search stream is refused by its first character: a JSON object begins with '{'.
    (The limit here is 64 MB, so that the code before fails in a second.)"""
    limit = 64 << 20
    monkeypatch.setattr(documents, "MAX_CLASSIFIER_BYTES", limit)
    zeros = tmp_path / "zeros"
    writer, written = _endless_pipe(zeros, bytes(1 << 20), 4 * limit)
    telemetry = tmp_path / "pass.csv"
    telemetry.write_text("time_s,wx,wy,wz\n0.05,0,0,0\n0.1,0,0,0\n")
    message = refused(["identify", "--classifier", str(zeros), str(telemetry)])
    assert message == (
        f"Error: {str(zeros)!r} is not a classifier's JSON document: it begins with "
        "'\\x00', not '{'; is it a classifier (inertia-id train writes one)?"
    )
    writer.join(10)
    assert not writer.is_alive() and written[0] < limit // 4
    # Blanks before the brace are JSON's; a scenario and a search are objects too.
    _pipe_of(tmp_path / "blank.json", b" \n\t" + Scenario.paper().model_dump_json().encode())
    assert (
        CliRunner()
        .invoke(
            main,
            [
                "plan",
                "--sequence",
                "4,4,4,0,0,0",
                "--scenario",
                str(tmp_path / "blank.json"),
                "--out",
                str(tmp_path / "p.json"),
            ],
        )
        .exit_code
        == 0
    )
    _pipe_of(tmp_path / "list.json", b"[1, 2]")
    assert "'list.json' is not a search's JSON: it begins with '[', not '{'" in refused(
        ["plan", "--search", str(tmp_path / "list.json")]
    ).replace(str(tmp_path) + os.sep, "")


@pytest.mark.parametrize("kind", ["file", "pipe"])
def test_a_file_read_under_a_limit_is_held_twice_at_most(tmp_path: Path, kind: str) -> None:
    """Reading a file under a byte limit held its bytes in pieces, the pieces joined and
    the text at once: three times the file (a 300 MB classifier: peak RSS 912 MB, now
    618 MB). Python's own allocations are counted (tracemalloc), not the process's."""
    import tracemalloc

    from inertia_id.checks import read_text

    size = 20 << 20
    data = b'{"a": [' + b"1.25, " * (size // 6) + b"0]}"
    path = tmp_path / "big.json"
    if kind == "file":
        path.write_bytes(data)
        writer = None
    else:
        writer = _pipe_of(path, data)
    tracemalloc.start()
    try:
        text = read_text(path, "JSON", limit=4 * size)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    held = len(data)
    assert len(text) == held
    assert peak < 2.2 * held, f"peak {peak} bytes for a file of {held}"
    if writer is not None:
        writer.join(10)


@pytest.mark.parametrize("kind", ["file", "pipe"])
def test_a_file_read_in_pieces_reads_as_one_text(tmp_path: Path, kind: str) -> None:
    """A stream is decoded a piece at a time: a character or a CRLF cut between two
    pieces is read whole, and a byte that is no UTF-8 is named at its place in the file."""
    from inertia_id.checks import read_text

    mib = 1 << 20
    cases = {
        "text": b"a" * (mib - 1) + "\u00e9".encode() + b"b\r" * (mib // 2) + b"\nc\r",
        "bad": b"a" * (mib - 1) + b"\xc3zz",
    }
    for name, data in cases.items():
        path = tmp_path / name
        if kind == "file":
            path.write_bytes(data)
        else:
            _pipe_of(path, data)
        if name == "text":
            expected = data.decode().replace("\r\n", "\n").replace("\r", "\n")
            assert read_text(path, "text", limit=4 * mib) == expected
        else:
            with pytest.raises(InputError, match=rf"\(byte b'\\xc3' at position {mib - 1}\)"):
                read_text(path, "text", limit=4 * mib)


def test_a_sequence_may_be_piped_and_keeps_its_byte_limit(tmp_path: Path) -> None:
    """``--sequence`` took a named pipe, ``/dev/stdin`` or a process substitution
    (``<(cat seq.json)``) for sequence text (``os.path.isfile``): "sequence '/dev/fd/63'
    is not rows of level indices". A pipe is read as a file, to the same byte limit."""
    fifo = tmp_path / "seq.json"
    _pipe_of(fifo, json.dumps(SEQUENCE).encode())
    out = tmp_path / "plan.json"
    result = CliRunner().invoke(main, ["plan", "--sequence", str(fifo), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["sequence"] == SEQUENCE
    # What a process substitution hands over: /dev/fd/N, the read end of a pipe.
    read_end, write_end = os.pipe()
    os.write(write_end, b"4,4,4,0,0,0;0,0,0,4,4,4\n")
    os.close(write_end)
    try:
        result = CliRunner().invoke(
            main, ["plan", "--sequence", f"/dev/fd/{read_end}", "--out", str(out)]
        )
    finally:
        os.close(read_end)
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["sequence"] == [[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]]
    big = tmp_path / "big.json"
    writer = _pipe_of(big, b" " * (MAX_SEQUENCE_BYTES + 1))
    assert refused(["plan", "--sequence", str(big)]) == (
        f"Error: {str(big)!r} holds more than {MAX_SEQUENCE_BYTES} bytes, over the limit of "
        f"{MAX_SEQUENCE_BYTES} bytes for a sequence: a JSON list of rows; is it a sequence "
        "(rows of level indices)?"
    )
    writer.join(10)
    # A path that names nothing is still sequence text, and the error says it is no file.
    for missing in (str(tmp_path / "nosuch.json"), "seq.jsn"):
        assert refused(["plan", "--sequence", missing]) == (
            f"Error: sequence {missing!r} is no file by that name, and not rows of level "
            "indices like '4,4,4,0,0,0;0,0,0,4,4,4' or a JSON list of rows"
        )
    assert "is no file" not in refused(["plan", "--sequence", "4.5,4,4,0,0,0"])
    # A folder is a name that exists: it is said to be a folder (it was "no file by that
    # name").
    assert refused(["plan", "--sequence", str(tmp_path)]) == (
        f"Error: sequence {str(tmp_path)!r} is a folder, not a file, and not rows of level "
        "indices like '4,4,4,0,0,0;0,0,0,4,4,4' or a JSON list of rows"
    )


def test_a_limit_far_above_memory_costs_only_the_file() -> None:
    """A buffered read allocates all it is asked for first: reading a small file under a
    limit of 2**62 bytes was a MemoryError."""
    from inertia_id.checks import read_text

    assert read_text(__file__, "Python", limit=2**62).startswith('"""Hostile input')


def test_too_few_realisations_to_train_on_are_refused_naming_n(tmp_path: Path) -> None:
    """`train -n 2` says what the API says of n_realisations = 2, before anything is
    simulated, in the option's words. (It printed the classifier's internal check: "y
    must label every candidate 0..K-1 (K >= 2) at least 3 time(s); series per
    candidate: [2, 2, 2, 2, 2]", which names no option, after the training's line.)"""
    out = tmp_path / "c.json"
    result = CliRunner().invoke(main, ["train", "-n", "2", "--out", str(out)])
    assert result.exit_code == 1, result.output
    assert result.output.strip() == (
        "Error: -n 2: the 'marginal-likelihood' classifier needs at least 3 realisations "
        "per candidate"
    )
    assert not out.exists()


def test_a_sequence_that_applies_no_torque_is_not_trained_on(tmp_path: Path) -> None:
    """Before, the all-off sequence trained (F1 at chance) and the CLI wrote it."""
    out = tmp_path / "c.json"
    result = CliRunner().invoke(
        main, ["train", "--sequence", "0,0,0,0,0,0;0,0,0,0,0,0", "-n", "3", "--out", str(out)]
    )
    # 1, as for every value the command refuses once it has read it (README: a ragged
    # sequence, candidates with the same tensor); 2 is click's, before the command runs.
    assert result.exit_code == 1, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert "fires no thruster at any step" in result.output
    assert not out.exists()
    # Opposing thrusters fired together: torque, but none net.
    with pytest.raises(InputError, match="applies no net torque at any step"):
        train_classifier(
            Scenario.paper(),
            [[4, 0, 0, 4, 0, 0]] * 2,
            3,
            np.random.default_rng(0),
            kind="least-squares",
        )
    Scenario.paper().check_fires([[0] * 6, [4, 0, 0, 0, 0, 0]])  # one firing is enough


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--sequence", "4,4,4,0,0,0;4,4,4,0,0"], "is not an array of level indices"),
        (["--sequence", "[[true,4,4,0,0,0]]"], "must hold integer level indices"),
        (["--pre-start", "nan"], "--pre-start nan s: at most 996 s"),
        (["--pre-start", "1e9"], "--pre-start 1e+09 s: at most 996 s"),
        (["--sample-rate", "nan"], "--sample-rate nan Hz: give a rate from 0.01 Hz"),
        # The range --help states (it said 0<x<=10000 while 0.001 was refused at run time).
        (["--sample-rate", "1e-300"], "'--sample-rate': 1e-300 is not in the range 0.01<=x<=10000"),
        (["--sample-rate", "0.001"], "'--sample-rate': 0.001 is not in the range 0.01<=x<=10000"),
    ],
)
def test_simulate_checks_its_options_before_it_builds_anything(
    option: list[str], message: str
) -> None:
    assert message in refused(["simulate", "-n", "1", *option])


def test_a_one_row_sequence_flies_as_one_step() -> None:
    result = CliRunner().invoke(main, ["simulate", "-n", "1", "--sequence", "[4,4,4,0,0,0]"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["series_shape"] == [5, 1, 20, 3]


@pytest.mark.parametrize("name", ["bogus", "seed", "sequence_length", "total_timesteps"])
def test_a_cem_setting_must_be_the_cems_own(name: str) -> None:
    message = refused(["search", "--method", "cem", "--length", "1", "--cem", f"{name}=2"])
    assert f"unknown CEM setting(s) ['{name}']" in message and "population" in message


@pytest.mark.parametrize(
    ("document", "member", "message"),
    [
        ({"best": [[4, 4, 4, 0, 0, 0]]}, None, "holds no best sequence"),
        ({"front": [1]}, "0", "holds no front"),
        ({"front": {"members": ["x"]}}, "0", "has no member 0"),
        ({"front": {"members": [{"index": 0}]}}, "0", "front member 0 holds no sequence"),
    ],
)
def test_a_malformed_search_document_is_named(
    tmp_path: Path, document: dict, member: str | None, message: str
) -> None:
    path = tmp_path / "search.json"
    path.write_text(json.dumps(document))
    args = ["plan", "--search", str(path), "--out", "-"]
    assert message in refused([*args, "--member", member] if member else args)


def test_a_search_file_over_the_byte_limit_is_refused_unread(tmp_path: Path) -> None:
    """It was read whole, whatever its size (a sparse file one byte past the limit)."""
    from inertia_id.cli.plan import MAX_SEARCH_BYTES

    big = _sparse(tmp_path / "search.json", MAX_SEARCH_BYTES + 1)
    assert refused(["plan", "--search", str(big), "--out", "-"]) == (
        f"Error: {str(big)!r} is {MAX_SEARCH_BYTES + 1} bytes, over the limit of "
        f"{MAX_SEARCH_BYTES} bytes for a search's JSON; is it a search (a job downloaded "
        "from the service, or inertia-id search --out)?"
    )


def test_a_scenario_error_is_one_line_without_pydantic_links(tmp_path: Path) -> None:
    document = Scenario.paper().model_dump(mode="json")
    document["timing"]["step_duration_s"] = -1
    path = tmp_path / "s.json"
    path.write_text(json.dumps(document))
    result = CliRunner().invoke(main, ["simulate", "--scenario", str(path)])
    assert result.exit_code == 1
    assert result.output.count("\n") == 1 and "errors.pydantic.dev" not in result.output
    assert "timing.step_duration_s" in result.output


@pytest.mark.parametrize(
    ("field", "named"),
    [
        ("lowpass_time_constant_s", "lowpass_time_constant_s = 1e+308 s is an actuation lag"),
        ("duty_jitter_sigma", "uncertainty.duty_jitter_sigma: duty_jitter_sigma = 1e+308"),
        ("disturbance_torque_sigma_nm", "disturbance_torque_sigma_nm = 1e+308 N m is beyond"),
    ],
)
def test_a_scenario_files_absurd_noise_is_refused_in_one_line(
    tmp_path: Path, field: str, named: str
) -> None:
    """A lag of 1e308 s trained to 0.425 accuracy without a word; now every command
    reading the file refuses it, in one line naming the figure."""
    document = Scenario.paper().model_dump(mode="json")
    document["uncertainty"][field] = 1e308
    path = tmp_path / "s.json"
    path.write_text(json.dumps(document))
    for command in (["simulate", "-n", "1"], ["train", "--sequence", "4,4,4,0,0,0"]):
        result = CliRunner().invoke(main, [*command, "--scenario", str(path)])
        assert result.exit_code == 1, result.output
        assert result.output.count("\n") == 1 and "Traceback" not in result.output
        assert named in result.output


@pytest.mark.parametrize("value", ["1_0", True])
def test_a_scenario_files_number_not_as_written_is_named(tmp_path: Path, value: object) -> None:
    """Pydantic's lax mode read "1_0" as 10 and true as 1 in a scenario file."""
    document = Scenario.paper().model_dump(mode="json")
    document["timing"]["sample_rate_hz"] = value
    path = tmp_path / "s.json"
    path.write_text(json.dumps(document))
    message = refused(["simulate", "--scenario", str(path)])
    assert "timing.sample_rate_hz: sample_rate_hz must be a decimal number" in message
    assert message.endswith(f"got {value!r}")


def test_a_candidate_name_template_is_no_format_string() -> None:
    document = Scenario.paper().model_dump(mode="json")
    document["inertia_candidates"] = None
    document["candidate_generator"]["variation_name"] = "{0} {x} {n:>99999999} #{n}"
    scenario = Scenario.model_validate(document)
    assert scenario.candidate_names[1] == "{0} {x} {n:>99999999} #1"


def test_rates_that_overflow_are_refused_naming_the_scenario() -> None:
    document = Scenario.paper().model_dump(mode="json")
    document["thrusters"]["torque_matrix_nm"] = [
        [5000 * v for v in row] for row in document["thrusters"]["torque_matrix_nm"]
    ]
    big = Scenario.model_validate(document)
    with pytest.raises(InputError, match=r"overflowed to inf or nan.*torques up to 10000 N m"):
        simulate(big, SEQUENCE, 1, np.random.default_rng(0))
    with pytest.raises(InputError, match="process x1e\\+300"):
        simulate(Scenario.paper(), SEQUENCE, 1, np.random.default_rng(0), 1e300)
    with pytest.raises(InputError, match="rng must be a numpy Generator"):
        simulate(Scenario.paper(), SEQUENCE, 1, None)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("field", "value", "named"),
    [
        ("disturbance_torque_sigma_nm", 1e6, "disturbance torque sigma 1e+06 N m"),
        ("thrust_scale_sigma", 1e3, "thrust-scale sigma 1000"),
    ],
)
def test_rates_that_overflow_name_the_noise_that_drove_them(
    field: str, value: float, named: str
) -> None:
    """A scenario whose disturbance or thrust-scale sigma overflowed the rates was told
    of its torques (2 N m, nominal) and its initial-rate sigma alone, none of them the
    cause, and to "scale them down". The disturbance is the most a scenario may state;
    the thrust-scale sigma past it, as a noise sweep's copy holds it."""
    paper = Scenario.paper()
    made = paper.with_swept_noise if field == "thrust_scale_sigma" else paper.with_uncertainty
    scenario = made(**{field: value})
    with pytest.raises(InputError, match="overflowed to inf or nan") as refused:
        simulate(scenario, SEQUENCE, 2, np.random.default_rng(0))
    assert named in str(refused.value)


def test_a_sweep_refuses_a_scenario_of_other_candidates(paper: Scenario) -> None:
    classifier = train_classifier(
        paper, SEQUENCE, 3, np.random.default_rng(0), kind="nearest-centroid", metric="euclidean"
    )
    document = paper.model_dump(mode="json")
    document["inertia_candidates"] = document["inertia_candidates"][::-1]
    document["candidate_generator"] = None
    reversed_ = Scenario.model_validate(document)
    # Before, the sweep scored the reversed labels: accuracy 0.2 instead of 1.0.
    with pytest.raises(InputError, match="not the ones the classifier was trained on"):
        run_sweep(classifier, scenario=reversed_, multiples=[1], n_test=10)
    with pytest.raises(InputError, match="not the ones the classifier was trained on"):
        run_inertia_sweep(classifier, scenario=reversed_)


def test_the_estimate_names_rates_it_cannot_fit(paper: Scenario) -> None:
    """Refused before any arithmetic on them: 1e300 rad/s raised numpy's "invalid value
    encountered in subtract" on the way to a failed SVD, and 1e100 rad/s gave an
    estimate whose normal matrix was infinite ("overflow encountered in square")."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for rate in (1e300, 1e100):
            with pytest.raises(InputError, match=re.escape(f"the largest is {rate:g} rad/s")):
                estimate_inertia(paper, SEQUENCE, np.full((80, 3), rate))
        # A rate this side of the float range is fitted.
        assert np.isfinite(
            estimate_inertia(paper, SEQUENCE, np.full((80, 3), 1e3)).normal_matrix
        ).all()
    with pytest.raises(InputError, match="window_s = nan"):
        estimate_inertia(paper, SEQUENCE, np.zeros((80, 3)), window_s=float("nan"))


def test_running_out_of_memory_is_an_error_saying_so() -> None:
    import click

    from inertia_id.cli.options import friendly_errors

    @friendly_errors
    def huge() -> None:
        raise MemoryError

    with pytest.raises(click.ClickException, match="out of memory: the sizes asked for"):
        huge()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("temperature", 0, "calibration.temperature must be a finite number > 0, got 0"),
        ("temperature", None, "calibration.temperature must be a finite number > 0, got None"),
        ("scale", -1.0, "novelty_tail.scale must be finite and > 0, got -1.0"),
    ],
)
def test_a_classifier_document_edited_inside_is_refused_by_name(
    paper: Scenario, field: str, value: object, message: str
) -> None:
    # A recomputed checksum vouches for the bytes, not for the figures: before, a
    # temperature of 0 gave the verdict "ambiguous (nan)".
    from inertia_id.classifiers.documents import checksum
    from inertia_id.classifiers.registry import classifier_from_json

    model = train_classifier(
        paper, SEQUENCE, 3, np.random.default_rng(0), kind="nearest-centroid", metric="euclidean"
    )
    document = json.loads(model.to_json())
    payload = document["classifier"]
    if field == "temperature":
        payload["calibration"] = {**(payload.get("calibration") or {}), "temperature": value}
    else:
        payload["novelty_tail"][field] = value
    document["sha256"] = checksum(payload)
    with pytest.raises(InputError, match=re.escape(message)):
        classifier_from_json(json.dumps(document))


def test_a_negative_seed_from_python_is_named(paper: Scenario) -> None:
    from inertia_id.search import random_search

    with pytest.raises(InputError, match="seed must be a whole number >= 0, got -1"):
        random_search(paper, sequence_length=1, total_timesteps=4, seed=-1)


def test_an_empty_multiple_is_refused() -> None:
    from inertia_id.cli.options import parse_multiples

    # Before, "1,,2" was read as [1.0, 2.0].
    with pytest.raises(InputError, match="'1,,2' has an empty item"):
        parse_multiples("1,,2")
    assert parse_multiples("1, 2") == [1.0, 2.0]


def test_a_scenario_whose_candidates_cannot_be_told_apart_is_refused() -> None:
    document = Scenario.paper().model_dump(mode="json")
    document["candidate_generator"] = None
    document["inertia_candidates"][1]["inertia_kg_m2"] = document["inertia_candidates"][0][
        "inertia_kg_m2"
    ]
    same = Scenario.model_validate(document)
    with pytest.raises(InputError, match="'none ejected' and 'payload 1 ejected' have the same"):
        train_classifier(same, SEQUENCE, 3, np.random.default_rng(0), kind="least-squares")
    silent = Scenario.paper().model_dump(mode="json")
    silent["thrusters"]["torque_matrix_nm"] = [[0.0] * 6] * 3
    with pytest.raises(ValueError, match="all zeros: no thruster gives any torque"):
        Scenario.model_validate(silent)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--search", "none", "--design-noise", "6,1"], "--design-noise: search settings"),
        (["--sequence", "4,4,4,0,0,0", "--cem", "population=3"], "(--sequence is given)"),
    ],
)
def test_paper_refuses_search_settings_when_no_search_runs(args: list[str], message: str) -> None:
    assert message in refused(["paper", *args])


@pytest.mark.parametrize(
    ("offset", "message"),
    [
        ("2026-12-06T10:00:00", "--time-offset = '2026-12-06T10:00:00' has no time zone"),
        ("12:00", "--time-offset = '12:00' is not an ISO-8601 UTC time stamp"),
    ],
)
def test_a_bad_time_offset_is_refused_by_its_option_name(
    offset: str, message: str, tmp_path: Path
) -> None:
    """``simulate --time-offset`` with no zone was refused as "sequence_start = ...", an
    option of ``identify``, not the one given."""
    args = ["simulate", "-n", "1", "--telemetry", str(tmp_path / "t.csv")]
    assert message in refused([*args, "--time-offset", offset])
    assert not (tmp_path / "t.csv").exists()


@pytest.mark.parametrize(
    ("start", "message"),
    [
        ("nan", "--sequence-start = 'nan' is not finite"),
        ("-inf", "--sequence-start = '-inf' is not finite"),
        ("2025-13-01T00:00:00Z", "--sequence-start = '2025-13-01T00:00:00Z' is not an ISO-8601"),
    ],
)
def test_a_bad_sequence_start_is_refused_by_its_option_name(
    start: str, message: str, tmp_path: Path
) -> None:
    """``identify --sequence-start nan`` was refused as "sequence_start = 'nan' is not
    finite", the JSON field's name, not the option given (simulate's --time-offset had
    been fixed so; identify's had not)."""
    classifier, telemetry = tmp_path / "c.json", tmp_path / "t.csv"
    classifier.write_text("{}")
    telemetry.write_text("time_s,wx,wy,wz\n")
    args = ["identify", "--classifier", str(classifier), str(telemetry)]
    assert message in refused([*args, "--sequence-start", start])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # 15 digits at 1e12 s are 10 ms: 200 Hz stamps were written twice each.
        (
            ["--sample-rate", "200", "--time-offset", "1e12"],
            "--time-offset 1e+12 s: stamps that large are off their times by up to 5.86e-05 s",
        ),
        # A float at 1e16 s is 2 s apart: every 20 Hz stamp was the same.
        (["--time-offset", "1e16"], "more than 1% of the 0.05 s sample period"),
        # An ISO start whose stamps leave the years a datetime holds: OverflowError.
        (
            ["--time-offset", "9999-12-31T23:59:59Z"],
            "the telemetry's stamps, 0.05 s to 4 s from it, leave the years 1 to 9999",
        ),
        (
            ["--pre-start", "10", "--time-offset", "0001-01-01T00:00:05Z"],
            "the telemetry's stamps, -9.95 s to 4 s from it, leave the years 1 to 9999",
        ),
    ],
)
def test_a_time_offset_whose_stamps_cannot_hold_the_times_is_refused(
    args: list[str], message: str, tmp_path: Path
) -> None:
    """Before, ``simulate`` wrote telemetry that its own ``identify`` refused ("time stamps
    must increase strictly") or raised a traceback; now it is refused before the flight,
    naming the offset, and writes nothing."""
    telemetry = tmp_path / "t.csv"
    out = tmp_path / "s.npz"
    command = ["simulate", "-n", "1", "--telemetry", str(telemetry), "--out", str(out)]
    assert message in refused([*command, *args])
    assert not telemetry.exists() and not out.exists()


def test_stamps_at_a_large_offset_are_written_with_the_digits_they_need(tmp_path: Path) -> None:
    """At 1e12 s, 15 digits are 10 ms: 125 Hz stamps (8 ms apart) were written up to 4 ms
    off their times; a float holds them to 0.06 ms, and they are written so."""
    from cli_support import run_cli

    telemetry = tmp_path / "t.csv"
    run_cli(["simulate", "-n", "1", "--sample-rate", "125", "--time-offset", "1e12",
             "--telemetry", str(telemetry)])  # fmt: skip
    rows = telemetry.read_text().splitlines()[1:]
    stamps = np.array([float(row.split(",")[0]) for row in rows]) - 1e12
    assert np.max(np.abs(stamps - np.arange(1, len(rows) + 1) / 125)) < 0.01 / 125


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # Refused once the flight was done and --out written (exit 1, the .npz replaced).
        (["-n", "2", "--realisation", "5"], "--realisation 5 but only 2 simulated"),
        # Basilisk flies one series: -n and --realisation were dropped without a word.
        (["--engine", "basilisk", "-n", "5"], "-n applies with --engine numpy only"),
        (
            ["--engine", "basilisk", "--realisation", "1", "-n", "2"],
            "-n, --realisation apply with --engine numpy only",
        ),
    ],
)
def test_a_realisation_simulate_cannot_write_is_refused_before_anything_is_written(
    args: list[str], message: str, tmp_path: Path
) -> None:
    telemetry, out = tmp_path / "t.csv", tmp_path / "s.npz"
    command = ["simulate", "--telemetry", str(telemetry)]
    if "basilisk" not in args:
        command += ["--out", str(out)]
    assert message in refused([*command, *args])
    assert not telemetry.exists() and not out.exists()


@pytest.mark.parametrize(
    "args",
    [
        # Blamed on the scenario: "overflow to inf or nan ... with every source of noise
        # off: the scenario's torques or inertia are likely wrong in units".
        ["--process-noise", "nan"],
        # Named measurement_noise_scale, an argument of the core, not the option.
        ["--measurement-noise", "nan"],
        # Flown: a gyro noise of 1e297 rad/s, telemetry that identify refuses.
        ["--measurement-noise", "1e300"],
        ["--process-noise", "1001"],
    ],
)
def test_simulate_refuses_a_noise_multiple_a_sweep_refuses_naming_the_option(
    args: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "s.npz"
    message = refused(["simulate", "-n", "1", "--out", str(out), *args])
    assert f"{args[0]} {float(args[1]):g}: a multiple of the scenario's own, 0 to 1000" in message
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # Refused as "fuel_weight must be finite", the core's name, once the bar had started.
        (["--method", "random", "--fuel-weight", "nan"], "--fuel-weight nan: give a finite"),
        (["--method", "ppo", "--lagrangian-lr", "inf"], "--lagrangian-lr inf: give a finite"),
        # Refused as "lagrangian_lr applies to method ppo only", after the bar had started.
        (
            ["--method", "random", "--lagrangian-lr", "1"],
            "--lagrangian-lr applies to --method ppo only, not 'random'",
        ),
        # NSGA-II has no reward: these ran and were dropped without a word (nan too).
        (["--method", "nsga2", "--fuel-weight", "3"], "--fuel-weight weighs the reward of"),
        (
            ["--method", "nsga2", "--constraint-penalty", "5"],
            "--constraint-penalty weighs the reward of --method ppo, cem, random or exhaustive",
        ),
        (["--method", "nsga2", "--constraint-penalty", "nan"], "--constraint-penalty nan"),
    ],
)
def test_a_search_weight_that_is_not_finite_or_has_no_effect_is_refused_before_it_runs(
    args: list[str], message: str, tmp_path: Path
) -> None:
    result = CliRunner().invoke(
        main,
        ["search", "--length", "1", "--timesteps", "5", "--out", str(tmp_path / "s.json"), *args],
    )
    assert result.exit_code == 1 and message in " ".join(result.output.split()), result.output
    assert "searching" not in result.output and not (tmp_path / "s.json").exists()


@pytest.mark.parametrize("method", ["nsga2", "exhaustive"])
@pytest.mark.parametrize(("option", "value"), [("--timesteps", "50"), ("--patience", "5")])
def test_a_search_budget_the_method_does_not_spend_is_refused_before_it_runs(
    method: str, option: str, value: str, tmp_path: Path
) -> None:
    """NSGA-II's budget is its generations and exhaustive scores every sequence: both
    ran with --timesteps or --patience and dropped it without a word."""
    out = tmp_path / "s.json"
    message = refused(
        ["search", "--method", method, "--length", "1", option, value, "--out", str(out)]
    )
    assert f"{option} applies to --method ppo, cem or random, not '{method}'" in message
    assert not out.exists()


@pytest.mark.parametrize(
    ("option", "value"),
    [("--estimate-start-within", "nan"), ("--pre-start-window", "inf")],
)
def test_identify_refuses_a_window_that_is_not_finite_once_by_its_option(
    option: str, value: str, tmp_path: Path
) -> None:
    """It was refused file by file (two JSON error lines for a folder of two), by the
    core's names estimate_start_within_s and pre_start_window_s."""
    for name in ("a.csv", "b.csv"):
        (tmp_path / name).write_text("time_s,wx_rad_s,wy_rad_s,wz_rad_s\n")
    message = refused(["identify", "--classifier", __file__, option, value, str(tmp_path)])
    assert message == f"Error: {option} {value}: give a finite number of seconds >= 0"


def test_a_named_pipe_in_a_telemetry_folder_is_not_waited_on(tmp_path: Path) -> None:
    import os

    from inertia_id.cli.classify import _telemetry_files

    (tmp_path / "a.csv").write_text("time_s,wx_rad_s,wy_rad_s,wz_rad_s\n")
    os.mkfifo(tmp_path / "pipe.csv")
    assert _telemetry_files((str(tmp_path),)) == [str(tmp_path / "a.csv")]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # Options that shape one output only, given without it: each was dropped silently.
        (["simulate", "-n", "1", "--candidate", "2"], "--candidate applies with --telemetry only"),
        (
            ["simulate", "-n", "1", "--realisation", "0", "--time-offset", "100"],
            "--realisation, --time-offset apply with --telemetry only",
        ),
        (["search", "--method", "cem", "--policy", "p.zip"], "--policy applies to --method ppo"),
        (
            ["train", "--kind", "clustering", "--metric", "euclidean", "--band", "3"],
            "applies to metric 'dtw' only, not 'euclidean'",
        ),
        # JSON text was written into a file named for another format.
        (["simulate", "-n", "1", "--out", "s.csv"], "simulate writes .npz (arrays) or .json"),
        (["search", "--out", "r.csv"], "this command writes JSON; name the file .json"),
        (["train", "--out", "c.NPZ"], "got 'c.NPZ'"),
        # An empty list read as the default front, and as no other classifiers.
        (["search", "--method", "nsga2", "--objectives", " , "], "--objectives names none"),
        # (Any existing file as the classifier: the list is checked before it is read.)
        (["sweep", "--classifier", __file__, "--others", ""], "--others names none, got ''"),
    ],
)
def test_an_option_that_would_be_ignored_is_refused(
    args: list[str], message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    assert message in refused(args)
    assert list(tmp_path.iterdir()) == []  # nothing simulated or searched, nothing written


def test_simulate_writes_arrays_to_an_npz_name_in_any_case_with_the_names(tmp_path: Path) -> None:
    """``S.NPZ`` got JSON text (the check was case-sensitive), and numpy would have added
    ".npz" to the name; the arrays now come with the candidates' names and the impulse."""
    out = tmp_path / "S.NPZ"
    result = CliRunner().invoke(main, ["simulate", "-n", "2", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["S.NPZ"]
    with np.load(out) as arrays:
        assert arrays["omega_measured_rad_s"].shape[:2] == (5, 2)
        assert list(arrays["candidate_names"]) == Scenario.paper().candidate_names
        assert float(arrays["impulse_nms"]) == 24.0


def test_a_simulation_past_the_memory_available_is_refused_before_it_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Linux overcommits: `simulate -n 100000000` grew to 21 GB and was killed, the
    # MemoryError handler never reached. 10**12 realisations need more than any machine.
    monkeypatch.chdir(tmp_path)
    message = refused(["simulate", "-n", str(10**12), "--out", "big.npz"])
    assert "-n 1000000000000: 5 candidates x 1000000000000 realisations x 80 samples" in message
    assert "need about 86.4 PB" in message and "of memory available" in message
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "asked"),
    [
        (["simulate", "-n", "1"], "-n 1: 5 candidates x 1 realisation x 80 samples"),
        (["train", "--kind", "least-squares", "-n", "3"], "-n 3: 5 candidates x 3 realisations"),
    ],
)
def test_sizes_past_the_memory_available_are_refused_naming_them(
    args: list[str], asked: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from inertia_id.cli import options

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(options, "available_memory_bytes", lambda: 1000)
    message = refused(args)
    assert asked in message and "more than the 1 KB of memory available" in message
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_past_the_memory_available_is_refused_naming_its_sizes(
    paper: Scenario, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from inertia_id.cli import options

    path = tmp_path / "c.json"
    train_classifier(paper, SEQUENCE, 3, np.random.default_rng(0), kind="least-squares").save(path)
    monkeypatch.setattr(options, "available_memory_bytes", lambda: 1000)
    message = refused(["sweep", "--classifier", str(path), "--n-test", "50", "--n-train", "7"])
    assert "--n-test 50, --n-train 7: 5 candidates x 10 realisations x 80 samples" in message


def test_the_memory_available_is_read_from_meminfo(tmp_path: Path) -> None:
    from inertia_id.cli.options import available_memory_bytes

    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:  2048 kB\nMemAvailable:    1024 kB\n")
    assert available_memory_bytes(str(meminfo)) == 1024 * 1024
    # Unknown (not Linux, a file without the line): no check rather than a refusal.
    assert available_memory_bytes(str(tmp_path / "missing")) is None
    meminfo.write_text("MemTotal:  2048 kB\n")
    assert available_memory_bytes(str(meminfo)) is None


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # Each wrote JSON text into a file named for another format.
        (
            ["plan", "--sequence", "4,4,4,0,0,0", "--out", "plan.npz"],
            "(to any name of no other known format); name the file .csv or .json, got 'plan.npz'",
        ),
        (["plan", "--sequence", "4,4,4,0,0,0", "--out", "plan.XLSX"], "got 'plan.XLSX'"),
        (["scenario", "--out", "s.npz"], "this command writes JSON; name the file .json"),
        # Refused by click like search's --out: exit 2 for each (simulate's was 1).
        (["simulate", "-n", "1", "--out", "foo.txt"], "simulate writes .npz (arrays) or .json"),
        (["search", "--out", "r.csv"], "got 'r.csv'"),
    ],
)
def test_an_out_named_for_a_format_not_written_is_a_usage_error(
    args: list[str], message: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert message in " ".join(result.output.split())
    assert list(tmp_path.iterdir()) == []


def test_plan_writes_csv_to_a_csv_name_and_json_to_others(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    for name in ("plan.csv", "plan.json", "plan"):
        result = CliRunner().invoke(main, ["plan", "--sequence", "4,4,4,0,0,0", "--out", name])
        assert result.exit_code == 0, result.output
    assert not (tmp_path / "plan.csv").read_text().startswith("{")
    # The same plan but for when each was written.
    as_json, plain = (json.loads((tmp_path / name).read_text()) for name in ("plan.json", "plan"))
    assert as_json.pop("exported_at") <= plain.pop("exported_at") and as_json == plain


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (["--kind", "least-squares"], "training least-squares classifier on 5 candidates x 3"),
        (["--kind", "1nn", "--metric", "euclidean"], "training 1nn euclidean classifier on 5"),
        # One realisation a candidate: "x 1 realisations" before.
        (["--metric", "euclidean", "-n", "1"], "on 5 candidates x 1 realisation ...\n"),
    ],
)
def test_train_names_its_classifier_without_a_double_space(
    args: list[str], line: str, tmp_path: Path
) -> None:
    # A kind without a metric read "training marginal-likelihood  classifier".
    result = CliRunner().invoke(
        main, ["train", "-n", "3", *args, "--out", str(tmp_path / "c.json")]
    )
    assert result.exit_code == 0, result.output
    assert line in result.stderr and "  " not in result.stderr.splitlines()[0]


@pytest.fixture
def nearest(paper: Scenario, tmp_path: Path) -> Path:
    path = tmp_path / "c.json"
    model = train_classifier(
        paper, SEQUENCE, 3, np.random.default_rng(0), kind="nearest-centroid", metric="euclidean"
    )
    model.save(path)
    return path


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        # What click refuses before the command runs: 2.
        (["simulate", "--seed", "-1"], 2, "-1 is not in the range 0<=x<=2147483647"),
        (["simulate", "--sample-rate", "0"], 2, "0.0 is not in the range 0.01<=x<=10000"),
        (["sweep", "--classifier", "missing.json"], 2, "'missing.json' does not exist"),
        (["simulate", "--bogus"], 2, "No such option '--bogus'"),
        # A value the command refuses once it has read it: 1, as the README says.
        (
            ["sweep", "--classifier", "{classifier}", "--multiples", "2000"],
            1,
            "must be at most 1000",
        ),
        (
            ["identify", "--classifier", "{classifier}", "--estimate-start-within", "1000"],
            1,
            "at most 4,001 (±100 s at this step)",
        ),
    ],
)
def test_the_exit_status_is_as_the_readme_states(
    args: list[str],
    code: int,
    message: str,
    nearest: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)
    telemetry = tmp_path / "t.csv"
    telemetry.write_text(
        "time_s,wx_rad_s,wy_rad_s,wz_rad_s\n"
        + "".join(f"{0.05 * (i + 1):g},0,0,0\n" for i in range(80))
    )
    args = [a.format(classifier=nearest) for a in args]
    if args[0] == "identify":
        args.append(str(telemetry))
    result = CliRunner().invoke(main, args)
    assert result.exit_code == code, result.output
    assert message in " ".join(result.output.split()) and "Traceback" not in result.output


def _twice(text: str, first: str) -> str:
    """``text`` (JSON) with the key-value pair that starts at ``first`` given twice."""
    start = text.index(first)
    depth, end = 0, start + len(first)
    for end in range(start + len(first), len(text)):
        depth += text[end] in "[{"
        depth -= text[end] in "]}"
        if depth < 0 or (depth == 0 and text[end] == ","):
            break
    pair = text[start:end]
    return text[:end] + ", " + pair + text[end:]


def test_a_key_given_twice_in_a_json_file_is_refused_naming_it(
    paper: Scenario, nearest: Path, tmp_path: Path
) -> None:
    """``json`` keeps the last of two values without a word: a telemetry file with two
    ``omega_rad_s`` was judged on the second, a scenario with two ``inertia_candidates``
    flown with the second (a hostile review). Every JSON file the commands read is read
    with :func:`inertia_id.checks.loads_unique_keys`."""
    telemetry = tmp_path / "t.json"
    rates = {"time_s": [0.05 * (i + 1) for i in range(80)], "omega_rad_s": [[0, 0, 0]] * 80}
    telemetry.write_text(_twice(json.dumps(rates), '"omega_rad_s"'))
    message = refused(["identify", "--classifier", str(nearest), str(telemetry)])
    assert "telemetry JSON has a duplicate key 'omega_rad_s' in the top-level object" in message

    scenario = tmp_path / "s.json"
    text = json.dumps(paper.model_dump(mode="json"))
    scenario.write_text(_twice(text, '"inertia_candidates"'))
    message = refused(["simulate", "-n", "1", "--scenario", str(scenario)])
    assert f"scenario {str(scenario)!r} has a duplicate key 'inertia_candidates' in the " in message
    scenario.write_text(_twice(text, '"gyro_noise_sigma_rad_s"'))
    message = refused(["simulate", "-n", "1", "--scenario", str(scenario)])
    assert "duplicate key 'gyro_noise_sigma_rad_s' in object at uncertainty" in message

    search = tmp_path / "search.json"
    document = {"best": {"sequence": SEQUENCE}, "scenario": paper.model_dump(mode="json")}
    search.write_text(_twice(json.dumps(document), '"best"'))
    message = refused(["plan", "--search", str(search), "--out", "-"])
    assert "has a duplicate key 'best' in the top-level object" in message

    classifier = tmp_path / "c.json"
    classifier.write_text(_twice(nearest.read_text(), '"version"'))
    telemetry.write_text(json.dumps(rates))
    message = refused(["identify", "--classifier", str(classifier), str(telemetry)])
    assert "classifier document has a duplicate key 'version' in the top-level" in message
    with pytest.raises(InputError, match="duplicate key 'version'"):
        load_classifier(classifier)


def test_a_grace_over_an_hour_is_refused_naming_it(tmp_path: Path) -> None:
    """Before, any grace up to 1e9 s ran (a tiny search here, so it fails fast)."""
    args = ["search", "--method", "random", "--length", "1", "--timesteps", "2"]
    args += ["--search-realisations", "2", "--fresh-realisations", "2"]
    args += ["--out", str(tmp_path / "s.json"), "--time-limit", "60"]
    message = refused([*args, "--time-limit-grace", "3600.5"])
    assert "'--time-limit-grace': 3600.5 is not in the range 0<=x<=3600" in message
    assert not (tmp_path / "s.json").exists()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        # One sentence for every number refused, a finite one under the floor too.
        ("0", "must be a finite number of seconds >= 1, got 0.0"),
        ("-5", "must be a finite number of seconds >= 1, got -5.0"),
        # Less than a second is no budget, most likely milliseconds meant as seconds.
        ("1e-9", "must be a finite number of seconds >= 1, got 1e-09"),
        ("0.5", "must be a finite number of seconds >= 1, got 0.5"),
        ("inf", "must be a finite number of seconds >= 1, got inf"),
        ("nan", "must be a finite number of seconds >= 1, got nan"),
        ("1_0", "'1_0' is not a decimal number"),
    ],
)
def test_train_refuses_a_time_limit_that_is_no_number_of_seconds(
    value: str, message: str, tmp_path: Path
) -> None:
    """As ``search --time-limit`` is refused (train had no --time-limit)."""
    out = tmp_path / "c.json"
    result = CliRunner().invoke(main, ["train", "--time-limit", value, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert "'--time-limit'" in result.output and message in " ".join(result.output.split())
    assert not out.exists()


@pytest.mark.parametrize("value", ["1e-9", "0.5"])
def test_search_refuses_a_time_limit_under_a_second(value: str, tmp_path: Path) -> None:
    """As a job's ``time_limit_s`` is: ``search --time-limit 1e-9`` ran, one sequence
    and its re-score, a limit that is most likely milliseconds meant as seconds."""
    out = tmp_path / "s.json"
    result = CliRunner().invoke(main, ["search", "--time-limit", value, "--out", str(out)])
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert f"'--time-limit': must be a finite number of seconds >= 1, got {float(value)!r}" in said
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        # What click reads with int() or float(): a usage error, 2.
        (["simulate", "-n", "1_0"], 2, "'1_0' is not a whole number"),
        (["simulate", "-n", "\uff11"], 2, "'\uff11' is not a whole number"),
        (["simulate", "-n", "1", "--sample-rate", "2_0"], 2, "'2_0' is not a decimal number"),
        (["search", "--time-limit", "1_0"], 2, "'1_0' is not a decimal number"),
        (["search", "--time-limit", "\uff11"], 2, "'\uff11' is not a decimal number"),
        (["search", "--time-limit-grace", "1_0"], 2, "'1_0' is not a decimal number"),
        (["search", "--time-limit-grace", "-1"], 2, "-1.0 is not in the range 0<=x<="),
        # An option that would have no effect is refused: 1.
        (["search", "--time-limit-grace", "5"], 1, "--time-limit-grace applies with --time-limit"),
        # What the command reads itself: 1.
        (["simulate", "-n", "1", "--sequence", "4,4,4,0,0,0_0"], 1, "'4,4,4,0,0,0_0' is not rows"),
        (
            ["sweep", "--classifier", "{classifier}", "--multiples", "1,1_0"],
            1,
            "'1_0' is not a decimal number",
        ),
        (
            ["search", "--method", "cem", "--length", "1", "--cem", "population=6_4"],
            1,
            "--cem population must be a number written in ASCII digits with no separator",
        ),
        (["search", "--design-noise", "1_0,1"], 1, "'1_0' is not a decimal number"),
        (["search", "--method", "cem", "--radius", "1_0"], 1, "got '1_0'"),
        (
            ["identify", "--classifier", "{classifier}", "--sequence-start", "1_0"],
            1,
            "--sequence-start = '1_0' is not a decimal number",
        ),
        (["identify", "--classifier", "{classifier}"], 1, "CSV data row 2 is not numeric: '1_0'"),
    ],
)
def test_a_number_with_an_underscore_is_refused_not_read_as_another(
    args: list[str],
    code: int,
    message: str,
    nearest: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``float("1_0")`` is 10 and ``int("\uff11")`` is 1: ``--multiples 1_0`` swept ten times
    the noise, a telemetry cell ``1_0`` read as 10 (a hostile review)."""
    monkeypatch.chdir(tmp_path)
    telemetry = tmp_path / "t.csv"
    rows = [f"{0.05 * (i + 1):g},0,0,0\n" for i in range(80)]
    rows[1] = "0.1,1_0,0,0\n"
    telemetry.write_text("time_s,wx_rad_s,wy_rad_s,wz_rad_s\n" + "".join(rows))
    args = [a.format(classifier=nearest) for a in args]
    if args[0] == "identify":
        args.append(str(telemetry))
    result = CliRunner().invoke(main, args)
    assert result.exit_code == code, result.output
    assert message in " ".join(result.output.split()) and "Traceback" not in result.output


def test_a_plan_whose_rates_no_gyro_measures_is_one_line_and_exit_1(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A scenario of an inertia in the wrong units (1e-30 kg m²) was planned: 1e30 rad/s
    written to plan.json as a prediction. Refused in one line, exit 1, nothing written."""
    document = Scenario.paper().model_dump(mode="json")
    document["inertia_candidates"][0]["inertia_kg_m2"] = (1e-30 * np.eye(3)).tolist()
    document["candidate_generator"] = None
    (tmp_path / "tiny.json").write_text(json.dumps(document))
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(
        main, ["plan", "--scenario", "tiny.json", "--sequence", "4,4,4,0,0,0", "--out", "p.json"]
    )
    assert result.exit_code == 1, result.output
    assert result.output.count("\n") == 1 and "Traceback" not in result.output
    assert result.output.startswith("Error: sequence [[4, 4, 4, 0, 0, 0]] spins candidate")
    assert "deg/s" in result.output and "no attitude gyro measures it" in result.output
    assert not (tmp_path / "p.json").exists()


def test_every_command_that_flies_a_users_sequence_refuses_rates_no_gyro_measures(
    tmp_path: Path, paper: Scenario
) -> None:
    """The plan's rule, everywhere a user's sequence is flown on a user's scenario: a
    sphere of 0.019 kg m² under one full-duty step reads up to 96 rad/s at the gyro's
    samples and is left at 105 rad/s once the lag has emptied. ``simulate`` wrote it,
    ``train`` trained on it and ``search`` searched it (its hand-designed baseline past
    the ceiling); each now refuses in one line, exit 1, naming the candidate and the rate.
    A sweep refuses a scenario whose thrusters spin the classifier's sequence past it."""
    document = paper.model_dump(mode="json")
    document["inertia_candidates"][0]["inertia_kg_m2"] = (0.019 * np.eye(3)).tolist()
    document["candidate_generator"] = None
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps(document))
    rate = "spins candidate 'none ejected' to 105 rad/s (6,031 deg/s)"
    for args in (
        ["simulate", "-n", "2", "--sequence", "4,4,4,0,0,0", "--out", str(tmp_path / "s.npz")],
        ["train", "-n", "3", "--sequence", "4,4,4,0,0,0", "--out", str(tmp_path / "c.json")],
        [
            *("search", "--method", "random", "--length", "1", "--timesteps", "2"),
            *("--search-realisations", "2", "--fresh-realisations", "2"),
            *("--out", str(tmp_path / "r.json")),
        ],
    ):
        result = CliRunner().invoke(main, [*args, "--scenario", str(tiny)])
        assert result.exit_code == 1, (args[0], result.output)
        *_, error = result.output.splitlines()  # after a progress line, if any
        assert error.startswith("Error: ") and "Traceback" not in result.output
        assert rate in error, result.output
    assert "its hand-designed baseline of 1 steps" in result.output
    assert not list(tmp_path.glob("[scr].*"))
    classifier = train_classifier(
        paper, SEQUENCE, 3, np.random.default_rng(0), kind="nearest-centroid", metric="euclidean"
    )
    strong = paper.model_dump(mode="json")
    strong["thrusters"]["torque_matrix_nm"] = [
        [1000 * v for v in row] for row in strong["thrusters"]["torque_matrix_nm"]
    ]
    with pytest.raises(InputError, match="beyond any attitude gyro's range"):
        sweep_with_limit(
            classifier, SweepRequest(), seed=0, scenario=Scenario.model_validate(strong)
        )


@pytest.mark.parametrize("out", ["plan.csv", "plan.json"])
def test_a_plan_that_cannot_be_written_whole_leaves_no_truncated_file(
    tmp_path: Path, out: str
) -> None:
    # A file-size limit of 2 KiB stands in for a disk that fills mid-write (EFBIG as
    # ENOSPC; Python ignores SIGXFSZ). Before: exit 1, "Error: [Errno 27] File too large"
    # naming no file, and plan.csv left holding its first 2,048 bytes, a command plan
    # cut short under the name asked for.
    args = ["plan", "--sequence", "4,4,4,0,0,0;4,4,4,0,0,0;0,0,0,4,4,4", "--out"]
    earlier = tmp_path / "earlier.csv"
    assert CliRunner().invoke(main, [*args, str(earlier)]).exit_code == 0  # warm, and whole
    target = tmp_path / out
    target.write_text("the plan flown last week\n", encoding="utf-8")
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (2048, hard))
    try:
        message = refused([*args, str(target)])
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert f"could not write {target}: File too large; nothing was written there" in message
    assert target.read_text(encoding="utf-8") == "the plan flown last week\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["earlier.csv", out])
    # With room, the same command writes the whole plan.
    assert CliRunner().invoke(main, [*args, str(target)]).exit_code == 0
    assert target.stat().st_size > 2048


def test_a_classifier_that_cannot_be_saved_whole_leaves_the_earlier_document(
    tmp_path: Path,
) -> None:
    # Before: `train --out` under a 8 KiB file-size limit left the first 8,192 bytes of
    # the document ("classifier document is not JSON" on load), the error naming no file.
    model = train_classifier(
        Scenario.paper(),
        SEQUENCE,
        5,
        np.random.default_rng(0),
        kind="nearest-centroid",
        metric="euclidean",
    )
    path = tmp_path / "classifier.json"
    model.save(path)
    earlier = path.read_bytes()
    assert len(earlier) > 8192
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (8192, hard))
    try:
        with pytest.raises(OSError, match="File too large") as raised:
            model.save(path)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert raised.value.filename == str(path)
    assert path.read_bytes() == earlier
    assert [p.name for p in tmp_path.iterdir()] == ["classifier.json"]
    assert load_classifier(path).to_json() == model.to_json()


_SMALL_PPO = ["search", "--method", "ppo", "--length", "2", "--timesteps", "64"]
_SMALL_PPO += ["--search-realisations", "2", "--ppo", "n_steps=32", "--ppo", "batch_size=32"]
_SMALL_PPO += ["--fresh-test-series", "0"]


def test_a_policy_that_cannot_be_saved_whole_leaves_the_earlier_zip(tmp_path: Path) -> None:
    # Before: stable-baselines3 wrote the zip in place, so under a 2 KiB file-size limit
    # `search --policy p.zip` left its first 2,048 bytes (no zip) and said only
    # "Error: [Errno 27] File too large", naming no file.
    policy, out = tmp_path / "p.zip", tmp_path / "s.json"
    args = [*_SMALL_PPO, "--policy", str(policy), "--out", str(out)]
    assert CliRunner().invoke(main, args).exit_code == 0  # warm, and whole
    earlier = policy.read_bytes()
    assert len(earlier) > 2048
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (2048, hard))
    try:
        message = refused(args)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert f"could not write {policy}: File too large; nothing was written there" in message
    assert policy.read_bytes() == earlier
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.zip", "s.json"]


def test_a_policy_is_reported_under_the_name_it_was_saved_as(tmp_path: Path) -> None:
    # stable-baselines3 adds ".zip" to a name with no suffix only. Before: `--policy
    # p.bin` wrote p.bin and the search document said policy_path "p.bin.zip".
    from stable_baselines3 import PPO

    for name, written in (("p.bin", "p.bin"), ("policy", "policy.zip")):
        out = tmp_path / f"{name}.json"
        args = [*_SMALL_PPO, "--policy", str(tmp_path / name), "--out", str(out)]
        assert CliRunner().invoke(main, args).exit_code == 0
        doc = json.loads(out.read_text(encoding="utf-8"))
        assert doc["policy_path"] == str(tmp_path / written)
        assert PPO.load(doc["policy_path"], device="cpu").policy is not None


def test_paper_files_that_cannot_be_written_whole_leave_the_earlier_ones(tmp_path: Path) -> None:
    # Before: `paper --out-dir` wrote report.html (4.9 MB) in place, so under a 64 KiB
    # file-size limit it left the report's first 65,536 bytes and said only
    # "Error: [Errno 27] File too large".
    out = tmp_path / "paper"
    args = ["paper", "--metric", "euclidean", "-n", "10", "--search", "none"]
    args += ["--multiples", "1", "--n-test", "20", "--out-dir", str(out)]
    assert CliRunner().invoke(main, args).exit_code == 0  # warm, and whole
    earlier = {p.name: p.read_bytes() for p in out.iterdir()}
    assert len(earlier["report.html"]) > 65536 > len(earlier["classifier.json"])
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (65536, hard))
    try:
        message = refused(args)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    report = out / "report.html"
    assert f"could not write {report}: File too large; nothing was written there" in message
    assert {p.name: p.read_bytes() for p in out.iterdir()}["report.html"] == earlier["report.html"]
    assert sorted(p.name for p in out.iterdir()) == sorted(earlier)


def test_train_says_which_classifier_it_could_not_write(tmp_path: Path) -> None:
    # Before: "Error: [Errno 27] File too large: '.../c.json'", which said neither that
    # the write failed whole nor what became of the file; now the one line every --out
    # gives.
    out = tmp_path / "c.json"
    args = ["train", "--metric", "euclidean", "-n", "10", "--out", str(out)]
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (8192, hard))
    try:
        message = refused(args)
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    assert f"could not write {out}: File too large; nothing was written there" in message
    assert list(tmp_path.iterdir()) == []


def test_train_refuses_a_classifier_identify_could_not_load(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before: `train` on 73 steps of the paper preset set out to write a document that
    # `identify --classifier` could refuse (past MAX_CLASSIFIER_BYTES); now it is refused
    # by its bound before a series is simulated. 72 steps pass and go on to train.
    def trained(*args: object, **kwargs: object) -> None:
        raise InputError("the training began")

    monkeypatch.setattr("inertia_id.pipelines.train_for_sequence", trained)
    out = tmp_path / "c.json"
    message = refused(["train", "--sequence", ";".join(["4,4,4,0,0,0"] * 73), "--out", str(out)])
    assert message.startswith(
        "Error: a marginal-likelihood classifier of 5 candidates on 73 steps (4,380 rate "
        "values a series, 100 realisations a candidate) writes a document of up to "
    ), message
    assert message.endswith(
        "bytes, over the limit of 1,000,000,000 bytes a classifier file may hold (the CLI "
        "refuses to load one past it): ask for a shorter sequence"
    )
    message = refused(["train", "--sequence", ";".join(["4,4,4,0,0,0"] * 72), "--out", str(out)])
    assert message.endswith("Error: the training began")
    assert not out.exists()


def test_a_failed_write_to_a_device_or_pipe_says_what_reached_it(tmp_path: Path) -> None:
    """A device or pipe is written directly (renaming over it would replace it), so a
    failed write there may have sent part of the data. Before, every failure said
    "nothing was written there (a file it held before is left as it was)": untrue for a
    pipe whose reader stopped after 100 bytes, which had taken 65,536 of them."""
    sequence = tmp_path / "seq.txt"
    sequence.write_text(";".join(["4,4,4,0,0,0", "0,0,0,4,4,4"] * 400))
    args = ["plan", "--sequence", str(sequence), "--out"]
    if os.path.exists("/dev/full"):
        message = refused(["plan", "--sequence", "4,4,4,0,0,0", "--out", "/dev/full"])
        assert message == (
            "Error: could not write /dev/full: No space left on device; nothing was written "
            "to it (a device, written directly)"
        )
    # A reader that takes 100 bytes and stops: the pipe holds more before the write fails.
    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    taken: list[bytes] = []

    def read_100() -> None:
        with pipe.open("rb") as reader:
            taken.append(reader.read(100))

    reader = threading.Thread(target=read_100, daemon=True)
    reader.start()
    message = refused([*args, str(pipe)])
    reader.join(10)
    found = re.fullmatch(
        rf"Error: could not write {re.escape(str(pipe))}: Broken pipe; the first (\d+) of "
        r"(\d+) bytes went to it before the write failed \(a pipe, written directly\): what "
        "it got is incomplete",
        message,
    )
    assert found is not None, message
    assert 100 <= int(found[1]) < int(found[2])
    assert taken and len(taken[0]) == 100


@pytest.mark.parametrize(
    ("args", "message"),
    [
        # Before: "searching (nsga2) for a 4-step sequence ..." and the bar's first frame,
        # then the refusal, from inside the pipeline.
        (
            [
                *("search", "--preset", "paper-in-orbit", "--method", "nsga2"),
                *("--constraint", "max_final_rate_deg_s=0.01"),
            ],
            "Error: constraint max_final_rate_deg_s = 0.01 deg/s is below what the scenario's "
            "initial-rate spread alone leaves (mean over flights of |ω(0)|: 0.4572 deg/s",
        ),
        # The commanded residual in both units at once (before: an unknown constraint).
        (
            [
                *("search", "--preset", "paper-in-orbit", "--method", "nsga2"),
                *("--constraint", "max_commanded_residual_rate_deg_s=0.2"),
                *("--constraint", "max_commanded_residual_rate_rad_s=0.003"),
            ],
            "Error: constraints max_commanded_residual_rate_rad_s = 0.003 and "
            "max_commanded_residual_rate_deg_s = 0.2 bound the same rate; give one",
        ),
        # Before: the whole search ran first, and the refusal came at its front.
        (
            [
                *("search", "--method", "random", "--length", "2", "--timesteps", "8"),
                *("--constraint", "max_duration_s=0.1"),
            ],
            "Error: constraint max_duration_s = 0.1 s is below the duration of every "
            "sequence of 2 steps",
        ),
        # Before: "[0/3] searching for the sequence", then the refusal.
        (
            ["paper", "--search", "random", "--constraint", "max_propellant_kg=1"],
            "Error: constraint max_propellant_kg needs the scenario's thrusters to state",
        ),
        # Before: the whole search, then "met by 0 of 85 sequences; loosen them or search
        # longer" (a hostile review): the disturbance alone leaves the all-off sequence
        # 0.021 deg/s over 2 steps, and no sequence leaves less.
        (
            [
                *("search", "--method", "nsga2", "--length", "2"),
                *("--constraint", "max_final_rate_deg_s=0.01"),
            ],
            "Error: constraint max_final_rate_deg_s = 0.01 deg/s is below what the "
            "disturbance torque alone leaves over the sequence's 2 s (mean over flights of "
            "|ω| after the all-off sequence, the candidate it leaves fastest: 0.02096 deg/s",
        ),
        # Before: "searching (nsga2) ..." and the bar's first frame, then the refusal.
        (
            [
                *("search", "--method", "nsga2", "--length", "2"),
                *("--search-realisations", "5", "--constraint", "max_final_rate_p95_deg_s=5"),
            ],
            "Error: constraint max_final_rate_p95_deg_s bounds a spread over flights: the "
            "search needs n_realisations >= ",
        ),
        # Past a float's range.
        (
            [
                *("search", "--method", "nsga2", "--length", "2"),
                *("--constraint", "max_final_rate_rad_s=1e400"),
            ],
            "Error: constraint max_final_rate_rad_s must be a finite number >= 0, got inf",
        ),
    ],
)
def test_a_search_setting_no_sequence_can_meet_is_refused_before_any_progress(
    tmp_path: Path, args: list[str], message: str
) -> None:
    out = ["--out-dir", str(tmp_path / "p")] if args[0] == "paper" else ["--out", "s.json"]
    result = CliRunner().invoke(main, [*args, *out])
    assert result.exit_code == 1, result.output
    assert result.output.startswith(message), result.output
    assert result.output.count("\n") == 1  # the refusal's one line, and nothing before it
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["search", "paper"])
def test_a_search_runs_its_checks_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    """The checks a search's settings can fail ran before the first progress line and
    again inside the pipeline: the hand-designed baseline's nominal simulation (the
    gyro-range check) twice a search. Once now. (The paper's training is stopped after
    the search: it flies a sequence of its own.)"""
    from inertia_id import pipelines
    from inertia_id.physics import simulate as simulation

    flown: list[int] = []
    check = simulation.check_nominal_gyro_range

    def counted(*args: object, **kwargs: object) -> object:
        flown.append(1)
        return check(*args, **kwargs)  # type: ignore[arg-type]

    class Trained(Exception):
        pass

    def stop(*args: object, **kwargs: object) -> None:
        raise Trained

    monkeypatch.setattr(simulation, "check_nominal_gyro_range", counted)
    monkeypatch.setattr(pipelines, "train_for_sequence", stop)
    search = ["--method", "random"] if command == "search" else ["--search", "random"]
    args = [command, *search, "--length", "2", "--timesteps", "8"]
    args += ["--out", str(tmp_path / "s.json")] if command == "search" else []
    args += ["--out-dir", str(tmp_path / "p")] if command == "paper" else []
    result = CliRunner().invoke(main, args)
    if command == "search":
        assert result.exit_code == 0, result.output
    else:
        assert isinstance(result.exception, Trained), result.output
    assert len(flown) == 1


def test_a_scenario_whose_noise_overflows_is_refused_before_anything_runs(
    tmp_path: Path,
) -> None:
    """The service's rule on the command line: a scenario whose own noise overflows the
    rates (1e4 N m on the paper preset, within its bound) is refused by ``scenario`` and
    by every command that would simulate it; one whose multiple overflows (3e3 N m at the
    sweep's 8x, the search's 6x design noise) by the sweep and the search, naming the
    figure, its value and the multiple. Before, ``scenario`` printed it and the others
    failed in the middle of their simulation, naming no figure."""
    field = "disturbance_torque_sigma_nm"
    paths = {}
    for name, sigma in (("overflowing", 1e4), ("loud", 3e3)):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(
            Scenario.paper().with_uncertainty(**{field: sigma}).model_dump_json()
        )
    at_1x = f"{field} = 10000 N m at noise multiple 1 (the scenario's own)"
    overflowing = str(paths["overflowing"])
    for args in (
        ["scenario", "--scenario", overflowing],
        ["train", "--scenario", overflowing, "-n", "5", "--out", str(tmp_path / "c.json")],
        ["search", "--scenario", overflowing, "--method", "cem", "--out", str(tmp_path / "s.json")],
        ["simulate", "--scenario", overflowing, "-n", "2"],
    ):
        message = refused(args)
        assert at_1x in message and "inf or nan within" in message, (args, message)
    assert not (tmp_path / "c.json").exists() and not (tmp_path / "s.json").exists()
    loud = str(paths["loud"])
    message = refused(["search", "--scenario", loud, "--out", str(tmp_path / "s.json")])
    assert "at its design noise" in message and f"{field} = 3000 N m at noise multiple 6" in message
    classifier = train_classifier(
        Scenario.model_validate_json(paths["loud"].read_text()),
        SEQUENCE,
        5,
        np.random.default_rng(0),
        kind="nearest-centroid",
        metric="euclidean",
    )
    classifier.save(tmp_path / "loud-classifier.json")
    message = refused(
        [
            "sweep",
            "--classifier",
            str(tmp_path / "loud-classifier.json"),
            "--multiples",
            "1,8",
            "--out",
            str(tmp_path / "sweep.json"),
        ]
    )
    assert "process noise at multiple 8 (24000 N m)" in message
    assert f"{field} = 3000 N m at noise multiple 8" in message
    assert not (tmp_path / "sweep.json").exists()


def test_a_bound_past_int64_on_the_command_line_is_taken_as_the_number_it_is(
    tmp_path: Path,
) -> None:
    """``--constraint max_impulse_nms=1e20`` was a TypeError traceback (read as the whole
    number 10**20, which np.isfinite refused); the API took it as a float. Now a bound
    that loose holds for every sequence."""
    result = CliRunner().invoke(
        main,
        [
            *("search", "--method", "nsga2", "--length", "2", "--seed", "1"),
            *("--nsga2", "population=8", "--nsga2", "generations=1"),
            *("--nsga2", "polish_iterations=1", "--fresh-test-series", "10"),
            *("--fresh-realisations", "4", "--constraint", "max_impulse_nms=1e20"),
            *("--out", str(tmp_path / "s.json")),
        ],
    )
    assert result.exit_code == 0, result.output[-500:]
    front = json.loads((tmp_path / "s.json").read_text())["front"]
    assert front["constraints"] == {"max_impulse_nms": 1e20}


@pytest.mark.parametrize("written", ["1e0", "2E0"])
def test_a_whole_number_setting_written_as_a_decimal_is_refused_as_the_api_refuses_it(
    written: str, tmp_path: Path
) -> None:
    """``--nsga2 generations=1e0`` ran one generation: a value with no '.' that was whole
    became an int, while the API's ``{"nsga2": {"generations": 1e0}}`` is a JSON float
    and refused. A setting is an integer only when written as one, as JSON reads it."""
    message = refused(
        [
            *("search", "--method", "nsga2", "--length", "2", "--nsga2", "population=8"),
            *("--nsga2", f"generations={written}", "--search-realisations", "4"),
            *("--fresh-test-series", "0", "--out", str(tmp_path / "s.json")),
        ]
    )
    assert f"NSGA-II generations must be an integer in 1..10000, got {float(written)}" in message
    assert not (tmp_path / "s.json").exists()


def test_a_command_plans_own_json_is_planned_again(tmp_path: Path) -> None:
    """A flight team keeps the plan JSON that ``inertia-id plan`` wrote and plans it
    again (on another scenario, with flights): ``--sequence plan.json`` said the file was
    "not rows of level indices". A search's result is refused naming how to plan one of
    its members; another JSON object, naming what a sequence is."""
    first = tmp_path / "plan.json"
    result = CliRunner().invoke(
        main, ["plan", "--sequence", "4,4,4,0,0,0;0,0,0,4,4,4", "--out", str(first)]
    )
    assert result.exit_code == 0, result.output
    again = tmp_path / "again.json"
    result = CliRunner().invoke(main, ["plan", "--sequence", str(first), "--out", str(again)])
    assert result.exit_code == 0, result.output
    assert json.loads(again.read_text())["sequence"] == json.loads(first.read_text())["sequence"]
    search = tmp_path / "search.json"
    search.write_text(json.dumps({"best": {"sequence": SEQUENCE}, "front": None}))
    message = refused(["plan", "--sequence", str(search), "--out", str(again)])
    assert message == (
        f"Error: sequence {str(search)!r} is a search's result, not one sequence: plan one "
        f"of its members with `inertia-id plan --search {search} --member N` (0 is its "
        "best), or give the rows of front.members[N].sequence"
    )
    other = tmp_path / "other.json"
    other.write_text('{"rows": [[4, 4, 4, 0, 0, 0]]}')
    message = refused(["plan", "--sequence", str(other), "--out", str(again)])
    assert "is a JSON object with no 'sequence' list" in message


@pytest.mark.parametrize("command", ["simulate", "train", "plan", "paper"])
@pytest.mark.parametrize(
    ("written", "named"),
    [
        ("[[1e0,4,4,0,0,0]]", "step 1, thruster 1 is 1.0, a decimal number"),
        ("[[4,4,4,0,0,0],[0,0,0,4,4,4.0]]", "step 2, thruster 6 is 4.0, a decimal number"),
        ('{"sequence": [[4,4,4,0,0,2.5]]}', "step 1, thruster 6 is 2.5, a decimal number"),
    ],
)
def test_a_level_written_as_a_decimal_number_is_refused_as_the_service_refuses_it(
    command: str, written: str, named: str, tmp_path: Path
) -> None:
    """The API's ``sequence`` and a job's take JSON integers only; the command line read
    ``1e0`` or ``4.0`` as the level (the core's check takes a whole float), written in
    ``--sequence`` or in the file it names."""
    # Each writes into tmp_path, should the sequence be taken (it was: train wrote
    # classifier.json into the working folder).
    out = {"simulate": [], "paper": ["--out-dir", str(tmp_path / "paper")]}.get(
        command, ["--out", str(tmp_path / "out.json")]
    )
    fewer = ["-n", "3"] if command in ("simulate", "train") else []
    path = tmp_path / "sequence.json"
    path.write_text(written)
    for given in (written, str(path)):
        message = refused([command, "--sequence", given, *fewer, *out])
        assert message.count("Error:") == 1 and f"sequence {given!r}: {named}" in message


def test_a_search_file_planned_with_a_decimal_level_is_refused(tmp_path: Path) -> None:
    """``plan --search FILE``: the member's sequence is checked as ``--sequence`` is."""
    search = tmp_path / "search.json"
    search.write_text(
        json.dumps({"best": {"sequence": [[4, 4, 4, 0, 0, 0], [1.0, 0, 0, 0, 0, 0]]}})
    )
    message = refused(["plan", "--search", str(search), "--out", str(tmp_path / "p.json")])
    assert f"sequence {str(search)!r}: step 2, thruster 1 is 1.0, a decimal number" in message


def test_a_kept_plan_planned_on_another_scenario_flies_its_own_duties(tmp_path: Path) -> None:
    """A kept plan's JSON states its commands (each step's duties, its step duration):
    planned again on a scenario of other duty levels (``n_levels: 11``) its level indices
    were read as that scenario's, and full-duty firings (6.0 s of on-time) became 0.4
    duty (2.4 s) with no word. Its duties are flown at the scenario's level of the same
    duty; a duty that is no level of the scenario, or another step duration, is refused
    naming both, by every command that reads a plan's JSON."""
    kept = tmp_path / "kept.json"
    result = CliRunner().invoke(
        main, ["plan", "--sequence", "4,4,4,0,0,0;0,0,0,4,4,4", "--out", str(kept)]
    )
    assert result.exit_code == 0, result.output
    eleven = preset("paper").model_dump(mode="json")
    eleven["thrusters"]["levels"] = [i / 10 for i in range(11)]
    other = tmp_path / "eleven.json"
    other.write_text(json.dumps(eleven))
    again = tmp_path / "again.json"
    result = CliRunner().invoke(
        main, ["plan", "--sequence", str(kept), "--scenario", str(other), "--out", str(again)]
    )
    assert result.exit_code == 0, result.output
    first, second = json.loads(kept.read_text()), json.loads(again.read_text())
    assert [s["duty"] for s in second["steps"]] == [s["duty"] for s in first["steps"]]
    assert second["propellant"]["on_time_s"] == first["propellant"]["on_time_s"] == 6.0
    assert second["sequence"] == [[10, 10, 10, 0, 0, 0], [0, 0, 0, 10, 10, 10]]

    fifths = preset("paper").model_dump(mode="json")
    fifths["thrusters"]["levels"] = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    other.write_text(json.dumps(fifths))
    half = tmp_path / "half.json"
    result = CliRunner().invoke(main, ["plan", "--sequence", "2,0,0,0,0,0", "--out", str(half)])
    assert result.exit_code == 0, result.output
    for command in (["plan", "--out", str(again)], ["simulate"], ["train", "--out", str(again)]):
        message = refused([*command, "--sequence", str(half), "--scenario", str(other)])
        assert message == (
            f"Error: sequence {str(half)!r} is a command plan whose step 1, thruster 1 fires "
            "at duty 0.5, which is no duty level of scenario 'paper' (levels 0, 0.2, 0.4, "
            "0.6, 0.8, 1): its commands cannot be flown on it"
        ), command
    edited = json.loads(kept.read_text())
    edited["sequence"][1] = [0, 0, 0, 2, 2, 2]
    kept.with_name("edited.json").write_text(json.dumps(edited))
    message = refused(["plan", "--sequence", str(kept.with_name("edited.json"))])
    assert "is a command plan whose sequence and steps disagree (at step 2)" in message
    slower = preset("paper").model_dump(mode="json")
    slower["timing"]["step_duration_s"] = 2.0
    other.write_text(json.dumps(slower))
    message = refused(["plan", "--sequence", str(kept), "--scenario", str(other)])
    assert message == (
        f"Error: sequence {str(kept)!r} is a command plan of 1 s steps, and scenario 'paper' "
        "steps 2 s: its on-times would change; plan its sequence on a scenario of 1 s steps"
    )


@pytest.mark.parametrize("steps", ["5", "true", '{"duty": [1, 1, 1, 0, 0, 0]}'])
def test_a_sequence_object_whose_steps_are_no_list_is_read_by_its_sequence(
    steps: str, tmp_path: Path
) -> None:
    """A JSON object with a ``sequence`` and a ``steps`` that is no list of a plan's
    steps (``"steps": 5``) holds no plan's commands: its sequence is flown as given, as
    before plans were read by their duties (``"steps": 5`` was a TypeError traceback)."""
    path = tmp_path / "sequence.json"
    path.write_text(f'{{"sequence": [[4, 4, 4, 0, 0, 0]], "steps": {steps}}}')
    out = tmp_path / "plan.json"
    result = CliRunner().invoke(main, ["plan", "--sequence", str(path), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["sequence"] == [[4, 4, 4, 0, 0, 0]]


def test_a_search_recorded_with_linspace_levels_plans_on_the_same_scenario_named(
    tmp_path: Path,
) -> None:
    """A search result recorded its scenario's ``n_levels`` as numpy.linspace's duties
    (0.30000000000000004 at 11 levels) before levels became i / (M - 1): ``plan --search
    FILE --scenario`` the same scenario file was refused as another scenario. Its levels
    are the same to the last bit of rounding; a level another duty is refused still."""
    document = preset("paper").model_dump(mode="json")
    document["thrusters"].pop("levels")
    document["thrusters"]["n_levels"] = 11
    named = tmp_path / "eleven.json"
    named.write_text(json.dumps(document))
    recorded = preset("paper").model_dump(mode="json")
    recorded["thrusters"]["levels"] = np.linspace(0.0, 1.0, 11).tolist()
    assert recorded["thrusters"]["levels"][3] == 0.30000000000000004
    search = tmp_path / "search.json"
    search.write_text(
        json.dumps({"best": {"sequence": [[10, 0, 3, 0, 0, 0]]}, "scenario": recorded})
    )
    out = tmp_path / "plan.json"
    args = ["plan", "--search", str(search), "--scenario", str(named), "--out", str(out)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    # Planned on the scenario searched, as ever (its duties as it held them).
    assert json.loads(out.read_text())["steps"][0]["duty"][:3] == [1.0, 0.0, 0.30000000000000004]
    recorded["thrusters"]["levels"][3] = 0.35
    search.write_text(
        json.dumps({"best": {"sequence": [[10, 0, 3, 0, 0, 0]]}, "scenario": recorded})
    )
    assert "which differs from the scenario named" in refused(args)
