"""Classifiers: list, get, download the checksummed document."""

from __future__ import annotations

import hashlib
import json

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
    assert response.text == classifier.to_json()
    document = json.loads(response.text)
    assert document["format"] == "inertia-id/classifier"
    canonical = json.dumps(document["classifier"], sort_keys=True, separators=(",", ":"))
    assert hashlib.sha256(canonical.encode()).hexdigest() == document["sha256"]
    assert response.headers["etag"] == f'"{document["sha256"]}"'
    loaded = InertiaClassifier.from_json(response.content)
    assert loaded.candidate_names_ == classifier.candidate_names_


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
