"""The distance-based supervised kinds: nearest centroid and 1-NN, euclidean and DTW."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE

from inertia_id import InputError, Scenario
from inertia_id.classifiers.base import SupervisedClassifier
from inertia_id.classifiers.documents import checksum
from inertia_id.classifiers.dtw import cdist_dtw
from inertia_id.classifiers.nearest import NearestCentroidClassifier, NearestNeighbourClassifier
from inertia_id.classifiers.registry import classifier_from_json, train_classifier

N_TRAIN = 8  # realisations per candidate
N_FRESH = 6

# name -> (kind, options); DTW both unconstrained and in a band.
CONFIGS: dict[str, tuple[str, dict[str, Any]]] = {
    "centroid-dtw": ("nearest-centroid", {"metric": "dtw"}),
    "centroid-euclidean": ("nearest-centroid", {"metric": "euclidean"}),
    "1nn-dtw-band": ("1nn", {"metric": "dtw", "sakoe_chiba_radius": 8}),
    "1nn-euclidean": ("1nn", {"metric": "euclidean"}),
}


def offsetless(X: np.ndarray) -> np.ndarray:
    """Series with each axis' mean removed: what a distance kind compares
    (``BaseClassifier.REMOVES_OFFSET``)."""
    return np.asarray(X - X.mean(axis=-2, keepdims=True))


@pytest.fixture(scope="module")
def trained(paper: Scenario) -> dict[str, SupervisedClassifier]:
    """Every configuration, trained once per module. Tests must not mutate them."""
    models = {}
    for name, (kind, options) in CONFIGS.items():
        model = train_classifier(
            paper, GOOD_SEQUENCE, N_TRAIN, np.random.default_rng(0), kind=kind, **options
        )
        assert isinstance(model, SupervisedClassifier)
        models[name] = model
    return models


@pytest.mark.parametrize("name", ["centroid-dtw", "1nn-dtw-band"])
def test_dtw_configurations_are_accurate_on_fresh_draws(
    name: str, trained: dict[str, SupervisedClassifier], good_fresh: Any
) -> None:
    X, y = good_fresh.dataset()
    scores = trained[name].evaluate(X, y)
    assert scores["accuracy"] >= 0.9, scores["confusion"]


@pytest.fixture(scope="module")
def offsetless_data(
    good_training: tuple[np.ndarray, np.ndarray], good_fresh: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X_train, y_train, X_fresh) as the euclidean kinds see them: offsets removed."""
    X_train, y_train = good_training
    return offsetless(X_train), y_train, offsetless(good_fresh.dataset()[0])


def euclidean(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Brute-force distances between every series of ``a`` and every series of ``b``."""
    return np.sqrt(((a[:, None] - b[None]) ** 2).sum(axis=(2, 3)))


def test_1nn_euclidean_matches_brute_force(
    trained: dict[str, SupervisedClassifier],
    offsetless_data: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    model = trained["1nn-euclidean"]
    X_train, y_train, X = offsetless_data
    pairwise = euclidean(X, X_train)
    per_candidate = np.stack([pairwise[:, y_train == k].min(axis=1) for k in range(5)], axis=1)
    np.testing.assert_allclose(model.transform(X), per_candidate, rtol=1e-12)
    np.testing.assert_array_equal(model.predict(X), y_train[pairwise.argmin(axis=1)])
    # The novelty rule's training distances leave each series out of its own candidate.
    self_pairs = euclidean(X_train, X_train)
    np.fill_diagonal(self_pairs, np.inf)
    own = [self_pairs[i, (y_train == y_train[i])].min() for i in range(len(y_train))]
    np.testing.assert_allclose(
        model.training_distances_[np.arange(len(y_train)), y_train], own, rtol=1e-12
    )
    largest = [max(d for d, k in zip(own, y_train, strict=True) if k == c) for c in range(5)]
    np.testing.assert_allclose(model.novelty_thresholds(), 1.5 * np.array(largest), rtol=1e-12)


def test_nearest_centroid_euclidean_centroid_is_the_class_mean(
    trained: dict[str, SupervisedClassifier],
    offsetless_data: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    model = trained["centroid-euclidean"]
    assert isinstance(model, NearestCentroidClassifier)
    X_train, y_train, X = offsetless_data
    means = np.stack([X_train[y_train == k].mean(axis=0) for k in range(5)])
    np.testing.assert_allclose(model.centroids_, means, rtol=1e-13, atol=1e-18)
    expected = euclidean(X, means)
    np.testing.assert_allclose(model.transform(X), expected, rtol=1e-12)


def test_dba_centroid_fits_its_candidate_better_than_the_mean(
    trained: dict[str, SupervisedClassifier], good_training: tuple[np.ndarray, np.ndarray]
) -> None:
    model = trained["centroid-dtw"]
    assert isinstance(model, NearestCentroidClassifier)
    X_train, y_train = good_training
    for k in range(5):
        members = offsetless(X_train[y_train == k])
        to_dba = np.mean(cdist_dtw(members, model.centroids_[k][None]) ** 2)
        to_mean = np.mean(cdist_dtw(members, members.mean(axis=0)[None]) ** 2)
        assert to_dba < to_mean


def test_dtw_in_a_zero_band_is_euclidean(
    good_training: tuple[np.ndarray, np.ndarray], good_fresh: Any
) -> None:
    X_train, y_train = good_training
    X, _ = good_fresh.dataset()
    for cls in (NearestNeighbourClassifier, NearestCentroidClassifier):
        banded = cls("dtw", sakoe_chiba_radius=0).fit(X_train, y_train)
        euclidean = cls("euclidean").fit(X_train, y_train)
        np.testing.assert_allclose(banded.transform(X), euclidean.transform(X), rtol=1e-9)


def test_the_shared_document_names_its_kind(trained: dict[str, SupervisedClassifier]) -> None:
    text = trained["centroid-euclidean"].to_json()
    assert json.loads(text)["classifier"]["kind"] == "nearest-centroid"
    assert type(SupervisedClassifier.from_json(text)) is NearestCentroidClassifier
    with pytest.raises(InputError, match="holds a 'nearest-centroid' classifier, not a '1nn'"):
        NearestNeighbourClassifier.from_json(text)
    doc = json.loads(text)
    doc["classifier"]["kind"] = "svm"
    with pytest.raises(InputError, match=r"kind 'svm' is not one of \['1nn', 'minirocket', "):
        classifier_from_json(json.dumps({**doc, "sha256": checksum(doc["classifier"])}))
