"""Gaussian noise models shared by the likelihood and marginal-likelihood classifiers.

Both treat a flattened response (``3 length`` numbers) as Gaussian around its candidate's
mean, with a covariance pooled over the candidates and shrunk towards a multiple of the
identity. What they share: stratified folds, per-candidate means and the pooled sample
covariance, shrinkage, the cross-validated shrinkage intensity, the Cholesky factor and
Mahalanobis distances.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from scipy.linalg import cholesky as scipy_cholesky
from scipy.linalg import solve_triangular
from scipy.linalg.lapack import dtrtri
from threadpoolctl import ThreadpoolController

from ..errors import InputError
from ..stopping import Checkpoint, no_checkpoint

__all__ = [
    "CV_INTENSITIES",
    "MAX_FOLDS",
    "cholesky",
    "cv_intensity",
    "inverse_cholesky",
    "log_softmax",
    "logsumexp",
    "means_and_scatter",
    "one_blas_thread",
    "shrink",
    "stratified_folds",
    "whitened_distances",
]

#: Shrinkage intensities tried by the cross-validated rule: a grid is enough, since the
#: held-out likelihood is flat near its optimum. Small values only win with many more
#: training series than dimensions.
CV_INTENSITIES = np.array([0.001, 0.003, 0.01, 0.02, *np.linspace(0.05, 0.95, 19), 0.98, 1.0])
#: At most this many folds: out-of-fold distances and the cross-validation.
MAX_FOLDS = 5


def logsumexp(a: np.ndarray, axis: int | tuple[int, ...]) -> np.ndarray:
    """log Σ exp(a) over ``axis``, stable; -inf where every term is -inf.

    scipy.special.logsumexp gives the same numbers, but its array-API dispatch costs
    about 0.25 ms a call on the small arrays of one verdict, which calls it seven times:
    a third of a request's computation.
    """
    a = np.asarray(a, dtype=float)
    peak = np.max(a, axis=axis, keepdims=True)
    peak = np.where(np.isfinite(peak), peak, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - peak), axis=axis, keepdims=True)) + peak
    return np.squeeze(out, axis=axis)


def log_softmax(a: np.ndarray, axis: int) -> np.ndarray:
    """a - logsumexp(a) along ``axis`` (scipy's, without its dispatch cost)."""
    a = np.asarray(a, dtype=float)
    return a - np.expand_dims(logsumexp(a, axis=axis), axis)


def stratified_folds(y: np.ndarray, n_folds: int) -> np.ndarray:
    """Fold of each series: within each candidate, series are dealt round-robin.

    Deterministic (no random state): simulated realisations are exchangeable already.
    """
    folds = np.empty(len(y), dtype=int)
    for k in np.unique(y):
        members = np.flatnonzero(y == k)
        folds[members] = np.arange(len(members)) % n_folds
    return folds


def means_and_scatter(
    F: np.ndarray, y: np.ndarray, n_candidates: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-candidate mean responses, pooled residuals and the pooled sample covariance.

    The covariance divides by ``n - K``: K means were estimated from the same series.
    """
    means = np.stack([F[y == k].mean(axis=0) for k in range(n_candidates)])
    residuals = F - means[y]
    dof = max(len(F) - n_candidates, 1)
    return means, residuals, residuals.T @ residuals / dof


def shrink(sample: np.ndarray, intensity: float) -> np.ndarray:
    """(1 - α) S + α (tr S / p) I: towards the isotropic matrix of the same total variance."""
    p = len(sample)
    target = float(np.trace(sample)) / p
    shrunk = (1.0 - intensity) * sample
    shrunk[np.diag_indices(p)] += intensity * target
    return shrunk


def whitened_distances(F: np.ndarray, means: np.ndarray, chol_lower: np.ndarray) -> np.ndarray:
    """Mahalanobis distance of each flattened series to each mean, (n, K)."""
    n, p = F.shape
    k = len(means)
    diffs = (F[:, None, :] - means[None, :, :]).reshape(n * k, p)
    white = solve_triangular(chol_lower, diffs.T, lower=True, check_finite=False)
    return np.sqrt(np.sum(white**2, axis=0)).reshape(n, k)


def shrink_towards(sample: np.ndarray, target: np.ndarray, intensity: float) -> np.ndarray:
    """(1 - α) S + α T: towards a covariance ``target`` known from a model."""
    return np.asarray((1.0 - intensity) * sample + intensity * target)


def cv_intensity(
    F: np.ndarray,
    y: np.ndarray,
    n_candidates: int,
    folds: np.ndarray,
    target: np.ndarray | None = None,
    checkpoint: Checkpoint = no_checkpoint,
) -> float:
    """The grid intensity of highest held-out Gaussian log-likelihood.

    Shrinking towards a multiple of the identity keeps the eigenvectors, so one
    eigendecomposition per fold serves every intensity of the grid.

    :param target: shrink towards this covariance (:func:`shrink_towards`) instead. In the
        basis that whitens it (T = C Cᵀ), (1 - α) S + α T is C ((1 - α) S' + α I) Cᵀ with
        S' = C⁻¹ S C⁻ᵀ, so again one eigendecomposition per fold serves every intensity,
        and log det T is added to each.
    :param checkpoint: called before each fold's eigendecomposition (a training's,
        :mod:`inertia_id.stopping`: about a second each at 480 dimensions).
    """
    factor = None if target is None else cholesky(target)
    target_log_det = 0.0 if factor is None else 2.0 * float(np.sum(np.log(np.diag(factor))))
    loglik = np.zeros(len(CV_INTENSITIES))
    for fold in np.unique(folds):
        checkpoint()
        train, test = folds != fold, folds == fold
        means, _, sample = means_and_scatter(F[train], y[train], n_candidates)
        residuals = (F[test] - means[y[test]]).T  # (p, n_test)
        if factor is not None:
            half = solve_triangular(factor, sample, lower=True, check_finite=False)
            sample = solve_triangular(factor, half.T, lower=True, check_finite=False)
            sample = 0.5 * (sample + sample.T)
            residuals = solve_triangular(factor, residuals, lower=True, check_finite=False)
        eigenvalues, eigenvectors = np.linalg.eigh(sample)
        eigenvalues = np.maximum(eigenvalues, 0.0)  # rounding makes null ones negative
        isotropic = 1.0 if factor is not None else float(np.mean(eigenvalues))
        projected = (eigenvectors.T @ residuals) ** 2  # (p, n_test)
        for i, intensity in enumerate(CV_INTENSITIES):
            shrunk = (1.0 - intensity) * eigenvalues + intensity * isotropic
            if shrunk.min() <= 0.0:
                loglik[i] = -np.inf  # singular: never the optimum
                continue
            mahalanobis = float(np.sum(projected / shrunk[:, None]))
            log_det = float(np.sum(np.log(shrunk))) + target_log_det
            loglik[i] += -0.5 * mahalanobis - 0.5 * int(test.sum()) * log_det
    return float(CV_INTENSITIES[int(np.argmax(loglik))])


def cholesky(covariance: np.ndarray) -> np.ndarray:
    """The lower Cholesky factor of a noise covariance; a singular one is the data's fault."""
    try:
        return np.asarray(scipy_cholesky(covariance, lower=True, check_finite=False))
    except np.linalg.LinAlgError:
        raise InputError(
            "the shrunk noise covariance is not positive definite; the training series "
            "do not vary (all noise off?) or the shrinkage is 0 with fewer series than "
            "dimensions"
        ) from None


def inverse_cholesky(chol_lower: np.ndarray) -> np.ndarray:
    """The inverse of a lower Cholesky factor (lower triangular, the whitening matrix).

    LAPACK's triangular inverse (``dtrtri``, n³/3 flops) rather than solving against the
    identity (``solve_triangular(L, I)``, n³): the same matrix to rounding, at a third of
    the work; loading a marginal-likelihood classifier forms 40 of them.
    """
    inverse, info = dtrtri(chol_lower, lower=1)
    if info != 0:
        # A Cholesky factor has a positive diagonal; a zero pivot means it underflowed.
        raise InputError(
            f"the noise covariance's Cholesky factor is singular (pivot {info} is zero)"
        )
    return np.asarray(inverse)


@functools.cache
def _threadpools() -> ThreadpoolController:
    return ThreadpoolController()


def one_blas_thread() -> Any:
    """Run BLAS and LAPACK on one thread (a context manager): for the factorisations of a
    covariance per noise condition, and for the search's separability scores (N ≈ 100,
    where threads save nothing: one score took 130 ms with them against 0.6 ms without on
    a loaded 2-core machine).

    OpenBLAS's threaded Cholesky waits for its threads at every block, and on a busy
    2-core machine they wait for cores: factoring one 960 x 960 covariance (a 16-step
    sequence) took 2.2 s wall with them against 0.09 s without, and loading a 16-step
    classifier (40 of them) 98 s. (threadpoolctl comes with scikit-learn.)
    """
    return _threadpools().limit(limits=1, user_api="blas")
