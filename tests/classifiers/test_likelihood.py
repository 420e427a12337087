"""The limit classifier: Gaussian likelihood of the candidates' mean responses."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from inertia_id import InertiaClassifier, Scenario, identify, simulate, train
from inertia_id.classifiers.likelihood import LikelihoodClassifier, train_likelihood

# A random 4-step sequence (numpy seed 3) that separates the paper's candidates only
# partly: at 1x noise euclidean k-means gets about 77 %, DTW 90 %, the likelihood 97 %.
MIXED_SEQUENCE = [[4, 0, 0, 1, 0, 4], [4, 2, 0, 0, 1, 2], [3, 2, 1, 0, 3, 3], [0, 0, 2, 1, 4, 2]]
GOOD_SEQUENCE = [[4, 4, 4, 0, 0, 0]] * 4
I0 = np.diag([100.0, 60.0, 90.0])


@pytest.fixture(scope="module")
def likelihood(paper: Scenario) -> LikelihoodClassifier:
    return train_likelihood(paper, MIXED_SEQUENCE, 20, np.random.default_rng(1))


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
    lw = train_likelihood(
        Scenario.paper(), MIXED_SEQUENCE, 20, np.random.default_rng(1), shrinkage="ledoit-wolf"
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
    X, y = simulate(
        paper,
        MIXED_SEQUENCE,
        40,
        np.random.default_rng(11),
        process_noise_scale=process_noise_scale,
    ).dataset()
    baseline = kmeans[metric].evaluate(X, y)["accuracy"]
    ours = likelihood.evaluate(X, y)["accuracy"]
    standard_error = math.sqrt(baseline * (1.0 - baseline) / len(y))
    assert ours >= baseline - 2.0 * standard_error


def test_evaluate_has_the_inertia_classifier_keys(
    likelihood: LikelihoodClassifier, kmeans: dict[str, InertiaClassifier], paper: Scenario
) -> None:
    X, y = simulate(paper, MIXED_SEQUENCE, 4, np.random.default_rng(3)).dataset()
    ours, theirs = likelihood.evaluate(X, y), kmeans["euclidean"].evaluate(X, y)
    assert set(ours) == set(theirs)
    assert ours["confusion"].shape == theirs["confusion"].shape
    assert likelihood.score(X, y) == ours["f1"]


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


def test_identify_names_each_candidate_and_refuses_strangers(
    likelihood: LikelihoodClassifier,
    paper: Scenario,
    scenario_like: Callable[..., Scenario],
) -> None:
    fresh = simulate(paper, MIXED_SEQUENCE, 2, np.random.default_rng(5))
    named = 0
    for k in range(paper.n_candidates):
        for i in range(2):
            verdict = identify(
                likelihood,
                {
                    "time_s": fresh.time_s.tolist(),
                    "omega_rad_s": fresh.omega_measured[k, i].tolist(),
                },
            )
            assert not verdict.matches_none
            named += verdict.candidate_index == k
    assert named >= 9  # 97 % accuracy on this sequence
    odd = simulate(
        scenario_like({"heavy": 1.3 * I0, "light": 0.6 * I0}),
        MIXED_SEQUENCE,
        2,
        np.random.default_rng(6),
    )
    for k in range(2):
        for i in range(2):
            verdict = identify(
                likelihood,
                {"time_s": odd.time_s.tolist(), "omega_rad_s": odd.omega_measured[k, i].tolist()},
            )
            assert verdict.matches_none
            assert verdict.distances[verdict.candidate] > verdict.threshold


# Storage.


def test_json_round_trip_gives_identical_predictions(
    likelihood: LikelihoodClassifier, paper: Scenario, tmp_path: Path
) -> None:
    X, _ = simulate(paper, MIXED_SEQUENCE, 4, np.random.default_rng(4)).dataset()
    path = tmp_path / "likelihood.json"
    likelihood.save(path)
    loaded = LikelihoodClassifier.load(path)
    np.testing.assert_array_equal(loaded.transform(X), likelihood.transform(X))
    np.testing.assert_array_equal(loaded.predict(X), likelihood.predict(X))
    np.testing.assert_array_equal(loaded.novelty_thresholds(), likelihood.novelty_thresholds())
    assert loaded.scenario_ == likelihood.scenario_
    np.testing.assert_array_equal(loaded.sequence_, likelihood.sequence_)
    doc = json.loads(path.read_text())
    doc["classifier"]["means_rad_s"][0][0][0] += 1e-3
    with pytest.raises(ValueError, match="checksum mismatch"):
        LikelihoodClassifier.from_json(json.dumps(doc))
    with pytest.raises(ValueError, match="not an inertia-id/likelihood-classifier document"):
        LikelihoodClassifier.from_json(json.dumps({**doc, "format": "inertia-id/classifier"}))


# Refusals quote what they got.


def test_refuses_series_of_the_wrong_shape(likelihood: LikelihoodClassifier) -> None:
    with pytest.raises(
        ValueError, match=r"series have 79 samples; the classifier was trained on 80"
    ):
        likelihood.predict(np.zeros((2, 79, 3)))
    with pytest.raises(ValueError, match=r"got \(2, 80, 4\)"):
        likelihood.predict(np.zeros((2, 80, 4)))


def test_refuses_nan_rates(likelihood: LikelihoodClassifier) -> None:
    X = np.zeros((3, 80, 3))
    X[2, 5, 1] = np.nan
    with pytest.raises(ValueError, match=r"series 2, sample 5, axis 1 is nan"):
        likelihood.transform(X)
    with pytest.raises(ValueError, match=r"series 0, sample 0, axis 0 is inf"):
        LikelihoodClassifier().fit(np.full((6, 80, 3), np.inf), [0, 0, 0, 1, 1, 1])


def test_refuses_bad_labels_and_parameters(paper: Scenario) -> None:
    X, y = simulate(paper, GOOD_SEQUENCE, 3, np.random.default_rng(0)).dataset()
    with pytest.raises(ValueError, match=r"one label per series \(15\), got shape \(9,\)"):
        LikelihoodClassifier().fit(X, y[:9])
    with pytest.raises(ValueError, match=r"series per candidate: \[3, 3, 3, 3, 2\]"):
        LikelihoodClassifier().fit(X[:-1], y[:-1])
    with pytest.raises(ValueError, match=r"got 'oracle'"):
        LikelihoodClassifier("oracle").fit(X, y)
    with pytest.raises(ValueError, match=r"got 1.5"):
        LikelihoodClassifier(1.5).fit(X, y)
    with pytest.raises(ValueError, match=r"got \[5\]"):
        LikelihoodClassifier().fit(X, y).evaluate(X, np.where(y == 4, 5, y))
