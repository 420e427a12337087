"""Cluster matching and the paper's k-means classifier (what every kind shares is
test_every_kind.py)."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE
from sklearn.metrics import f1_score

from inertia_id import InertiaClassifier, Scenario, match_clusters, simulate, train

# match_clusters: the Hungarian matching of clusters to candidates.


def offsetless(X: np.ndarray) -> np.ndarray:
    """Series with each axis' mean removed: what a distance kind compares
    (``BaseClassifier.REMOVES_OFFSET``)."""
    return np.asarray(X - X.mean(axis=-2, keepdims=True))


def macro_f1(y: np.ndarray, predicted: np.ndarray) -> float:
    """Textbook macro F1 over the candidates present: mean of 2 TP / (|true| + |predicted|)."""
    scores = [
        2.0 * np.sum((y == j) & (predicted == j)) / (np.sum(y == j) + np.sum(predicted == j))
        for j in np.unique(y)
    ]
    return float(np.mean(scores))


def brute_force_f1(y: np.ndarray, clusters: np.ndarray, k: int) -> float:
    """Best macro F1 over every one-to-one cluster -> candidate assignment."""
    return max(macro_f1(y, np.asarray(perm)[clusters]) for perm in itertools.permutations(range(k)))


def test_perfect_clustering_scores_one() -> None:
    y = np.array([0, 0, 1, 1, 2, 2])
    clusters = np.array([2, 2, 0, 0, 1, 1])
    scores = match_clusters(y, clusters, 3)
    assert scores.f1 == 1.0 and scores.accuracy == 1.0
    np.testing.assert_array_equal(scores.cluster_to_candidate, [1, 2, 0])
    np.testing.assert_array_equal(scores.confusion, 2 * np.eye(3, dtype=int))


def test_known_contingency_table_gives_hand_computed_f1() -> None:
    # Cluster 0 holds two of candidate 0; cluster 1 holds one of candidate 0 and all
    # three of candidate 1. Matching 0->0, 1->1:
    #   F1(candidate 0) = 2*2 / (2 + 3) = 0.8, F1(candidate 1) = 2*3 / (4 + 3) = 6/7.
    y = np.array([0, 0, 0, 1, 1, 1])
    clusters = np.array([0, 0, 1, 1, 1, 1])
    scores = match_clusters(y, clusters, 2)
    assert scores.f1 == pytest.approx((0.8 + 6 / 7) / 2, rel=1e-15)
    assert scores.accuracy == pytest.approx(5 / 6, rel=1e-15)
    np.testing.assert_array_equal(scores.confusion, [[2, 1], [0, 3]])
    np.testing.assert_array_equal(scores.cluster_to_candidate, [0, 1])


def test_matching_is_global_not_greedy() -> None:
    # Greedy would pair the largest entry (cluster 0, candidate 0: F1 = 2*4/(6+5) = 0.727)
    # first, leaving cluster 1 -> candidate 1 (F1 = 0). The optimum swaps them:
    # cluster 0 -> candidate 1 (2*2/(6+2) = 0.5), cluster 1 -> candidate 0
    # (2*1/(1+5) = 1/3): total 0.833 > 0.727.
    y = np.array([0, 0, 0, 0, 1, 1, 0])
    clusters = np.array([0, 0, 0, 0, 0, 0, 1])
    scores = match_clusters(y, clusters, 2)
    np.testing.assert_array_equal(scores.cluster_to_candidate, [1, 0])
    assert scores.f1 == pytest.approx((0.5 + 1 / 3) / 2, rel=1e-15)
    assert scores.f1 == pytest.approx(brute_force_f1(y, clusters, 2), rel=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_matching_is_optimal_against_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    k = int(rng.integers(2, 6))
    y = np.concatenate([np.arange(k), rng.integers(0, k, size=40)])
    clusters = np.where(rng.random(y.size) < 0.5, (y + 1) % k, rng.integers(0, k, y.size))
    scores = match_clusters(y, clusters, k)
    assert scores.f1 == pytest.approx(brute_force_f1(y, clusters, k), rel=1e-12)
    assert scores.f1 == pytest.approx(
        f1_score(y, scores.cluster_to_candidate[clusters], average="macro"), rel=1e-12
    )
    # Accuracy and confusion are those of the returned mapping.
    predicted = scores.cluster_to_candidate[clusters]
    assert scores.accuracy == pytest.approx(np.mean(predicted == y))
    assert scores.confusion.sum() == y.size
    assert np.trace(scores.confusion) == np.sum(predicted == y)


@pytest.mark.parametrize("seed", range(3))
def test_relabelling_clusters_changes_nothing(seed: int) -> None:
    rng = np.random.default_rng(seed)
    y = np.repeat(np.arange(5), 30)
    clusters = np.where(rng.random(y.size) < 0.7, y, rng.integers(0, 5, y.size))
    base = match_clusters(y, clusters, 5)
    perm = rng.permutation(5)
    relabelled = match_clusters(y, perm[clusters], 5)
    assert relabelled.f1 == base.f1
    assert relabelled.accuracy == base.accuracy
    np.testing.assert_array_equal(relabelled.confusion, base.confusion)
    # The mapping follows the relabelling: new cluster perm[c] maps where c did.
    np.testing.assert_array_equal(relabelled.cluster_to_candidate[perm], base.cluster_to_candidate)


def test_twelve_candidates_use_hungarian_matching() -> None:
    k = 12
    rng = np.random.default_rng(0)
    y = np.repeat(np.arange(k), 10)
    perm = rng.permutation(k)
    clusters = perm[y]
    wrong = rng.choice(y.size, size=7, replace=False)
    clusters[wrong] = perm[(y[wrong] + 1) % k]  # 7 series land in a neighbour's cluster
    scores = match_clusters(y, clusters, k)
    inverse = np.argsort(perm)
    np.testing.assert_array_equal(scores.cluster_to_candidate, inverse)
    assert scores.accuracy == pytest.approx(1 - 7 / 120, rel=1e-15)
    assert scores.f1 == pytest.approx(f1_score(y, inverse[clusters], average="macro"), rel=1e-12)
    assert scores.f1 < 1.0


def test_extra_clusters_stay_unmatched() -> None:
    y = np.array([0, 0, 1, 1])
    clusters = np.array([0, 2, 1, 1])
    scores = match_clusters(y, clusters, 2, n_clusters=3)
    assert (scores.cluster_to_candidate == -1).sum() == 1
    assert scores.accuracy < 1.0
    assert scores.confusion.sum() == 4 - np.sum(scores.cluster_to_candidate[clusters] < 0)


def test_match_clusters_validates_its_input() -> None:
    with pytest.raises(ValueError, match=r"equal length, got \(3,\) and \(2,\)"):
        match_clusters([0, 1, 1], [0, 1], 2)
    with pytest.raises(ValueError, match=r"candidate labels must lie in 0\.\.1"):
        match_clusters([0, 2], [0, 1], 2)
    with pytest.raises(ValueError, match=r"cluster labels must lie in 0\.\.1"):
        match_clusters([0, 1], [0, 5], 2)


# The classifier.


@pytest.fixture(scope="module")
def fresh_set(paper: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Series never seen in training (another seed)."""
    return simulate(paper, GOOD_SEQUENCE, 20, np.random.default_rng(99)).dataset()


