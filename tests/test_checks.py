"""The core's number tests (inertia_id.checks): what counts as an integer or a number,
and the reader of a user's JSON that refuses a key given twice."""

from __future__ import annotations

import json
import os
import re
import tracemalloc
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from inertia_id.checks import (
    DuplicateKeyError,
    control_characters,
    csv_note_text,
    is_integer,
    is_number,
    loads_unique_keys,
    number_as_written,
    parse_decimal,
    parse_whole,
    read_text,
    spreadsheet_safe,
    spreadsheet_safe_json,
)
from inertia_id.errors import InputError


@pytest.mark.parametrize(
    ("value", "options", "expected"),
    [
        (3, {}, True),
        (True, {}, False),  # a bool given for a count is a mistake, not 1
        (np.int64(3), {}, True),
        (np.int64(3), {"numpy": False}, False),  # stored as given: a Python int only
        (3.0, {}, False),
        ("3", {}, False),
        (0, {"minimum": 1}, False),
        (1, {"minimum": 1}, True),
        (5, {"maximum": 4}, False),
        (4, {"minimum": 1, "maximum": 4}, True),
    ],
)
def test_is_integer(value: Any, options: dict[str, Any], expected: bool) -> None:
    assert is_integer(value, **options) is expected


@pytest.mark.parametrize(
    ("value", "options", "expected"),
    [
        (0.5, {"minimum": 0.0}, True),
        (0, {"minimum": 0.0}, True),
        (0, {"minimum": 0.0, "exclusive": True}, False),
        (False, {"minimum": 0.0}, False),
        (float("nan"), {"minimum": 0.0}, False),
        (float("inf"), {"minimum": 0.0}, False),
        (-1e-9, {"minimum": 0.0}, False),
        ("1", {"minimum": 0.0}, False),
    ],
)
def test_is_number(value: Any, options: dict[str, Any], expected: bool) -> None:
    assert is_number(value, **options) is expected


def test_text_is_made_safe_for_csv_files() -> None:
    """Names are the user's text: what a CSV writer does with them."""
    import csv
    import io
    import json

    from service.exports import Table, to_csv

    assert control_characters("a\u202eb\u2069") == ["U+202E", "U+2069"]
    # Marks reorder nothing: a name in Arabic or Hebrew may need them.
    assert control_characters("\u200f\u200e\u061c") == []
    assert control_characters("a\tb\r\nc\u2028d\x00") == [
        "U+0000",
        "U+0009",
        "U+000A",
        "U+000D",
        "U+2028",
    ]
    assert control_characters("payload, one éjecté =1") == []
    assert [spreadsheet_safe(t) for t in ("=1+1", "+x", "-x", "@a", "\tx", "x=1", "")] == [
        "'=1+1",
        "'+x",
        "'-x",
        "'@a",
        "'\tx",
        "x=1",
        "",
    ]
    name = 'a, b\n=HYPERLINK("x")'
    assert "," not in csv_note_text(name) and "\n" not in csv_note_text(name)
    assert json.loads(csv_note_text(name)) == name
    # An export: cells, header and notes that hold names, numbers left alone.
    text = to_csv(
        Table(["name", "=evil"], [["=1+1", -0.5], ["ok", None]], [("names", ["-x", "y"])])
    )
    lines = text.splitlines()
    # A name in a JSON note or cell keeps its text: the formula's first character is a
    # JSON escape a spreadsheet shows as text (an apostrophe changed the name read back).
    assert lines[0] == '# names: ["\\u002dx","y"]'
    assert json.loads(lines[0].removeprefix("# names: ")) == ["-x", "y"]
    nested = {"=a": ["-x", None, 1.5, {"k": "@y"}], 1: True, None: "+z"}
    assert json.loads(spreadsheet_safe_json(nested)) == json.loads(json.dumps(nested))
    rows = list(csv.reader(io.StringIO("\n".join(lines[1:]))))
    assert rows == [["name", "'=evil"], ["'=1+1", "-0.5"], ["ok", ""]]


def test_an_export_read_with_hash_comments_keeps_a_name_holding_a_hash() -> None:
    """Exports are read for their ``# name: value`` notes with ``comment="#"``: a candidate
    named ``config #2`` was cut there, and its row lost its figures (a hostile review)."""
    import csv
    import io

    import pandas as pd

    from service.exports import Table, to_csv

    names = ["stowed", "config #2 boom out", 'say "#3", gone']
    text = to_csv(
        Table(
            ["candidate", "distance", f"predicted_{names[1]}"],
            [[name, float(k), k] for k, name in enumerate(names)],
            [("candidates", names)],
        )
    )
    frame = pd.read_csv(io.StringIO(text), comment="#")
    assert list(frame.columns) == ["candidate", "distance", f"predicted_{names[1]}"]
    assert frame["candidate"].tolist() == names
    assert frame["distance"].tolist() == [0.0, 1.0, 2.0]
    rows = list(csv.reader(line for line in text.splitlines() if not line.startswith("# ")))
    assert rows[1:] == [[name, f"{float(k)!r}", str(k)] for k, name in enumerate(names)]
    assert to_csv(Table(["only"], [[""]])).splitlines() == ["only", '""']


