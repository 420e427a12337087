"""The tests behind the core's checks of a number parameter, numbers made JSON-safe, and
text made safe for a CSV file; and the readers of a user's JSON and number text that
refuse what Python's own readers take silently (a key given twice, ``1_0`` read as 10).

Each caller raises its own :class:`~inertia_id.errors.InputError`, with its own message
(they name the parameter and the rule in their own words); what they share is the test.
A bool is never a number here, although Python counts it as an ``int``: ``True`` given
for a count is a mistake, not 1.
"""

from __future__ import annotations

import codecs
import io
import json
import math
import os
import re
import stat
import unicodedata
from typing import Any, TypeGuard

import numpy as np

__all__ = [
    "BIDI_CONTROLS",
    "MAX_SEED",
    "DuplicateKeyError",
    "check_seed",
    "control_characters",
    "csv_note_text",
    "finite_or_none",
    "is_integer",
    "is_number",
    "json_location",
    "loads_unique_keys",
    "number_as_written",
    "parse_decimal",
    "parse_whole",
    "read_text",
    "spreadsheet_safe",
    "spreadsheet_safe_json",
]

#: What a spreadsheet reads as the start of a formula (OWASP, "CSV injection").
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


#: The largest seed the service keeps: a 32-bit INTEGER column (PostgreSQL ``integer``).
#: The command line takes no larger one, so that a run made there can be made again as
#: a job with the same seed.
MAX_SEED = 2**31 - 1
#: The largest noise multiple a sweep visits and ``simulate`` takes
#: (:data:`inertia_id.evaluation.sweep.MAX_MULTIPLE`, which says why); here so that the
#: command line checks it without importing the sweep (and scipy).
MAX_NOISE_MULTIPLE = 1000.0


def check_seed(seed: Any, name: str = "seed") -> int:
    """A seed as numpy takes it: a whole number >= 0 (a bool is not one); else an
    :class:`~inertia_id.errors.InputError` naming it."""
    from .errors import InputError

    if not is_integer(seed, minimum=0):
        raise InputError(f"{name} must be a whole number >= 0, got {seed!r}")
    return int(seed)


def read_text(
    path: str | os.PathLike[str],
    what: str,
    *,
    gzip_limit: int | None = None,
    limit: int | None = None,
    advice: str = "",
    opening: str = "",
) -> str:
    """A UTF-8 text file's content; a file that is no such text (a binary file, another
    encoding) is an :class:`~inertia_id.errors.InputError` naming it and ``what`` it
    should have been. A missing or unreadable file raises the ``OSError``, which names
    the path. A named pipe, ``/dev/stdin`` or a process substitution (``<(cat f)``) is
    read as a file is, once.

    The memory it takes is the text twice at most, while the last piece is decoded or
    the pieces joined: a regular file is read in one buffer of its size, a stream a
    megabyte at a time, each piece decoded as it comes (the bytes' pieces, the bytes
    joined and the text had made three copies of the file at once).

    :param gzip_limit: with it, a file that is gzip (known by its magic bytes, whatever
        its name) is decompressed, at most this many bytes
        (:func:`inertia_id.gzipped.gunzip`); without it, gzip is not text.
    :param limit: with it, a plain file of more bytes is an
        :class:`~inertia_id.errors.InputError` naming the file, its size and the limit,
        raised before its content is read (a named pipe, whose size is not known
        beforehand: after ``limit + 1`` bytes of it).
    :param advice: what to do about a file over ``limit`` or not ``opening``, said after
        the limit.
    :param opening: the characters ``what`` begins with (``{`` for a JSON object): a
        stream whose first character other than JSON's whitespace is none of them is
        refused as that character comes. A stream has no size to check, and one that is
        no such text (``/dev/zero``, a disk) was read to the limit before it was refused:
        4 GB of memory for a classifier. A regular file is refused by its size, and its
        reader says what is wrong with what it holds.
    """
    from .errors import InputError
    from .gzipped import gunzip, is_gzip

    # One pass over the file (a named pipe can be read once), decoded as Path.read_text
    # decodes: UTF-8, universal newlines.
    decoder = io.IncrementalNewlineDecoder(codecs.getincrementaldecoder("utf-8")(), True)
    with open(path, "rb") as file:
        if gzip_limit is not None and is_gzip(file.peek(2)[:2]):
            data = gunzip(file, limit=gzip_limit, what=repr(os.fspath(path)))
            return _decode(decoder, data, 0, final=True, path=path, what=what)
        status = os.fstat(file.fileno())
        regular = stat.S_ISREG(status.st_mode)
        if limit is not None and regular and status.st_size > limit:
            raise InputError(_over_limit(path, f"is {status.st_size} bytes", limit, what, advice))
        # A regular file in one read of its size (read(n) allocates n before it reads, so
        # never of the limit: read(40_000_000_001) of a 2.6 MB file was a MemoryError); a
        # stream a megabyte at a time, each piece as soon as it comes (read1).
        size = status.st_size + 1 if regular else _CHUNK_BYTES
        pieces: list[str] = []
        total = 0
        begun = regular or not opening
        while True:
            ask = size if limit is None else min(size, limit + 1 - total)
            chunk = file.read(ask) if regular else file.read1(ask)
            total += len(chunk)
            if limit is not None and total > limit:
                raise InputError(
                    _over_limit(path, f"holds more than {limit} bytes", limit, what, advice)
                )
            piece = _decode(
                decoder, chunk, total - len(chunk), final=not chunk, path=path, what=what
            )
            if not begun and (first := _NOT_JSON_SPACE.search(piece)) is not None:
                begun = True
                if first.group() not in opening:
                    raise InputError(_not_opening(path, first.group(), opening, what, advice))
            pieces.append(piece)
            if not chunk:
                break
            size = _CHUNK_BYTES
    return "".join(pieces)


