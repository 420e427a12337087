"""Every classifier kind behind one door: choose, train and load any of them by name.

Kinds (:data:`CLASSIFIER_KINDS`):

- ``clustering``: :class:`~inertia_id.classify.InertiaClassifier`, the paper's
  time-series k-means (metric dtw, softdtw or euclidean);
- ``nearest-centroid`` and ``1nn``: supervised, dtw or euclidean
  (:mod:`inertia_id.supervised`);
- ``minirocket``: MiniRocket features and a ridge classifier;
- ``likelihood``: the Gaussian matched filter that knows the simulator, the accuracy
  limit (:mod:`inertia_id.likelihood`);
- ``least-squares``: the physics baseline, an integral-form least-squares inertia
  estimate and the nearest candidate (:mod:`inertia_id.leastsquares`);
- ``marginal-likelihood``: the likelihood classifier marginalised over the unknown noise
  level (:mod:`inertia_id.marginal`), the shipped default: within half a percentage
  point of the limit up to 8x noise (``bench/classifier_limit.py``).

A *spec* names a kind and, optionally, its metric: ``"1nn:euclidean"``,
``"clustering:dtw"``, ``"likelihood"``.
"""

from __future__ import annotations

import inspect
import os
from typing import Any, Protocol

import numpy as np

from ..physics.scenario import Scenario
from ..physics.simulate import simulate
from . import documents
from .clustering import FORMAT as CLUSTERING_FORMAT
from .clustering import InertiaClassifier, train
from .leastsquares import FORMAT as LEAST_SQUARES_FORMAT
from .leastsquares import LeastSquaresClassifier
from .likelihood import FORMAT as LIKELIHOOD_FORMAT
from .likelihood import LikelihoodClassifier
from .marginal import FORMAT as MARGINAL_FORMAT
from .marginal import MarginalLikelihoodClassifier, train_marginal
from .nearest import FORMAT as SUPERVISED_FORMAT
from .nearest import SUPERVISED_CLASSES, MiniRocketClassifier, SupervisedClassifier

__all__ = [
    "CLASSIFIER_KINDS",
    "DEFAULT_KIND",
    "CandidateClassifier",
    "classifier_from_json",
    "default_realisations",
    "describe",
    "load_classifier",
    "make_classifier",
    "parse_spec",
    "resolve_kind",
    "train_classifier",
]


class CandidateClassifier(Protocol):
    """What identify and the noise sweep need of a classifier; every kind fits it."""

    candidate_names_: list[str]

    @property
    def metric(self) -> str: ...

    def transform(self, X: Any) -> np.ndarray: ...

    def predict(self, X: Any) -> np.ndarray: ...

    def evaluate(self, X: Any, y: Any) -> dict[str, Any]: ...

    def novelty_thresholds(self) -> np.ndarray: ...

    def to_json(self) -> str: ...


_CLASSES: dict[str, type[Any]] = {
    "clustering": InertiaClassifier,
    **SUPERVISED_CLASSES,
    "likelihood": LikelihoodClassifier,
    "least-squares": LeastSquaresClassifier,
    "marginal-likelihood": MarginalLikelihoodClassifier,
}
CLASSIFIER_KINDS = tuple(_CLASSES)
#: What ``train`` gives when no kind is asked for.
DEFAULT_KIND = "marginal-likelihood"
#: The marginal likelihood estimates three noise covariances of 240+ dimensions: it
#: reaches the limit from 100 realisations per candidate (2.4 points short from 20).
_DEFAULT_REALISATIONS = {"marginal-likelihood": 100}


def resolve_kind(kind: str | None, metric: str | None) -> str:
    """The kind meant: as given; else the paper's clustering when only a metric is given
    (the metric names a clustering), else :data:`DEFAULT_KIND`."""
    if kind is not None:
        return kind
    return "clustering" if metric is not None else DEFAULT_KIND


def default_realisations(kind: str) -> int:
    """Training realisations per candidate when none are asked for."""
    return _DEFAULT_REALISATIONS.get(kind, 20)


