"""The paper's classifier: time-series k-means over the candidates' rate responses.

:class:`InertiaClassifier` follows scikit-learn conventions (``fit``, ``predict``,
``fit_predict``, ``transform``, ``score``; arrays shaped (n_series, length, 3)) and wraps
tslearn's ``TimeSeriesKMeans`` to fit; distances to the centroids are this package's own
numba DTW and soft-DTW (:mod:`inertia_id.classifiers.dtw`), equal to tslearn's to
rounding, so classifying new series needs no tslearn. Clustering is unsupervised; the
labels given to ``fit`` are used only afterwards, to match clusters to candidates
(Hungarian assignment on the cluster-by-candidate F1 table) and to score the result. New
series are predicted to the candidate whose matched centroid is nearest.

Two traps of tslearn's defaults are avoided here:

- one k-means initialisation often ends in a poor local optimum, so ``n_init`` runs are
  made and the one with the lowest inertia kept;
- soft-DTW's ``gamma = 1`` is meaningless for rates of 1e-3 rad/s, so series are scaled
  to unit RMS and gamma is set from the data (the per-sample noise energy), and the
  best initialisation is chosen by DTW inertia (soft-DTW values are negative, which
  makes tslearn's squared soft-DTW inertia pick the wrong run).

A fitted classifier is stored as JSON with a SHA-256 checksum (:meth:`to_json`,
:meth:`save`, :meth:`load`); nothing is pickled.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from ..errors import InputError
from ..physics.series import check_series
from .base import BaseClassifier, check_int, is_number
from .dtw import cdist_dtw, cdist_soft_dtw_normalized

__all__ = ["METRICS", "InertiaClassifier", "MatchScores", "match_clusters"]

#: The clustering's metrics: the paper's DTW first.
METRICS = ("dtw", "softdtw", "euclidean")


@dataclass(frozen=True)
class MatchScores:
    """How well clusters agree with the true candidates under the best matching.

    :param cluster_to_candidate: candidate index of each cluster (-1: unmatched).
    :param f1: macro F1 over candidates.
    :param accuracy: fraction of series whose cluster maps to their true candidate.
    :param confusion: (K, K) counts, row = true candidate, column = predicted.
    """

    cluster_to_candidate: np.ndarray
    f1: float
    accuracy: float
    confusion: np.ndarray


def match_clusters(
    y_true: Any, clusters: Any, n_candidates: int, n_clusters: int | None = None
) -> MatchScores:
    """Match clusters to candidates so that the macro F1 is as high as possible.

    The F1 of the pair (cluster c, candidate j) is ``2 n_cj / (|c| + |j|)``; macro F1 is
    the mean over candidates of the F1 of their matched cluster, so it is a sum over the
    matched pairs and the Hungarian algorithm on that table finds the best matching in
    polynomial time (no loop over permutations; 10+ candidates are fine).

    :param y_true: true candidate index of each series.
    :param clusters: cluster index of each series.
    :param n_candidates: K, the number of candidates.
    :param n_clusters: number of clusters (default: K).
    """
    y_true = np.asarray(y_true, dtype=int)
    clusters = np.asarray(clusters, dtype=int)
    n_clusters = n_candidates if n_clusters is None else n_clusters
    if y_true.shape != clusters.shape or y_true.ndim != 1:
        raise InputError(
            f"labels and clusters must be 1-d of equal length, got {y_true.shape} and "
            f"{clusters.shape}"
        )
    if y_true.size and (y_true.min() < 0 or y_true.max() >= n_candidates):
        raise InputError(f"candidate labels must lie in 0..{n_candidates - 1}")
    if clusters.size and (clusters.min() < 0 or clusters.max() >= n_clusters):
        raise InputError(f"cluster labels must lie in 0..{n_clusters - 1}")
    contingency = np.zeros((n_clusters, n_candidates))
    np.add.at(contingency, (clusters, y_true), 1.0)
    sizes = contingency.sum(axis=1)[:, None] + contingency.sum(axis=0)[None, :]
    pair_f1 = np.divide(2.0 * contingency, sizes, out=np.zeros_like(contingency), where=sizes > 0)
    rows, cols = linear_sum_assignment(pair_f1, maximize=True)
    mapping = np.full(n_clusters, -1, dtype=int)
    mapping[rows] = cols
    predicted = mapping[clusters]
    confusion = np.zeros((n_candidates, n_candidates), dtype=int)
    hit = predicted >= 0
    np.add.at(confusion, (y_true[hit], predicted[hit]), 1)
    present = contingency.sum(axis=0) > 0
    f1_per_candidate = np.zeros(n_candidates)
    f1_per_candidate[cols] = pair_f1[rows, cols]
    f1 = float(f1_per_candidate[present].mean()) if present.any() else 0.0
    accuracy = float(np.mean(predicted == y_true)) if y_true.size else 0.0
    return MatchScores(mapping, f1, accuracy, confusion)


class InertiaClassifier(BaseClassifier):
    """Time-series k-means classifier of rate responses (the paper's TSC).

    :param metric: "dtw" (the paper's), "softdtw" or "euclidean".
    :param n_init: k-means runs from different seeds; the lowest-inertia run is kept.
    :param max_iter: k-means iterations per run.
    :param max_iter_barycenter: DBA / soft-DTW barycenter iterations.
    :param sakoe_chiba_radius: DTW band half-width in samples; None = unconstrained
        DTW. Thruster delays shift responses by at most a few samples, so a band is
        physically justified and much faster.
    :param gamma: soft-DTW smoothing on unit-RMS series; "auto" sets it to the
        per-sample noise energy estimated from the training series.
    :param novelty_factor: a series farther from its nearest centroid than this multiple
        of the largest training distance to that centroid "matches none".
    :param init: optional (K, length, 3) initial centroids in rad/s (warm start).
    :param random_state: seed of the k-means initialisations.
    """

    kind: ClassVar[str] = "clustering"
    FORMAT = "inertia-id/classifier"
    METRICS = METRICS
    SUPERVISED = False
    LISTING_ORDER = 10
    LABEL = "clustering (the paper's time-series k-means)"

    def __init__(
        self,
        metric: str = "dtw",
        *,
        n_init: int = 5,
        max_iter: int = 50,
        max_iter_barycenter: int = 30,
        sakoe_chiba_radius: int | None = None,
        gamma: float | str = "auto",
        novelty_factor: float = 1.5,
        init: Any = None,
        random_state: int | None = None,
    ) -> None:
        self.metric = metric
        self.n_init = n_init
        self.max_iter = max_iter
        self.max_iter_barycenter = max_iter_barycenter
        self.sakoe_chiba_radius = sakoe_chiba_radius
        self.gamma = gamma
        self.novelty_factor = novelty_factor
        self.init = init
        self.random_state = random_state

    # Fitting.

    def _check_params(self) -> None:
        super()._check_params()
        check_int("n_init", self.n_init)
        if self.sakoe_chiba_radius is not None:
            check_int("sakoe_chiba_radius", self.sakoe_chiba_radius, minimum=0)
        if self.gamma != "auto" and not is_number(self.gamma, minimum=0, exclusive=True):
            raise InputError(f"gamma must be 'auto' or a number > 0, got {self.gamma!r}")

    def _metric_params(self) -> dict[str, Any] | None:
        if self.metric == "dtw" and self.sakoe_chiba_radius is not None:
            return {
                "global_constraint": "sakoe_chiba",
                "sakoe_chiba_radius": self.sakoe_chiba_radius,
            }
        if self.metric == "softdtw":
            return {"gamma": self.gamma_}
        return None

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Cluster the series into K = number of candidates, then match clusters to
        candidates; the training distances are each series' distance to each candidate's
        centroid."""
        # tslearn fits; it is imported here so that classifying (transform) never needs it.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # tslearn warns at import that h5py is missing
            from tslearn.clustering import TimeSeriesKMeans

        n_candidates = self.n_candidates_
        rms = float(np.sqrt(np.mean(X**2)))
        self.scale_ = rms if rms > 0 else 1.0
        Xs = X / self.scale_
        self.gamma_ = self._auto_gamma(Xs) if self.gamma == "auto" else float(self.gamma)
        init = "k-means++" if self.init is None else np.asarray(self.init, float) / self.scale_
        kmeans = TimeSeriesKMeans(
            n_clusters=n_candidates,
            metric=self.metric,
            n_init=self.n_init if self.init is None else 1,
            max_iter=self.max_iter,
            max_iter_barycenter=self.max_iter_barycenter,
            metric_params=self._metric_params(),
            dtw_inertia=self.metric == "softdtw",
            init=init,
            random_state=self.random_state,
        )
        # tslearn's k-means (all its initialisations and iterations) is one call with no
        # callback: a training can stop before it and after it, not inside it.
        self._checkpoint()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kmeans.fit(Xs)
        self._checkpoint()
        self.cluster_centers_ = np.asarray(kmeans.cluster_centers_) * self.scale_
        self.inertia_ = float(kmeans.inertia_)
        by_cluster = self._cluster_distances(X)
        self.labels_ = by_cluster.argmin(axis=1)
        matched = match_clusters(y, self.labels_, n_candidates)
        self.cluster_to_candidate_ = matched.cluster_to_candidate
        return self._by_candidate(by_cluster)

    @staticmethod
    def _auto_gamma(Xs: np.ndarray) -> float:
        # Half the energy of sample-to-sample differences estimates the gyro noise energy
        # per sample, plus the rate's own change per sample; under a steep ramp (the
        # paper preset at full duty) that change doubles the estimate, which only smooths
        # soft-DTW a little more. Alignments whose costs differ by less than the noise
        # energy are indistinguishable, so that is the scale gamma should have.
        diffs = np.diff(Xs, axis=1)
        energy = 0.5 * float(np.median(np.sum(diffs**2, axis=2).mean(axis=1)))
        return max(energy, 1e-6)

    # Prediction.

    def _cluster_distances(self, X: np.ndarray) -> np.ndarray:
        Xs = X / self.scale_
        centers = self.cluster_centers_ / self.scale_
        if self.metric == "euclidean":
            return np.asarray(cdist(Xs.reshape(len(Xs), -1), centers.reshape(len(centers), -1)))
        if self.metric == "dtw":
            return cdist_dtw(Xs, centers, self.sakoe_chiba_radius)
        # Soft-DTW divergence: >= 0, zero for identical series, unlike raw soft-DTW.
        return cdist_soft_dtw_normalized(Xs, centers, self.gamma_)

    def _by_candidate(self, by_cluster: np.ndarray) -> np.ndarray:
        """Cluster distances as candidate distances; a candidate without a cluster: +inf."""
        out = np.full((len(by_cluster), self.n_candidates_), np.inf)
        matched = self.cluster_to_candidate_ >= 0
        out[:, self.cluster_to_candidate_[matched]] = by_cluster[:, matched]
        return out

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        """Distance of each series to each candidate's centroid, (n_series, K), in units of
        the training RMS rate; candidates without a matched cluster get +inf."""
        return self._by_candidate(self._cluster_distances(X))

    # Storage as data: documents keep the thresholds per cluster, as they always have.

    def _document_params(self) -> dict[str, Any]:
        # The warm-start centroids are training input, not a setting of the model.
        return {**super()._document_params(), "init": None}

    def _state(self) -> dict[str, Any]:
        return {
            "scale": self.scale_,
            "gamma": self.gamma_,
            "cluster_centers_rad_s": self.cluster_centers_.tolist(),
            "cluster_to_candidate": self.cluster_to_candidate_.tolist(),
            "max_training_distance": self._per_cluster(self.max_training_distance_).tolist(),
            "inertia": self.inertia_,
        }

    def _per_cluster(self, per_candidate: np.ndarray) -> np.ndarray:
        matched = self.cluster_to_candidate_ >= 0
        out = np.full(len(self.cluster_to_candidate_), np.inf)
        out[matched] = per_candidate[self.cluster_to_candidate_[matched]]
        return out

    def _load_state(self, data: dict[str, Any]) -> None:
        self.scale_ = float(data["scale"])
        self.gamma_ = float(data["gamma"])
        self.cluster_centers_ = check_series(data["cluster_centers_rad_s"])
        self.cluster_to_candidate_ = np.asarray(data["cluster_to_candidate"], dtype=int)
        self.inertia_ = float(data["inertia"])
        k = len(self.cluster_centers_)
        per_cluster = self.max_training_distance_
        if self.cluster_to_candidate_.shape != (k,) or per_cluster.shape != (k,):
            raise InputError(
                f"{k} centroids but {self.cluster_to_candidate_.shape} cluster matches and "
                f"{per_cluster.shape} thresholds"
            )
        matched = self.cluster_to_candidate_ >= 0
        if np.any(self.cluster_to_candidate_ >= self.n_candidates_):
            raise InputError(
                f"cluster matches {self.cluster_to_candidate_.tolist()} name candidates "
                f"beyond the {self.n_candidates_} named"
            )
        per_candidate = np.full(self.n_candidates_, np.inf)
        per_candidate[self.cluster_to_candidate_[matched]] = per_cluster[matched]
        self.max_training_distance_ = per_candidate
        self.length_ = int(self.cluster_centers_.shape[1])
