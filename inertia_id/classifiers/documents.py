"""Classifier documents: JSON data with a format name, a version and a SHA-256.

Every classifier kind stores itself as ``{"format", "version", "sha256", "classifier"}``
where ``sha256`` hashes the canonical JSON of the ``classifier`` payload. Models are data
(arrays as lists), never pickles, so a document from anywhere can be loaded safely; the
checksum catches a document edited or truncated in transit.

A document the service hands out (``GET /classifiers/{id}/download``) also carries
``provenance`` (:func:`with_provenance`): the classifier's id, its training job's id, its
scenario's id and when it was stored. It lies outside the checksummed payload, so the
``sha256`` is the stored classifier's and every reader loads the document as before;
the checksum does not guard it.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Callable
from typing import Any, BinaryIO

from ..checks import DuplicateKeyError, loads_unique_keys, read_text
from ..errors import InputError

__all__ = [
    "MAX_CLASSIFIER_BYTES",
    "PROVENANCE_KEYS",
    "VERSION",
    "checksum",
    "parse",
    "provenance_of",
    "read",
    "read_file",
    "with_provenance",
    "write",
    "writer",
]

VERSION = 1
#: Most bytes a classifier file may hold (:func:`~inertia_id.classifiers.registry.
#: load_classifier`): a file past it is refused by its size, unread; a pipe, whose size is
#: not known, one byte past it (one that does not begin with '{', at its first character),
#: so a stream that begins with '{' and never ends costs this much memory before it is
#: refused. A document grows with the square of its series: the default kind keeps its
#: covariances as lower triangles shared by the candidates, and measured 1.8 MB trained
#: on the paper's 4-step sequence (240 values) and 26.6 MB on 16 steps (960 values;
#: ``inertia-id train -n 20 --sequence``), 28.8 bytes a value squared. The paper preset's
#: 64 steps (3,840 values) make 425 MB by that count, and the longest series the service
#: trains on the paper preset (5,181 values, where its 5 candidates' covariances reach
#: 2^27 values) 773 MB: 1 GB is above both. Loading a document takes about 13 times the
#: file in memory (most of it a whitening matrix for each of the default kind's 40 noise
#: conditions, 8 bytes x 40 x values², which every verdict uses): 13 GB for one of 1 GB.
#: It was 4 GB, which a stream of '{' and blanks held before it was refused (peak RSS
#: 4.1 GB); the service's largest series of all (8,192 values, on a scenario of 2
#: candidates) made 1.9 GB, and would take 21 GB of whitening matrices to load: a training
#: whose document could pass this is refused before it runs, by the CLI and the service
#: (:func:`~inertia_id.classifiers.registry.check_document_size`).
MAX_CLASSIFIER_BYTES = 1_000_000_000


def checksum(payload: dict[str, Any]) -> str:
    """SHA-256 of the payload's canonical JSON (sorted keys, no spaces)."""
    return hashlib.sha256(_canonical(payload).encode()).hexdigest()


def _canonical(payload: Any) -> str:
    return json.dumps(payload, sort_keys=True, separators=(",", ":"))


#: A document as :func:`write` lays it out begins with this: the whole document's
#: canonical JSON (sorted keys, no spaces), so the payload's text in it is the very text
#: its checksum hashes.
_HEAD = '{"classifier":'


def _tail(format_name: Any, sha256: Any, version: Any, provenance: Any = None) -> str:
    """What follows the payload in a document :func:`write` lays out (with its
    ``provenance`` in its sorted place, when it has one: :func:`with_provenance`)."""
    origin = "" if provenance is None else f',"provenance":{_canonical(provenance)}'
    return (
        f',"format":{json.dumps(format_name)}{origin},"sha256":{json.dumps(sha256)},'
        f'"version":{json.dumps(version)}}}'
    )


#: What a document's ``provenance`` states (:func:`with_provenance`): the stored
#: classifier's id, the id of the job that trained it (null for one stored without a
#: job), its scenario's id, and when it was stored (ISO-8601 UTC, ending in Z).
PROVENANCE_KEYS = ("classifier_id", "job_id", "scenario_id", "created_at")

#: The tail :func:`write` lays out, at the end of a stored document: its format, checksum
#: and version, read without parsing the payload before it.
_PLAIN_TAIL = re.compile(
    r',"format":("(?:[^"\\]|\\.)*"),"sha256":("[0-9a-f]*"),"version":(\d+)\}[ \t\n\r]*\Z'
)


