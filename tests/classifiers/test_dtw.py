"""The numba DTW k-means: distances and DBA against tslearn, and the k-means contract."""

from __future__ import annotations

import itertools
import re
import warnings
from collections.abc import Callable

import numpy as np
import pytest

from inertia_id import InputError, Scenario, match_clusters, simulate
from inertia_id.classifiers import dtw as dtw_module
from inertia_id.classifiers.dtw import (
    cdist_dtw,
    cdist_soft_dtw_normalized,
    dba,
    dtw,
    kmeans_dtw,
)

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # tslearn warns about optional h5py at import
    from tslearn.barycenters import dtw_barycenter_averaging
    from tslearn.metrics import cdist_dtw as tslearn_cdist_dtw
    from tslearn.metrics import cdist_soft_dtw_normalized as tslearn_soft_dtw


def random_series(seed: int, n: int, length: int = 15, dims: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal((n, length, dims))


def separated_groups(
    seed: int, per_group: int = 8, length: int = 40
) -> tuple[np.ndarray, np.ndarray]:
    """Three groups of time-shifted sinusoids (different frequency and offset) plus noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, length)
    series, labels = [], []
    for group, (freq, offset) in enumerate([(1.0, 0.0), (2.0, 1.5), (3.0, -1.5)]):
        for _ in range(per_group):
            shift = rng.uniform(-0.05, 0.05)
            wave = np.sin(2 * np.pi * freq * (t - shift)) + offset
            second = np.cos(2 * np.pi * freq * (t - shift))
            clean = np.stack([wave, second], axis=1)
            series.append(clean + 0.05 * rng.standard_normal(clean.shape))
            labels.append(group)
    order = rng.permutation(len(labels))
    return np.asarray(series)[order], np.asarray(labels)[order]


def banded_cost(x: np.ndarray, barycenter: np.ndarray, radius: int | None) -> float:
    """Mean squared DTW distance of the members of x to a barycenter."""
    return float(np.mean(cdist_dtw(x, barycenter[None], radius)[:, 0] ** 2))


# Distances.


@pytest.mark.parametrize("seed", [0, 1])
def test_cdist_matches_tslearn_unconstrained(seed: int) -> None:
    x, y = random_series(seed, 6), random_series(seed + 100, 4)
    expected = tslearn_cdist_dtw(x, y)
    np.testing.assert_allclose(cdist_dtw(x, y), expected, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cdist_dtw(x, y, None), expected, rtol=0, atol=1e-10)


@pytest.mark.parametrize("radius", [0, 1, 3])
def test_cdist_matches_tslearn_in_a_sakoe_chiba_band(radius: int) -> None:
    x, y = random_series(radius, 6), random_series(radius + 100, 5)
    expected = tslearn_cdist_dtw(x, y, global_constraint="sakoe_chiba", sakoe_chiba_radius=radius)
    np.testing.assert_allclose(cdist_dtw(x, y, radius), expected, rtol=0, atol=1e-10)


@pytest.mark.parametrize("gamma", [0.01, 0.3, 2.0])
def test_normalised_soft_dtw_matches_tslearn(gamma: float) -> None:
    x, y = random_series(7, 5), random_series(8, 3, length=11)
    expected = tslearn_soft_dtw(x, y, gamma=gamma)
    np.testing.assert_allclose(
        cdist_soft_dtw_normalized(x, y, gamma), expected, rtol=1e-12, atol=1e-12
    )
    # A divergence: zero for a series against itself, never negative.
    np.testing.assert_allclose(np.diag(cdist_soft_dtw_normalized(x, x, gamma)), 0.0, atol=1e-12)


@pytest.mark.parametrize("gamma", [0.0, -1.0, float("nan")])
def test_soft_dtw_refuses_a_gamma_it_cannot_use(gamma: float) -> None:
    x = random_series(0, 2)
    with pytest.raises(InputError, match=rf"gamma must be a number > 0, got {gamma!r}"):
        cdist_soft_dtw_normalized(x, x, gamma)


def test_every_kernel_is_cached_on_disk() -> None:
    """A fresh process loads compiled code numba wrote to disk rather than compiling."""
    kernels = [v for v in vars(dtw_module).values() if hasattr(v, "signatures")]
    assert {k.__name__ for k in kernels} >= {"_cdist", "_cdist_soft_dtw_normalized", "_lloyd"}
    assert all(kernel._cache.__class__.__name__ != "NullCache" for kernel in kernels)


def test_narrower_band_never_gives_a_shorter_distance() -> None:
    # A band only removes warping paths, so the distance can only grow as it narrows;
    # on random data it does grow somewhere, else the radius would be ignored.
    x, y = random_series(3, 5), random_series(4, 5)
    distances = [cdist_dtw(x, y, r) for r in (None, 3, 1, 0)]
    for wider, narrower in itertools.pairwise(distances):
        assert np.all(narrower >= wider - 1e-12)
        assert np.any(narrower > wider + 1e-9)


def test_distance_of_identical_series_is_zero() -> None:
    a = random_series(5, 1)[0]
    assert dtw(a, a) == 0.0
    assert dtw(a, a, radius=2) == 0.0
    assert dtw(a, a + 0.1) > 0.0


def test_time_shifted_copy_is_closer_under_warping_than_euclidean() -> None:
    # A pulse delayed by two samples: unconstrained DTW and a band of 2 realign it
    # exactly, the Euclidean distance (radius 0) cannot.
    a = np.zeros((20, 1))
    a[5:9, 0] = 1.0
    b = np.roll(a, 2, axis=0)
    assert dtw(a, b) == 0.0
    assert dtw(a, b, radius=2) == 0.0
    assert dtw(a, b, radius=1) > 0.0
    assert dtw(a, b, radius=0) == pytest.approx(2.0, rel=1e-12)  # 4 unit differences


def test_radius_zero_is_the_euclidean_distance_of_the_flattened_series() -> None:
    x, y = random_series(6, 4), random_series(7, 3)
    expected = np.linalg.norm(x.reshape(4, 1, -1) - y.reshape(1, 3, -1), axis=-1)
    np.testing.assert_allclose(cdist_dtw(x, y, 0), expected, rtol=1e-12, atol=0)


def test_radius_wider_than_the_series_is_unconstrained() -> None:
    x, y = random_series(8, 3, length=10), random_series(9, 3, length=10)
    np.testing.assert_array_equal(cdist_dtw(x, y, 50), cdist_dtw(x, y, None))


@pytest.mark.parametrize("radius", [-1, 1.5, True, "2"])
def test_bad_radius_is_refused(radius: object) -> None:
    x = random_series(10, 6)
    with pytest.raises(ValueError, match=re.escape(repr(radius))):
        cdist_dtw(x, x, radius)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=re.escape(repr(radius))):
        kmeans_dtw(x, 2, np.random.default_rng(0), radius=radius)  # type: ignore[arg-type]


def test_series_of_different_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match=r"\(2, 10, 3\)"):
        cdist_dtw(np.zeros((2, 10, 3)), np.zeros((2, 11, 3)))
    with pytest.raises(ValueError, match="equal shape"):
        dtw(np.zeros((10, 3)), np.zeros((10, 2)))


# DBA barycentres.


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_unconstrained_dba_matches_tslearn(seed: int) -> None:
    x = random_series(seed, 7, length=12)
    # A start away from the mean so that several majorise-minimise iterations run.
    init = random_series(seed + 50, 1, length=12)[0]
    expected = dtw_barycenter_averaging(x, init_barycenter=init, max_iter=30)
    np.testing.assert_allclose(dba(x, init, None, max_iter=30), expected, rtol=0, atol=1e-10)
    assert not np.allclose(expected, x.mean(axis=0))  # DBA is not the plain mean here


def test_dba_with_radius_zero_is_the_plain_mean() -> None:
    x = random_series(11, 6)
    init = random_series(12, 1)[0]
    np.testing.assert_allclose(dba(x, init, 0), x.mean(axis=0), rtol=0, atol=1e-12)
    np.testing.assert_allclose(dba(x, None, 0), x.mean(axis=0), rtol=0, atol=1e-12)


def test_dba_of_a_single_series_is_that_series() -> None:
    x = random_series(13, 1)
    np.testing.assert_allclose(dba(x, None, 2), x[0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("radius", [1, 2, 4])
def test_banded_dba_lowers_the_banded_cost_to_the_members(radius: int) -> None:
    x, _ = separated_groups(14)
    x = x[:10]
    start = random_series(15, 1, length=x.shape[1], dims=x.shape[2])[0]
    barycenter = dba(x, start, radius)
    before, after = banded_cost(x, start, radius), banded_cost(x, barycenter, radius)
    assert after <= before
    assert after < 0.5 * before  # a random start is far from the barycentre


# k-means.


def test_kmeans_recovers_well_separated_groups() -> None:
    x, y = separated_groups(20)
    for radius in (None, 3):
        result = kmeans_dtw(x, 3, np.random.default_rng(0), radius=radius)
        assert match_clusters(y, result.labels, 3).f1 == 1.0
        assert result.centers.shape == (3, *x.shape[1:])
        # The inertia is the mean squared distance of each series to its own centroid.
        own = cdist_dtw(x, result.centers, radius)[np.arange(len(x)), result.labels]
        assert result.inertia == pytest.approx(np.mean(own**2), rel=1e-6)


def test_kmeans_is_reproducible_for_the_same_rng_seed() -> None:
    x, _ = separated_groups(21)
    first = kmeans_dtw(x, 3, np.random.default_rng(4), radius=2)
    second = kmeans_dtw(x, 3, np.random.default_rng(4), radius=2)
    np.testing.assert_array_equal(first.labels, second.labels)
    np.testing.assert_array_equal(first.centers, second.centers)
    assert first.inertia == second.inertia


def bad_start(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Two centroids inside group 0, one between groups 1 and 2: a poor local optimum."""
    group0 = x[y == 0]
    between = 0.5 * (x[y == 1].mean(axis=0) + x[y == 2].mean(axis=0))
    return np.stack([group0[0], group0[1], between])


def test_kmeans_keeps_the_lowest_inertia_run() -> None:
    x, y = separated_groups(22)
    init = bad_start(x, y)
    alone = kmeans_dtw(x, 3, np.random.default_rng(0), radius=2, n_init=0, init=init)
    assert match_clusters(y, alone.labels, 3).f1 < 1.0  # the bad start stays bad
    seeded = kmeans_dtw(x, 3, np.random.default_rng(0), radius=2, n_init=3)
    assert seeded.inertia < alone.inertia
    # The same k-means++ starts (same seed) plus the bad start: the better run is kept.
    both = kmeans_dtw(x, 3, np.random.default_rng(0), radius=2, n_init=3, init=init)
    assert both.inertia == seeded.inertia
    np.testing.assert_array_equal(both.labels, seeded.labels)
    assert match_clusters(y, both.labels, 3).f1 == 1.0


def test_more_initialisations_never_give_a_higher_inertia(paper: Scenario) -> None:
    # With the same seed the first k-means++ start of n_init=5 is the start of n_init=1,
    # so the kept inertia can only be lower. The paper's good sequence has local optima
    # that a single start falls into, so on some seed it is strictly lower.
    x, _ = simulate(paper, [[4, 4, 4, 0, 0, 0]] * 4, 8, np.random.default_rng(0)).dataset()
    x = x / np.sqrt(np.mean(x**2))
    one, five = [], []
    for seed in range(4):
        one.append(kmeans_dtw(x, 5, np.random.default_rng(seed), radius=2, n_init=1).inertia)
        five.append(kmeans_dtw(x, 5, np.random.default_rng(seed), radius=2, n_init=5).inertia)
    assert all(f <= o for f, o in zip(five, one, strict=True))
    assert any(f < o - 1e-9 for f, o in zip(five, one, strict=True))


def test_init_of_the_wrong_shape_is_refused_with_the_shapes() -> None:
    x, _ = separated_groups(23)
    wrong = np.zeros((2, *x.shape[1:]))
    with pytest.raises(ValueError, match=re.escape(f"{(3, *x.shape[1:])}, got {wrong.shape}")):
        kmeans_dtw(x, 3, np.random.default_rng(0), init=wrong)


def test_too_few_series_or_no_start_is_refused() -> None:
    x = random_series(24, 2)
    with pytest.raises(ValueError, match="n >= 3"):
        kmeans_dtw(x, 3, np.random.default_rng(0))
    with pytest.raises(ValueError, match="n_init"):
        kmeans_dtw(x, 2, np.random.default_rng(0), n_init=0)


@pytest.mark.parametrize("radius", [None, 0, 2])
def test_degenerate_init_gives_no_empty_cluster(radius: int | None) -> None:
    # Every centroid equal: all series tie for cluster 0 at first, so every other
    # cluster starts empty and must be reseeded.
    x, _ = separated_groups(25)
    init = np.repeat(x[:1], 3, axis=0)
    result = kmeans_dtw(x, 3, np.random.default_rng(0), radius=radius, n_init=0, init=init)
    np.testing.assert_array_equal(np.sort(np.unique(result.labels)), [0, 1, 2])
    assert np.all(np.isfinite(result.centers))
    assert np.isfinite(result.inertia)


def singleton_stolen() -> tuple[np.ndarray, np.ndarray]:
    # Series 2 is alone in cluster 1 and is the worst-fitted series, so reseeding the
    # empty cluster 2 takes it and leaves cluster 1 empty.
    a = np.zeros((6, 1))
    return np.stack([a, a + 0.01, a + 10.0]), np.stack([a, a + 11.0, a])


def identical_series() -> tuple[np.ndarray, np.ndarray]:
    # Every series the same (a noise-free response to thrusters off): every distance is
    # zero, so each empty cluster is reseeded from the same series.
    x = np.zeros((6, 5, 3))
    return x, x[:3].copy()


@pytest.mark.parametrize("case", [singleton_stolen, identical_series])
def test_reseeding_does_not_empty_another_cluster(
    case: Callable[[], tuple[np.ndarray, np.ndarray]],
) -> None:
    x, init = case()
    result = kmeans_dtw(x, 3, np.random.default_rng(0), n_init=0, init=init)
    np.testing.assert_array_equal(np.unique(result.labels), [0, 1, 2])
    assert np.all(np.isfinite(result.centers))


# The paper's problem.


@pytest.mark.parametrize("seed", [0, 1])
def test_banded_kmeans_separates_the_paper_candidates_under_the_good_sequence(
    paper: Scenario, good_sequence: np.ndarray, seed: int
) -> None:
    x, y = simulate(paper, good_sequence, 20, np.random.default_rng(seed)).dataset()
    x = x / np.sqrt(np.mean(x**2))
    result = kmeans_dtw(x, paper.n_candidates, np.random.default_rng(seed), radius=2, n_init=10)
    assert match_clusters(y, result.labels, paper.n_candidates).f1 >= 0.99