def make_classifier(kind: str, **options: Any) -> Any:
    """An unfitted classifier of the given kind, its options checked.

    :param kind: one of :data:`CLASSIFIER_KINDS`.
    :param options: the class's constructor arguments, e.g. ``metric="euclidean"``.
    """
    if not isinstance(kind, str) or kind not in _CLASSES:
        raise ValueError(f"classifier kind must be one of {list(CLASSIFIER_KINDS)}, got {kind!r}")
    cls = _CLASSES[kind]
    accepted = set(inspect.signature(cls.__init__).parameters) - {"self"}
    unknown = sorted(set(options) - accepted)
    if unknown:
        raise ValueError(
            f"the {kind!r} classifier does not take option(s) {unknown}; it takes "
            f"{sorted(accepted)}"
        )
    model = cls(**options)
    model._check_params()
    return model


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"1nn:euclidean"`` -> ``("1nn", {"metric": "euclidean"})``, checked."""
    if not isinstance(spec, str):
        raise ValueError(f"a classifier spec is a string like '1nn:euclidean', got {spec!r}")
    kind, _, metric = spec.partition(":")
    options = {"metric": metric} if metric else {}
    make_classifier(kind, **options)
    return kind, options


def describe(model: Any) -> str:
    """A short label: kind and metric, e.g. "1nn euclidean", "likelihood"."""
    for kind, cls in _CLASSES.items():
        if type(model) is cls:
            metric = getattr(model, "metric", "")
            return f"{kind} {metric}" if kind in ("clustering", "nearest-centroid", "1nn") else kind
    return type(model).__name__


def train_classifier(
    scenario: Scenario,
    sequence: Any,
    n_realisations: int,
    rng: np.random.Generator,
    *,
    kind: str = "clustering",
    **options: Any,
) -> Any:
    """Simulate every candidate under ``sequence`` at 1x noise and fit a classifier.

    Like :func:`~inertia_id.classify.train` (which it calls for "clustering"), for any
    kind; a MiniRocket seed not given is drawn from ``rng``, so the same rng state gives
    the same model. The classifier remembers the scenario and sequence (identify needs
    them).

    :param kind: see :func:`make_classifier`.
    :param options: constructor arguments of that kind.
    """
    if kind == "clustering":
        return train(scenario, sequence, n_realisations, rng, **options)
    model = make_classifier(kind, **options)
    if isinstance(model, MarginalLikelihoodClassifier):
        return train_marginal(scenario, sequence, n_realisations, rng, **options)
    sequence = scenario.check_sequence(sequence)
    X, y = simulate(scenario, sequence, n_realisations, rng).dataset()
    if isinstance(model, MiniRocketClassifier) and model.random_state is None:
        model.random_state = int(rng.integers(2**31 - 1))
    if isinstance(model, LikelihoodClassifier | LeastSquaresClassifier):
        return model.fit(
            X, y, candidate_names=scenario.candidate_names, scenario=scenario, sequence=sequence
        )
    model.fit(X, y, candidate_names=scenario.candidate_names)
    model.scenario_ = scenario
    model.sequence_ = sequence
    return model


_LOADERS: dict[str, Any] = {
    CLUSTERING_FORMAT: InertiaClassifier.from_json,
    SUPERVISED_FORMAT: SupervisedClassifier.from_json,
    LIKELIHOOD_FORMAT: LikelihoodClassifier.from_json,
    LEAST_SQUARES_FORMAT: LeastSquaresClassifier.from_json,
    MARGINAL_FORMAT: MarginalLikelihoodClassifier.from_json,
}


def classifier_from_json(text: str | bytes) -> Any:
    """Load any classifier document, whatever its kind (the checksum is verified)."""
    fmt = documents.parse(text).get("format")
    if fmt not in _LOADERS:
        raise ValueError(
            f"not a classifier document: format {fmt!r} is not one of {sorted(_LOADERS)}"
        )
    return _LOADERS[fmt](text)


def load_classifier(path: str | os.PathLike[str]) -> Any:
    """Read any classifier document from a file (see :func:`classifier_from_json`)."""
    with open(path, encoding="utf-8") as fh:
        return classifier_from_json(fh.read())