def with_provenance(document: str, provenance: dict[str, Any]) -> bytearray:
    """``document`` with ``provenance`` beside its payload, outside the checksum, as UTF-8
    bytes: the payload's text and its ``sha256`` are unchanged, so the document loads and
    verifies as before. A document laid out as :func:`write` lays it out stays so (the
    provenance goes into its tail, in its sorted place; the payload's text is encoded in
    pieces, never copied whole beside the bytes), and its payload is still verified by
    hashing the text as read; any other is parsed and laid out so, a provenance it held
    replaced."""
    tail = _PLAIN_TAIL.search(document, max(0, len(document) - 400))
    if not document.startswith(_HEAD) or tail is None:
        doc = parse(document)
        head = _HEAD + _canonical(doc.get("classifier"))
        tail_text = _tail(doc.get("format"), doc.get("sha256"), doc.get("version"), provenance)
        return bytearray((head + tail_text).encode())
    format_name, sha256, version = (json.loads(g) for g in tail.groups())
    out = bytearray()
    for at in range(0, tail.start(), _PIECE):
        out += document[at : min(at + _PIECE, tail.start())].encode()
    out += _tail(format_name, sha256, version, provenance).encode()
    return out


def provenance_of(doc: dict[str, Any]) -> dict[str, str | None] | None:
    """The document's ``provenance`` (:data:`PROVENANCE_KEYS`, each a string or null),
    None when it states none; one that is not an object of those is refused by name.
    The checksum does not cover it: it says where the file came from, as handed out."""
    provenance = doc.get("provenance")
    if provenance is None:
        return None
    if not isinstance(provenance, dict):
        raise InputError(
            f"classifier document's provenance must be a JSON object, got "
            f"{type(provenance).__name__}: {_clip(provenance)}"
        )
    for key, value in provenance.items():
        if value is not None and not isinstance(value, str):
            raise InputError(
                f"classifier document's provenance.{key[:60]} must be a string or null, "
                f"got {_clip(value)}"
            )
    return {key: provenance.get(key) for key in PROVENANCE_KEYS}


def _clip(value: Any, limit: int = 60) -> str:
    text = json.dumps(value) if not isinstance(value, str) else repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def write(format_name: str, payload: dict[str, Any]) -> str:
    """The document holding ``payload`` under ``format_name``: its canonical JSON
    (``json.dumps(document, sort_keys=True, separators=(",", ":"))``), built around the
    payload's canonical text, which the checksum hashes, so that :func:`read` can verify
    the payload by hashing the text as read (it had written the default ``json.dumps``,
    whose spaces and key order left a reader only the re-encoding to hash)."""
    canonical = _canonical(payload)
    return _HEAD + canonical + _tail(format_name, _text_digest(canonical), VERSION)


def writer(format_name: str, payload: dict[str, Any]) -> Callable[[BinaryIO], None]:
    """A function that writes the document :func:`write` returns, byte for byte, to an
    open binary file (for :func:`~inertia_id.files.write_whole`), holding the payload's
    canonical text once, in the pieces the encoder made, and ``payload`` no longer once
    this returns (the caller's reference aside). :func:`write` holds that text joined,
    the encoder's pieces while it joins them, then the document made of it (what a save
    had written): a save peaked at 4.4 times the document above the classifier, now 2.5
    (the payload's lists and the text beside them while the encoder runs)."""
    # The pieces json.dumps joins (on CPython 3.11 the C encoder's, each of up to 100,000
    # small strings joined): the same text, never copied whole into one string.
    encoder = json.JSONEncoder(sort_keys=True, separators=(",", ":"))
    pieces = list(encoder.iterencode(payload, _one_shot=True))
    del payload
    tail = _tail(format_name, _text_digest(pieces), VERSION)

    def write_document(handle: BinaryIO) -> None:
        handle.write(_HEAD.encode())
        for piece in pieces:
            for at in range(0, len(piece), _PIECE):
                handle.write(piece[at : at + _PIECE].encode())
        handle.write(tail.encode())

    return write_document


def _text_digest(text: str | list[str]) -> str:
    """SHA-256 of ``text`` (a list: its strings one after another) as UTF-8, encoded in
    pieces of :data:`_PIECE` characters, never whole."""
    digest = hashlib.sha256()
    for piece in [text] if isinstance(text, str) else text:
        for at in range(0, len(piece), _PIECE):
            digest.update(piece[at : at + _PIECE].encode())
    return digest.hexdigest()


