"""Supervised classifiers of rate responses by distance: nearest centroid and 1-NN.

In simulation every training series' candidate is known, so a classifier may learn from
the labels instead of clustering blind and matching clusters to candidates afterwards
(:class:`~inertia_id.classifiers.clustering.InertiaClassifier`, the paper's method):

============================  =================================  ============================
class (``make_classifier``)   fit                                ``transform``: distance to
                                                                 each candidate
============================  =================================  ============================
NearestCentroidClassifier     one centroid per candidate: DBA    to the candidate's centroid,
(``"nearest-centroid"``)      barycentre (dtw) or mean           rad/s
                              (euclidean)
NearestNeighbourClassifier    keeps every training series        to the candidate's nearest
(``"1nn"``)                                                      training series, rad/s
============================  =================================  ============================

(MiniRocket, the third supervised kind, is :mod:`inertia_id.classifiers.minirocket`.)
Distances are DTW (:mod:`inertia_id.classifiers.dtw`: squared-Euclidean local cost,
optional Sakoe-Chiba band, square root of the total) or Euclidean, on the series in
rad/s, so a distance is a root-sum-square rate difference in rad/s.

"Matches none": a series farther from its predicted candidate than ``novelty_factor``
times the largest distance a training series of that candidate had to it. For 1-NN the
training distances are leave-one-out (a training series is its own nearest neighbour, so
its plain training distance says nothing about fresh series); for the nearest centroid
they are the distances to the centroid.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from scipy.spatial.distance import cdist

from ..errors import InputError
from ..physics.series import check_series
from .base import SupervisedClassifier, check_int, check_training_labels
from .dtw import cdist_dtw, dba

__all__ = ["NearestCentroidClassifier", "NearestNeighbourClassifier"]

#: The metrics of the distance-based supervised kinds: DTW first.
METRICS = ("dtw", "euclidean")


class _DistanceClassifier(SupervisedClassifier):
    METRICS = METRICS
    sakoe_chiba_radius: int | None

    def _check_params(self) -> None:
        super()._check_params()
        if self.sakoe_chiba_radius is not None:
            check_int("sakoe_chiba_radius", self.sakoe_chiba_radius, minimum=0)

    def _distances(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """Distance of every series of X to every series of Y, rad/s."""
        if self.metric == "euclidean":
            return np.asarray(cdist(X.reshape(len(X), -1), Y.reshape(len(Y), -1)))
        radius = None if self.sakoe_chiba_radius is None else int(self.sakoe_chiba_radius)
        return cdist_dtw(X, Y, radius)


class NearestCentroidClassifier(_DistanceClassifier):
    """Nearest candidate centroid: one template response per candidate, from the labels.

    What the clustering finds when it works, without the risk of a poor k-means optimum
    or a cluster split between candidates.

    :param metric: "dtw" (centroids are DBA barycentres, so a time shift between
        realisations does not smear the template) or "euclidean" (centroids are means).
    :param sakoe_chiba_radius: DTW band half-width in samples; None = unconstrained.
        Thruster delays shift responses by a few samples at most, so a band is physically
        justified and faster.
    :param max_iter_barycenter: DBA iterations per centroid.
    :param novelty_factor: see
        :meth:`~inertia_id.classifiers.base.BaseClassifier.novelty_thresholds`.
    """

    kind: ClassVar[str] = "nearest-centroid"
    LISTING_ORDER = 20
    LABEL = "nearest centroid (supervised)"

    def __init__(
        self,
        metric: str = "dtw",
        *,
        sakoe_chiba_radius: int | None = None,
        max_iter_barycenter: int = 30,
        novelty_factor: float = 1.5,
    ) -> None:
        self.metric = metric
        self.sakoe_chiba_radius = sakoe_chiba_radius
        self.max_iter_barycenter = max_iter_barycenter
        self.novelty_factor = novelty_factor

    def _check_params(self) -> None:
        super()._check_params()
        check_int("max_iter_barycenter", self.max_iter_barycenter)

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        centroids = np.empty((int(y.max()) + 1, *X.shape[1:]))
        # DBA's stopping tolerance is absolute, so it runs on unit-RMS series.
        rms = float(np.sqrt(np.mean(X**2)))
        scale = rms if rms > 0 else 1.0
        radius = None if self.sakoe_chiba_radius is None else int(self.sakoe_chiba_radius)
        for k in range(len(centroids)):
            # A DTW barycentre a candidate: each one a piece a training may stop after.
            self._checkpoint()
            members = X[y == k]
            if self.metric == "euclidean":
                centroids[k] = members.mean(axis=0)
            else:
                centroids[k] = (
                    dba(members / scale, radius=radius, max_iter=int(self.max_iter_barycenter))
                    * scale
                )
        self.centroids_ = centroids
        return self._candidate_distances(X)

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        return self._distances(X, self.centroids_)

    def _model_state(self) -> dict[str, Any]:
        return {"centroids_rad_s": self.centroids_.tolist()}

    def _load_model_state(self, state: dict[str, Any]) -> None:
        centroids = check_series(state["centroids_rad_s"])
        if centroids.shape[:2] != (self.n_candidates_, self.length_):
            raise InputError(
                f"{centroids.shape[0]} centroids of {centroids.shape[1]} samples for "
                f"{self.n_candidates_} candidates of {self.length_}"
            )
        self.centroids_ = centroids


class NearestNeighbourClassifier(_DistanceClassifier):
    """1-nearest neighbour over the training series.

    Makes no assumption about the shape of a candidate's spread of responses (a
    centroid assumes it is compact), at the cost of keeping every training series and
    comparing a new series with each.

    :param metric: "dtw" or "euclidean".
    :param sakoe_chiba_radius: DTW band half-width in samples; None = unconstrained.
    :param novelty_factor: see
        :meth:`~inertia_id.classifiers.base.BaseClassifier.novelty_thresholds`; the
        training distances are each series' distance to its nearest *other* training
        series of its own candidate.
    """

    kind: ClassVar[str] = "1nn"
    LISTING_ORDER = 30
    LABEL = "1-nearest neighbour (supervised)"

    def __init__(
        self,
        metric: str = "dtw",
        *,
        sakoe_chiba_radius: int | None = None,
        novelty_factor: float = 1.5,
    ) -> None:
        self.metric = metric
        self.sakoe_chiba_radius = sakoe_chiba_radius
        self.novelty_factor = novelty_factor

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        self.training_series_ = X.copy()
        self.training_labels_ = y.copy()
        distances = self._distances(X, X)
        np.fill_diagonal(distances, np.inf)  # leave one out
        return self._nearest_per_candidate(distances)

    def _nearest_per_candidate(self, distances: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                distances[:, self.training_labels_ == k].min(axis=1)
                for k in range(self.n_candidates_)
            ],
            axis=1,
        )

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        return self._nearest_per_candidate(self._distances(X, self.training_series_))

    @classmethod
    def stored_numbers(cls, n_candidates: int, values: int, n_realisations: int) -> int:
        """Every training series and its label."""
        return n_candidates * n_realisations * (values + 1)

    def _model_state(self) -> dict[str, Any]:
        return {
            "training_series_rad_s": self.training_series_.tolist(),
            "training_labels": self.training_labels_.tolist(),
        }

    def _load_model_state(self, state: dict[str, Any]) -> None:
        series = check_series(state["training_series_rad_s"])
        labels = check_training_labels(state["training_labels"], len(series), self.MIN_REALISATIONS)
        if series.shape[1] != self.length_ or int(labels.max()) + 1 != self.n_candidates_:
            raise InputError(
                f"training series of {series.shape[1]} samples and {int(labels.max()) + 1} "
                f"candidates for {self.n_candidates_} candidates of {self.length_}"
            )
        self.training_series_ = series
        self.training_labels_ = labels
