"""What every classifier kind shares: checks, names, training scores, the novelty rule,
storage as a checksummed document.

A kind subclasses :class:`BaseClassifier`, declares what it is in class attributes
(:attr:`~BaseClassifier.kind`, the document :attr:`~BaseClassifier.FORMAT`, the
:attr:`~BaseClassifier.METRICS` it takes, its minimum and default training realisations)
and implements four hooks, the way stable-baselines3's callbacks implement ``_on_step``:

- ``_fit(X, y)``: learn from checked series and labels; return the training distances
  (n_series, K) behind the novelty rule and the training scores (out-of-sample where the
  kind would otherwise flatter itself, e.g. leave-one-out for 1-NN);
- ``_candidate_distances(X)``: the (n_series, K) distances of checked series;
- ``_state()`` / ``_load_state(data)``: its fitted arrays as document fields and back.

Defining the class registers the kind (:mod:`inertia_id.classifiers.registry` lists every
kind of the package), so adding a kind touches one file: its own module.

The base does the rest, the same for every kind: parameter and input checks that quote
the value, candidate names and their defaults, the scenario and sequence a classifier
remembers for identify, ``predict`` (the nearest candidate of ``transform``),
``fit_predict``, ``evaluate`` and ``score`` (macro F1), the "matches none" thresholds,
the common document fields and JSON storage (never a pickle).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import Any, ClassVar, Self

import numpy as np
from scipy import special
from scipy.stats import chi2
from sklearn.base import BaseEstimator

from ..checks import is_integer, is_number
from ..errors import InputError
from ..physics.scenario import AS_TRAINED, Scenario
from ..physics.series import check_series
from ..physics.simulate import simulate
from ..stopping import Checkpoint, checkpoint_of, no_checkpoint
from . import documents
from .gaussian import log_softmax

__all__ = [
    "KINDS",
    "NONE_PRIOR",
    "BaseClassifier",
    "NoveltyTail",
    "SupervisedClassifier",
    "check_int",
    "check_labels",
    "check_training_labels",
    "confusion_scores",
    "document_class",
    "is_number",
]

#: Every kind defined so far, by name: filled as the kind classes are defined.
KINDS: dict[str, type[BaseClassifier]] = {}

#: Prior probability that a series comes from none of the candidates. The novelty
#: bound's Bayes factor of "none" is never below 1 (see :func:`none_log_odds`), so the
#: prior is the floor of P(none) (half of it where "none" also has a proper model of
#: other bodies, whose factor goes to 0 on a genuine series): 1e-4 leaves a genuine
#: series room to pass the online stop rule's 1 - 1e-3.
NONE_PRIOR = 1e-4


class NoveltyTail:
    """How far a genuine series lies from its own candidate: a scaled chi-square.

    A squared distance is matched by ``scale · χ²(dof)`` with the mean and variance of
    the own-candidate squared distances it is fitted on (Satterthwaite's moment match):
    exact for Mahalanobis distances (scale 1, dof = 3 length), the usual approximation
    for a Euclidean distance under correlated Gaussian noise (scale = the noise variance
    per effective dimension), a description for the others. ``scale`` also puts a kind's
    distances on the log-likelihood scale of its posterior: ``-d² / (2 scale)``.

    :param scale: the chi-square's scale, in the distance's units squared.
    :param dof: its degrees of freedom, over the whole series.
    """

    def __init__(self, scale: float, dof: float) -> None:
        self.scale = float(scale)
        self.dof = float(dof)

    @classmethod
    def fit(cls, own_distances: np.ndarray) -> NoveltyTail | None:
        squared = np.asarray(own_distances, dtype=float) ** 2
        squared = squared[np.isfinite(squared)]
        if squared.size < 3:
            return None
        mean, var = float(squared.mean()), float(squared.var(ddof=1))
        if not (mean > 0.0 and var > 0.0):
            return None
        return cls(scale=var / (2.0 * mean), dof=2.0 * mean**2 / var)

    def log_sf(self, distance: np.ndarray, fraction: float | np.ndarray = 1.0) -> np.ndarray:
        """log P(D >= distance) for a genuine series; over a ``fraction`` of the series,
        the degrees of freedom shrink in proportion."""
        dof = np.maximum(self.dof * np.asarray(fraction, dtype=float), 1.0)
        # scipy.special's chi-squared functions, not scipy.stats.chi2.logsf: the same
        # numbers (log1p of the CDF where the tail is near 1) for a hundredth of the cost
        # (0.25 ms of a verdict's 2 ms went to the distribution machinery).
        x = np.asarray(distance, dtype=float) ** 2 / self.scale
        tail = special.chdtrc(dof, x)
        with np.errstate(divide="ignore"):
            return np.asarray(
                np.where(tail > 0.5, np.log1p(-special.chdtr(dof, x)), np.log(tail)), dtype=float
            )

    def to_dict(self) -> dict[str, float]:
        return {"scale": self.scale, "dof": self.dof}

    @classmethod
    def from_dict(cls, data: Any) -> NoveltyTail | None:
        if data is None:
            return None
        tail = cls(scale=float(data["scale"]), dof=float(data["dof"]))
        for name in ("scale", "dof"):
            value = getattr(tail, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"novelty_tail.{name} must be finite and > 0, got {value!r}")
        return tail


def none_log_odds(log_p_value: np.ndarray, prior: float) -> np.ndarray:
    """log odds of "none of these" given the novelty p-value of the nearest candidate.

    The p-value is turned into a Bayes factor for "none" by the Sellke, Bayarri and
    Berger (2001) bound ``1 / (-e p log p)`` (for p < 1/e; 1 above): the largest
    evidence a p-value can carry against the null, so "none" is never believed more
    than the data allow, whatever the alternative.
    """
    log_p = np.clip(np.asarray(log_p_value, dtype=float), -1e300, -1.0)
    log_bayes = -1.0 - log_p - np.log(-log_p)
    return np.asarray(math.log(prior) - math.log1p(-prior) + log_bayes)


def check_int(name: str, value: Any, minimum: int = 1) -> None:
    """Refuse anything but an integer >= ``minimum`` (a bool is not one), quoting it."""
    if not is_integer(value, minimum=minimum):
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")


def _integer_labels(y: Any, n_series: int) -> np.ndarray:
    arr = np.asarray(y)
    if arr.shape != (n_series,):
        raise InputError(f"y must hold one label per series ({n_series}), got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        if (
            not np.issubdtype(arr.dtype, np.number)
            or not np.all(np.isfinite(arr))
            or np.any(arr != np.round(arr))
        ):
            raise InputError(f"labels must be candidate indices, got {arr.tolist()[:10]}")
    return arr.astype(int)


def check_labels(y: Any, n_series: int, n_candidates: int) -> np.ndarray:
    """Candidate indices, one per series, each in 0..K-1."""
    labels = _integer_labels(y, n_series)
    outside = sorted({int(v) for v in labels if v < 0 or v >= n_candidates})
    if outside:
        raise InputError(
            f"labels must lie in 0..{n_candidates - 1} (candidate indices), got {outside}"
        )
    return labels


def check_training_labels(y: Any, n_series: int, minimum: int) -> np.ndarray:
    """Labels of a training set: every candidate 0..K-1 (K >= 2) at least ``minimum`` times."""
    labels = _integer_labels(y, n_series)
    if labels.size and labels.min() < 0:
        raise InputError(f"candidate indices must be >= 0, got {int(labels.min())}")
    counts = np.bincount(labels) if labels.size else np.zeros(0, dtype=int)
    if len(counts) < 2 or counts.min() < minimum:
        raise InputError(
            f"y must label every candidate 0..K-1 (K >= 2) at least {minimum} time(s); "
            f"series per candidate: {counts.tolist()}"
        )
    return labels


def confusion_scores(confusion: np.ndarray) -> dict[str, Any]:
    """Macro F1 (over the candidates present), accuracy and the confusion matrix itself."""
    tp = np.diag(confusion).astype(float)
    denom = confusion.sum(axis=0) + confusion.sum(axis=1)
    present = confusion.sum(axis=1) > 0
    f1 = np.divide(2.0 * tp, denom, out=np.zeros_like(tp), where=denom > 0)
    return {
        "f1": float(f1[present].mean()) if present.any() else 0.0,
        "accuracy": float(np.trace(confusion) / max(confusion.sum(), 1)),
        "confusion": confusion,
    }


def document_class(format_name: str, data: dict[str, Any]) -> type[BaseClassifier]:
    """The kind a payload of ``format_name`` holds: the format's one kind, or, where
    several kinds share the format, the one the payload's "kind" names."""
    sharing = {kind: cls for kind, cls in KINDS.items() if cls.FORMAT == format_name}
    if len(sharing) == 1:
        return next(iter(sharing.values()))
    kind = data.get("kind")
    if not isinstance(kind, str) or kind not in sharing:
        raise InputError(
            f"not a valid classifier document: kind {kind!r} is not one of {sorted(sharing)}"
        )
    return sharing[kind]


def _plain(value: Any) -> Any:
    """A parameter value as JSON data: arrays and tuples as lists, numpy scalars as numbers."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


class BaseClassifier(BaseEstimator):
    """The bookkeeping every kind shares; see the module docstring for the hooks.

    Fitted, every classifier carries ``candidate_names_``, ``n_candidates_``, ``length_``
    (samples per series), ``training_distances_`` (n_series, K) and
    ``max_training_distance_`` (K,) behind the novelty thresholds, the training
    ``f1_``, ``accuracy_`` and ``confusion_``, and ``scenario_`` and ``sequence_`` when
    it was fitted with them (identify needs them).
    """

    #: The name the registry, the CLI and the API know the kind by.
    kind: ClassVar[str] = ""
    #: The document format name (several kinds may share one; the document then names
    #: its kind).
    FORMAT: ClassVar[str] = ""
    #: The metrics the kind takes as its ``metric`` parameter, the first the default;
    #: empty for a kind that takes none (its ``metric`` is then a fixed label).
    METRICS: ClassVar[tuple[str, ...]] = ()
    #: Training series per candidate the fit needs at the least.
    MIN_REALISATIONS: ClassVar[int] = 1
    #: Fresh draws per candidate :meth:`fit_scenario` calibrates the posterior on.
    CALIBRATION_DRAWS: ClassVar[int] = 50
    #: Training realisations per candidate when none are asked for.
    DEFAULT_REALISATIONS: ClassVar[int] = 20
    #: The scenario and sequence are the model itself (least squares), not just context.
    NEEDS_SCENARIO: ClassVar[bool] = False
    #: Whether the labels teach the classifier. An unsupervised kind (the clustering) sets
    #: its novelty threshold from the series it assigns to a candidate, which it knows
    #: without the labels, rather than from the candidate's own series.
    SUPERVISED: ClassVar[bool] = True
    #: Whether the training scores count the in-sample predictions rather than the
    #: nearest candidate of the training distances: the likelihood kinds, whose
    #: out-of-fold distances calibrate the novelty threshold only.
    IN_SAMPLE_SCORES: ClassVar[bool] = False
    #: Whether the kind compares series with each axis' mean removed. A constant gyro
    #: bias and (for small rates) an initial body rate shift a response by a constant per
    #: axis; a distance kind that compared raw series would weigh that offset, which says
    #: nothing about the inertia, like a misfit (the paper's Euclidean clustering falls
    #: from F1 1.0 to 0.49 on the paper preset with 5e-3 rad/s initial rates and 2e-3
    #: rad/s biases). Removing the per-axis mean is the orthogonal projection off those
    #: offsets. The likelihood kinds model them in their covariance instead, and the least
    #: squares uses absolute rates in its gyroscopic term, so they keep the raw series.
    REMOVES_OFFSET: ClassVar[bool] = True
    #: Where the kind stands in lists of kinds (CLI choices, API enums).
    LISTING_ORDER: ClassVar[int] = 100
    #: What the kind is, in a few words, for lists a person reads (the dashboard's).
    LABEL: ClassVar[str] = ""

    #: What the distances are, for reports and sweeps: the ``metric`` parameter of a kind
    #: that takes one, a fixed label (a class attribute) for the others.
    metric: str
    novelty_factor: float
    # The novelty tail of the own-candidate training distances, and the calibration
    # report of calibrate() (its temperature among it); None in an older document.
    novelty_tail_: NoveltyTail | None = None
    calibration_: dict[str, Any] | None = None
    # Whether fitted series had each axis' mean removed (REMOVES_OFFSET at fit time; a
    # document written before the rule existed loads as False, its centroids raw).
    offset_removed_: bool = False
    # Set by a fit given them, or by a loaded document; identify needs them.
    scenario_: Scenario | None = None
    sequence_: np.ndarray | None = None
    candidate_names_: list[str]
    n_candidates_: int
    length_: int
    training_distances_: np.ndarray
    max_training_distance_: np.ndarray
    f1_: float
    accuracy_: float
    confusion_: np.ndarray

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kind = cls.__dict__.get("kind")
        if kind:
            if kind in KINDS and KINDS[kind].__qualname__ != cls.__qualname__:
                raise TypeError(f"two classifier classes claim the kind {kind!r}")
            KINDS[kind] = cls

    # Hooks.

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _state(self) -> dict[str, Any]:
        raise NotImplementedError

    @classmethod
    def stored_numbers(cls, n_candidates: int, values: int, n_realisations: int) -> int:
        """Most numbers the kind's own state (:meth:`_state`) holds, trained on
        ``n_realisations`` series a candidate of ``values`` rate values each: what
        :func:`~inertia_id.classifiers.registry.document_bytes` bounds a document by
        before it is trained. Here one series a candidate (a centroid or a mean)."""
        return n_candidates * values

    def _load_state(self, data: dict[str, Any]) -> None:
        raise NotImplementedError

    def _form_derived(self) -> None:
        """Form what the kind derives from its loaded state (after :meth:`_load_state`,
        once the document's data may be let go); nothing unless the kind has it."""

    def _check_params(self) -> None:
        """Refuse parameters the kind cannot use, quoting them; kinds extend it."""
        factor = self.novelty_factor
        if not is_number(factor, minimum=1.0):
            raise InputError(f"novelty_factor must be a number >= 1, got {factor!r}")
        if self.METRICS and self.metric not in self.METRICS:
            raise InputError(f"metric must be one of {list(self.METRICS)}, got {self.metric!r}")

    def _draw_seed(self, rng: np.random.Generator) -> None:
        """Take a ``random_state`` left unset from ``rng``, so the same rng state gives the
        same model."""
        params = self.get_params(deep=False)
        if "random_state" in params and params["random_state"] is None:
            self.set_params(random_state=int(rng.integers(2**31 - 1)))

    # Fitting.

    def fit(
        self,
        X: Any,
        y: Any,
        *,
        candidate_names: list[str] | None = None,
        scenario: Scenario | None = None,
        sequence: Any = None,
    ) -> Self:
        """Learn each candidate's responses from labelled series.

        :param X: (n_series, length, 3) rates, rad/s.
        :param y: candidate index of each series, 0..K-1, every candidate at least
            :attr:`MIN_REALISATIONS` times.
        :param candidate_names: names of the K candidates, for reports and verdicts;
            default the scenario's, if given.
        :param scenario: the scenario the series were simulated in; kept, with
            ``sequence``, so that :func:`~inertia_id.evaluation.identify.identify` can
            resample telemetry onto the training grid.
        :param sequence: the (L, N) level indices the series respond to.
        """
        X, y = self._prepare(X, y, candidate_names, scenario, sequence)
        self._record_training(X, y, self._fit(X, y))
        return self

    def fit_scenario(
        self,
        scenario: Scenario,
        sequence: Any,
        n_realisations: int,
        rng: np.random.Generator,
        *,
        should_stop: Callable[[], bool] | None = None,
    ) -> Self:
        """Simulate every candidate's response to ``sequence`` at 1x noise and fit on it.

        :param n_realisations: training series per candidate.
        :param rng: source of the simulated noise (and of a seed the kind needs); the same
            state gives the same model.
        :param should_stop: asked at the training's checkpoints (after each simulation,
            between the pieces of a kind's fit, in the calibration); True stops it there
            with :class:`~inertia_id.stopping.TrainingStopped`, the model left part-fitted
            (not to be used).
        """
        self._check_params()
        scenario.check_distinguishable()
        self.__dict__["_stop_checkpoint"] = checkpoint_of(should_stop)
        try:
            self._fit_simulated(scenario, scenario.check_fires(sequence), n_realisations, rng)
            self._checkpoint()
            # The posterior's novelty tail and temperature from fresh draws of a fixed
            # seed (the caller's rng untouched): training distances are in-sample, or, for
            # the marginal likelihood, taken at the grid's extremes, both wider than 1x.
            from ..evaluation.calibration import calibrate

            calibrate(self, self.CALIBRATION_DRAWS, checkpoint=self._checkpoint)
        finally:
            # Only for the fit: a fitted model does not hold on to its trainer's callback
            # (it is copied, pickled and written as a document).
            self.__dict__.pop("_stop_checkpoint", None)
        return self

    def _checkpoint(self) -> None:
        """A point where the fit under way may stop (:meth:`fit_scenario`'s
        ``should_stop``); nothing outside such a fit."""
        checkpoint: Checkpoint = self.__dict__.get("_stop_checkpoint", no_checkpoint)
        checkpoint()

    def _fit_simulated(
        self, scenario: Scenario, steps: np.ndarray, n_realisations: int, rng: np.random.Generator
    ) -> None:
        """Simulate the training set and fit; a kind that needs other runs overrides it."""
        X, y = simulate(scenario, steps, n_realisations, rng).dataset()
        self._checkpoint()
        self._draw_seed(rng)
        self.fit(X, y, candidate_names=scenario.candidate_names, scenario=scenario, sequence=steps)

    def _prepare(
        self,
        X: Any,
        y: Any,
        candidate_names: list[str] | None,
        scenario: Scenario | None,
        sequence: Any,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Check a training set and its context, and set what every fitted kind carries."""
        self._check_params()
        self.offset_removed_ = self.REMOVES_OFFSET
        X = self._without_offset(check_series(X))
        y = check_training_labels(y, len(X), self.MIN_REALISATIONS)
        n_candidates = int(y.max()) + 1
        if (scenario is None) != (sequence is None):
            raise InputError("give the scenario and the sequence together, or neither")
        steps = None
        if scenario is None:
            if self.NEEDS_SCENARIO:
                raise InputError(
                    f"the {self.kind!r} classifier needs the scenario and the sequence: "
                    "they are its model"
                )
        else:
            if scenario.n_candidates != n_candidates:
                raise InputError(
                    f"the scenario has {scenario.n_candidates} candidates, y labels {n_candidates}"
                )
            steps = scenario.check_sequence(sequence)
            expected = len(steps) * scenario.timing.samples_per_step
            if X.shape[1] != expected:
                raise InputError(
                    f"series have {X.shape[1]} samples; the {len(steps)}-step sequence gives "
                    f"{expected}"
                )
        if candidate_names is not None and len(candidate_names) != n_candidates:
            raise InputError(
                f"{len(candidate_names)} candidate names for {n_candidates} candidates"
            )
        if candidate_names is not None:
            names = [str(n) for n in candidate_names]
        elif scenario is not None:
            names = list(scenario.candidate_names)
        else:
            # Numbered from 1, as plan tables and candidate_number number candidates.
            names = [f"candidate {i}" for i in range(1, n_candidates + 1)]
        self.n_candidates_ = n_candidates
        self.candidate_names_ = names
        self.length_ = int(X.shape[1])
        self.scenario_ = scenario
        self.sequence_ = steps
        return X, y

    def _record_training(self, X: np.ndarray, y: np.ndarray, training: np.ndarray) -> None:
        """The novelty thresholds' training maxima, and the training scores."""
        k = self.n_candidates_
        owner = y if self.SUPERVISED else training.argmin(axis=1)
        own = training[np.arange(len(owner)), owner]
        self.training_distances_ = training
        self.novelty_tail_ = NoveltyTail.fit(own)
        self.calibration_ = None
        self.max_training_distance_ = np.array(
            [own[owner == c].max() if np.any(owner == c) else np.inf for c in range(k)]
        )
        predicted = self.predict(X) if self.IN_SAMPLE_SCORES else training.argmin(axis=1)
        confusion = np.zeros((k, k), dtype=int)
        np.add.at(confusion, (y, predicted), 1)
        scores = confusion_scores(confusion)
        self.f1_ = scores["f1"]
        self.accuracy_ = scores["accuracy"]
        self.confusion_ = confusion

    # Prediction.

    def _check_fitted(self) -> None:
        if not hasattr(self, "max_training_distance_"):
            raise InputError(f"this {type(self).__name__} is not fitted yet; call fit first")

    def _without_offset(self, X: np.ndarray) -> np.ndarray:
        """The series with each axis' mean removed, where the kind compares them so."""
        if not self.offset_removed_:
            return X
        return np.asarray(X - X.mean(axis=1, keepdims=True))

    def _check_input(self, X: Any) -> np.ndarray:
        """Series to classify, checked against what the classifier was trained on (each
        axis' mean removed where the kind was fitted so)."""
        self._check_fitted()
        X = self._without_offset(check_series(X))
        if X.shape[1] != self.length_:
            raise InputError(
                f"series have {X.shape[1]} samples; the classifier was trained on {self.length_}"
            )
        return X

    def transform(self, X: Any) -> np.ndarray:
        """Distance of each series to each candidate, (n_series, K); the nearest is predicted.

        What the distance is depends on the kind (its :attr:`metric`).
        """
        return np.asarray(self._candidate_distances(self._check_input(X)))

    def predict(self, X: Any) -> np.ndarray:
        """Candidate index of each series: the nearest candidate."""
        return np.asarray(self.transform(X).argmin(axis=1))

    def fit_predict(self, X: Any, y: Any, **kwargs: Any) -> np.ndarray:
        """Fit on the series, then predict them."""
        return self.fit(X, y, **kwargs).predict(X)

    def novelty_thresholds(self, fraction: float = 1.0) -> np.ndarray:
        """Per-candidate distance beyond which a series "matches none", (K,).

        ``novelty_factor`` times the largest distance a training series had to the
        candidate (out-of-sample where the kind's training distances are, see ``_fit``).

        :param fraction: the part of the series' values the distances cover (the
            measured grid points of slow telemetry, :meth:`observed_fraction`): the
            threshold is then the novelty tail's quantile of the same tail probability
            with the degrees of freedom in proportion (``sqrt(fraction)`` times the
            whole series' without a tail).
        """
        self._check_fitted()
        full = np.asarray(self.novelty_factor * self.max_training_distance_)
        if fraction >= 1.0:
            return full
        tail = self.novelty_tail_
        if tail is None:
            return np.asarray(full * math.sqrt(fraction))
        log_p = tail.log_sf(full)
        dof = max(tail.dof * fraction, 1.0)
        return np.asarray(np.sqrt(tail.scale * chi2.isf(np.exp(log_p), dof)))

    def evaluate(self, X: Any, y: Any) -> dict[str, Any]:
        """F1 (macro), accuracy and confusion matrix (row = true) of predictions against ``y``."""
        predicted = self.predict(X)
        labels = check_labels(y, len(predicted), self.n_candidates_)
        confusion = np.zeros((self.n_candidates_, self.n_candidates_), dtype=int)
        np.add.at(confusion, (labels, predicted), 1)
        return confusion_scores(confusion)

    def score(self, X: Any, y: Any) -> float:
        """Macro F1 of the predictions (the paper's score)."""
        return float(self.evaluate(X, y)["f1"])

    # Posterior probabilities.

    #: Whether the kind's distances are (marginal) Mahalanobis distances of a Gaussian
    #: model, so that ``-d² / 2`` is its log-likelihood up to a shared constant.
    GAUSSIAN_DISTANCES: ClassVar[bool] = False

    @property
    def temperature_(self) -> float:
        """The softmax temperature fitted by :func:`~inertia_id.evaluation.calibration.calibrate`;
        1 before (or in an older document)."""
        if self.calibration_ is None:
            return 1.0
        return float(self.calibration_.get("temperature", 1.0))

    def _evidence_scale(self) -> float:
        """What divides ``-d² / 2`` into a log-likelihood: 1 for Gaussian distances, the
        novelty tail's scale for the others."""
        if self.GAUSSIAN_DISTANCES or self.novelty_tail_ is None:
            return 1.0
        return self.novelty_tail_.scale

    @classmethod
    def has_partial_posterior(cls) -> bool:
        """Whether the kind gives a posterior for a leading part of a series (it overrides
        :meth:`_prefix_distances`)."""
        return cls._prefix_distances is not BaseClassifier._prefix_distances

    # Slow telemetry: the measured grid points only.

    @classmethod
    def supports_observed(cls) -> bool:
        """Whether the kind evaluates a series on its measured grid points only (it
        overrides :meth:`_observed_distances`: the likelihood kinds, the exact Gaussian
        marginal of the measured values); the others use every grid point."""
        return cls._observed_distances is not BaseClassifier._observed_distances

    def _observed_values(self, observed: Any) -> np.ndarray | None:
        """The flattened indices of the measured values, or None when every grid point
        was measured (or the kind uses every one)."""
        if observed is None:
            return None
        self._check_fitted()
        mask = np.asarray(observed)
        if mask.dtype != bool or mask.shape != (self.length_,):
            raise InputError(
                f"observed must be {self.length_} booleans (one per grid point), got "
                f"{mask.dtype} shaped {mask.shape}"
            )
        if not mask.any():
            raise InputError("observed marks no grid point as measured")
        if mask.all() or not self.supports_observed():
            return None
        return np.asarray((np.flatnonzero(mask)[:, None] * 3 + np.arange(3)).ravel())

    def observed_fraction(self, observed: Any = None) -> float:
        """The part of the series' values the distances use: the measured grid points'
        (:meth:`transform_observed`), 1 for a whole series."""
        values = self._observed_values(observed)
        return 1.0 if values is None else values.size / (3.0 * self.length_)

    def transform_observed(self, X: Any, observed: Any = None) -> np.ndarray:
        """:meth:`transform` on the grid points ``observed`` marks as measured, (n, K):
        for a likelihood kind the distance of the exact Gaussian marginal of those
        values; the whole series (today's distances, bit for bit) when every point is
        marked, when ``observed`` is None, or for a kind without the hook."""
        values = self._observed_values(observed)
        if values is None:
            return self.transform(X)
        return np.asarray(self._observed_distances(self._check_input(X), values))

    def _observed_distances(self, X: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Distances of checked series on the flattened values ``values`` only, (n, K);
        by default (a kind without a Gaussian model) the whole series'."""
        return self._candidate_distances(X)

    def _observed_near_log_bayes(self, X: np.ndarray, values: np.ndarray) -> np.ndarray | None:
        """(n,) log Bayes factor of a proper "other bodies" model on ``values``; None
        for a kind without one."""
        return None

    def _observed_prefix_distances(self, X: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Distances after each measured sample, (n, len(values) // 3, K): the leading
        blocks of the measured values' marginal."""
        raise InputError(
            f"the {self.kind!r} classifier has no posterior for a partly measured series"
        )

    def _observed_prefix_near_log_bayes(
        self, X: np.ndarray, values: np.ndarray
    ) -> np.ndarray | None:
        return None

    def _prefix_distances(self, X: np.ndarray) -> np.ndarray:
        """Distances of every leading part of checked series, (n, length, K): after the
        first sample, the first two, ... The kinds with a Gaussian model give the exact
        marginal of the leading block; the others have none."""
        raise InputError(
            f"the {self.kind!r} classifier has no posterior for a partial series; the "
            "likelihood kinds have (their Gaussian's leading block)"
        )

    def posterior_from_distances(
        self,
        distances: np.ndarray,
        fraction: float | np.ndarray = 1.0,
        near_log_bayes: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Posterior of each candidate and of "none of these" from distances (..., K).

        The candidates' part is the softmax of ``-d² / (2 s T)`` (s the evidence scale,
        T the fitted temperature) with equal priors; "none" has the prior
        :data:`NONE_PRIOR` and the Bayes factor its novelty p-value bounds (see
        :func:`none_log_odds`). Without a novelty tail (an older document) "none" is
        its prior within the novelty thresholds and 1 - prior beyond them.

        :param fraction: the part of the series the distances cover (online decisions).
        :param near_log_bayes: (...) log Bayes factor of a proper model of other bodies
            near the candidates, where the kind has one (the marginal likelihood's
            ``near_none_log_bayes``): "none" is then that model or something else
            entirely (the novelty bound), with equal weight, so its Bayes factor is the
            mean of the two.
        :returns: (..., K) candidate probabilities and (...) the probability of none;
            together they sum to 1.
        """
        d = np.asarray(distances, dtype=float)
        logits = -0.5 * d**2 / (self._evidence_scale() * self.temperature_)
        candidates = np.exp(log_softmax(logits, axis=-1))
        nearest = d.min(axis=-1)
        if self.novelty_tail_ is not None:
            log_odds = none_log_odds(self.novelty_tail_.log_sf(nearest, fraction), NONE_PRIOR)
            if near_log_bayes is not None:
                prior_odds = math.log(NONE_PRIOR) - math.log1p(-NONE_PRIOR)
                log_odds = (
                    prior_odds
                    + np.logaddexp(log_odds - prior_odds, np.asarray(near_log_bayes, dtype=float))
                    - math.log(2.0)
                )
        else:
            beyond = np.all(d > self.novelty_thresholds(), axis=-1)
            log_odds = np.where(beyond, 1.0, -1.0) * math.log((1 - NONE_PRIOR) / NONE_PRIOR)
        p_none = 1.0 / (1.0 + np.exp(-np.clip(log_odds, -700.0, 700.0)))
        return candidates * (1.0 - p_none)[..., None], p_none

    def _near_log_bayes(self, X: np.ndarray) -> np.ndarray | None:
        """(n,) log Bayes factor of a proper "other bodies" model on checked whole
        series; None for a kind without one."""
        return None

    def distances_and_posterior(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The distances (n, K) and the posterior of :meth:`predict_posterior` ((n, K)
        candidates and (n,) none) from one evaluation of the series.

        :param observed: (length,) booleans, the grid points that hold a measurement
            (slow telemetry, :func:`~inertia_id.evaluation.telemetry.resample_observed`);
            a likelihood kind then uses those values only. None: every point.
        """
        distances, candidates, p_none, _ = self.verdict_evidence(X, observed)
        return distances, candidates, p_none

    def verdict_evidence(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`distances_and_posterior` and, beside it, the log Bayes factor (n,) of
        the kind's model of other bodies near the candidates against the candidates
        (None for a kind without one): what a verdict
        (:func:`~inertia_id.evaluation.identify.verdicts`) needs, from one evaluation.

        The posterior weighs that factor by the prior of "none" (:data:`NONE_PRIOR`);
        the verdict also reads it alone, as what the telemetry says whatever the prior.
        """
        values = self._observed_values(observed)
        series = self._check_input(X)
        if values is None:
            distances = np.asarray(self._candidate_distances(series))
            near = self._near_log_bayes(series)
            candidates, p_none = self.posterior_from_distances(distances, near_log_bayes=near)
        else:
            distances = np.asarray(self._observed_distances(series, values))
            near = self._observed_near_log_bayes(series, values)
            candidates, p_none = self.posterior_from_distances(
                distances, values.size / (3.0 * self.length_), near_log_bayes=near
            )
        return distances, candidates, p_none, None if near is None else np.asarray(near)

    def predict_posterior(self, X: Any, observed: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Posterior of each candidate (n, K) and of "none of these" (n,); they sum to 1.

        "None" is a body near the candidates, where the kind models one
        (:meth:`_near_log_bayes`), or something else entirely (the novelty tail's
        bound). ``observed``: as for :meth:`distances_and_posterior`.
        """
        _, candidates, p_none = self.distances_and_posterior(X, observed)
        return candidates, p_none

    def posterior_over_time(self, X: Any, observed: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """The posterior after each sample of the series: (n, length, K) candidates and
        (n, length) none, from the leading part of the series up to that sample.

        :param observed: (length,) booleans, the grid points that hold a measurement: the
            posterior then moves at those only (the leading blocks of the measured
            values' marginal), and is the prior before the first. None: every point.
        """
        candidates, none, _ = self.evidence_over_time(X, observed)
        return candidates, none

    def evidence_over_time(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`posterior_over_time` and, beside it, the log Bayes factor (n, length)
        of the kind's model of other bodies near the candidates against the candidates
        after each sample (None for a kind without one; NaN before the first measured
        point): what the online decision
        (:func:`~inertia_id.evaluation.identify.identify_online`) needs, as
        :meth:`verdict_evidence` is what a verdict needs."""
        values = self._observed_values(observed)
        if values is not None:
            return self._observed_evidence_over_time(X, values)
        series = self._check_input(X)
        distances = self._prefix_distances(series)
        fraction = np.arange(1, self.length_ + 1) / self.length_
        near = self._prefix_near_log_bayes(series)
        candidates, none = self.posterior_from_distances(
            distances, fraction[None, :], near_log_bayes=near
        )
        return candidates, none, None if near is None else np.asarray(near)

    def _observed_evidence_over_time(
        self, X: Any, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        series = self._check_input(X)
        distances = self._observed_prefix_distances(series, values)  # (n, m, K)
        measured = values.size // 3
        fraction = np.arange(1, measured + 1) / self.length_
        near = self._observed_prefix_near_log_bayes(series, values)
        candidates, none = self.posterior_from_distances(
            distances, fraction[None, :], near_log_bayes=near
        )
        # Row 0 the prior (before the first measurement), row j after the j-th.
        n, k = len(series), self.n_candidates_
        prior_candidates = np.full((n, 1, k), (1.0 - NONE_PRIOR) / k)
        candidates = np.concatenate([prior_candidates, candidates], axis=1)
        none = np.concatenate([np.full((n, 1), NONE_PRIOR), none], axis=1)
        mask = np.zeros(self.length_, dtype=bool)
        mask[values[::3] // 3] = True
        seen = np.cumsum(mask)
        if near is not None:
            # No data before the first measurement: no factor either.
            near = np.concatenate([np.full((n, 1), np.nan), np.asarray(near)], axis=1)[:, seen]
        return candidates[:, seen], none[:, seen], near

    def _prefix_near_log_bayes(self, X: np.ndarray) -> np.ndarray | None:
        """(n, length) log Bayes factor of a proper "other bodies" model after each
        sample, for a kind that has one; None for the others."""
        return None

    # Storage as data.

    def _document_params(self) -> dict[str, Any]:
        return {name: _plain(value) for name, value in self.get_params(deep=False).items()}

    def to_dict(self) -> dict[str, Any]:
        """The fitted classifier as JSON data: the common fields and the kind's state."""
        self._check_fitted()
        return {
            "params": self._document_params(),
            "candidate_names": list(self.candidate_names_),
            "max_training_distance": self.max_training_distance_.tolist(),
            "f1": float(self.f1_),
            "accuracy": float(self.accuracy_),
            "confusion": np.asarray(self.confusion_).tolist(),
            "scenario": None if self.scenario_ is None else self.scenario_.model_dump(mode="json"),
            "sequence": None if self.sequence_ is None else np.asarray(self.sequence_).tolist(),
            "offset_removed": bool(self.offset_removed_),
            "novelty_tail": None if self.novelty_tail_ is None else self.novelty_tail_.to_dict(),
            "calibration": self.calibration_,
            **self._state(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Self:
        """The classifier a :meth:`to_dict` payload describes, checked."""
        model = cls._from_dict_unformed(data)
        model._form_loaded()
        return model

    def _form_loaded(self) -> None:
        """:meth:`_form_derived` of a classifier :meth:`_from_dict_unformed` built, its errors
        worded as a bad document's."""
        try:
            self._form_derived()
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"not a valid {self.kind} classifier document: {exc}") from None

    @classmethod
    def _from_dict_unformed(cls, data: dict[str, Any]) -> Self:
        """:meth:`from_dict` short of :meth:`_form_derived`; the classifier keeps arrays
        made from ``data``'s lists of numbers, not the lists, so a caller that owns the
        payload lets it go before the kind forms what it derives from it (the default
        kind's 40 whitening matrices, 295 MB at 960 values, had been formed while the
        parsed payload, 46 MB, was still held)."""
        if not isinstance(data, dict):
            raise InputError(f"a classifier payload is a JSON object, got {type(data).__name__}")
        target = document_class(cls.FORMAT, data)
        if cls.kind and target is not cls:
            raise InputError(
                f"the document holds a {target.kind!r} classifier, not a {cls.kind!r} one"
            )
        invalid = f"not a valid {target.kind} classifier document"
        try:
            model = target(**data["params"])
            model._check_params()
            model.candidate_names_ = [str(n) for n in data["candidate_names"]]
            model.n_candidates_ = len(model.candidate_names_)
            model.max_training_distance_ = np.asarray(data["max_training_distance"], dtype=float)
            model.f1_ = float(data["f1"])
            model.accuracy_ = float(data["accuracy"])
            model.confusion_ = np.asarray(data["confusion"], dtype=int)
            model.scenario_ = (
                None
                if data.get("scenario") is None
                else Scenario.model_validate(data["scenario"], context=AS_TRAINED)
            )
            model.sequence_ = (
                None if data.get("sequence") is None else np.asarray(data["sequence"], dtype=int)
            )
            model.offset_removed_ = bool(data.get("offset_removed", False))
            model.novelty_tail_ = NoveltyTail.from_dict(data.get("novelty_tail"))
            calibration = data.get("calibration")
            if calibration is not None and not isinstance(calibration, dict):
                raise TypeError(f"calibration must be an object, got {type(calibration).__name__}")
            temperature = (calibration or {}).get("temperature", 1.0)
            if not is_number(temperature, minimum=0.0, exclusive=True):
                raise ValueError(
                    f"calibration.temperature must be a finite number > 0, got {temperature!r}"
                )
            model.calibration_ = calibration
            model._load_state(data)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"{invalid}: {exc}") from None
        k = model.n_candidates_
        if model.max_training_distance_.shape != (k,) or model.confusion_.shape != (k, k):
            raise InputError(
                f"{invalid}: {k} candidate names, thresholds of shape "
                f"{model.max_training_distance_.shape} and a confusion matrix of shape "
                f"{model.confusion_.shape}"
            )
        return model

    def to_json(self) -> str:
        """The fitted classifier as a checksummed JSON document."""
        return documents.write(self.FORMAT, self.to_dict())

    @classmethod
    def from_json(cls, text: str | bytes) -> Self:
        """Load a document written by :meth:`to_json`, verifying its checksum."""
        return cls.from_dict(documents.read(text, cls.FORMAT))

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`to_json` to ``path``, whole or not at all (a failed write leaves
        what the path held before, never a truncated document)."""
        from ..files import write_whole

        # The document's text is made once and written in pieces, its payload let go
        # first: to_json's text, and the payload beside it, had held 4.4 times the
        # document at the peak.
        write_whole(path, documents.writer(self.FORMAT, self.to_dict()))

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Self:
        """Read a document written by :meth:`save` (at most
        :data:`~inertia_id.classifiers.documents.MAX_CLASSIFIER_BYTES`)."""
        model = cls._from_dict_unformed(cls._read_verified(path))
        model._form_loaded()  # the document let go
        return model

    @classmethod
    def _read_verified(cls, path: str | os.PathLike[str]) -> dict[str, Any]:
        """The verified payload of the document at ``path``; its text is let go on return,
        before the classifier is built."""
        text = documents.read_file(path)
        return documents.read(documents.parse(text, unique_keys=True), cls.FORMAT, source=text)


class SupervisedClassifier(BaseClassifier):
    """The kinds stored in one shared document format, the nearest centroid, 1-NN and
    MiniRocket: their state sits under ``"model"`` beside ``"kind"`` and ``"length"``.

    A kind of this format implements ``_model_state`` / ``_load_model_state`` instead of
    ``_state`` / ``_load_state``. Every candidate needs two training series, so that the
    novelty threshold has a spread within each.
    """

    FORMAT = "inertia-id/supervised-classifier"
    MIN_REALISATIONS = 2

    def _model_state(self) -> dict[str, Any]:
        raise NotImplementedError

    def _load_model_state(self, state: dict[str, Any]) -> None:
        raise NotImplementedError

    def _state(self) -> dict[str, Any]:
        return {"kind": self.kind, "length": self.length_, "model": self._model_state()}

    def _load_state(self, data: dict[str, Any]) -> None:
        self.length_ = int(data["length"])
        self._load_model_state(data["model"])