def read_file(path: str | os.PathLike[str]) -> str:
    """A classifier file's text, refused unread past :data:`MAX_CLASSIFIER_BYTES`."""
    return read_text(
        path,
        "a classifier's JSON document",
        limit=MAX_CLASSIFIER_BYTES,
        advice="is it a classifier (inertia-id train writes one)?",
        opening="{",
    )


def parse(text: str | bytes | dict[str, Any], *, unique_keys: bool = False) -> dict[str, Any]:
    """The document as a JSON object (not yet verified); one parsed already as it is.

    :param unique_keys: refuse a key given twice in one object, naming it: for a document
        a user hands over (a file), where ``json`` would keep the last value silently. The
        service's own stored documents (``json.dumps`` of a dict, which cannot repeat a
        key) are read without the check's cost.
    """
    if isinstance(text, dict):
        return text
    try:
        doc = loads_unique_keys(text) if unique_keys else json.loads(text)
    except DuplicateKeyError as exc:
        raise InputError(f"classifier document has a {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"classifier document is not JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise InputError(f"classifier document must be a JSON object, got {type(doc).__name__}")
    return doc


def read(
    text: str | bytes | dict[str, Any],
    format_name: str,
    *,
    source: str | bytes | None = None,
) -> dict[str, Any]:
    """The verified payload of a ``format_name`` document.

    :param source: the text ``text`` was parsed from, when it is a parsed document (its
        own text otherwise): a document laid out as :func:`write` lays it out is
        verified by hashing its payload's text as read, in 1 MB pieces; any other (one
        written before, or edited since) by re-encoding the parsed payload, as every
        document was (2.9 s of the 7.7 s that loading a 28 MB one took). Both accept
        every document the writer wrote, as written or re-laid out (indented, keys
        reordered, CRLF), and refuse every one edited or truncated since. They part
        only on a document whose SHA-256 was remade by hand over a payload text that is
        not this canonical form (a number written ``1.00``, a key escaped as
        ``\u0061``, keys out of order, raw UTF-8 as ``jq -cS`` writes it): its text
        as read hashes to the stated SHA-256 and it is accepted, where the re-encoding
        (and every release before) refuses it. The checksum guards against damage, not
        against its author: whoever remakes it can state any payload either way.
    """
    doc = text if isinstance(text, dict) else parse(text)
    if source is None and not isinstance(text, dict):
        source = text
    if doc.get("format") != format_name:
        raise InputError(f"not an {format_name} document (format {doc.get('format')!r})")
    if doc.get("version") != VERSION:
        raise InputError(f"unsupported classifier format version {doc.get('version')!r}")
    payload = doc.get("classifier")
    if not isinstance(payload, dict):
        raise InputError("classifier document has no classifier payload")
    if source is not None and _verified_as_read(source, doc):
        return payload
    actual = checksum(payload)
    if actual != doc.get("sha256"):
        raise InputError(
            f"classifier checksum mismatch: document says {doc.get('sha256')!r}, "
            f"content hashes to {actual!r}"
        )
    return payload


#: JSON's whitespace (RFC 8259), which may surround the document.
_BLANKS = " \t\n\r"


def _verified_as_read(source: str | bytes, doc: dict[str, Any]) -> bool:
    """Whether ``source`` is ``doc`` laid out as :func:`write` lays it out and its
    payload's text hashes to the SHA-256 it states. The payload's text starts right after
    the head: the value of the document's first key, which is "classifier", and JSON's
    values are self-delimiting, so what the parse took for the payload is that text."""
    stated = doc.get("sha256")
    if not isinstance(stated, str):
        return False
    text = source if isinstance(source, str) else None
    if text is None:
        try:
            text = source.decode("utf-8")  # type: ignore[union-attr]
        except UnicodeDecodeError:
            return False
    start, end = 0, len(text)
    while start < end and text[start] in _BLANKS:
        start += 1
    while end > start and text[end - 1] in _BLANKS:
        end -= 1
    tail = _tail(doc.get("format"), stated, doc.get("version"), doc.get("provenance"))
    if not text.startswith(_HEAD, start) or not text.endswith(tail, start, end):
        return False
    digest = hashlib.sha256()
    first, last = start + len(_HEAD), end - len(tail)
    for at in range(first, last, _PIECE):
        digest.update(text[at : min(at + _PIECE, last)].encode())
    return digest.hexdigest() == stated


#: Characters hashed at a time: the payload's text is not copied whole.
_PIECE = 1 << 20