@pytest.fixture(scope="module")
def dtw_classifier(paper: Scenario) -> InertiaClassifier:
    """The paper's DTW classifier. The first DTW fit of a session compiles numba (~10 s)."""
    return train(paper, GOOD_SEQUENCE, 20, np.random.default_rng(2), metric="dtw")


def test_euclidean_classifier_separates_every_candidate(
    euclidean_classifier: InertiaClassifier,
    paper: Scenario,
    fresh_set: tuple[np.ndarray, np.ndarray],
) -> None:
    clf = euclidean_classifier
    assert clf.f1_ == 1.0 and clf.accuracy_ == 1.0
    np.testing.assert_array_equal(clf.confusion_, 20 * np.eye(5, dtype=int))
    assert sorted(clf.cluster_to_candidate_.tolist()) == list(range(5))
    assert clf.candidate_names_ == paper.candidate_names
    X, y = fresh_set
    report = clf.evaluate(X, y)
    assert report["f1"] == 1.0 and report["accuracy"] == 1.0
    assert clf.score(X, y) == 1.0
    np.testing.assert_array_equal(clf.predict(X), y)


def test_euclidean_centroids_are_the_mean_responses(
    euclidean_classifier: InertiaClassifier, paper: Scenario, zero_uncertainty: dict
) -> None:
    """Euclidean k-means centroids are cluster means, close to the noise-free response."""
    clf = euclidean_classifier
    X, y = simulate(paper, GOOD_SEQUENCE, 20, np.random.default_rng(1)).dataset()
    X = offsetless(X)
    quiet = paper.with_uncertainty(**{**zero_uncertainty, "lowpass_time_constant_s": 0.1})
    clean = offsetless(simulate(quiet, GOOD_SEQUENCE, 1, np.random.default_rng(0)).omega_true[:, 0])
    for k in range(5):
        centroid = clf.cluster_centers_[np.flatnonzero(clf.cluster_to_candidate_ == k)[0]]
        np.testing.assert_allclose(centroid, X[y == k].mean(axis=0), rtol=0, atol=1e-12)
        # Mean of 20 noisy responses: within a few mrad/s of the noise-free one (~0.14).
        assert np.abs(centroid - clean[k]).max() < 5e-3
        # The signal itself, offset removed: tens of mrad/s.
        assert np.abs(clean[k]).max() > 0.05


