"""Supervised classifiers of rate responses, beside the paper's clustering.

In simulation every training series' candidate is known, so a classifier may learn from
the labels instead of clustering blind and matching clusters to candidates afterwards
(:class:`~inertia_id.classify.InertiaClassifier`, the paper's method). Three are offered:

============================  =================================  ============================
class (``make_classifier``)   fit                                ``transform``: distance to
                                                                 each candidate
============================  =================================  ============================
NearestCentroidClassifier     one centroid per candidate: DBA    to the candidate's centroid,
(``"nearest-centroid"``)      barycentre (dtw) or mean           rad/s
                              (euclidean)
NearestNeighbourClassifier    keeps every training series        to the candidate's nearest
(``"1nn"``)                                                      training series, rad/s
MiniRocketClassifier          MiniRocket features + ridge        from the ridge's decision
(``"minirocket"``)            classifier (``RidgeClassifierCV``)  vector to the candidate's
                                                                 target code (dimensionless)
============================  =================================  ============================

Distances are DTW (:mod:`inertia_id.dtw`: squared-Euclidean local cost, optional
Sakoe-Chiba band, square root of the total) or Euclidean, on the series in rad/s, so a
distance is a root-sum-square rate difference in rad/s.

All share :class:`~inertia_id.classify.InertiaClassifier`'s interface: ``fit(X, y,
candidate_names=...)`` on X (n_series, length, 3) in rad/s and labels 0..K-1, then
``predict``, ``transform``, ``evaluate`` (same keys), ``score`` (macro F1),
``novelty_thresholds``, the training figures ``f1_``, ``accuracy_``, ``confusion_``,
``scenario_`` and ``sequence_`` (set by :func:`train_classifier`, needed by
:func:`~inertia_id.identify.identify`), and checksummed JSON storage (never pickle).

"Matches none" (:meth:`SupervisedClassifier.novelty_thresholds`): a series farther from
its predicted candidate than ``novelty_factor`` times the largest distance a training
series of that candidate had to it. For 1-NN and MiniRocket the training distances are
leave-one-out (a training series is its own nearest neighbour, and ridge nearly
interpolates its training set, so their plain training distances say nothing about fresh
series); for the nearest centroid they are the distances to the centroid, as for
InertiaClassifier.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from scipy.spatial.distance import cdist
from sklearn.base import BaseEstimator
from sklearn.linear_model import RidgeClassifierCV

from ..physics.scenario import Scenario
from .base import StoredClassifier, confusion_scores
from .dtw import cdist_dtw, dba
from .minirocket import MiniRocketParameters, fit_minirocket, minirocket_transform

__all__ = [
    "SUPERVISED_CLASSES",
    "SUPERVISED_METRICS",
    "MiniRocketClassifier",
    "NearestCentroidClassifier",
    "NearestNeighbourClassifier",
    "SupervisedClassifier",
]

SUPERVISED_METRICS = ("dtw", "euclidean")
FORMAT = "inertia-id/supervised-classifier"
# The paper's (and the reference code's) ridge penalties.
DEFAULT_ALPHAS = tuple(float(a) for a in np.logspace(-3, 3, 10))


def _check_series(X: Any) -> np.ndarray:
    """X as a float (n_series, length, 3) array of finite rates, or a ValueError."""
    try:
        arr = np.asarray(X, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"series must be numeric rates in rad/s: {exc}") from None
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[2] != 3 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ValueError(f"series must be shaped (n_series, length, 3) in rad/s, got {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        i, t, c = (int(v) for v in bad[0])
        raise ValueError(
            f"series[{i}, {t}, {c}] = {float(arr[i, t, c])!r} is not finite "
            f"({len(bad)} non-finite values in all)"
        )
    return arr


def _check_labels(y: Any, n_series: int) -> np.ndarray:
    arr = np.asarray(y)
    if arr.shape != (n_series,):
        raise ValueError(f"y must hold one label per series ({n_series}), got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ValueError(
                f"y must hold integer candidate indices, got {arr[:10].tolist()} "
                f"(dtype {arr.dtype})"
            )
    labels = arr.astype(int)
    if labels.min() < 0:
        raise ValueError(f"candidate indices must be >= 0, got {int(labels.min())}")
    counts = np.bincount(labels)
    if len(counts) < 2 or np.any(counts < 2):
        raise ValueError(
            "y must label every candidate 0..K-1 (K >= 2) with at least 2 series each; "
            f"series per candidate: {counts.tolist()}"
        )
    return labels


def _check_positive_int(name: str, value: Any, minimum: int = 1) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


class SupervisedClassifier(StoredClassifier, BaseEstimator):
    """What the supervised classifiers share: validation, scoring, novelty and storage.

    A subclass sets :attr:`kind`, and implements ``_fit`` (learn from checked series
    and labels; return the training distances the novelty rule uses, (n_series, K)),
    ``_candidate_distances`` (the (n_series, K) distances of checked series), and
    ``_state`` / ``_load_state`` (its fitted arrays as JSON data and back).

    Fitted, every classifier carries ``candidate_names_``, ``n_candidates_``,
    ``length_`` (samples per series), ``training_distances_`` (n_series, K) and
    ``max_training_distance_`` (K,) behind the novelty thresholds, and the training
    ``f1_``, ``accuracy_`` and ``confusion_`` computed from those distances (so
    leave-one-out for 1-NN and MiniRocket, where training on a series and scoring it
    would flatter them).
    """

    FORMAT = FORMAT

    kind: ClassVar[str] = ""
    novelty_factor: float
    # Set by train_classifier or a loaded document; identify needs them.
    scenario_: Scenario | None = None
    sequence_: np.ndarray | None = None

    # Hooks.

    def _check_params(self) -> None:
        factor = self.novelty_factor
        if (
            isinstance(factor, bool)
            or not isinstance(factor, int | float)
            or not (math.isfinite(factor) and factor >= 1.0)
        ):
            raise ValueError(f"novelty_factor must be a number >= 1, got {factor!r}")

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _state(self) -> dict[str, Any]:
        raise NotImplementedError

    def _load_state(self, state: dict[str, Any]) -> None:
        raise NotImplementedError

    # Fitting.

    def fit(
        self, X: Any, y: Any, *, candidate_names: list[str] | None = None
    ) -> SupervisedClassifier:
        """Learn each candidate's responses from labelled series.

        :param X: (n_series, length, 3) rates, rad/s.
        :param y: candidate index of each series, 0..K-1, at least 2 series per candidate
            (the novelty threshold needs a spread within each candidate).
        :param candidate_names: names of the K candidates, kept for reports and verdicts.
        """
        self._check_params()
        X = _check_series(X)
        y = _check_labels(y, len(X))
        n_candidates = int(y.max()) + 1
        if candidate_names is not None and len(candidate_names) != n_candidates:
            raise ValueError(
                f"{len(candidate_names)} candidate names for {n_candidates} candidates"
            )
        self.n_candidates_ = n_candidates
        self.candidate_names_ = (
            [str(n) for n in candidate_names]
            if candidate_names
            else [f"candidate {i}" for i in range(n_candidates)]
        )
        self.length_ = int(X.shape[1])
        training = self._fit(X, y)
        self.training_distances_ = training
        own = training[np.arange(len(y)), y]
        self.max_training_distance_ = np.array([own[y == k].max() for k in range(n_candidates)])
        confusion = np.zeros((n_candidates, n_candidates), dtype=int)
        np.add.at(confusion, (y, training.argmin(axis=1)), 1)
        self.confusion_ = confusion
        scores = confusion_scores(confusion)
        self.f1_ = scores["f1"]
        self.accuracy_ = scores["accuracy"]
        return self

    # Prediction.

    def _check_fitted(self) -> None:
        if not hasattr(self, "max_training_distance_"):
            raise ValueError(f"this {type(self).__name__} is not fitted yet; call fit first")

    def transform(self, X: Any) -> np.ndarray:
        """Distance of each series to each candidate, (n_series, K); the nearest is predicted.

        What the distance is depends on the classifier (see the module docstring): in
        rad/s for the nearest centroid and 1-NN, in ridge-output units for MiniRocket.
        """
        self._check_fitted()
        X = _check_series(X)
        if X.shape[1] != self.length_:
            raise ValueError(
                f"series have {X.shape[1]} samples; the classifier was trained on {self.length_}"
            )
        return np.asarray(self._candidate_distances(X))

    def predict(self, X: Any) -> np.ndarray:
        """Candidate index of each series: the nearest candidate."""
        return np.asarray(self.transform(X).argmin(axis=1))

    def novelty_thresholds(self) -> np.ndarray:
        """Per-candidate distance beyond which a series "matches none", (K,).

        ``novelty_factor`` times the largest distance a training series of the candidate
        had to it (leave-one-out for 1-NN and MiniRocket; see the module docstring).
        """
        self._check_fitted()
        return np.asarray(self.novelty_factor * self.max_training_distance_)

    # Storage as data.

    def to_dict(self) -> dict[str, Any]:
        self._check_fitted()
        params = self.get_params()
        if "alphas" in params and params["alphas"] is not None:
            params["alphas"] = [float(a) for a in params["alphas"]]
        return {
            "kind": self.kind,
            "params": params,
            "candidate_names": self.candidate_names_,
            "length": self.length_,
            "max_training_distance": self.max_training_distance_.tolist(),
            "f1": self.f1_,
            "accuracy": self.accuracy_,
            "confusion": self.confusion_.tolist(),
            "scenario": None if self.scenario_ is None else self.scenario_.model_dump(mode="json"),
            "sequence": None if self.sequence_ is None else np.asarray(self.sequence_).tolist(),
            "model": self._state(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SupervisedClassifier:
        kind = data.get("kind") if isinstance(data, dict) else None
        target = SUPERVISED_CLASSES.get(kind) if isinstance(kind, str) else None
        if target is None:
            raise ValueError(
                f"not a valid classifier document: kind {kind!r} is not one of "
                f"{sorted(SUPERVISED_CLASSES)}"
            )
        if cls is not SupervisedClassifier and target is not cls:
            raise ValueError(f"the document holds a {kind!r} classifier, not a {cls.kind!r} one")
        try:
            model = target(**data["params"])
            model._check_params()
            model.candidate_names_ = [str(n) for n in data["candidate_names"]]
            model.n_candidates_ = len(model.candidate_names_)
            model.length_ = int(data["length"])
            model.max_training_distance_ = np.asarray(data["max_training_distance"], float)
            model.f1_ = float(data["f1"])
            model.accuracy_ = float(data["accuracy"])
            model.confusion_ = np.asarray(data["confusion"], dtype=int)
            model.scenario_ = (
                None if data.get("scenario") is None else Scenario.model_validate(data["scenario"])
            )
            model.sequence_ = (
                None if data.get("sequence") is None else np.asarray(data["sequence"], dtype=int)
            )
            model._load_state(data["model"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"not a valid classifier document: {exc}") from None
        k = model.n_candidates_
        if model.max_training_distance_.shape != (k,) or model.confusion_.shape != (k, k):
            raise ValueError(
                f"not a valid classifier document: {k} candidates but thresholds of shape "
                f"{model.max_training_distance_.shape}"
            )
        return model


# Distance-based classifiers.


class _DistanceClassifier(SupervisedClassifier):
    metric: str
    sakoe_chiba_radius: int | None

    def _check_params(self) -> None:
        super()._check_params()
        if self.metric not in SUPERVISED_METRICS:
            raise ValueError(
                f"metric must be one of {list(SUPERVISED_METRICS)}, got {self.metric!r}"
            )
        radius = self.sakoe_chiba_radius
        if radius is not None:
            _check_positive_int("sakoe_chiba_radius", radius, minimum=0)

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
    :param novelty_factor: see :meth:`~SupervisedClassifier.novelty_thresholds`.
    """

    kind: ClassVar[str] = "nearest-centroid"

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
        _check_positive_int("max_iter_barycenter", self.max_iter_barycenter)

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        centroids = np.empty((int(y.max()) + 1, *X.shape[1:]))
        # DBA's stopping tolerance is absolute, so it runs on unit-RMS series.
        rms = float(np.sqrt(np.mean(X**2)))
        scale = rms if rms > 0 else 1.0
        radius = None if self.sakoe_chiba_radius is None else int(self.sakoe_chiba_radius)
        for k in range(len(centroids)):
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

    def _state(self) -> dict[str, Any]:
        return {"centroids_rad_s": self.centroids_.tolist()}

    def _load_state(self, state: dict[str, Any]) -> None:
        centroids = _check_series(state["centroids_rad_s"])
        if centroids.shape[:2] != (self.n_candidates_, self.length_):
            raise ValueError(
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
    :param novelty_factor: see :meth:`~SupervisedClassifier.novelty_thresholds`; the
        training distances are each series' distance to its nearest *other* training series
        of its own candidate.
    """

    kind: ClassVar[str] = "1nn"

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

    def _state(self) -> dict[str, Any]:
        return {
            "training_series_rad_s": self.training_series_.tolist(),
            "training_labels": self.training_labels_.tolist(),
        }

    def _load_state(self, state: dict[str, Any]) -> None:
        series = _check_series(state["training_series_rad_s"])
        labels = _check_labels(state["training_labels"], len(series))
        if series.shape[1] != self.length_ or int(labels.max()) + 1 != self.n_candidates_:
            raise ValueError(
                f"training series of {series.shape[1]} samples and {int(labels.max()) + 1} "
                f"candidates for {self.n_candidates_} candidates of {self.length_}"
            )
        self.training_series_ = series
        self.training_labels_ = labels


# MiniRocket.


class MiniRocketClassifier(SupervisedClassifier):
    """MiniRocket features and a ridge classifier (Dempster et al. 2021).

    The transform is :mod:`inertia_id.minirocket` (our implementation, following the
    paper; aeon and sktime cannot be installed beside the project's pinned stack). The
    features are scaled to unit variance over the training set, as the reference
    pipeline does, and scikit-learn's ``RidgeClassifierCV`` picks the penalty by
    leave-one-out. The scaling is folded into the stored coefficients.

    ``transform`` gives, for each candidate k, the Euclidean distance from the ridge's
    decision vector d (one value per candidate; the ridge targets are +1 for the true
    candidate and -1 for the others) to candidate k's target code: 0 for a series the
    ridge maps exactly onto k's code, 2 sqrt(2) between two codes. The nearest code is
    the largest decision value, so ``predict`` is the ridge classifier's prediction. A
    distance rather than the negative decision value, because a response unlike any
    candidate (a far-off inertia, no response at all) is extrapolated by the linear model
    to a decision vector far from every code, while its largest decision value can look
    ordinary; the distance lets "matches none" work. The novelty thresholds use the
    leave-one-out decision vectors of the training series (closed form, at the chosen
    penalty).

    :param n_features: MiniRocket feature budget (the paper's 10 000; rounded down to a
        multiple of 84).
    :param max_dilations_per_kernel: the paper's 32.
    :param alphas: ridge penalties to choose from; None = the paper's
        ``logspace(-3, 3, 10)``.
    :param novelty_factor: see :meth:`~SupervisedClassifier.novelty_thresholds`.
    :param random_state: seed of the channel subsets and bias draws.
    """

    kind: ClassVar[str] = "minirocket"

    def __init__(
        self,
        *,
        n_features: int = 10_000,
        max_dilations_per_kernel: int = 32,
        alphas: Sequence[float] | None = None,
        novelty_factor: float = 1.5,
        random_state: int | None = None,
    ) -> None:
        self.n_features = n_features
        self.max_dilations_per_kernel = max_dilations_per_kernel
        self.alphas = alphas
        self.novelty_factor = novelty_factor
        self.random_state = random_state

    @property
    def metric(self) -> str:
        """ "minirocket": what the sweep and the report print as the metric."""
        return "minirocket"

    def _check_params(self) -> None:
        super()._check_params()
        _check_positive_int("n_features", self.n_features, minimum=84)
        _check_positive_int("max_dilations_per_kernel", self.max_dilations_per_kernel)
        if self.alphas is not None:
            alphas = np.asarray(self.alphas, dtype=float)
            if (
                alphas.ndim != 1
                or alphas.size < 1
                or not np.all(np.isfinite(alphas) & (alphas > 0))
            ):
                raise ValueError(f"alphas must be numbers > 0, got {self.alphas!r}")
        if self.random_state is not None:
            _check_positive_int("random_state", self.random_state, minimum=0)

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        rng = np.random.default_rng(self.random_state)
        self.parameters_ = fit_minirocket(
            X,
            rng,
            n_features=int(self.n_features),
            max_dilations_per_kernel=int(self.max_dilations_per_kernel),
        )
        features = minirocket_transform(X, self.parameters_)
        std = features.std(axis=0)
        scale = np.where(std > 10 * np.finfo(float).eps, std, 1.0)
        scaled = features / scale
        alphas = DEFAULT_ALPHAS if self.alphas is None else tuple(float(a) for a in self.alphas)
        ridge = RidgeClassifierCV(alphas=alphas).fit(scaled, y)
        self.alpha_ = float(ridge.alpha_)
        # One row per candidate, or a single row (candidate 1's) for two candidates.
        self.coef_ = np.atleast_2d(np.asarray(ridge.coef_, dtype=float)) / scale
        self.intercept_ = np.asarray(ridge.intercept_, dtype=float).reshape(-1)
        targets = -np.ones((len(y), self.n_candidates_))
        targets[np.arange(len(y)), y] = 1.0
        if self.n_candidates_ == 2:
            targets = targets[:, 1:]  # scikit-learn's single column for two classes
        left_out = _leave_one_out_ridge(scaled, targets, self.alpha_)
        return _distance_to_codes(_per_candidate(left_out))

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        decision = minirocket_transform(X, self.parameters_) @ self.coef_.T + self.intercept_
        return _distance_to_codes(_per_candidate(decision))

    def _state(self) -> dict[str, Any]:
        return {
            "transform": self.parameters_.to_dict(),
            "coef": self.coef_.tolist(),
            "intercept": self.intercept_.tolist(),
            "alpha": self.alpha_,
        }

    def _load_state(self, state: dict[str, Any]) -> None:
        parameters = MiniRocketParameters.from_dict(state["transform"])
        coef = np.asarray(state["coef"], dtype=float)
        intercept = np.asarray(state["intercept"], dtype=float).reshape(-1)
        rows = 1 if self.n_candidates_ == 2 else self.n_candidates_
        if (
            parameters.length != self.length_
            or coef.shape != (rows, parameters.n_features)
            or intercept.shape != (rows,)
        ):
            raise ValueError(
                f"ridge coefficients of shape {coef.shape} and {intercept.shape} intercepts "
                f"for {self.n_candidates_} candidates and {parameters.n_features} features"
            )
        self.parameters_ = parameters
        self.coef_ = coef
        self.intercept_ = intercept
        self.alpha_ = float(state["alpha"])


def _per_candidate(decision: np.ndarray) -> np.ndarray:
    """Ridge decision values as (n, K); two classes come as one column (class 1's)."""
    return np.hstack([-decision, decision]) if decision.shape[1] == 1 else decision


def _distance_to_codes(decision: np.ndarray) -> np.ndarray:
    """Euclidean distance of each (K,) decision vector to each candidate's target code.

    The code of candidate k is +1 at k and -1 elsewhere, so the squared distance is
    ``|d|^2 + K - 4 d_k + 2 sum(d)``: the nearest code is the largest decision value,
    the ridge classifier's own prediction.
    """
    k = decision.shape[1]
    codes = 2.0 * np.eye(k) - 1.0
    return np.asarray(cdist(decision, codes))


def _leave_one_out_ridge(features: np.ndarray, targets: np.ndarray, alpha: float) -> np.ndarray:
    """Leave-one-out predictions of ridge regression with an unpenalised intercept.

    The residuals of the full fit are ``R Y`` with ``R = I - H`` (H the hat matrix), and
    the prediction for series i from a fit without it is ``y_i - (R Y)_i / R_ii`` (the
    identity scikit-learn's RidgeCV chooses alpha with). With B an orthonormal basis of
    the vectors orthogonal to the constant (the intercept absorbs the constant) and
    ``B^T F = U S W^T``, ``R = G diag(alpha / (s^2 + alpha)) G^T`` with ``G = B U``: a sum
    of positive terms, so R_ii stays accurate when it is tiny (small alpha, more features
    than series), where ``1 - H_ii`` would cancel. n x n work only.
    """
    n = len(features)
    basis = np.linalg.qr(np.ones((n, 1)), mode="complete")[0][:, 1:]
    u, s, _ = np.linalg.svd(basis.T @ features, full_matrices=False)
    g = basis @ u
    weights = alpha / (s**2 + alpha)
    residuals = g @ (weights[:, None] * (g.T @ targets))
    leverage_complement = (g**2) @ weights
    return np.asarray(targets - residuals / leverage_complement[:, None])


#: The supervised classes by kind name (what a document's "kind" field names).
SUPERVISED_CLASSES: dict[str, type[SupervisedClassifier]] = {
    cls.kind: cls
    for cls in (NearestCentroidClassifier, NearestNeighbourClassifier, MiniRocketClassifier)
}
