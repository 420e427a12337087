"""Supervised classifiers beside the clustering: nearest centroid, 1-NN and MiniRocket."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sklearn.linear_model import Ridge, RidgeClassifierCV
from sklearn.metrics import f1_score

from inertia_id import InertiaClassifier, Scenario, Telemetry, identify, simulate
from inertia_id.classifiers.dtw import cdist_dtw
from inertia_id.classifiers.minirocket import fit_minirocket, minirocket_transform
from inertia_id.classifiers.nearest import (
    MiniRocketClassifier,
    NearestCentroidClassifier,
    NearestNeighbourClassifier,
    SupervisedClassifier,
)
from inertia_id.classifiers.registry import (
    CLASSIFIER_KINDS,
    classifier_from_json,
    load_classifier,
    make_classifier,
    train_classifier,
)

GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4
I0 = np.diag([100.0, 60.0, 90.0])
N_TRAIN = 8  # realisations per candidate
N_FRESH = 6

# name -> (kind, options); DTW both unconstrained and in a band.
CONFIGS: dict[str, tuple[str, dict[str, Any]]] = {
    "centroid-dtw": ("nearest-centroid", {"metric": "dtw"}),
    "centroid-euclidean": ("nearest-centroid", {"metric": "euclidean"}),
    "1nn-dtw-band": ("1nn", {"metric": "dtw", "sakoe_chiba_radius": 8}),
    "1nn-euclidean": ("1nn", {"metric": "euclidean"}),
    "minirocket": ("minirocket", {}),
}


@pytest.fixture(scope="module")
def training(paper: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """What train_classifier(..., np.random.default_rng(0)) simulates."""
    return simulate(paper, GOOD_SEQUENCE, N_TRAIN, np.random.default_rng(0)).dataset()


@pytest.fixture(scope="module")
def fresh(paper: Scenario) -> Any:
    """Responses never seen in training."""
    return simulate(paper, GOOD_SEQUENCE, N_FRESH, np.random.default_rng(1))


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


def telemetry_of(time_s: np.ndarray, omega: np.ndarray) -> Telemetry:
    return Telemetry(time_s=np.asarray(time_s).tolist(), omega_rad_s=np.asarray(omega).tolist())


# Accuracy and scores.


@pytest.mark.parametrize("name", CONFIGS)
def test_every_classifier_is_accurate_on_fresh_draws(
    name: str,
    trained: dict[str, SupervisedClassifier],
    fresh: Any,
    euclidean_classifier: InertiaClassifier,
) -> None:
    model = trained[name]
    X, y = fresh.dataset()
    scores = model.evaluate(X, y)
    assert scores["accuracy"] >= 0.9, scores["confusion"]
    assert set(scores) == set(euclidean_classifier.evaluate(X, y))
    predicted = model.predict(X)
    assert scores["f1"] == pytest.approx(f1_score(y, predicted, average="macro"), rel=1e-12)
    assert scores["accuracy"] == pytest.approx(np.mean(predicted == y), rel=1e-12)
    assert model.score(X, y) == scores["f1"]
    np.testing.assert_array_equal(scores["confusion"].sum(axis=1), np.full(5, N_FRESH))
    assert model.transform(X).shape == (len(X), 5)
    np.testing.assert_array_equal(predicted, model.transform(X).argmin(axis=1))


def test_1nn_euclidean_matches_brute_force(
    trained: dict[str, SupervisedClassifier],
    training: tuple[np.ndarray, np.ndarray],
    fresh: Any,
) -> None:
    model = trained["1nn-euclidean"]
    X_train, y_train = training
    X, _ = fresh.dataset()
    pairwise = np.sqrt(((X[:, None] - X_train[None]) ** 2).sum(axis=(2, 3)))
    per_candidate = np.stack([pairwise[:, y_train == k].min(axis=1) for k in range(5)], axis=1)
    np.testing.assert_allclose(model.transform(X), per_candidate, rtol=1e-12)
    np.testing.assert_array_equal(model.predict(X), y_train[pairwise.argmin(axis=1)])
    # The novelty rule's training distances leave each series out of its own candidate.
    self_pairs = np.sqrt(((X_train[:, None] - X_train[None]) ** 2).sum(axis=(2, 3)))
    np.fill_diagonal(self_pairs, np.inf)
    own = [self_pairs[i, (y_train == y_train[i])].min() for i in range(len(y_train))]
    np.testing.assert_allclose(
        model.training_distances_[np.arange(len(y_train)), y_train], own, rtol=1e-12
    )
    largest = [max(d for d, k in zip(own, y_train, strict=True) if k == c) for c in range(5)]
    np.testing.assert_allclose(model.novelty_thresholds(), 1.5 * np.array(largest), rtol=1e-12)


def test_nearest_centroid_euclidean_centroid_is_the_class_mean(
    trained: dict[str, SupervisedClassifier],
    training: tuple[np.ndarray, np.ndarray],
    fresh: Any,
) -> None:
    model = trained["centroid-euclidean"]
    assert isinstance(model, NearestCentroidClassifier)
    X_train, y_train = training
    means = np.stack([X_train[y_train == k].mean(axis=0) for k in range(5)])
    np.testing.assert_allclose(model.centroids_, means, rtol=1e-13, atol=1e-18)
    X, _ = fresh.dataset()
    expected = np.sqrt(((X[:, None] - means[None]) ** 2).sum(axis=(2, 3)))
    np.testing.assert_allclose(model.transform(X), expected, rtol=1e-12)


def test_dba_centroid_fits_its_candidate_better_than_the_mean(
    trained: dict[str, SupervisedClassifier], training: tuple[np.ndarray, np.ndarray]
) -> None:
    model = trained["centroid-dtw"]
    assert isinstance(model, NearestCentroidClassifier)
    X_train, y_train = training
    for k in range(5):
        members = X_train[y_train == k]
        to_dba = np.mean(cdist_dtw(members, model.centroids_[k][None]) ** 2)
        to_mean = np.mean(cdist_dtw(members, members.mean(axis=0)[None]) ** 2)
        assert to_dba < to_mean


def test_dtw_in_a_zero_band_is_euclidean(
    training: tuple[np.ndarray, np.ndarray], fresh: Any
) -> None:
    X_train, y_train = training
    X, _ = fresh.dataset()
    for cls in (NearestNeighbourClassifier, NearestCentroidClassifier):
        banded = cls("dtw", sakoe_chiba_radius=0).fit(X_train, y_train)
        euclidean = cls("euclidean").fit(X_train, y_train)
        np.testing.assert_allclose(banded.transform(X), euclidean.transform(X), rtol=1e-9)


# MiniRocket.


def test_minirocket_features_are_dilated_convolutions_ppv(
    training: tuple[np.ndarray, np.ndarray], fresh: Any
) -> None:
    X_train, _ = training
    params = fit_minirocket(X_train, np.random.default_rng(4))
    length = X_train.shape[1]
    # The paper's layout: 84 kernels x 119 features for a budget of 10 000, kernels that
    # span at most the series, 1 to 3 distinct rate channels per combination.
    assert params.n_features == 9996
    assert params.dilations[0] == 1 and 8 * params.dilations[-1] <= length - 1
    assert set(params.channels_per_combination.tolist()) <= {1, 2, 3}
    X = fresh.dataset()[0][:3]
    features = minirocket_transform(X, params)
    assert features.shape == (3, 9996)
    assert np.all((features >= 0.0) & (features <= 1.0))
    for f in np.random.default_rng(5).choice(params.n_features, 60, replace=False):
        kernel = params.describe(int(f))
        assert sorted(kernel.weights.tolist()) == [-1.0] * 6 + [2.0] * 3
        assert len(set(kernel.channels.tolist())) == len(kernel.channels)
        pad = 4 * kernel.dilation
        for s in range(len(X)):
            summed = np.concatenate(
                [np.zeros(pad), X[s][:, kernel.channels].sum(axis=1), np.zeros(pad)]
            )
            output = np.array(
                [
                    kernel.weights @ summed[t : t + 2 * pad + 1 : kernel.dilation]
                    for t in range(length)
                ]
            )
            if not kernel.padded:
                output = output[pad : length - pad]
            assert features[s, f] == pytest.approx(np.mean(output > kernel.bias), abs=1e-12)


def test_minirocket_is_seeded_by_its_generator(training: tuple[np.ndarray, np.ndarray]) -> None:
    X_train, _ = training
    a = fit_minirocket(X_train, np.random.default_rng(7), n_features=500)
    b = fit_minirocket(X_train, np.random.default_rng(7), n_features=500)
    c = fit_minirocket(X_train, np.random.default_rng(8), n_features=500)
    assert a.to_dict() == b.to_dict()
    assert a.to_dict() != c.to_dict()
    assert a.n_features == 84 * (500 // 84)


def test_minirocket_is_ridge_on_scaled_features_with_exact_leave_one_out(
    trained: dict[str, SupervisedClassifier],
    training: tuple[np.ndarray, np.ndarray],
    fresh: Any,
) -> None:
    model = trained["minirocket"]
    assert isinstance(model, MiniRocketClassifier)
    X_train, y_train = training
    features = minirocket_transform(X_train, model.parameters_)
    scale = features.std(axis=0)
    scale[scale < 1e-12] = 1.0
    scaled = features / scale
    ridge = RidgeClassifierCV(alphas=np.logspace(-3, 3, 10)).fit(scaled, y_train)
    assert model.alpha_ == ridge.alpha_
    X, _ = fresh.dataset()
    fresh_scaled = minirocket_transform(X, model.parameters_) / scale
    np.testing.assert_array_equal(model.predict(X), ridge.predict(fresh_scaled))
    codes = 2.0 * np.eye(5) - 1.0
    decision = ridge.decision_function(fresh_scaled)
    expected = np.linalg.norm(decision[:, None, :] - codes[None], axis=2)
    np.testing.assert_allclose(model.transform(X), expected, rtol=1e-9)
    # Leave-one-out distances (behind the novelty thresholds) equal refitting without
    # the series.
    targets = codes[y_train]
    for i in (0, 13, 39):
        keep = np.arange(len(y_train)) != i
        refit = Ridge(alpha=model.alpha_).fit(scaled[keep], targets[keep])
        left_out = refit.predict(scaled[i : i + 1])[0]
        np.testing.assert_allclose(
            model.training_distances_[i], np.linalg.norm(left_out - codes, axis=1), atol=1e-8
        )


def test_minirocket_handles_two_candidates(
    training: tuple[np.ndarray, np.ndarray], fresh: Any
) -> None:
    X_train, y_train = training
    X, y = fresh.dataset()
    model = MiniRocketClassifier(n_features=1000, random_state=0)
    model.fit(X_train[y_train < 2], y_train[y_train < 2])
    distances = model.transform(X[y < 2])
    assert distances.shape == (2 * N_FRESH, 2)
    assert model.evaluate(X[y < 2], y[y < 2])["accuracy"] >= 0.9
    assert model.coef_.shape == (1, model.parameters_.n_features)
    reloaded = classifier_from_json(model.to_json())
    np.testing.assert_array_equal(reloaded.transform(X[y < 2]), distances)


# Storage.


@pytest.mark.parametrize("name", CONFIGS)
def test_json_round_trip_gives_identical_predictions(
    name: str, trained: dict[str, SupervisedClassifier], fresh: Any, tmp_path: Path
) -> None:
    model = trained[name]
    X, _ = fresh.dataset()
    text = model.to_json()
    assert "pickle" not in text
    for loaded in (
        classifier_from_json(text),
        type(model).from_json(text),
        SupervisedClassifier.from_json(text.encode()),
    ):
        assert type(loaded) is type(model)
        assert loaded.get_params() == model.get_params()
        np.testing.assert_array_equal(loaded.transform(X), model.transform(X))
        np.testing.assert_array_equal(loaded.novelty_thresholds(), model.novelty_thresholds())
        assert loaded.candidate_names_ == model.candidate_names_
        assert loaded.scenario_ == model.scenario_
        np.testing.assert_array_equal(loaded.sequence_, model.sequence_)
        assert loaded.f1_ == model.f1_ and loaded.accuracy_ == model.accuracy_
    path = tmp_path / f"{name}.json"
    model.save(path)
    assert type(model).load(path).to_json() == text
    assert load_classifier(path).to_json() == text


def test_tampered_or_mismatched_documents_are_refused(
    trained: dict[str, SupervisedClassifier],
) -> None:
    text = trained["centroid-euclidean"].to_json()
    doc = json.loads(text)
    doc["classifier"]["model"]["centroids_rad_s"][0][0][0] += 1e-3
    with pytest.raises(ValueError, match="checksum mismatch"):
        classifier_from_json(json.dumps(doc))
    with pytest.raises(ValueError, match="holds a 'nearest-centroid' classifier, not a '1nn'"):
        NearestNeighbourClassifier.from_json(text)
    with pytest.raises(ValueError, match="not JSON"):
        classifier_from_json("{")
    with pytest.raises(ValueError, match="format 'something/else'"):
        SupervisedClassifier.from_json(json.dumps({"format": "something/else"}))


def test_clustering_documents_load_through_the_same_door(
    euclidean_classifier: InertiaClassifier, fresh: Any
) -> None:
    X, _ = fresh.dataset()
    loaded = classifier_from_json(euclidean_classifier.to_json())
    assert isinstance(loaded, InertiaClassifier)
    np.testing.assert_array_equal(loaded.predict(X), euclidean_classifier.predict(X))


# Refusing bad input.


def nan_at(X: np.ndarray, index: tuple[int, int, int]) -> np.ndarray:
    bad = X.copy()
    bad[index] = np.nan
    return bad


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda X, y: (X[:, :, :2], y), r"\(n_series, length, 3\) in rad/s, got \(40, 80, 2\)"),
        (lambda X, y: (X[0, :, 0], y), r"got \(80,\)"),
        (lambda X, y: (nan_at(X, (3, 17, 1)), y), r"series\[3, 17, 1\] = nan is not finite"),
        (lambda X, y: (X, y[:-1]), r"one label per series \(40\), got shape \(39,\)"),
        (lambda X, y: (X, y + 0.5), r"integer candidate indices, got \[0\.5, "),
        (lambda X, y: (X, np.where(y == 2, 3, y)), r"series per candidate: \[8, 8, 0, 16, 8\]"),
        (lambda X, y: (X, -y), r"must be >= 0, got -4"),
    ],
)
def test_bad_training_data_is_refused(
    build: Callable[[np.ndarray, np.ndarray], tuple[Any, Any]],
    match: str,
    training: tuple[np.ndarray, np.ndarray],
) -> None:
    X, y = build(*training)
    for kind in ("nearest-centroid", "1nn", "minirocket"):
        with pytest.raises(ValueError, match=match):
            make_classifier(kind).fit(X, y)


def test_bad_series_at_prediction_are_refused(
    trained: dict[str, SupervisedClassifier], fresh: Any
) -> None:
    X, y = fresh.dataset()
    for model in trained.values():
        with pytest.raises(ValueError, match="60 samples; the classifier was trained on 80"):
            model.predict(X[:, :60])
        with pytest.raises(ValueError, match=r"series\[0, 5, 0\] = inf"):
            model.transform(np.where(np.arange(80)[None, :, None] == 5, np.inf, X)[:1])
        with pytest.raises(ValueError, match=r"labels must lie in 0\.\.4 .* got \[7\]"):
            model.evaluate(X, np.where(y == 4, 7, y))
    with pytest.raises(ValueError, match="not fitted yet"):
        NearestNeighbourClassifier().predict(X)


@pytest.mark.parametrize(
    ("kind", "options", "match"),
    [
        ("svm", {}, r"kind must be one of \['clustering', 'nearest-centroid', '1nn', "),
        ("nearest-centroid", {"metric": "manhattan"}, r"one of \['dtw', 'euclidean'\], got 'manh"),
        ("1nn", {"metric": "softdtw"}, r"got 'softdtw'"),
        ("clustering", {"metric": "cosine"}, r"got 'cosine'"),
        ("1nn", {"sakoe_chiba_radius": -1}, r"sakoe_chiba_radius must be an integer >= 0, got -1"),
        ("nearest-centroid", {"novelty_factor": 0.5}, r"novelty_factor must be .* got 0\.5"),
        ("minirocket", {"n_features": 50}, r"n_features must be an integer >= 84, got 50"),
        ("minirocket", {"alphas": [1.0, -2.0]}, r"alphas must be numbers > 0, got \[1\.0, -2\.0\]"),
        ("minirocket", {"metric": "dtw"}, r"does not take option\(s\) \['metric'\]"),
    ],
)
def test_bad_kinds_and_options_are_refused(kind: str, options: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_classifier(kind, **options)


def test_make_classifier_lists_and_builds_every_kind() -> None:
    assert CLASSIFIER_KINDS == (
        "clustering",
        "nearest-centroid",
        "1nn",
        "minirocket",
        "likelihood",
        "least-squares",
        "marginal-likelihood",
    )
    clustering = make_classifier("clustering", metric="euclidean", random_state=0)
    assert isinstance(clustering, InertiaClassifier) and clustering.metric == "euclidean"
    centroid = make_classifier("nearest-centroid", metric="euclidean")
    assert isinstance(centroid, NearestCentroidClassifier) and centroid.metric == "euclidean"
    assert isinstance(make_classifier("1nn", sakoe_chiba_radius=3), NearestNeighbourClassifier)
    rocket = make_classifier("minirocket", n_features=840)
    assert isinstance(rocket, MiniRocketClassifier) and rocket.metric == "minirocket"


def test_training_is_reproducible_from_the_generator(paper: Scenario) -> None:
    def build(seed: int) -> str:
        rng = np.random.default_rng(seed)
        return train_classifier(
            paper, GOOD_SEQUENCE, 3, rng, kind="minirocket", n_features=840
        ).to_json()

    assert build(3) == build(3)
    assert build(3) != build(4)


# Identification.


@pytest.mark.parametrize("name", CONFIGS)
def test_identify_names_fresh_responses_and_rejects_strangers(
    name: str,
    trained: dict[str, SupervisedClassifier],
    paper: Scenario,
    fresh: Any,
    scenario_like: Callable[..., Scenario],
) -> None:
    model = trained[name]
    thresholds = model.novelty_thresholds()
    correct = 0
    for k, candidate in enumerate(paper.candidate_names):
        for i in range(2):
            omega = fresh.omega_measured[k, i]
            verdict = identify(model, telemetry_of(fresh.time_s, omega))
            assert verdict.candidate_index == model.predict(omega)[0]
            assert not verdict.matches_none
            correct += verdict.candidate == candidate
            np.testing.assert_allclose(
                list(verdict.distances.values()), model.transform(omega)[0], rtol=1e-12
            )
            assert verdict.threshold == pytest.approx(thresholds[verdict.candidate_index])
    # MiniRocket, trained on 8 responses per candidate, confuses about 1 in 25.
    assert correct >= 9
    # A body 30 % heavier than I0 or 40 % lighter is none of the candidates, and a
    # spacecraft that did not turn at all is not either.
    odd = scenario_like({"heavy": 1.3 * I0, "light": 0.6 * I0})
    strangers = simulate(odd, GOOD_SEQUENCE, 2, np.random.default_rng(6))
    for k in range(2):
        for i in range(2):
            verdict = identify(
                model, telemetry_of(strangers.time_s, strangers.omega_measured[k, i])
            )
            assert verdict.matches_none, (k, i, verdict.distances, verdict.threshold)
    still = identify(model, telemetry_of(fresh.time_s, np.zeros_like(fresh.omega_measured[0, 0])))
    assert still.matches_none