def _decode(
    decoder: io.IncrementalNewlineDecoder,
    chunk: bytes,
    offset: int,
    *,
    final: bool,
    path: str | os.PathLike[str],
    what: str,
) -> str:
    """``chunk``, the file's bytes from ``offset`` on, as text; bytes that are no UTF-8
    are an :class:`~inertia_id.errors.InputError` naming the file and their position."""
    from .errors import InputError

    pending = len(decoder.getstate()[0])  # a character's first bytes, from the last chunk
    try:
        return decoder.decode(chunk, final=final)
    except UnicodeDecodeError as exc:
        raise InputError(
            f"{os.fspath(path)!r} is not UTF-8 text (byte {exc.object[exc.start : exc.end]!r} "
            f"at position {offset - pending + exc.start}): it should be {what}"
        ) from None


#: The first character that is not JSON's whitespace (RFC 8259: space, tab, LF, CR).
_NOT_JSON_SPACE = re.compile(r"[^ \t\n\r]")

_CHUNK_BYTES = 1 << 20


def _not_opening(
    path: str | os.PathLike[str], found: str, opening: str, what: str, advice: str
) -> str:
    expected = " or ".join(repr(c) for c in opening)
    text = f"{os.fspath(path)!r} is not {what}: it begins with {found!r}, not {expected}"
    return f"{text}; {advice}" if advice else text


def _over_limit(path: str | os.PathLike[str], size: str, limit: int, what: str, advice: str) -> str:
    text = f"{os.fspath(path)!r} {size}, over the limit of {limit} bytes for {what}"
    return f"{text}; {advice}" if advice else text


def is_integer(
    value: Any,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    numpy: bool = True,
) -> TypeGuard[int | np.integer[Any]]:
    """``value`` is an integer (a bool is not one) in ``minimum..maximum`` (both
    inclusive, None for no bound).

    :param numpy: whether a NumPy integer counts; False where the value is stored or
        sent on as it was given (a JSON document, a settings object), which takes a
        Python ``int`` only.
    """
    kinds = int | np.integer if numpy else int
    if isinstance(value, bool) or not isinstance(value, kinds):
        return False
    return (minimum is None or value >= minimum) and (maximum is None or value <= maximum)