def test_transform_predict_and_thresholds(
    euclidean_classifier: InertiaClassifier, fresh_set: tuple[np.ndarray, np.ndarray]
) -> None:
    clf = euclidean_classifier
    X, y = fresh_set
    distances = clf.transform(X)
    assert distances.shape == (100, 5)
    assert np.all(distances >= 0) and np.all(np.isfinite(distances))
    np.testing.assert_array_equal(clf.predict(X), distances.argmin(axis=1))
    # A single (length, 3) series is accepted as a batch of one.
    np.testing.assert_array_equal(clf.transform(X[3]), distances[3:4])
    # Euclidean distance in units of the training RMS rate, by hand.
    centroid = clf.cluster_centers_[np.flatnonzero(clf.cluster_to_candidate_ == 2)[0]]
    assert distances[7, 2] == pytest.approx(
        np.linalg.norm(offsetless(X[7]) - centroid) / clf.scale_, rel=1e-12
    )
    assert np.all(distances.min(axis=1) < clf.novelty_thresholds()[y])


def test_thresholds_come_from_the_series_each_cluster_holds(
    euclidean_classifier: InertiaClassifier, paper: Scenario
) -> None:
    """Unsupervised: a candidate's threshold is the spread of the series the clustering
    assigned to it (what it knows without labels), not of the candidate's own series."""
    clf = euclidean_classifier
    X, _ = simulate(paper, GOOD_SEQUENCE, 20, np.random.default_rng(1)).dataset()
    distances = clf.transform(X)
    assigned = distances.argmin(axis=1)
    largest = [distances[assigned == k, k].max() for k in range(5)]
    np.testing.assert_allclose(clf.novelty_thresholds(), 1.5 * np.array(largest), rtol=1e-12)
    # Stored per cluster, as documents always have been.
    stored = json.loads(clf.to_json())["classifier"]["max_training_distance"]
    np.testing.assert_array_equal(stored, np.array(largest)[clf.cluster_to_candidate_])


def test_fit_predict_returns_candidates(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 6, np.random.default_rng(3)).dataset()
    clf = InertiaClassifier("euclidean", random_state=0)
    np.testing.assert_array_equal(clf.fit_predict(X, y), y)
    # Warm start from the fitted centroids converges to the same partition.
    warm = InertiaClassifier("euclidean", init=clf.cluster_centers_).fit(X, y)
    np.testing.assert_array_equal(warm.predict(X), y)


