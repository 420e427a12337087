"""Every classifier kind trains, identifies and reloads through the registry."""

from __future__ import annotations

import numpy as np
import pytest

from inertia_id import (
    CLASSIFIER_KINDS,
    Scenario,
    classifier_from_json,
    identify,
    make_classifier,
    simulate,
    train_classifier,
)
from inertia_id.classifiers.registry import describe, parse_spec

GOOD = [[4, 4, 4, 0, 0, 0]] * 4
FAST_OPTIONS = {
    "clustering": {"metric": "euclidean"},
    "nearest-centroid": {"metric": "euclidean"},
    "1nn": {"metric": "euclidean"},
    "minirocket": {"n_features": 840},
    "likelihood": {},
    "least-squares": {},
    "marginal-likelihood": {},
}


@pytest.mark.parametrize("kind", CLASSIFIER_KINDS)
def test_every_kind_trains_identifies_and_round_trips(paper: Scenario, kind: str) -> None:
    model = train_classifier(
        paper, GOOD, 10, np.random.default_rng(0), kind=kind, **FAST_OPTIONS[kind]
    )
    X, y = simulate(paper, GOOD, 6, np.random.default_rng(1)).dataset()
    assert model.evaluate(X, y)["accuracy"] >= 0.9, kind
    again = classifier_from_json(model.to_json())
    assert type(again) is type(model)
    assert np.array_equal(again.predict(X), model.predict(X))
    verdict = identify(
        again, {"time_s": paper.sample_times(4).tolist(), "omega_rad_s": X[7].tolist()}
    )
    assert verdict.candidate == paper.candidate_names[y[7]]
    assert describe(model).split()[0] == kind


def test_specs_name_a_kind_and_its_metric() -> None:
    assert parse_spec("1nn:euclidean") == ("1nn", {"metric": "euclidean"})
    assert parse_spec("likelihood") == ("likelihood", {})
    with pytest.raises(ValueError, match=r"kind must be one of .* got 'knn'"):
        parse_spec("knn:dtw")
    with pytest.raises(ValueError, match="metric"):
        parse_spec("1nn:softdtw")


def test_unknown_options_and_documents_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"does not take option\(s\) \['depth'\]"):
        make_classifier("likelihood", depth=3)
    with pytest.raises(ValueError, match="format 'someone/else' is not one of"):
        classifier_from_json('{"format": "someone/else"}')