@pytest.mark.parametrize(
    ("text", "key", "path", "where"),
    [
        ('{"a": 1, "a": 2}', "a", (), "the top-level object"),
        ('{"t": {"w": [1], "w": [2]}}', "w", ("t",), "object at t"),
        ('[{}, {"k": 1, "k": 1}]', "k", (1,), "object at [1]"),
        (
            '{"s": {"c": [{"n": "x"}, {"n": "y", "n": "z"}]}}',
            "n",
            ("s", "c", 1),
            "object at s.c[1]",
        ),
        # The outer key is named: the inner object was one of the values it overwrote.
        ('{"t": {"x": 1, "x": 2}, "t": 3}', "t", (), "the top-level object"),
        # The first in the document, however deep.
        ('{"a": {"b": {"q": 1, "q": 2}}, "c": {"r": 1, "r": 2}}', "q", ("a", "b"), "object at a.b"),
    ],
)
def test_a_key_given_twice_is_named_with_where_it_is(
    text: str, key: str, path: tuple[str | int, ...], where: str
) -> None:
    assert json.loads(text) is not None  # what json takes silently
    with pytest.raises(DuplicateKeyError) as raised:
        loads_unique_keys(text.encode())
    assert (raised.value.key, raised.value.path) == (key, path)
    assert str(raised.value) == f"duplicate key {key!r} in {where}"
    assert isinstance(raised.value, ValueError)


def test_json_without_a_key_given_twice_reads_as_json_reads_it() -> None:
    text = '{"a": [1, 2.5, {"b": null, "B": true}], "c": "\\u00e9", "d": NaN}'
    assert repr(loads_unique_keys(text)) == repr(json.loads(text))
    with pytest.raises(json.JSONDecodeError):
        loads_unique_keys('{"a": ')


@pytest.mark.parametrize(
    ("text", "expected"),
    [("0.1", 0.1), (" -2 ", -2.0), ("1e-3", 1e-3), (".5", 0.5), ("+3.", 3.0)],
)
def test_a_number_as_written_reads_as_float_reads_it(text: str, expected: float) -> None:
    assert parse_decimal(text) == float(text) == expected


@pytest.mark.parametrize(
    # (str.strip and float also take the ideographic space and U+001C-U+001F around it.)
    "text",
    ["1_0", "\uff11\uff10", "\u0663", "inf", "NaN", "", "0x10", "1\u3000", "\x1f1"],
)
def test_what_float_takes_and_no_one_writes_is_refused_quoting_it(text: str) -> None:
    with pytest.raises(ValueError, match=re.escape(repr(text))):
        parse_decimal(text)
    assert parse_decimal(" -Infinity", non_finite=True) == float("-inf")
    with pytest.raises(ValueError, match="'1_0' is not a whole number"):
        parse_whole("1_0")
    assert int("1_0") == 10 and parse_whole(" -3 ") == -3


@given(st.text(max_size=12) | st.from_regex(r"\s?[+-]?[0-9_\uff10-\uff19]{1,4}\s?", fullmatch=True))
def test_a_number_parameter_takes_a_string_only_as_the_command_line_does(text: str) -> None:
    """What the API's query numbers and a scenario's numbers go through: a string is a
    whole number exactly when it is sign and ASCII digits (spaces around), read as
    ``int`` reads it; anything else is refused naming the parameter and quoting it."""
    plain = re.fullmatch(r"[+-]?[0-9]+", text.strip(" \t\n\r\v\f")) is not None
    try:
        read = number_as_written(text, "seed", whole=True)
    except ValueError as exc:
        assert not plain
        assert str(exc).startswith("seed must be a whole number")
        assert str(exc).endswith(f"got {text!r}") or len(repr(text)) > 60
    else:
        assert plain and read == int(text)


@pytest.mark.parametrize("value", [True, np.bool_(False), "1_0", "1e1", "\uff11"])
def test_a_bool_or_a_number_not_as_written_is_no_number(value: Any) -> None:
    with pytest.raises(
        ValueError, match=f"^n must be a whole number .*got {re.escape(repr(value))}$"
    ):
        number_as_written(value, "n", whole=True)


@pytest.mark.parametrize("value", [2, 2.5, np.float64(2.5), np.int64(2), None, [1, 2]])
def test_anything_but_a_string_or_a_bool_is_left_to_the_field_type(value: Any) -> None:
    assert number_as_written(value, "x") is value


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_a_stream_over_the_byte_limit_is_refused_holding_it_once() -> None:
    # A file whose size is not known beforehand (a device, a named pipe) is read up to
    # the limit and a byte. The pieces were joined before the length was checked, so a
    # stream past the limit held it twice: `inertia-id identify --classifier /dev/zero`
    # peaked at 8.1 GB for the 4 GB limit of a classifier. Refused before the join now.
    limit = 20_000_000
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="holds more than 20000000 bytes"):
            read_text("/dev/zero", "a test document", limit=limit)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1.5 * limit, peak
