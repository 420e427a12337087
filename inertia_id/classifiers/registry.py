"""Every classifier kind behind one door: choose, train and load any of them by name.

The registry is built from the classes: every module of :mod:`inertia_id.classifiers`
is imported, and each class that declares a ``kind`` registers itself
(:class:`~inertia_id.classifiers.base.BaseClassifier`), with what it is (document
format, metrics, minimum and default realisations) in its class attributes. Kinds
(:data:`CLASSIFIER_KINDS`):

- ``clustering``: :class:`~inertia_id.classifiers.clustering.InertiaClassifier`, the
  paper's time-series k-means (metric dtw, softdtw or euclidean);
- ``nearest-centroid`` and ``1nn``: supervised, dtw or euclidean
  (:mod:`inertia_id.classifiers.nearest`);
- ``minirocket``: MiniRocket features and a ridge classifier
  (:mod:`inertia_id.classifiers.minirocket`);
- ``likelihood``: the Gaussian matched filter that knows the simulator, fitted at one
  noise level (:mod:`inertia_id.classifiers.likelihood`);
- ``least-squares``: the physics baseline, an integral-form least-squares inertia
  estimate and the nearest candidate (:mod:`inertia_id.classifiers.leastsquares`);
- ``marginal-likelihood``: the likelihood classifier marginalised over the unknown noise
  level (:mod:`inertia_id.classifiers.marginal`), the shipped default
  (:data:`DEFAULT_KIND`): within 3 percentage points of the ceiling up to 8x noise on
  the paper preset's three benchmark sequences (``bench/classifier_ceiling.py``).

A *spec* names a kind and, optionally, its metric: ``"1nn:euclidean"``,
``"clustering:dtw"``, ``"likelihood"``.
"""

from __future__ import annotations

import importlib
import inspect
import os
import pkgutil
from collections.abc import Callable
from types import ModuleType
from typing import Any, ClassVar, Protocol

import numpy as np

from ..errors import InputError
from ..physics.scenario import Scenario
from . import documents
from .base import KINDS, BaseClassifier, document_class

__all__ = [
    "CLASSIFIER_KINDS",
    "DEFAULT_KIND",
    "CandidateClassifier",
    "check_document_size",
    "classifier_from_json",
    "default_realisations",
    "describe",
    "document_bytes",
    "kind_class",
    "kind_metrics",
    "load_classifier",
    "load_classifier_identified",
    "make_classifier",
    "parse_spec",
    "resolve_kind",
    "train",
    "train_classifier",
    "warm_up",
]


