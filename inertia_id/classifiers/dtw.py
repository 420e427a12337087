"""Fast DTW k-means: band-constrained DTW, DBA barycentres and Lloyd iterations in numba.

The search scores thousands of candidate sequences, each by clustering ~100 rate series,
so the clustering must take milliseconds, not the ~1 s of tslearn's ``TimeSeriesKMeans``
(Python loops around its numba DTW). This module computes the same things:

- DTW with a squared-Euclidean local cost, optionally inside a Sakoe-Chiba band
  (``radius`` samples either side of the diagonal; ``None`` = unconstrained), returning
  the square root of the accumulated cost, as ``tslearn.metrics.dtw`` does;
- DBA barycentres (Petitjean et al. 2011) by the same majorise-minimise iteration as
  ``tslearn.barycenters.dtw_barycenter_averaging``;
- k-means with DTW k-means++ seeding, DBA centroid updates, and the lowest-inertia run
  kept over several initialisations;
- the normalised soft-DTW divergence (Cuturi and Blondel 2017, squared-Euclidean cost),
  ``sdtw(x, y) - (sdtw(x, x) + sdtw(y, y)) / 2``, as
  ``tslearn.metrics.cdist_soft_dtw_normalized`` computes it.

The cumulative cost is stored as a band (T x (2 radius + 1)) rather than T x T, so a
band-constrained distance costs O(T radius). ``radius=0`` is exactly the Euclidean
distance (and the DBA update the plain mean), which gives the fast Euclidean metric for
free. Series must all have the same length.

Every kernel is compiled with ``cache=True``, so a fresh process loads the machine code
numba wrote to disk instead of compiling again; :func:`warm_up` compiles (or loads) them
all on tiny inputs, for a service to call at start rather than inside a request.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..checks import is_integer
from ..errors import InputError

__all__ = [
    "KMeansResult",
    "cdist_dtw",
    "cdist_soft_dtw_normalized",
    "dba",
    "dtw",
    "kmeans_dtw",
    "warm_up",
]

_INF = np.inf


def _band(radius: int | None, length: int) -> int:
    if radius is None:
        return length - 1
    if not is_integer(radius, minimum=0):
        raise InputError(f"radius must be None or an integer >= 0, got {radius!r}")
    return int(min(radius, length - 1))


@njit(cache=True)
def _accumulate(a: np.ndarray, b: np.ndarray, r: int, acc: np.ndarray) -> float:
    """Fill the banded cumulative cost of aligning a to b; return the total (squared).

    ``acc[i + 1, j - i + r + 1]`` holds the cost of the best path to (i, j); row 0 and the
    first and last columns are padding (+inf, except the start cell), so the recurrence
    needs no bounds tests.
    """
    t = a.shape[0]
    d = a.shape[1]
    acc[:, :] = _INF
    acc[0, r + 1] = 0.0
    for i in range(t):
        lo = max(0, i - r)
        hi = min(t - 1, i + r)
        for j in range(lo, hi + 1):
            col = j - i + r + 1
            cost = 0.0
            for c in range(d):
                diff = a[i, c] - b[j, c]
                cost += diff * diff
            best = acc[i, col]  # (i-1, j-1)
            if acc[i, col + 1] < best:  # (i-1, j)
                best = acc[i, col + 1]
            if acc[i + 1, col - 1] < best:  # (i, j-1)
                best = acc[i + 1, col - 1]
            acc[i + 1, col] = cost + best
    return acc[t, r + 1]


@njit(cache=True)
def _cdist(x: np.ndarray, y: np.ndarray, r: int) -> np.ndarray:
    n = x.shape[0]
    m = y.shape[0]
    out = np.empty((n, m))
    acc = np.empty((x.shape[1] + 1, 2 * r + 3))
    for i in range(n):
        for j in range(m):
            out[i, j] = np.sqrt(_accumulate(x[i], y[j], r, acc))
    return out


@njit(cache=True)
def _soft_dtw(a: np.ndarray, b: np.ndarray, gamma: float, acc: np.ndarray) -> float:
    """Soft-DTW of a and b with a squared-Euclidean local cost (tslearn's recursion).

    ``acc[i + 1, j + 1]`` holds the soft-minimal cost of aligning a[:i+1] with b[:j+1];
    row and column 0 are the boundary, the largest float but at the start (tslearn's).
    """
    t = a.shape[0]
    u = b.shape[0]
    d = a.shape[1]
    big = np.finfo(np.float64).max
    acc[:, :] = big
    acc[0, 0] = 0.0
    for i in range(t):
        for j in range(u):
            cost = 0.0
            for c in range(d):
                diff = a[i, c] - b[j, c]
                cost += diff * diff
            # softmin(x, y, z) = -gamma log(exp(-x/gamma) + exp(-y/gamma) + exp(-z/gamma)),
            # shifted by the largest exponent so that nothing overflows.
            x = -acc[i, j + 1] / gamma
            y = -acc[i, j] / gamma
            z = -acc[i + 1, j] / gamma
            top = max(max(x, y), z)
            total = np.exp(x - top) + np.exp(y - top) + np.exp(z - top)
            acc[i + 1, j + 1] = cost - gamma * (np.log(total) + top)
    return float(acc[t, u])


@njit(cache=True)
def _cdist_soft_dtw_normalized(x: np.ndarray, y: np.ndarray, gamma: float) -> np.ndarray:
    n = x.shape[0]
    m = y.shape[0]
    # One buffer for every pair, self-pairs included: as large as the longer series.
    longest = max(x.shape[1], y.shape[1])
    acc = np.empty((longest + 1, longest + 1))
    self_x = np.empty(n)
    self_y = np.empty(m)
    for i in range(n):
        self_x[i] = _soft_dtw(x[i], x[i], gamma, acc)
    for j in range(m):
        self_y[j] = _soft_dtw(y[j], y[j], gamma, acc)
    out = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            out[i, j] = _soft_dtw(x[i], y[j], gamma, acc) - 0.5 * (self_x[i] + self_y[j])
    return out


@njit(cache=True)
def _dba_iterations(
    series: np.ndarray, barycenter: np.ndarray, r: int, max_iter: int, tol: float
) -> tuple[np.ndarray, float]:
    """DBA from ``barycenter``; stops when the mean squared DTW changes by < tol."""
    n, t, d = series.shape
    acc = np.empty((t + 1, 2 * r + 3))
    sums = np.empty((t, d))
    counts = np.empty(t)
    current = barycenter.copy()
    cost_prev = _INF
    for _ in range(max_iter):
        sums[:] = 0.0
        counts[:] = 0.0
        cost = 0.0
        for s in range(n):
            cost += _accumulate(current, series[s], r, acc)
            # Backtrack the optimal path, preferring the diagonal, then (i-1, j), then
            # (i, j-1) on ties (tslearn's order). Padding keeps the walk inside.
            i = t - 1
            j = t - 1
            while True:
                for c in range(d):
                    sums[i, c] += series[s, j, c]
                counts[i] += 1.0
                if i == 0 and j == 0:
                    break
                col = j - i + r + 1
                diag = acc[i, col]
                up = acc[i, col + 1]
                left = acc[i + 1, col - 1]
                if diag <= up and diag <= left:
                    i -= 1
                    j -= 1
                elif up <= left:
                    i -= 1
                else:
                    j -= 1
        cost /= n
        # The update is always applied, then convergence checked (tslearn's order).
        for i in range(t):
            for c in range(d):
                current[i, c] = sums[i, c] / counts[i]
        if abs(cost_prev - cost) < tol or cost > cost_prev:
            cost_prev = min(cost, cost_prev)
            break
        cost_prev = cost
    return current, cost_prev


@njit(cache=True)
def _lloyd(
    x: np.ndarray,
    centers: np.ndarray,
    r: int,
    max_iter: int,
    max_iter_barycenter: int,
    tol: float,
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Lloyd iterations with DBA updates; empty clusters take the worst-fitted series."""
    n = x.shape[0]
    k = centers.shape[0]
    centers = centers.copy()
    labels = np.zeros(n, dtype=np.int64)
    inertia = _INF
    old_inertia = _INF
    iterations = 0
    for it in range(max_iter):
        iterations = it + 1
        dist = _cdist(x, centers, r)
        own = np.empty(n)
        for s in range(n):
            best = 0
            for c in range(1, k):
                if dist[s, c] < dist[s, best]:
                    best = c
            labels[s] = best
            own[s] = dist[s, best]
        # Reseed an empty cluster with the series farthest from its centroid among
        # clusters that keep a member after giving it up (n >= k, so one always does).
        counts = np.zeros(k, dtype=np.int64)
        for s in range(n):
            counts[labels[s]] += 1
        reseeded = False
        for c in range(k):
            if counts[c] == 0:
                worst = -1
                worst_distance = -1.0
                for s in range(n):
                    if counts[labels[s]] > 1 and own[s] > worst_distance:
                        worst = s
                        worst_distance = own[s]
                counts[labels[worst]] -= 1
                labels[worst] = c
                counts[c] = 1
                own[worst] = 0.0
                centers[c] = x[worst]
                reseeded = True
        inertia = float(np.mean(own**2))
        if abs(old_inertia - inertia) < tol and not reseeded:
            break
        old_inertia = inertia
        for c in range(k):
            members = x[labels == c]
            centers[c], _ = _dba_iterations(members, centers[c], r, max_iter_barycenter, tol)
    return labels, centers, inertia, iterations


def dtw(a: np.ndarray, b: np.ndarray, radius: int | None = None) -> float:
    """DTW distance between two (T, d) series of equal length (``tslearn.metrics.dtw``)."""
    a = np.ascontiguousarray(a, dtype=float)
    b = np.ascontiguousarray(b, dtype=float)
    if a.shape != b.shape or a.ndim != 2:
        raise InputError(f"series must be (T, d) of equal shape, got {a.shape} and {b.shape}")
    return float(cdist_dtw(a[None], b[None], radius)[0, 0])


def cdist_dtw(x: np.ndarray, y: np.ndarray, radius: int | None = None) -> np.ndarray:
    """DTW distance of every series of x (n, T, d) to every series of y (m, T, d)."""
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    if x.ndim != 3 or y.ndim != 3 or x.shape[1:] != y.shape[1:]:
        raise InputError(f"series must be (n, T, d) of equal T and d, got {x.shape}, {y.shape}")
    return np.asarray(_cdist(x, y, _band(radius, x.shape[1])))


def cdist_soft_dtw_normalized(x: np.ndarray, y: np.ndarray, gamma: float) -> np.ndarray:
    """Normalised soft-DTW divergence of every series of x (n, T, d) to every series of y
    (m, T', d): ``sdtw(x, y) - (sdtw(x, x) + sdtw(y, y)) / 2``, >= 0 and 0 for identical
    series (``tslearn.metrics.cdist_soft_dtw_normalized``).

    :param gamma: the soft-min's smoothing, > 0.
    """
    x = np.ascontiguousarray(x, dtype=float)
    y = np.ascontiguousarray(y, dtype=float)
    if x.ndim != 3 or y.ndim != 3 or x.shape[2] != y.shape[2]:
        raise InputError(f"series must be (n, T, d) of equal d, got {x.shape}, {y.shape}")
    if not (np.isfinite(gamma) and gamma > 0):
        raise InputError(f"gamma must be a number > 0, got {gamma!r}")
    return np.asarray(_cdist_soft_dtw_normalized(x, y, float(gamma)))


def dba(
    x: np.ndarray,
    init: np.ndarray | None = None,
    radius: int | None = None,
    *,
    max_iter: int = 30,
    tol: float = 1e-5,
) -> np.ndarray:
    """DBA barycentre of x (n, T, d), starting from ``init`` (default: the plain mean)."""
    x = np.ascontiguousarray(x, dtype=float)
    if x.ndim != 3 or len(x) == 0:
        raise InputError(f"series must be (n, T, d) with n >= 1, got {x.shape}")
    start = x.mean(axis=0) if init is None else np.array(init, dtype=float)
    barycenter, _ = _dba_iterations(x, start, _band(radius, x.shape[1]), max_iter, tol)
    return np.asarray(barycenter)


@dataclass(frozen=True)
class KMeansResult:
    """A DTW k-means clustering.

    :param labels: cluster of each series (n,).
    :param centers: (k, T, d) DBA centroids.
    :param inertia: mean squared DTW distance of each series to its centroid.
    :param n_iter: Lloyd iterations of the kept run.
    """

    labels: np.ndarray
    centers: np.ndarray
    inertia: float
    n_iter: int


def _kmeans_plusplus(x: np.ndarray, k: int, r: int, rng: np.random.Generator) -> np.ndarray:
    n = len(x)
    chosen = [int(rng.integers(n))]
    closest = _cdist(x, x[chosen[-1]][None], r)[:, 0] ** 2
    for _ in range(1, k):
        total = closest.sum()
        if total <= 0:
            pick = int(rng.integers(n))
        else:
            pick = int(rng.choice(n, p=closest / total))
        chosen.append(pick)
        closest = np.minimum(closest, _cdist(x, x[pick][None], r)[:, 0] ** 2)
    return np.asarray(x[chosen].copy())


def kmeans_dtw(
    x: np.ndarray,
    n_clusters: int,
    rng: np.random.Generator,
    *,
    radius: int | None = None,
    n_init: int = 3,
    init: np.ndarray | None = None,
    max_iter: int = 50,
    max_iter_barycenter: int = 30,
    tol: float = 1e-6,
) -> KMeansResult:
    """DTW k-means of x (n, T, d); the lowest-inertia of the runs is returned.

    :param rng: seeds the k-means++ initialisations.
    :param radius: Sakoe-Chiba band half-width in samples; None = unconstrained DTW,
        0 = Euclidean k-means.
    :param n_init: k-means++ initialisations.
    :param init: optional (n_clusters, T, d) centroids to start one more run from (a warm
        start, e.g. the previous prefix's centroids extended).
    :param tol: stop when the inertia (mean squared distance) changes by less.
    """
    x = np.ascontiguousarray(x, dtype=float)
    if x.ndim != 3 or len(x) < n_clusters or n_clusters < 1:
        raise InputError(f"need (n, T, d) series with n >= {n_clusters}, got {x.shape}")
    r = _band(radius, x.shape[1])
    starts = [_kmeans_plusplus(x, n_clusters, r, rng) for _ in range(n_init)]
    if init is not None:
        init = np.ascontiguousarray(init, dtype=float)
        if init.shape != (n_clusters, *x.shape[1:]):
            raise InputError(f"init must be {(n_clusters, *x.shape[1:])}, got {init.shape}")
        starts.insert(0, init)
    if not starts:
        raise InputError("need n_init >= 1 or an init")
    best: KMeansResult | None = None
    for start in starts:
        labels, centers, inertia, n_iter = _lloyd(x, start, r, max_iter, max_iter_barycenter, tol)
        if best is None or inertia < best.inertia:
            best = KMeansResult(np.asarray(labels), np.asarray(centers), float(inertia), n_iter)
    assert best is not None
    return best


def warm_up() -> None:
    """Compile, or load from numba's cache, every kernel of this module on tiny inputs.

    The first call of a numba kernel in a process compiles it (seconds) or loads it from
    the on-disk cache; a service calls this at start so that no request pays for it.
    """
    rng = np.random.default_rng(0)
    x = rng.standard_normal((4, 6, 3))
    cdist_dtw(x, x, None)
    cdist_dtw(x, x, 1)
    cdist_soft_dtw_normalized(x, x[:2], 0.1)
    dba(x, radius=1, max_iter=2)
    kmeans_dtw(x, 2, rng, radius=1, n_init=1, max_iter=2, max_iter_barycenter=2)
