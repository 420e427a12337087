"""MiniRocket: our transform against its definition, and the ridge classifier on it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE
from sklearn.linear_model import Ridge, RidgeClassifierCV

from inertia_id import Scenario
from inertia_id.classifiers.minirocket import (
    MiniRocketClassifier,
    fit_minirocket,
    minirocket_transform,
)
from inertia_id.classifiers.registry import classifier_from_json, train_classifier

N_TRAIN = 8  # realisations per candidate
N_FRESH = 6


def offsetless(X: np.ndarray) -> np.ndarray:
    """Series with each axis' mean removed: what a distance kind compares
    (``BaseClassifier.REMOVES_OFFSET``)."""
    return np.asarray(X - X.mean(axis=-2, keepdims=True))


@pytest.fixture(scope="module")
def model(paper: Scenario) -> MiniRocketClassifier:
    trained = train_classifier(
        paper, GOOD_SEQUENCE, N_TRAIN, np.random.default_rng(0), kind="minirocket"
    )
    assert isinstance(trained, MiniRocketClassifier)
    return trained


def test_minirocket_features_are_dilated_convolutions_ppv(
    good_training: tuple[np.ndarray, np.ndarray], good_fresh: Any
) -> None:
    X_train, _ = good_training
    params = fit_minirocket(X_train, np.random.default_rng(4))
    length = X_train.shape[1]
    # The paper's layout: 84 kernels x 119 features for a budget of 10 000, kernels that
    # span at most the series, 1 to 3 distinct rate channels per combination.
    assert params.n_features == 9996
    assert params.dilations[0] == 1 and 8 * params.dilations[-1] <= length - 1
    assert set(params.channels_per_combination.tolist()) <= {1, 2, 3}
    X = good_fresh.dataset()[0][:3]
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


def test_minirocket_is_seeded_by_its_generator(
    good_training: tuple[np.ndarray, np.ndarray],
) -> None:
    X_train, _ = good_training
    a = fit_minirocket(X_train, np.random.default_rng(7), n_features=500)
    b = fit_minirocket(X_train, np.random.default_rng(7), n_features=500)
    c = fit_minirocket(X_train, np.random.default_rng(8), n_features=500)
    assert a.to_dict() == b.to_dict()
    assert a.to_dict() != c.to_dict()
    assert a.n_features == 84 * (500 // 84)


def test_minirocket_is_ridge_on_scaled_features_with_exact_leave_one_out(
    model: MiniRocketClassifier,
    good_training: tuple[np.ndarray, np.ndarray],
    good_fresh: Any,
) -> None:
    X_train, y_train = good_training
    X_train = offsetless(X_train)
    features = minirocket_transform(X_train, model.parameters_)
    scale = features.std(axis=0)
    scale[scale < 1e-12] = 1.0
    scaled = features / scale
    ridge = RidgeClassifierCV(alphas=np.logspace(-3, 3, 10)).fit(scaled, y_train)
    assert model.alpha_ == ridge.alpha_
    X, _ = good_fresh.dataset()
    fresh_scaled = minirocket_transform(offsetless(X), model.parameters_) / scale
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
    good_training: tuple[np.ndarray, np.ndarray], good_fresh: Any
) -> None:
    X_train, y_train = good_training
    X, y = good_fresh.dataset()
    model = MiniRocketClassifier(n_features=1000, random_state=0)
    model.fit(X_train[y_train < 2], y_train[y_train < 2])
    distances = model.transform(X[y < 2])
    assert distances.shape == (2 * N_FRESH, 2)
    assert model.evaluate(X[y < 2], y[y < 2])["accuracy"] >= 0.9
    assert model.coef_.shape == (1, model.parameters_.n_features)
    reloaded = classifier_from_json(model.to_json())
    np.testing.assert_array_equal(reloaded.transform(X[y < 2]), distances)