def is_number(value: Any, *, minimum: float, exclusive: bool = False) -> TypeGuard[int | float]:
    """``value`` is a finite real number (a bool is not one) >= ``minimum``, or >
    ``minimum`` when ``exclusive``: the test behind the kinds' checks of a number
    parameter, each with its own message."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        if not math.isfinite(value):
            return False
    except OverflowError:  # an int past a float's range (10**400): no finite float
        return False
    return value > minimum if exclusive else value >= minimum


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None and numpy scalars made
    Python's, through dicts, lists and tuples: strict JSON has no NaN or Infinity."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_none(v) for v in value]
    return value


#: The bidirectional embeddings, overrides and isolates (U+202A-U+202E, U+2066-U+2069):
#: in a name they reorder what follows on screen, so ``report\u202etxt.exe`` shows as
#: ``reportexe.txt``. (The marks U+200E, U+200F, U+061C reorder nothing and stay allowed.)
BIDI_CONTROLS = "\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069"


def control_characters(text: str) -> list[str]:
    """The control characters in ``text`` (Unicode category Cc, the line and paragraph
    separators and the bidirectional controls), as ``U+XXXX``, once each: what no name
    may hold, since a name is written into CSV and text files a line at a time, and shown
    as written."""
    found = {
        f"U+{ord(c):04X}"
        for c in text
        if unicodedata.category(c) == "Cc" or c in "\u2028\u2029" or c in BIDI_CONTROLS
    }
    return sorted(found)


def spreadsheet_safe(text: str) -> str:
    """``text`` as a CSV cell a spreadsheet shows as text: one that starts with ``=``,
    ``+``, ``-``, ``@``, a tab or a carriage return gets a leading apostrophe (OWASP's
    remedy for CSV injection), so a name such as ``=HYPERLINK(...)`` is not a formula."""
    return "'" + text if text.startswith(_FORMULA_START) else text


def spreadsheet_safe_json(value: Any) -> str:
    """``value`` as compact JSON for a CSV cell or ``#`` note whose strings a spreadsheet
    shows as text and ``json.loads`` gives back exactly: a string that would start a
    formula (see :func:`spreadsheet_safe`) has its first character written as a ``\\u``
    escape (``"\\u003dHYPERLINK(...)"``) instead of gaining an apostrophe, which changed
    the name a reader got back."""
    if isinstance(value, str):
        if value.startswith(_FORMULA_START):
            return f'"\\u{ord(value[0]):04x}' + json.dumps(value[1:], ensure_ascii=False)[1:]
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, list | tuple):
        return "[" + ",".join(spreadsheet_safe_json(v) for v in value) + "]"
    if isinstance(value, dict):
        items = (
            f"{spreadsheet_safe_json(k if isinstance(k, str) else json.dumps(k))}:"
            f"{spreadsheet_safe_json(v)}"
            for k, v in value.items()
        )
        return "{" + ",".join(items) + "}"
    return json.dumps(value)


def csv_note_text(text: str) -> str:
    """A user's text (a name) inside a CSV file's ``#`` line: as a JSON string (quoted;
    a newline or other control character escaped, so it cannot end the line) whose commas
    are written ``\\u002c``, so that a spreadsheet keeps it in the one cell the ``#``
    starts. ``json.loads`` gives the text back."""
    return json.dumps(text, ensure_ascii=False).replace(",", "\\u002c")


class DuplicateKeyError(ValueError):
    """A JSON object holds one key twice. Python's ``json`` keeps the last value without a
    word, so a flight team's file with two ``omega_rad_s`` was read as the second alone.

    A ``ValueError``, as ``json``'s own errors are, so a caller that refuses JSON it
    cannot take refuses this too; ``key`` and ``path`` (the keys and list indices from
    the top of the document to the object that holds it) let a caller say where.
    """

    def __init__(self, key: str, path: tuple[str | int, ...]) -> None:
        self.key = key
        self.path = path
        super().__init__(f"duplicate key {key!r} in {json_location(path)}")


def json_location(path: tuple[str | int, ...]) -> str:
    """Where ``path`` leads in a JSON document, as a reader writes it: ``the top-level
    object``, ``object at telemetry``, ``object at scenario.inertia_candidates[1]``."""
    if not path:
        return "the top-level object"
    text = "".join(f"[{part}]" if isinstance(part, int) else f".{part}" for part in path)
    return f"object at {text.removeprefix('.')}"


class _Duplicated(dict[str, Any]):
    """An object :func:`loads_unique_keys` found a key twice in: ``duplicate`` is the key."""

    duplicate: str = ""


def loads_unique_keys(text: str | bytes) -> Any:
    """``json.loads(text)``, but a key given twice in one object is a
    :class:`DuplicateKeyError` naming the key and the object: what every read of a
    user's JSON goes through (the API's bodies, the command line's files). Malformed JSON
    raises as ``json.loads`` does.

    The hook only counts keys as each object is built; where the object lies is worked
    out after the parse, and only when a key was repeated, so a document without one
    costs a dict per object more than ``json.loads`` (telemetry is a few objects around
    long lists of numbers).
    """
    repeated: list[_Duplicated] = []

    def build(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        built = dict(pairs)
        if len(built) == len(pairs):
            return built
        marked = _Duplicated(built)
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                marked.duplicate = key
                break
            seen.add(key)
        repeated.append(marked)
        return marked

    value = json.loads(text, object_pairs_hook=build)
    if repeated:
        key, path = _first_duplicate(value)
        raise DuplicateKeyError(key, path)
    return value


def _first_duplicate(value: Any) -> tuple[str, tuple[str | int, ...]]:
    """The first object, in document order, that :func:`loads_unique_keys` marked: its
    repeated key and its path. Walked with a stack, not recursion: the document may be
    nested as deep as ``json`` takes."""
    stack: list[tuple[Any, tuple[str | int, ...]]] = [(value, ())]
    while stack:
        node, path = stack.pop()
        if isinstance(node, _Duplicated):
            return node.duplicate, path
        if isinstance(node, dict):
            children: list[tuple[Any, tuple[str | int, ...]]] = [
                (v, (*path, k)) for k, v in node.items() if isinstance(v, dict | list)
            ]
        elif isinstance(node, list):
            children = [(v, (*path, i)) for i, v in enumerate(node) if isinstance(v, dict | list)]
        else:
            continue
        stack.extend(reversed(children))
    raise AssertionError("a marked object was not found in the document it was built in")


#: A number as a person writes one: ASCII digits, an optional sign, point and exponent.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_WHOLE = re.compile(r"[+-]?[0-9]+")
_NON_FINITE = re.compile(r"[+-]?(?:inf|infinity|nan)", re.IGNORECASE)
#: The spaces allowed around a number: ASCII ones. ``str.strip`` would also take the
#: ideographic space U+3000 and the control characters U+001C-U+001F, as ``float`` does.
_ASCII_SPACE = " \t\n\r\v\f"


def parse_decimal(text: str, *, non_finite: bool = False) -> float:
    """``float(text)`` for a number as a person writes one (``0.1``, ``-2``, ``1e-3``,
    ``.5``; ASCII spaces around it allowed), else a ``ValueError`` quoting the text: ``float``
    also takes ``1_0`` (read as 10), digits of other scripts (full-width ``１０``), and
    ``inf`` or ``nan`` in any case, none of which a flight team's file or option means.

    :param non_finite: take ``inf``, ``infinity`` and ``nan`` (any case and sign), for a
        reader whose next check names a non-finite value by where it stands (telemetry).
    """
    bare = text.strip(_ASCII_SPACE)
    if _DECIMAL.fullmatch(bare) or (non_finite and _NON_FINITE.fullmatch(bare)):
        return float(bare)
    raise ValueError(f"{text!r} is not a decimal number ({_AS_WRITTEN}, e.g. -0.25 or 1e-3)")


def parse_whole(text: str) -> int:
    """``int(text)`` for a whole number written in ASCII digits with an optional sign
    (ASCII spaces around it allowed), else a ``ValueError`` quoting the text: ``int`` also takes
    ``1_0`` (10) and other scripts' digits."""
    bare = text.strip(_ASCII_SPACE)
    if _WHOLE.fullmatch(bare):
        return int(bare)
    raise ValueError(f"{text!r} is not a whole number ({_AS_WRITTEN}, e.g. 42)")


_AS_WRITTEN = "ASCII digits with no separator"


def number_as_written(value: Any, name: str, *, whole: bool = False) -> Any:
    """A number parameter's input as a validator should take it: a string is read with
    :func:`parse_whole` (``whole``) or :func:`parse_decimal`, a bool is refused, anything
    else (a JSON number, ``None``, a list) is handed back for the parameter's own type to
    judge. A ``ValueError`` names the parameter and quotes the value.

    What the API's query and path parameters and a scenario document's numbers go
    through: pydantic's lax mode reads ``"1_0"`` as 10, ``"10.0"`` as the int 10, ``"inf"``
    as infinity and ``true`` as 1, none of which a person writing the number means.
    """
    if isinstance(value, str):
        try:
            return parse_whole(value) if whole else parse_decimal(value)
        except ValueError:
            pass
    elif not isinstance(value, bool | np.bool_):
        return value
    kind, example = ("a whole number", "42") if whole else ("a decimal number", "-0.25 or 1e-3")
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    raise ValueError(f"{name} must be {kind} ({_AS_WRITTEN}, e.g. {example}), got {shown}")
