"""Classifier documents: JSON data with a format name, a version and a SHA-256.

Every classifier kind stores itself as ``{"format", "version", "sha256", "classifier"}``
where ``sha256`` hashes the canonical JSON of the ``classifier`` payload. Models are data
(arrays as lists), never pickles, so a document from anywhere can be loaded safely; the
checksum catches a document edited or truncated in transit.
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any

from ..checks import DuplicateKeyError, loads_unique_keys, read_text
from ..errors import InputError

__all__ = ["MAX_CLASSIFIER_BYTES", "VERSION", "checksum", "parse", "read", "read_file", "write"]

VERSION = 1
#: Most bytes a classifier file may hold (:func:`~inertia_id.classifiers.registry.
#: load_classifier`): a file past it is refused by its size, unread (a pipe, one byte past
#: it; a pipe that does not begin with '{', at its first character). A document grows
#: with the square of its series: the default kind keeps its covariances as lower
#: triangles shared by the candidates, three of them at 23.8 bytes a value, and measured
#: 2.6 MB trained on the paper's 4-step sequence (240 values) and 33.8 MB on 16 steps
#: (960; ``inertia-id train --sequence``). The longest series the service trains on
#: (8,192 values) makes 2.4 GB by the same count. 4 GB is above every document the
#: service writes and still refuses a wrong file (a disk image, an endless pipe) before
#: it is read. It is no setting: what bounds the classifiers a machine loads is its
#: memory, about 12 times the file (loading the 33.8 MB one took 413 MB; 399 MB for a
#: 28 MB one, bench/classifier_load.py), most of it the whitening matrix of each of the
#: default kind's 40 noise conditions (8 bytes x 40 x 960² = 295 MB at 960 values),
#: which every verdict uses.
MAX_CLASSIFIER_BYTES = 4_000_000_000


def checksum(payload: dict[str, Any]) -> str:
    """SHA-256 of the payload's canonical JSON (sorted keys, no spaces)."""
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def write(format_name: str, payload: dict[str, Any]) -> str:
    """The document holding ``payload`` under ``format_name``."""
    return json.dumps(
        {
            "format": format_name,
            "version": VERSION,
            "sha256": checksum(payload),
            "classifier": payload,
        }
    )


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


def read(text: str | bytes | dict[str, Any], format_name: str) -> dict[str, Any]:
    """The verified payload of a ``format_name`` document."""
    doc = text if isinstance(text, dict) else parse(text)
    if doc.get("format") != format_name:
        raise InputError(f"not an {format_name} document (format {doc.get('format')!r})")
    if doc.get("version") != VERSION:
        raise InputError(f"unsupported classifier format version {doc.get('version')!r}")
    payload = doc.get("classifier")
    if not isinstance(payload, dict):
        raise InputError("classifier document has no classifier payload")
    actual = checksum(payload)
    if actual != doc.get("sha256"):
        raise InputError(
            f"classifier checksum mismatch: document says {doc.get('sha256')!r}, "
            f"content hashes to {actual!r}"
        )
    return payload