def test_dtw_classifier_separates_every_candidate(
    dtw_classifier: InertiaClassifier, fresh_set: tuple[np.ndarray, np.ndarray]
) -> None:
    assert dtw_classifier.metric == "dtw"
    assert dtw_classifier.f1_ == 1.0
    X, y = fresh_set
    assert dtw_classifier.score(X, y) == 1.0


def test_dtw_json_round_trip(
    dtw_classifier: InertiaClassifier, fresh_set: tuple[np.ndarray, np.ndarray]
) -> None:
    X, _ = fresh_set
    loaded = InertiaClassifier.from_json(dtw_classifier.to_json())
    np.testing.assert_array_equal(loaded.transform(X[:10]), dtw_classifier.transform(X[:10]))
    np.testing.assert_array_equal(loaded.predict(X[:10]), dtw_classifier.predict(X[:10]))
    assert loaded.to_json() == dtw_classifier.to_json()


def test_softdtw_tiny_fit_and_round_trip(paper: Scenario) -> None:
    """Soft-DTW is slow; 2 candidates x 4 realisations x 1 step only."""
    data = paper.model_dump()
    data["inertia_candidates"] = data["inertia_candidates"][:2]
    data["candidate_generator"] = None
    small = Scenario.model_validate(data)
    clf = train(
        small,
        GOOD_SEQUENCE[:1],
        4,
        np.random.default_rng(0),
        metric="softdtw",
        n_init=1,
        max_iter=5,
        max_iter_barycenter=5,
    )
    # gamma is set from the data (noise energy of unit-RMS series), not tslearn's 1.
    assert 1e-6 <= clf.gamma_ < 0.5
    X, _ = simulate(small, GOOD_SEQUENCE[:1], 2, np.random.default_rng(5)).dataset()
    distances = clf.transform(X)
    assert np.all(distances >= -1e-9)  # normalised soft-DTW is a divergence
    loaded = InertiaClassifier.from_json(clf.to_json())
    assert loaded.gamma_ == clf.gamma_
    np.testing.assert_array_equal(loaded.transform(X), distances)


def test_invalid_parameters_are_rejected(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE[:1], 2, np.random.default_rng(0)).dataset()
    cases = [
        (
            {"metric": "cosine"},
            r"metric must be one of \['dtw', 'softdtw', 'euclidean'\], got 'cosine'",
        ),
        ({"n_init": 0}, r"n_init must be an integer >= 1, got 0"),
        ({"sakoe_chiba_radius": -1}, r"sakoe_chiba_radius must be an integer >= 0, got -1"),
        ({"gamma": -0.5}, r"gamma must be 'auto' or a number > 0, got -0\.5"),
        ({"gamma": True}, r"gamma must be 'auto' or a number > 0, got True"),
    ]
    for params, match in cases:
        with pytest.raises(ValueError, match=match):
            InertiaClassifier(**params).fit(X, y)
    with pytest.raises(ValueError, match=r"got 'cosine'"):
        train(paper, GOOD_SEQUENCE[:1], 2, np.random.default_rng(0), metric="cosine")


def test_fit_input_is_validated() -> None:
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6, 10, 3))
    clf = InertiaClassifier("euclidean")
    with pytest.raises(ValueError, match=r"series per candidate: \[3, 0, 3\]"):
        clf.fit(X, [0, 0, 2, 2, 0, 2])
    with pytest.raises(ValueError, match=r"one label per series \(6\), got shape \(5,\)"):
        clf.fit(X, [0, 1, 0, 1, 0])
    with pytest.raises(ValueError, match=r"3 candidate names for 2 candidates"):
        clf.fit(X, [0, 1, 0, 1, 0, 1], candidate_names=["a", "b", "c"])
    with pytest.raises(ValueError, match=r"\(n_series, length, 3\) in rad/s, got \(6, 10, 2\)"):
        clf.fit(X[..., :2], [0, 1, 0, 1, 0, 1])
    bad = X.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(ValueError, match="series 2, sample 3, axis 1 is nan"):
        clf.fit(bad, [0, 1, 0, 1, 0, 1])
