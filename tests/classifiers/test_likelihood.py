"""The limit classifier: Gaussian likelihood of the candidates' mean responses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scenario_support import GOOD_SEQUENCE, noisy
from scipy.stats import multivariate_normal

from inertia_id import InertiaClassifier, InputError, Scenario, simulate, train
from inertia_id.classifiers.likelihood import LikelihoodClassifier
from inertia_id.classifiers.registry import train_classifier

# A random 4-step sequence (numpy seed 3) that separates the paper's candidates only
# partly: at 1x noise euclidean k-means gets about 77 %, DTW 90 %, the likelihood 97 %.
MIXED_SEQUENCE = [[4, 0, 0, 1, 0, 4], [4, 2, 0, 0, 1, 2], [3, 2, 1, 0, 3, 3], [0, 0, 2, 1, 4, 2]]


@pytest.fixture(scope="module")
def likelihood(paper: Scenario) -> LikelihoodClassifier:
    model = train_classifier(paper, MIXED_SEQUENCE, 20, np.random.default_rng(1), kind="likelihood")
    assert isinstance(model, LikelihoodClassifier)
    return model


@pytest.fixture(scope="module")
def kmeans(paper: Scenario) -> dict[str, InertiaClassifier]:
    """The paper's classifier, trained on exactly the likelihood classifier's data.

    DTW within a 5-sample band (thruster lags are shorter): same accuracy on this
    sequence as unconstrained DTW, in a third of the time.
    """
    return {
        "euclidean": train(paper, MIXED_SEQUENCE, 20, np.random.default_rng(1), metric="euclidean"),
        "dtw": train(
            paper,
            MIXED_SEQUENCE,
            20,
            np.random.default_rng(1),
            metric="dtw",
            sakoe_chiba_radius=5,
        ),
    }


def gaussian_data(
    means: np.ndarray, covariance: np.ndarray, per_class: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Series (n, length, 3) drawn from N(mean_k, covariance) around flattened means."""
    k, length, _ = means.shape
    chol = np.linalg.cholesky(covariance)
    noise = rng.standard_normal((k * per_class, 3 * length)) @ chol.T
    y = np.repeat(np.arange(k), per_class)
    return means[y] + noise.reshape(-1, length, 3), y


# The Gaussian model itself, where the truth is known.


def test_recovers_the_bayes_rule_on_gaussian_data() -> None:
    rng = np.random.default_rng(0)
    length, p = 4, 12
    factor = rng.standard_normal((p, 3))
    covariance = 1e-6 * (np.eye(p) + factor @ factor.T)  # white noise + 3 correlated modes
    means = 1e-3 * rng.standard_normal((3, length, 3))
    X, y = gaussian_data(means, covariance, 2000, rng)
    model = LikelihoodClassifier(shrinkage=1e-3).fit(X, y)
    np.testing.assert_allclose(model.means_, means, atol=1e-4)
    np.testing.assert_allclose(model.covariance_, covariance, atol=0.1 * covariance.max())

    X_test, y_test = gaussian_data(means, covariance, 500, rng)
    flat = X_test.reshape(len(X_test), -1)
    precision = np.linalg.inv(covariance)
    diffs = flat[:, None, :] - means.reshape(3, -1)[None]
    true_distances = np.sqrt(np.einsum("nki,ij,nkj->nk", diffs, precision, diffs))
    np.testing.assert_allclose(model.transform(X_test), true_distances, rtol=0.05)
    agree = np.mean(model.predict(X_test) == true_distances.argmin(axis=1))
    assert agree > 0.98
    # The classes overlap: the rule is not trivially perfect, so agreement means something.
    assert np.mean(true_distances.argmin(axis=1) == y_test) < 0.99


def test_log_likelihood_is_the_gaussian_density(likelihood: LikelihoodClassifier) -> None:
    X = likelihood.means_[:2] + 1e-4
    expected = np.stack(
        [
            multivariate_normal(mean.reshape(-1), likelihood.covariance_).logpdf(
                X.reshape(len(X), -1)
            )
            for mean in likelihood.means_
        ],
        axis=1,
    )
    np.testing.assert_allclose(likelihood.log_likelihood(X), expected, rtol=1e-9)
    proba = likelihood.predict_proba(X)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0)
    np.testing.assert_array_equal(proba.argmax(axis=1), likelihood.predict(X))


def test_shrinkage_makes_the_singular_covariance_invertible(
    likelihood: LikelihoodClassifier,
) -> None:
    """100 series in 240 dimensions: the sample covariance has rank <= 95."""
    assert likelihood.covariance_.shape == (240, 240)
    assert 0.0 < likelihood.shrinkage_ < 1.0
    assert np.linalg.eigvalsh(likelihood.covariance_).min() > 0.0
    lw = train_classifier(
        Scenario.paper(),
        MIXED_SEQUENCE,
        20,
        np.random.default_rng(1),
        kind="likelihood",
        shrinkage="ledoit-wolf",
    )
    assert 0.0 < lw.shrinkage_ < 1.0 and lw.shrinkage_ != likelihood.shrinkage_


# Against the paper's classifier.


@pytest.mark.parametrize(
    ("metric", "process_noise_scale"), [("euclidean", 1.0), ("euclidean", 4.0), ("dtw", 1.0)]
)
def test_never_worse_than_the_kmeans_classifier(
    likelihood: LikelihoodClassifier,
    kmeans: dict[str, InertiaClassifier],
    paper: Scenario,
    metric: str,
    process_noise_scale: float,
) -> None:
    X, y = noisy(paper, MIXED_SEQUENCE, 40, 11, process=process_noise_scale)
    baseline = kmeans[metric].evaluate(X, y)["accuracy"]
    ours = likelihood.evaluate(X, y)["accuracy"]
    standard_error = math.sqrt(baseline * (1.0 - baseline) / len(y))
    assert ours >= baseline - 2.0 * standard_error


# Novelty and identify.


def test_out_of_fold_thresholds_hold_fresh_responses(
    likelihood: LikelihoodClassifier, paper: Scenario
) -> None:
    """In-sample distances are biased low; out-of-fold ones are what fresh series see."""
    X, y = simulate(paper, MIXED_SEQUENCE, 40, np.random.default_rng(12)).dataset()
    own = likelihood.transform(X)[np.arange(len(y)), y]
    assert np.mean(own > likelihood.novelty_thresholds()[y]) == 0.0
    assert np.mean(own > likelihood.max_training_distance_[y]) < 0.1
    X_train, y_train = simulate(paper, MIXED_SEQUENCE, 20, np.random.default_rng(1)).dataset()
    in_sample = likelihood.transform(X_train)[np.arange(len(y_train)), y_train]
    in_sample_max = np.array([in_sample[y_train == k].max() for k in range(5)])
    assert np.mean(own > in_sample_max[y]) > 0.9


# Refusals quote what they got.


@pytest.mark.parametrize("shrinkage", ["oracle", 1.5, 0.0, True])
def test_refuses_a_shrinkage_it_cannot_use(paper: Scenario, shrinkage: object) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 3, np.random.default_rng(0)).dataset()
    with pytest.raises(InputError, match=rf"shrinkage must be one of .* got {shrinkage!r}"):
        LikelihoodClassifier(shrinkage).fit(X, y)


def test_refuses_training_series_that_do_not_vary(quiet_paper: Scenario) -> None:
    X, y = simulate(quiet_paper, GOOD_SEQUENCE, 3, np.random.default_rng(0)).dataset()
    with pytest.raises(InputError, match="covariance is not positive definite"):
        LikelihoodClassifier(0.5).fit(X, y)