class CandidateClassifier(Protocol):
    """What identify, the sweeps, the CLI and the service need of a fitted classifier;
    every kind fits it."""

    kind: ClassVar[str]
    candidate_names_: list[str]
    n_candidates_: int
    f1_: float
    accuracy_: float
    confusion_: np.ndarray
    scenario_: Scenario | None
    sequence_: np.ndarray | None

    @property
    def metric(self) -> str: ...

    def transform(self, X: Any) -> np.ndarray: ...

    def predict(self, X: Any) -> np.ndarray: ...

    def evaluate(self, X: Any, y: Any) -> dict[str, Any]: ...

    def novelty_thresholds(self, fraction: float = 1.0) -> np.ndarray: ...

    def transform_observed(self, X: Any, observed: Any = None) -> np.ndarray: ...

    def observed_fraction(self, observed: Any = None) -> float: ...

    def distances_and_posterior(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def verdict_evidence(
        self, X: Any, observed: Any = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]: ...

    def to_json(self) -> str: ...

    def save(self, path: str | os.PathLike[str]) -> None: ...


def _import_package() -> list[ModuleType]:
    """Every module of the package: importing a kind's module registers the kind."""
    package = importlib.import_module(__package__ or "inertia_id.classifiers")
    return [
        importlib.import_module(f"{package.__name__}.{info.name}")
        for info in pkgutil.iter_modules(package.__path__)
    ]


_MODULES = _import_package()
_CLASSES: dict[str, type[BaseClassifier]] = dict(
    sorted(KINDS.items(), key=lambda item: item[1].LISTING_ORDER)
)
CLASSIFIER_KINDS = tuple(_CLASSES)
#: What a training gives when neither a kind nor a metric is asked for; the one place
#: the default is named.
DEFAULT_KIND = "marginal-likelihood"


def kind_class(kind: str) -> type[BaseClassifier]:
    """The class of a kind, or an input error listing the kinds."""
    if not isinstance(kind, str) or kind not in _CLASSES:
        raise InputError(f"classifier kind must be one of {list(CLASSIFIER_KINDS)}, got {kind!r}")
    return _CLASSES[kind]


def kind_metrics(kind: str) -> tuple[str, ...]:
    """The metrics a kind takes (its default first); empty for a kind that takes none."""
    return kind_class(kind).METRICS


def resolve_kind(kind: str | None, metric: str | None) -> str:
    """The kind meant: as given; else the paper's clustering when only a metric is given
    (the metric names a clustering), else :data:`DEFAULT_KIND`.

    The CLI, the worker and :func:`train_classifier` all ask this function.
    """
    if kind is not None:
        return kind
    return "clustering" if metric is not None else DEFAULT_KIND


def default_realisations(kind: str) -> int:
    """Training realisations per candidate when none are asked for."""
    return kind_class(kind).DEFAULT_REALISATIONS


#: Most bytes a number takes in a document: a float's shortest repr is at most 24
#: characters (``-2.2250738585072014e-308``), then a comma and, for a nested list's last
#: item, a bracket.
BYTES_PER_NUMBER = 26
#: Most bytes of a document's fields beside its numbers and its scenario: names, params,
#: the calibration's bins, the novelty tail (3.5 KB measured on the paper preset).
FIELDS_BYTES = 65_536


def document_bytes(kind: str, scenario: Scenario, n_steps: int, n_realisations: int) -> int:
    """Most bytes the document of a ``kind`` classifier trained on ``scenario`` for a
    sequence of ``n_steps`` steps, with ``n_realisations`` series a candidate, can hold:
    every number the kind stores (:meth:`~inertia_id.classifiers.base.BaseClassifier.
    stored_numbers`) and the common fields (scenario, sequence, confusion matrix) at
    :data:`BYTES_PER_NUMBER` each. A bound, not a guess: it never falls below the
    document (the default kind's covariances are counted whole, four triangles, however
    many zeros the process one holds or whether the measurement one is one number), and
    lies within 2 times of what the default kind wrote on the paper preset."""
    import json

    k = scenario.n_candidates
    values = n_steps * scenario.timing.samples_per_step * 3
    numbers = kind_class(kind).stored_numbers(k, values, n_realisations)
    common = k * k + 2 * k + n_steps * scenario.n_thrusters
    scenario_text = json.dumps(scenario.model_dump(mode="json"), separators=(",", ":"))
    return BYTES_PER_NUMBER * (numbers + common) + len(scenario_text.encode()) + FIELDS_BYTES


def check_document_size(kind: str, scenario: Scenario, n_steps: int, n_realisations: int) -> None:
    """Refuse a training whose document could pass what a classifier file may hold
    (:data:`~inertia_id.classifiers.documents.MAX_CLASSIFIER_BYTES`), so that every
    classifier trained, by the CLI or the service, is one ``identify --classifier`` loads.

    :raises InputError: naming the kind, the candidates, the series, the document's
        bound and the limit.
    """
    limit = documents.MAX_CLASSIFIER_BYTES
    bound = document_bytes(kind, scenario, n_steps, n_realisations)
    if bound <= limit:
        return
    k, values = scenario.n_candidates, n_steps * scenario.timing.samples_per_step * 3
    stored = kind_class(kind).stored_numbers
    # A kind that keeps its training series (1nn) shrinks with fewer of them too.
    fewer = (
        " or fewer realisations" if stored(k, values, n_realisations) > stored(k, values, 1) else ""
    )
    raise InputError(
        f"a {kind} classifier of {k} candidates on {n_steps} steps "
        f"({values:,} rate values a series, {n_realisations} realisations a candidate) "
        f"writes a document of up to {bound:,} bytes, over the limit of {limit:,} bytes "
        f"a classifier file may hold (the CLI refuses to load one past it): ask for a "
        f"shorter sequence{fewer}"
    )


def make_classifier(kind: str, **options: Any) -> CandidateClassifier:
    """An unfitted classifier of the given kind, its options checked.

    :param kind: one of :data:`CLASSIFIER_KINDS`.
    :param options: the class's constructor arguments, e.g. ``metric="euclidean"``.
    """
    return _make(kind, options)


def _make(kind: str, options: dict[str, Any]) -> BaseClassifier:
    cls = kind_class(kind)
    accepted = set(inspect.signature(cls.__init__).parameters) - {"self"}
    unknown = sorted(set(options) - accepted)
    if unknown:
        raise InputError(
            f"the {kind!r} classifier does not take option(s) {unknown}; it takes "
            f"{sorted(accepted)}"
        )
    model = cls(**options)
    model._check_params()
    return model


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """``"1nn:euclidean"`` -> ``("1nn", {"metric": "euclidean"})``, checked."""
    if not isinstance(spec, str):
        raise InputError(f"a classifier spec is a string like '1nn:euclidean', got {spec!r}")
    kind, _, metric = spec.partition(":")
    options = {"metric": metric} if metric else {}
    make_classifier(kind, **options)
    return kind, options


def describe(model: Any) -> str:
    """A short label: kind and metric, e.g. "1nn euclidean", "likelihood"."""
    cls = type(model)
    if isinstance(model, BaseClassifier) and _CLASSES.get(cls.kind) is cls:
        return f"{cls.kind} {model.metric}" if cls.METRICS else cls.kind
    return cls.__name__


def train_classifier(
    scenario: Scenario,
    sequence: Any,
    n_realisations: int,
    rng: np.random.Generator,
    *,
    kind: str | None = None,
    should_stop: Callable[[], bool] | None = None,
    **options: Any,
) -> CandidateClassifier:
    """Simulate every candidate under ``sequence`` at 1x noise and fit a classifier.

    The kind is :func:`resolve_kind`'s: as given, else the paper's clustering when a
    metric is given, else :data:`DEFAULT_KIND`. A seed the kind needs (k-means,
    MiniRocket) and not given is drawn from ``rng``, so the same rng state gives the same
    model. The classifier remembers the scenario and sequence (identify needs them).

    :param kind: see :func:`make_classifier`.
    :param should_stop: asked at the training's checkpoints; True stops it there
        (:meth:`~inertia_id.classifiers.base.BaseClassifier.fit_scenario`).
    :param options: constructor arguments of that kind.
    """
    model = _make(resolve_kind(kind, options.get("metric")), options)
    return model.fit_scenario(scenario, sequence, n_realisations, rng, should_stop=should_stop)


#: The name the paper's pipeline has always used for :func:`train_classifier`.
train = train_classifier


def classifier_from_json(text: str | bytes | dict[str, Any]) -> CandidateClassifier:
    """Load any classifier document, whatever its kind (the checksum is verified): its
    JSON text, or the text parsed already (:func:`documents.parse`)."""
    document = documents.parse(text)
    fmt = _format_of(document)
    payload = documents.read(document, fmt, source=None if isinstance(text, dict) else text)
    del document  # what this function parsed is let go before the model is formed
    model = document_class(fmt, payload)._from_dict_unformed(payload)
    del payload
    model._form_loaded()
    return model


def _format_of(document: dict[str, Any]) -> str:
    fmt = document.get("format")
    formats = sorted({cls.FORMAT for cls in _CLASSES.values()})
    if fmt not in formats:
        raise InputError(f"not a classifier document: format {fmt!r} is not one of {formats}")
    return str(fmt)


def load_classifier(path: str | os.PathLike[str]) -> CandidateClassifier:
    """Read any classifier document from a file (see :func:`classifier_from_json`); one
    of more than :data:`~inertia_id.classifiers.documents.MAX_CLASSIFIER_BYTES` is
    refused by its size, unread."""
    return load_classifier_identified(path)[0]


def load_classifier_identified(
    path: str | os.PathLike[str],
) -> tuple[CandidateClassifier, dict[str, Any]]:
    """:func:`load_classifier`, with what identifies the file: ``file`` (the path as
    given), ``sha256`` (the checksum the document states over its payload, verified: the
    service's classifier ``sha256`` and its download's ETag, not a hash of the file's
    bytes) and ``provenance`` (:func:`~inertia_id.classifiers.documents.provenance_of`:
    the service's classifier id, training job id, scenario id and when it was stored;
    None for a file that states none, such as ``inertia-id train`` writes)."""
    fmt, payload, identity = _read_verified(path)
    model = document_class(fmt, payload)._from_dict_unformed(payload)
    del payload  # let go before the model factors its covariances
    model._form_loaded()
    return model, {"file": os.fspath(path), **identity}


def _read_verified(
    path: str | os.PathLike[str],
) -> tuple[str, dict[str, Any], dict[str, Any]]:
    """The format and verified payload of the document at ``path``, and its stated
    ``sha256`` and ``provenance``; its text is let go on return, before the classifier is
    built (it was held while the classifier factored its covariances)."""
    text = documents.read_file(path)
    document = documents.parse(text, unique_keys=True)
    fmt = _format_of(document)
    payload = documents.read(document, fmt, source=text)
    identity = {
        "sha256": document.get("sha256"),
        "provenance": documents.provenance_of(document),
    }
    return fmt, payload, identity


def warm_up() -> None:
    """Compile, or load from numba's cache, every numba kernel that a kind's ``transform``
    uses (each module of the package that has a ``warm_up`` runs it) and the simulator's
    RK4 kernel (:mod:`inertia_id.physics._rk4`), which every training, sweep and search
    runs."""
    from ..physics import _rk4

    for module in _MODULES:
        if module.__name__ != __name__ and callable(getattr(module, "warm_up", None)):
            module.warm_up()
    _rk4.warm_up()
