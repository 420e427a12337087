"""Classifiers: list, get, download the checksummed document."""

from __future__ import annotations

import hashlib
import json
from datetime import datetime, timedelta
from pathlib import Path

from service_support import classifier_row

from inertia_id import InertiaClassifier, Scenario

from .support import GOOD_SEQUENCE, Api


def test_list_and_get(api: Api, classifier: InertiaClassifier, paper: Scenario) -> None:
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    other_scenario = api.create_scenario(name="other")["id"]
    other_id = api.insert_classifier(other_scenario, classifier)

    listing = api.get("/classifiers").json()
    assert listing["total"] == 2
    assert [c["id"] for c in listing["items"]] == [other_id, classifier_id]
    only = api.get("/classifiers", params={"scenario_id": scenario_id}).json()
    assert [c["id"] for c in only["items"]] == [classifier_id]

    response = api.get(f"/classifiers/{classifier_id}")
    assert response.status_code == 200
    got = response.json()
    assert got["scenario_id"] == scenario_id
    assert got["job_id"] is None
    assert got["metric"] == "euclidean"
    assert got["sequence"] == GOOD_SEQUENCE
    assert got["candidate_names"] == paper.candidate_names
    assert got["f1"] == classifier.f1_
    assert got["accuracy"] == classifier.accuracy_
    assert got["confusion"] == classifier.confusion_.tolist()
    # 10 realisations of each of the 5 candidates.
    assert sum(map(sum, got["confusion"])) == 50
    assert got["created_at"].endswith("Z")


def test_download_is_the_stored_checksummed_document(
    api: Api, classifier: InertiaClassifier
) -> None:
    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    response = api.get(f"/classifiers/{classifier_id}/download")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("application/json")
    assert f"classifier-{classifier_id}.json" in response.headers["content-disposition"]
    document = json.loads(response.text)
    # The stored document, with its provenance beside the payload (next test).
    assert {k: v for k, v in document.items() if k != "provenance"} == json.loads(
        classifier.to_json()
    )
    assert document["format"] == "inertia-id/classifier"
    canonical = json.dumps(document["classifier"], sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(canonical.encode()).hexdigest() == document["sha256"]
    assert response.headers["etag"] == f'"{document["sha256"]}"'
    loaded = InertiaClassifier.from_json(response.content)
    assert loaded.candidate_names_ == classifier.candidate_names_


def test_download_states_where_it_came_from_outside_the_checksum(
    api: Api, classifier: InertiaClassifier, tmp_path: Path
) -> None:
    """A downloaded classifier file said nothing of where it came from (a hostile review:
    a flight team keeps that file): it states the classifier's id, its training job's,
    its scenario's and when it was stored (UTC, with its zone), beside the checksummed
    payload, so that the checksum, the ETag and ``identify --classifier`` hold as before,
    and the payload is still verified by hashing its text as read."""
    from inertia_id.classifiers import documents
    from inertia_id.classifiers.registry import load_classifier_identified

    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier, with_job=True)
    stored = api.get(f"/classifiers/{classifier_id}").json()
    job_id = stored["job_id"]
    assert job_id is not None

    response = api.get(f"/classifiers/{classifier_id}/download")
    assert response.status_code == 200
    document = json.loads(response.text)
    assert document["provenance"] == {
        "classifier_id": classifier_id,
        "job_id": job_id,
        "scenario_id": scenario_id,
        "created_at": stored["created_at"],
    }
    assert document["provenance"]["created_at"].endswith("Z")
    assert datetime.fromisoformat(document["provenance"]["created_at"]).utcoffset() == timedelta(0)
    # The payload and its checksum are the stored classifier's.
    assert document["sha256"] == stored["sha256"] == json.loads(classifier.to_json())["sha256"]
    assert response.headers["etag"] == f'"{stored["sha256"]}"'
    # Laid out as the writer lays out a document: verified by its text as read.
    assert response.text == json.dumps(document, sort_keys=True, separators=(",", ":"))
    assert documents._verified_as_read(response.content, document)
    path = tmp_path / "kept.json"
    path.write_bytes(response.content)
    loaded, identity = load_classifier_identified(path)
    assert loaded.candidate_names_ == classifier.candidate_names_
    assert identity == {
        "file": str(path),
        "sha256": stored["sha256"],
        "provenance": document["provenance"],
    }
    assert InertiaClassifier.from_json(response.content).f1_ == classifier.f1_


def test_download_of_a_document_stored_in_another_layout_states_its_provenance(
    api: Api, classifier: InertiaClassifier
) -> None:
    """A document stored indented (as documents were written before the canonical
    layout) gets its provenance too, and still verifies."""
    scenario_id = api.create_scenario()["id"]
    row = classifier_row(scenario_id, classifier)
    row.document = json.dumps(json.loads(row.document), indent=1)
    with api.db.session() as session:
        session.add(row)
        session.flush()
        classifier_id = row.id
    response = api.get(f"/classifiers/{classifier_id}/download")
    assert response.status_code == 200
    document = json.loads(response.text)
    assert document["provenance"]["classifier_id"] == classifier_id
    assert document["provenance"]["job_id"] is None
    assert InertiaClassifier.from_json(response.content).f1_ == classifier.f1_


def test_unknown_classifier_is_404(api: Api) -> None:
    for url in ("/classifiers/0123456789abcdef0123456789abcdef", "/classifiers/x/download"):
        response = api.get(url)
        assert response.status_code == 404
        assert "not found" in response.json()["detail"]


def test_lists_and_gets_never_read_the_document(
    api: Api, classifier: InertiaClassifier, paper: Scenario
) -> None:
    """The document of a 1-NN classifier of long series is hundreds of MB; a list or a
    GET of classifiers (no key needed) read it whole each time (a review: 1.1 GB of API
    memory for one list). Only the routes that serve it read it."""
    from sqlalchemy import event

    scenario_id = api.create_scenario()["id"]
    classifier_id = api.insert_classifier(scenario_id, classifier)
    statements: list[str] = []
    engine = api.app.state.db.engine

    def record(_conn: object, _cursor: object, statement: str, *_: object) -> None:
        statements.append(statement)

    event.listen(engine, "before_cursor_execute", record)
    try:
        for path in ("/classifiers", f"/classifiers/{classifier_id}", "/classifiers?q=dtw"):
            assert api.get(path).status_code == 200
        read = [s for s in statements if "classifiers.document" in s]
        assert statements and read == []
        assert api.get(f"/classifiers/{classifier_id}/download").status_code == 200
        assert [s for s in statements if "classifiers.document" in s]
    finally:
        event.remove(engine, "before_cursor_execute", record)
