"""The paper's classifier: time-series k-means over the candidates' rate responses.

:class:`InertiaClassifier` follows scikit-learn conventions (``fit``, ``predict``,
``fit_predict``, ``transform``, ``score``; arrays shaped (n_series, length, 3)) and wraps
tslearn's ``TimeSeriesKMeans``. Clustering is unsupervised; the labels given to ``fit``
are used only afterwards, to match clusters to candidates (Hungarian assignment on the
cluster-by-candidate F1 table) and to score the result. New series are predicted to the
candidate whose matched centroid is nearest.

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

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist
from sklearn.base import BaseEstimator

with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # tslearn warns at import that h5py is missing
    from tslearn.clustering import TimeSeriesKMeans
    from tslearn.metrics import cdist_dtw, cdist_soft_dtw_normalized

from ..physics.scenario import Scenario
from ..physics.simulate import simulate
from .base import StoredClassifier

__all__ = [
    "METRICS",
    "InertiaClassifier",
    "MatchScores",
    "match_clusters",
    "train",
]

METRICS = ("dtw", "softdtw", "euclidean")
FORMAT = "inertia-id/classifier"


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
        raise ValueError(
            f"labels and clusters must be 1-d of equal length, got {y_true.shape} and "
            f"{clusters.shape}"
        )
    if y_true.size and (y_true.min() < 0 or y_true.max() >= n_candidates):
        raise ValueError(f"candidate labels must lie in 0..{n_candidates - 1}")
    if clusters.size and (clusters.min() < 0 or clusters.max() >= n_clusters):
        raise ValueError(f"cluster labels must lie in 0..{n_clusters - 1}")
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


def _as_dataset(X: Any) -> np.ndarray:
    arr = np.asarray(X, dtype=float)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"series must be shaped (n_series, length, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("series contain NaN or infinite values")
    return arr


class InertiaClassifier(StoredClassifier, BaseEstimator):
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

    FORMAT = FORMAT

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
        if self.metric not in METRICS:
            raise ValueError(f"metric must be one of {list(METRICS)}, got {self.metric!r}")
        if not isinstance(self.n_init, int) or self.n_init < 1:
            raise ValueError(f"n_init must be a positive integer, got {self.n_init!r}")
        if self.sakoe_chiba_radius is not None and (
            not isinstance(self.sakoe_chiba_radius, int) or self.sakoe_chiba_radius < 0
        ):
            raise ValueError(
                f"sakoe_chiba_radius must be None or an integer >= 0, got "
                f"{self.sakoe_chiba_radius!r}"
            )
        if self.gamma != "auto" and not (
            isinstance(self.gamma, int | float) and math.isfinite(self.gamma) and self.gamma > 0
        ):
            raise ValueError(f"gamma must be 'auto' or a number > 0, got {self.gamma!r}")
        if not (math.isfinite(self.novelty_factor) and self.novelty_factor >= 1.0):
            raise ValueError(f"novelty_factor must be >= 1, got {self.novelty_factor!r}")

    def _metric_params(self) -> dict[str, Any] | None:
        if self.metric == "dtw" and self.sakoe_chiba_radius is not None:
            return {
                "global_constraint": "sakoe_chiba",
                "sakoe_chiba_radius": self.sakoe_chiba_radius,
            }
        if self.metric == "softdtw":
            return {"gamma": self.gamma_}
        return None

    def fit(self, X: Any, y: Any, *, candidate_names: list[str] | None = None) -> InertiaClassifier:
        """Cluster the series into K = number of candidates, then match and score.

        :param X: (n_series, length, 3) rates, rad/s.
        :param y: true candidate index of each series (0..K-1; every candidate present).
        :param candidate_names: names of the K candidates, kept for reports.
        """
        self._check_params()
        X = _as_dataset(X)
        y = np.asarray(y, dtype=int)
        if y.shape != (X.shape[0],):
            raise ValueError(f"y must hold one label per series ({X.shape[0]}), got {y.shape}")
        n_candidates = int(y.max()) + 1 if y.size else 0
        missing = sorted(set(range(n_candidates)) - set(y.tolist()))
        if n_candidates < 2 or missing or y.min() < 0:
            raise ValueError(f"y must label every candidate 0..K-1 with K >= 2; missing {missing}")
        if candidate_names is not None and len(candidate_names) != n_candidates:
            raise ValueError(
                f"{len(candidate_names)} candidate names for {n_candidates} candidates"
            )
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
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            kmeans.fit(Xs)
        self.cluster_centers_ = np.asarray(kmeans.cluster_centers_) * self.scale_
        self.n_candidates_ = n_candidates
        self.candidate_names_ = list(
            candidate_names or [f"candidate {i}" for i in range(n_candidates)]
        )
        self.inertia_ = float(kmeans.inertia_)
        distances = self._cluster_distances(X)
        self.labels_ = distances.argmin(axis=1)
        scores = match_clusters(y, self.labels_, n_candidates)
        self.cluster_to_candidate_ = scores.cluster_to_candidate
        self.f1_ = scores.f1
        self.accuracy_ = scores.accuracy
        self.confusion_ = scores.confusion
        own = distances[np.arange(len(X)), self.labels_]
        self.max_training_distance_ = np.array(
            [
                own[self.labels_ == c].max() if np.any(self.labels_ == c) else np.inf
                for c in range(n_candidates)
            ]
        )
        return self

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
            return np.asarray(cdist_dtw(Xs, centers, **(self._metric_params() or {})))
        # Soft-DTW divergence: >= 0, zero for identical series, unlike raw soft-DTW.
        return np.asarray(cdist_soft_dtw_normalized(Xs, centers, gamma=self.gamma_))

    def _check_fitted(self) -> None:
        if not hasattr(self, "cluster_centers_"):
            raise ValueError("this classifier is not fitted yet; call fit first")

    def _check_length(self, X: np.ndarray) -> None:
        if X.shape[1] != self.cluster_centers_.shape[1]:
            raise ValueError(
                f"series have {X.shape[1]} samples; the classifier was trained on "
                f"{self.cluster_centers_.shape[1]}"
            )

    def transform(self, X: Any) -> np.ndarray:
        """Distance of each series to each candidate's centroid, (n_series, K).

        Distances are in units of the training RMS rate; candidates without a matched
        cluster get +inf.
        """
        self._check_fitted()
        X = _as_dataset(X)
        self._check_length(X)
        by_cluster = self._cluster_distances(X)
        out = np.full((len(X), self.n_candidates_), np.inf)
        matched = self.cluster_to_candidate_ >= 0
        out[:, self.cluster_to_candidate_[matched]] = by_cluster[:, matched]
        return out

    def predict(self, X: Any) -> np.ndarray:
        """Candidate index of each series: the nearest matched centroid."""
        return np.asarray(self.transform(X).argmin(axis=1))

    def fit_predict(self, X: Any, y: Any, **kwargs: Any) -> np.ndarray:
        self.fit(X, y, **kwargs)
        return np.asarray(self.cluster_to_candidate_[self.labels_])

    def novelty_thresholds(self) -> np.ndarray:
        """Per-candidate distance beyond which a series "matches none", (K,)."""
        self._check_fitted()
        out = np.full(self.n_candidates_, np.inf)
        matched = self.cluster_to_candidate_ >= 0
        out[self.cluster_to_candidate_[matched]] = (
            self.novelty_factor * self.max_training_distance_[matched]
        )
        return out

    # Storage as data.

    def to_dict(self) -> dict[str, Any]:
        self._check_fitted()
        params = self.get_params()
        params["init"] = None
        return {
            "params": params,
            "scale": self.scale_,
            "gamma": self.gamma_,
            "cluster_centers_rad_s": self.cluster_centers_.tolist(),
            "cluster_to_candidate": self.cluster_to_candidate_.tolist(),
            "candidate_names": self.candidate_names_,
            "max_training_distance": self.max_training_distance_.tolist(),
            "inertia": self.inertia_,
            "f1": self.f1_,
            "accuracy": self.accuracy_,
            "confusion": self.confusion_.tolist(),
            "scenario": None
            if getattr(self, "scenario_", None) is None
            else self.scenario_.model_dump(mode="json"),
            "sequence": None
            if getattr(self, "sequence_", None) is None
            else np.asarray(self.sequence_).tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> InertiaClassifier:
        try:
            model = cls(**data["params"])
            model._check_params()
            model.scale_ = float(data["scale"])
            model.gamma_ = float(data["gamma"])
            model.cluster_centers_ = _as_dataset(data["cluster_centers_rad_s"])
            model.cluster_to_candidate_ = np.asarray(data["cluster_to_candidate"], dtype=int)
            model.candidate_names_ = [str(n) for n in data["candidate_names"]]
            model.n_candidates_ = len(model.candidate_names_)
            model.max_training_distance_ = np.asarray(data["max_training_distance"], float)
            model.inertia_ = float(data["inertia"])
            model.f1_ = float(data["f1"])
            model.accuracy_ = float(data["accuracy"])
            model.confusion_ = np.asarray(data["confusion"], dtype=int)
            model.scenario_ = (
                None if data.get("scenario") is None else Scenario.model_validate(data["scenario"])
            )
            model.sequence_ = (
                None if data.get("sequence") is None else np.asarray(data["sequence"], dtype=int)
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"not a valid classifier document: {exc}") from None
        k = len(model.cluster_centers_)
        if model.cluster_to_candidate_.shape != (k,) or model.max_training_distance_.shape != (k,):
            raise ValueError(
                f"not a valid classifier document: {k} centroids but "
                f"{model.cluster_to_candidate_.shape} cluster matches"
            )
        return model


def train(
    scenario: Scenario,
    sequence: Any,
    n_realisations: int,
    rng: np.random.Generator,
    *,
    metric: str = "dtw",
    **classifier_params: Any,
) -> InertiaClassifier:
    """Simulate every candidate under ``sequence`` at 1x noise and fit a classifier.

    The k-means seed is drawn from ``rng``, so the same rng state gives the same model.
    The returned classifier remembers the scenario and sequence (needed by identify).
    """
    sequence = scenario.check_sequence(sequence)
    result = simulate(scenario, sequence, n_realisations, rng)
    X, y = result.dataset()
    classifier_params.setdefault("random_state", int(rng.integers(2**31 - 1)))
    model = InertiaClassifier(metric, **classifier_params)
    model.fit(X, y, candidate_names=scenario.candidate_names)
    model.scenario_ = scenario
    model.sequence_ = sequence
    return model
