"""Classifier documents: the envelope, the checksum and what a damaged document says."""

from __future__ import annotations

import json
from typing import Any

import pytest

from inertia_id import InertiaClassifier, InputError
from inertia_id.classifiers import documents


def tamper(text: str, edit: Any) -> str:
    doc = json.loads(text)
    edit(doc["classifier"])
    return json.dumps(doc)


def test_the_envelope_is_plain_json(euclidean_classifier: InertiaClassifier) -> None:
    doc = json.loads(euclidean_classifier.to_json())
    assert set(doc) == {"format", "version", "sha256", "classifier"}
    assert doc["format"] == "inertia-id/classifier" and doc["version"] == documents.VERSION
    assert doc["sha256"] == documents.checksum(doc["classifier"])


@pytest.mark.parametrize(
    "edit",
    [
        lambda c: c["cluster_centers_rad_s"][0][0].__setitem__(
            0, c["cluster_centers_rad_s"][0][0][0] + 1e-6
        ),
        lambda c: c.__setitem__("scale", c["scale"] * 2),
        lambda c: c.__setitem__("max_training_distance", [9.0] * 5),
        lambda c: c["params"].__setitem__("novelty_factor", 100.0),
    ],
)
def test_tampered_document_is_rejected(euclidean_classifier: InertiaClassifier, edit: Any) -> None:
    text = tamper(euclidean_classifier.to_json(), edit)
    with pytest.raises(
        InputError,
        match=r"checksum mismatch: document says '[0-9a-f]{64}', "
        r"content hashes to '[0-9a-f]{64}'",
    ):
        InertiaClassifier.from_json(text)


def test_tampered_text_is_rejected(euclidean_classifier: InertiaClassifier) -> None:
    text = euclidean_classifier.to_json()
    assert '"f1": 1.0' in text
    with pytest.raises(InputError, match="checksum mismatch"):
        InertiaClassifier.from_json(text.replace('"f1": 1.0', '"f1": 0.5', 1))


def test_bad_documents_are_rejected(euclidean_classifier: InertiaClassifier) -> None:
    good = json.loads(euclidean_classifier.to_json())
    with pytest.raises(InputError, match="not JSON"):
        InertiaClassifier.from_json("{nope")
    with pytest.raises(InputError, match="must be a JSON object, got list"):
        InertiaClassifier.from_json("[1]")
    with pytest.raises(InputError, match="not an inertia-id/classifier document"):
        InertiaClassifier.from_json(json.dumps({**good, "format": "other"}))
    with pytest.raises(InputError, match="unsupported classifier format version 2"):
        InertiaClassifier.from_json(json.dumps({**good, "version": 2}))
    with pytest.raises(InputError, match="no classifier payload"):
        InertiaClassifier.from_json(json.dumps({**good, "classifier": [1, 2]}))
