"""The separability objective: its algebra against dense linear algebra, its statistics,
and its use as the search's score."""

from __future__ import annotations

import re
import warnings
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scenario_support import GOOD_SEQUENCE
from sklearn.covariance import ledoit_wolf

from inertia_id import Scenario
from inertia_id.physics.simulate import simulate
from inertia_id.search import (
    PrefixScorer,
    ScorerSettings,
    SequenceSearchEnv,
    evaluate_sequence,
)
from inertia_id.search.objectives import (
    bhattacharyya_matrix,
    error_bound,
    mahalanobis_matrix,
    pooled_covariance,
    separability_score,
)

# Every thruster at the same duty: opposite thrusters cancel, no torque, no signal.
BALANCED = [[1, 1, 1, 1, 1, 1]] * 4
# One weak thruster at a quarter duty for one step, then nothing.
WEAK = [[1, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]]
SEPARABILITY = ScorerSettings(objective="separability")


def small_omega(seed: int = 0) -> np.ndarray:
    """(K=3, n=4, T=5, 3): d = 15 dimensions, N = 12 residuals (rank 9 < d)."""
    rng = np.random.default_rng(seed)
    means = rng.standard_normal((3, 1, 5, 3))
    mixing = rng.standard_normal((15, 15)) / 4  # correlated, anisotropic noise
    noise = (rng.standard_normal((3, 4, 15)) @ mixing).reshape(3, 4, 5, 3)
    return means + noise


def dense_mahalanobis(omega: np.ndarray, shrinkage: float | None, debias: bool) -> np.ndarray:
    """The same quantity with a dense d x d covariance and numpy's inverse."""
    k, n = omega.shape[:2]
    x = omega.reshape(k, n, -1)
    means = x.mean(axis=1)
    residuals = (x - x.mean(axis=1, keepdims=True)).reshape(k * n, -1)
    covariance = pooled_covariance(omega, shrinkage=shrinkage)
    sigma = covariance.dense()
    inverse = np.linalg.inv(sigma)
    out = np.zeros((k, k))
    for i in range(k):
        for j in range(k):
            diff = means[i] - means[j]
            out[i, j] = diff @ inverse @ diff
    if debias:
        b = covariance.residual_weight
        left_out = [r @ np.linalg.inv(sigma - b * np.outer(r, r)) @ r for r in residuals]
        out = np.maximum(out - 2.0 * np.mean(left_out) / (1.0 - 1.0 / n) / n, 0.0)
        np.fill_diagonal(out, 0.0)
    return out


# The algebra: Gram matrix and Woodbury against dense matrices.


