"""The registry: kinds built from the classes, one default, specs, and refusals by name."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import (
    CLASSIFIER_KINDS,
    InertiaClassifier,
    InputError,
    MarginalLikelihoodClassifier,
    Scenario,
    classifier_from_json,
    make_classifier,
    train,
    train_classifier,
)
from inertia_id.classifiers.base import KINDS
from inertia_id.classifiers.documents import MAX_CLASSIFIER_BYTES
from inertia_id.classifiers.registry import (
    DEFAULT_KIND,
    check_document_size,
    default_realisations,
    document_bytes,
    kind_class,
    kind_metrics,
    parse_spec,
    resolve_kind,
)


def test_every_kind_class_of_the_package_is_listed_in_a_fixed_order() -> None:
    assert CLASSIFIER_KINDS == (
        "clustering",
        "nearest-centroid",
        "1nn",
        "minirocket",
        "likelihood",
        "least-squares",
        "marginal-likelihood",
    )
    assert set(CLASSIFIER_KINDS) == set(KINDS)
    assert all(kind_class(kind).kind == kind for kind in CLASSIFIER_KINDS)


def test_the_metrics_and_realisations_come_from_the_classes() -> None:
    assert kind_metrics("clustering") == ("dtw", "softdtw", "euclidean")
    assert kind_metrics("1nn") == kind_metrics("nearest-centroid") == ("dtw", "euclidean")
    assert [k for k in CLASSIFIER_KINDS if kind_metrics(k)] == [
        "clustering",
        "nearest-centroid",
        "1nn",
    ]
    assert default_realisations("marginal-likelihood") == 100
    assert {default_realisations(k) for k in CLASSIFIER_KINDS if k != DEFAULT_KIND} == {20}


def test_one_rule_resolves_the_kind_meant() -> None:
    assert DEFAULT_KIND == "marginal-likelihood"
    assert resolve_kind(None, None) == DEFAULT_KIND
    assert resolve_kind(None, "euclidean") == "clustering"
    assert resolve_kind("1nn", "euclidean") == "1nn"
    assert resolve_kind("likelihood", None) == "likelihood"


def test_train_without_a_kind_follows_the_rule(paper: Scenario) -> None:
    """``train`` and ``train_classifier`` are one function: a metric alone means the
    paper's clustering, nothing at all the default."""
    assert train is train_classifier
    clustering = train(paper, GOOD_SEQUENCE, 3, np.random.default_rng(0), metric="euclidean")
    assert isinstance(clustering, InertiaClassifier) and clustering.metric == "euclidean"
    default = train_classifier(paper, GOOD_SEQUENCE, 3, np.random.default_rng(0))
    assert isinstance(default, MarginalLikelihoodClassifier)


def test_specs_name_a_kind_and_its_metric() -> None:
    assert parse_spec("1nn:euclidean") == ("1nn", {"metric": "euclidean"})
    assert parse_spec("likelihood") == ("likelihood", {})
    with pytest.raises(InputError, match=r"kind must be one of .* got 'knn'"):
        parse_spec("knn:dtw")
    with pytest.raises(InputError, match="metric"):
        parse_spec("1nn:softdtw")
    with pytest.raises(InputError, match=r"a string like '1nn:euclidean', got 3"):
        parse_spec(3)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kind", "options", "match"),
    [
        ("svm", {}, r"kind must be one of \['clustering', 'nearest-centroid', '1nn', "),
        ("nearest-centroid", {"metric": "manhattan"}, r"one of \['dtw', 'euclidean'\], got 'manh"),
        ("1nn", {"metric": "softdtw"}, r"got 'softdtw'"),
        ("clustering", {"metric": "cosine"}, r"got 'cosine'"),
        ("1nn", {"sakoe_chiba_radius": -1}, r"sakoe_chiba_radius must be an integer >= 0, got -1"),
        ("minirocket", {"n_features": 50}, r"n_features must be an integer >= 84, got 50"),
        ("minirocket", {"alphas": [1.0, -2.0]}, r"alphas must be numbers > 0, got \[1\.0, -2\.0\]"),
        ("minirocket", {"metric": "dtw"}, r"does not take option\(s\) \['metric'\]"),
        ("likelihood", {"depth": 3}, r"does not take option\(s\) \['depth'\]"),
    ],
)
def test_bad_kinds_and_options_are_refused(kind: str, options: dict[str, Any], match: str) -> None:
    with pytest.raises(InputError, match=match):
        make_classifier(kind, **options)


def test_unknown_documents_are_refused_by_name() -> None:
    with pytest.raises(InputError, match="format 'someone/else' is not one of"):
        classifier_from_json('{"format": "someone/else"}')


@pytest.mark.parametrize("steps", [1, 2])
def test_the_document_bound_holds_the_default_kinds_documents(paper: Scenario, steps: int) -> None:
    # What a training will write, bounded before it runs (the service and `inertia-id
    # train` refuse one past MAX_CLASSIFIER_BYTES): above the document, and not far above
    # (measured 1.8 times on 2 to 16 steps of the paper preset at 20 realisations).
    sequence = np.array([[4, 4, 4, 0, 0, 0], [0, 0, 0, 4, 4, 4]])[:steps]
    model = train_classifier(paper, sequence, 5, np.random.default_rng(0))
    written = len(model.to_json().encode())
    bound = document_bytes("marginal-likelihood", paper, steps, 5)
    assert written <= bound <= 2.5 * written


def test_a_training_whose_document_could_pass_the_files_limit_is_refused(
    paper: Scenario,
) -> None:
    # The default kind's covariances grow with the square of the series: on the paper
    # preset (60 values a step) 72 steps are bounded under 1 GB, 73 over it.
    check_document_size("marginal-likelihood", paper, 72, 100)
    assert document_bytes("marginal-likelihood", paper, 72, 100) <= MAX_CLASSIFIER_BYTES
    with pytest.raises(InputError) as refused:
        check_document_size("marginal-likelihood", paper, 73, 100)
    bound = document_bytes("marginal-likelihood", paper, 73, 100)
    assert str(refused.value) == (
        "a marginal-likelihood classifier of 5 candidates on 73 steps (4,380 rate values a "
        f"series, 100 realisations a candidate) writes a document of up to {bound:,} bytes, "
        "over the limit of 1,000,000,000 bytes a classifier file may hold (the CLI refuses "
        "to load one past it): ask for a shorter sequence"
    )
    # A kind that keeps its training series says fewer of them would do too.
    with pytest.raises(InputError, match="ask for a shorter sequence or fewer realisations"):
        check_document_size("1nn", paper, 100, 10_000)