def test_shrunk_covariance_is_ledoit_wolf_of_the_residuals_over_their_dof() -> None:
    omega = small_omega()
    k, n = omega.shape[:2]
    x = omega.reshape(k, n, -1)
    residuals = (x - x.mean(axis=1, keepdims=True)).reshape(k * n, -1)
    expected, intensity = ledoit_wolf(residuals, assume_centered=True)
    covariance = pooled_covariance(omega)
    assert covariance.shrinkage == pytest.approx(intensity, rel=1e-10)
    assert 0.0 < covariance.shrinkage < 1.0  # neither end: both terms are exercised
    dof = k * n / (k * n - k)
    np.testing.assert_allclose(covariance.dense(), dof * expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("shrinkage", [None, 0.3, 1.0])
@pytest.mark.parametrize("debias", [False, True])
def test_distances_match_a_dense_inverse(shrinkage: float | None, debias: bool) -> None:
    omega = small_omega(1)
    expected = dense_mahalanobis(omega, shrinkage, debias)
    assert expected.max() > 1.0  # the candidates differ: the comparison is not 0 == 0
    got = mahalanobis_matrix(omega, shrinkage=shrinkage, debias=debias)
    np.testing.assert_allclose(got, expected, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(
        bhattacharyya_matrix(omega, shrinkage=shrinkage, debias=debias), expected / 8.0,
        rtol=1e-8, atol=1e-9,
    )  # fmt: skip


def test_error_bound_is_the_union_of_pairwise_bhattacharyya_bounds() -> None:
    omega = small_omega(2)
    distances = bhattacharyya_matrix(omega)
    k = len(distances)
    pairs = [(i, j) for i in range(k) for j in range(i + 1, k)]
    expected = sum(np.exp(-distances[i, j]) for i, j in pairs) / k
    assert error_bound(omega) == pytest.approx(expected, rel=1e-12)
    # A noise margin m divides every distance by m².
    expected_m = sum(np.exp(-distances[i, j] / 4.0) for i, j in pairs) / k
    assert error_bound(omega, noise_margin=2.0) == pytest.approx(expected_m, rel=1e-12)
    score = separability_score(omega, noise_margin=2.0)
    assert score == pytest.approx(1.0 - min(1.0, expected_m / ((k - 1) / k)), rel=1e-12)


# The statistics.


def test_debiased_distance_estimates_the_true_one() -> None:
    # Two Gaussian candidates, isotropic noise sigma, means delta apart: the true squared
    # Mahalanobis distance is (delta / sigma)². The plain plug-in estimate is too large by
    # about 2 d / n (the noise of the estimated means); the debiased one is not.
    rng = np.random.default_rng(5)
    n, t, sigma = 40, 20, 0.01
    d = 3 * t
    means = np.zeros((2, 1, t, 3))
    means[1, 0, :, 0] = 0.03 / np.sqrt(t)  # |Δμ| = 0.03, true D² = 9
    estimates = []
    for _ in range(20):
        omega = means + sigma * rng.standard_normal((2, n, t, 3))
        plain = mahalanobis_matrix(omega, shrinkage=1.0, debias=False)[0, 1]
        fair = mahalanobis_matrix(omega, shrinkage=1.0)[0, 1]
        estimates.append((plain, fair))
    plain_mean, fair_mean = np.mean(estimates, axis=0)
    assert plain_mean == pytest.approx(9.0 + 2.0 * d / n, rel=0.1)
    assert fair_mean == pytest.approx(9.0, rel=0.1)


def test_identical_candidates_are_not_separable(
    scenario_like: Any, paper: Scenario, good_sequence: np.ndarray
) -> None:
    # Five copies of one spacecraft: responses differ by noise only.
    tensor = paper.inertia_array[0]
    twins = scenario_like({f"copy {i}": tensor for i in range(5)})
    omega = simulate(twins, good_sequence, 20, np.random.default_rng(0)).omega_measured
    for shrinkage in (None, 1.0):
        assert error_bound(omega, shrinkage=shrinkage) >= 1.0
        assert separability_score(omega, shrinkage=shrinkage) < 0.05
    # Without the correction for the means' noise, the Ledoit–Wolf metric calls the
    # copies far apart: the reason for the correction.
    assert separability_score(omega, debias=False) > 0.5
    # The very same series for every candidate: distance exactly 0.
    same = np.repeat(omega[:1], 5, axis=0)
    assert np.all(mahalanobis_matrix(same) == 0.0)
    assert error_bound(same) == pytest.approx(2.0)  # (1/K) * K(K-1)/2 pairs of exp(0)
    assert separability_score(same) == 0.0


def test_noise_free_distinct_candidates_are_perfectly_separable(
    quiet_paper: Scenario, good_sequence: np.ndarray
) -> None:
    omega = simulate(quiet_paper, good_sequence, 3, np.random.default_rng(0)).omega_measured
    assert separability_score(omega) == 1.0
    assert error_bound(omega) == 0.0


# The objective on the paper preset.


def test_a_good_sequence_scores_above_a_balanced_or_weak_one(paper: Scenario) -> None:
    scorer = PrefixScorer(paper, 4, SEPARABILITY, seed=0)
    good, balanced, weak = (scorer.score(s) for s in (GOOD_SEQUENCE, BALANCED, WEAK))
    assert good.f1 > 0.9
    assert balanced.f1 < 0.1 and weak.f1 < 0.1
    assert good.error_bound is not None and balanced.error_bound is not None
    assert good.error_bound < 0.1 < 1.0 < balanced.error_bound
    # The clustering agrees on the order (on the same noise draw).
    clustering = PrefixScorer(paper, 4, ScorerSettings(), seed=0)
    assert clustering.score(GOOD_SEQUENCE).f1 > clustering.score(BALANCED).f1 + 0.3


def test_separability_scorer_is_deterministic_and_order_free(paper: Scenario) -> None:
    settings = replace(SEPARABILITY, n_realisations=6)
    prefixes = [
        GOOD_SEQUENCE[:1],
        GOOD_SEQUENCE[:3],
        WEAK[:2],
        [GOOD_SEQUENCE[0], WEAK[0]],
        BALANCED,
    ]
    forward = PrefixScorer(paper, 4, settings, seed=3)
    backward = PrefixScorer(paper, 4, settings, seed=3)
    uncached = PrefixScorer(paper, 4, replace(settings, cache_mb=0.0), seed=3)
    expected = [forward.score(p) for p in prefixes]
    assert [backward.score(p) for p in reversed(prefixes)] == expected[::-1]
    assert [uncached.score(p) for p in prefixes] == expected
    assert all(s.objective == "separability" and 0.0 <= s.f1 <= 1.0 for s in expected)
    # The prefixes score differently, so the comparisons above can tell them apart.
    assert len({s.error_bound for s in expected}) == len(expected)
    # The simulation is the clustering objective's, on the same noise.
    clustering = PrefixScorer(paper, 4, replace(settings, objective="f1"), seed=3)
    for prefix, score in zip(prefixes, expected, strict=True):
        assert score.final_rate_rad_s == clustering.score(prefix).final_rate_rad_s


def test_f1_objective_scores_carry_no_bound(paper: Scenario) -> None:
    score = PrefixScorer(paper, 1, ScorerSettings(n_realisations=3), seed=0).score(
        GOOD_SEQUENCE[:1]
    )
    assert score.objective == "f1" and score.error_bound is None


def test_environment_with_the_separability_objective_passes_the_checker(
    paper: Scenario,
) -> None:
    env = SequenceSearchEnv(paper, sequence_length=3, seed=0, settings=SEPARABILITY)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    assert [w for w in caught if issubclass(w.category, UserWarning)] == []
    env.reset(seed=1)
    _, reward, _, _, info = env.step(np.asarray(GOOD_SEQUENCE[0]))
    assert info["objective"] == "separability"
    assert reward == pytest.approx(-1.0 + 3.0 * info["f1"], abs=1e-12)
    scorer = PrefixScorer(paper, 3, SEPARABILITY, seed=1)
    assert info["f1"] == scorer.score(GOOD_SEQUENCE[:1]).f1
    assert info["error_bound"] == scorer.score(GOOD_SEQUENCE[:1]).error_bound


def test_fresh_evaluation_of_a_separability_search_reports_the_clustering_f1(
    paper: Scenario,
) -> None:
    settings = replace(SEPARABILITY, n_realisations=5)
    fresh = evaluate_sequence(paper, GOOD_SEQUENCE[:2], settings, seed=11, n_draws=2)
    clustering = evaluate_sequence(
        paper, GOOD_SEQUENCE[:2], replace(settings, objective="f1"), seed=11, n_draws=2
    )
    assert fresh.f1 == clustering.f1
    assert fresh.final_rate_rad_s == clustering.final_rate_rad_s
    assert clustering.separability is None
    assert fresh.separability is not None and len(fresh.separability) == 2
    seeds = np.random.SeedSequence(11).generate_state(2, np.uint32)
    assert fresh.separability == [
        PrefixScorer(paper, 2, settings, seed=int(s)).score(GOOD_SEQUENCE[:2]).f1 for s in seeds
    ]


# Refusals.


@pytest.mark.parametrize(
    ("changes", "quoted"),
    [
        ({"objective": "entropy"}, "'entropy'"),
        ({"objective": "separability", "n_realisations": 1}, "at least 2, got 1"),
        ({"separability_margin": 0.0}, "0.0"),
        ({"separability_margin": float("inf")}, "inf"),
        ({"separability_shrinkage": 1.5}, "1.5"),
    ],
)
def test_bad_separability_settings_are_refused(
    paper: Scenario, changes: dict[str, Any], quoted: str
) -> None:
    with pytest.raises(ValueError, match=re.escape(quoted)):
        PrefixScorer(paper, 2, ScorerSettings(**changes))


@pytest.mark.parametrize(
    ("omega", "quoted"),
    [
        (np.zeros((5, 20, 3)), "(5, 20, 3)"),
        (np.zeros((1, 4, 2, 3)), "K = 1"),
        (np.zeros((3, 1, 2, 3)), "n = 1"),
        (np.full((2, 2, 2, 3), np.nan), "non-finite"),
    ],
)
def test_malformed_responses_are_refused(omega: np.ndarray, quoted: str) -> None:
    with pytest.raises(ValueError, match=re.escape(quoted)):
        separability_score(omega)
    with pytest.raises(ValueError, match="noise_margin"):
        error_bound(small_omega(), noise_margin=-1.0)
    with pytest.raises(ValueError, match="shrinkage"):
        mahalanobis_matrix(small_omega(), shrinkage=2.0)
