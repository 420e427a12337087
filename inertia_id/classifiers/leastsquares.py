"""The physics baseline as a classifier: the candidate whose tensor fits Euler's equations.

:func:`~inertia_id.physics.estimate.estimate_inertia` solves the integral form of Euler's
equations for the inertia tensor by least squares; :class:`LeastSquaresClassifier` ranks
the candidates by how much worse their tensors fit the same equations. A sequence that
fires one fixed torque direction identifies the full tensor poorly but still separates
the candidates this way (see the class docstring).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator

from ..physics.estimate import (
    InertiaEstimate,
    estimate_inertia,
    parameters_from_tensor,
    tensor_from_parameters,
)
from ..physics.scenario import Scenario
from ..physics.simulate import simulate
from .base import StoredClassifier, check_labels, confusion_scores
from .likelihood import _check_series

__all__ = ["DISTANCES", "LeastSquaresClassifier", "train_least_squares"]

DISTANCES = ("equation-error", "frobenius")
FORMAT = "inertia-id/least-squares-classifier"


class LeastSquaresClassifier(StoredClassifier, BaseEstimator):
    """Nearest candidate to the least-squares inertia estimate.

    Distances (``distance``):

    - "equation-error" (default): how much worse candidate k's tensor θ_k satisfies the
      integrated Euler equations than the best-fitting tensor θ̂, as an RMS over the
      equations, N m s: ``sqrt((θ_k - θ̂)ᵀ ΦᵀΦ (θ_k - θ̂) / m)``. Parameter combinations
      the sequence does not excite weigh nothing, so a sequence that pins down only I⁻¹M
      (one torque direction) still separates the candidates; this is testing each
      candidate's tensor against the data, which the estimate merely makes cheap.
    - "frobenius": ``|Î - I_k|_F / |I_k|_F``, the relative tensor error. Intuitive, but
      only meaningful when all six parameters are excited (small condition number):
      with one torque direction the poorly excited combinations swamp it.

    ``fit`` estimates nothing from the data beyond the novelty thresholds: the model is
    the scenario (candidates, thrusters, timing) and the sequence. Novelty: a series
    farther from its nearest candidate than ``novelty_factor`` times the largest
    distance of that candidate's training series to it "matches none". Training
    distances are unbiased here (nothing was fitted to them), so no hold-out is needed.

    :param distance: "equation-error" or "frobenius".
    :param window_s: window length passed to :func:`estimate_inertia`; None: cumulative
        windows from the sequence start.
    :param lowpass: apply the scenario's known low-pass to the commanded torque.
    :param start_at_rest: rate known to be zero at t = 0; None: from the scenario.
    :param novelty_factor: multiple of the largest training distance beyond which a
        series matches no candidate.
    """

    FORMAT = FORMAT

    def __init__(
        self,
        distance: str = "equation-error",
        *,
        window_s: float | None = None,
        lowpass: bool = True,
        start_at_rest: bool | None = None,
        novelty_factor: float = 1.5,
    ) -> None:
        self.distance = distance
        self.window_s = window_s
        self.lowpass = lowpass
        self.start_at_rest = start_at_rest
        self.novelty_factor = novelty_factor

    @property
    def metric(self) -> str:
        """What the distances are, for reports and sweeps (``SweepResult.metric``)."""
        return "least-squares"

    def _check_params(self) -> None:
        if self.distance not in DISTANCES:
            raise ValueError(f"distance must be one of {list(DISTANCES)}, got {self.distance!r}")
        if self.window_s is not None and not (
            isinstance(self.window_s, int | float)
            and not isinstance(self.window_s, bool)
            and math.isfinite(self.window_s)
            and self.window_s > 0
        ):
            raise ValueError(f"window_s must be None or a time > 0 s, got {self.window_s!r}")
        if not (
            isinstance(self.novelty_factor, int | float)
            and math.isfinite(self.novelty_factor)
            and self.novelty_factor >= 1.0
        ):
            raise ValueError(f"novelty_factor must be >= 1, got {self.novelty_factor!r}")

    # Fitting.

    def fit(
        self,
        X: Any,
        y: Any,
        *,
        scenario: Scenario,
        sequence: Any,
        candidate_names: list[str] | None = None,
    ) -> LeastSquaresClassifier:
        """Take the candidates from ``scenario`` and calibrate the novelty thresholds.

        :param X: (n_series, length, 3) responses to ``sequence``, rad/s.
        :param y: candidate index of each series in ``scenario`` (every candidate once
            at least, to set its threshold).
        :param scenario: the candidates, thrusters and timing: the model itself.
        :param sequence: (L, N) level indices the series respond to.
        :param candidate_names: names for reports; default the scenario's.
        """
        self._check_params()
        sequence = scenario.check_sequence(sequence)
        n_candidates = scenario.n_candidates
        X = _check_series(X, len(sequence) * scenario.timing.samples_per_step)
        labels = check_labels(y, len(X), n_candidates)
        missing = sorted(set(range(n_candidates)) - set(labels.tolist()))
        if missing:
            raise ValueError(f"y must label every candidate of the scenario; missing {missing}")
        if candidate_names is not None and len(candidate_names) != n_candidates:
            raise ValueError(
                f"{len(candidate_names)} candidate names for {n_candidates} candidates"
            )
        # Estimate first: a window that does not suit the scenario fails before any
        # fitted attribute is set.
        estimate = estimate_inertia(
            scenario,
            sequence,
            X,
            window_s=self.window_s,
            lowpass=self.lowpass,
            start_at_rest=self.start_at_rest,
        )
        self.scenario_ = scenario
        self.sequence_ = sequence
        self.n_candidates_ = n_candidates
        self.candidate_names_ = list(candidate_names or scenario.candidate_names)
        self.candidate_parameters_kg_m2_ = parameters_from_tensor(scenario.inertia_array)
        distances = self._distances(estimate)
        own = distances[np.arange(len(X)), labels]
        self.max_training_distance_ = np.array(
            [own[labels == k].max() for k in range(n_candidates)]
        )
        predicted = distances.argmin(axis=1)
        confusion = np.zeros((n_candidates, n_candidates), dtype=int)
        np.add.at(confusion, (labels, predicted), 1)
        scores = confusion_scores(confusion)
        self.f1_ = scores["f1"]
        self.accuracy_ = scores["accuracy"]
        self.confusion_ = scores["confusion"]
        return self

    # Prediction.

    def _check_fitted(self) -> None:
        if not hasattr(self, "candidate_parameters_kg_m2_"):
            raise ValueError("this classifier is not fitted yet; call fit first")

    def estimate(self, X: Any) -> InertiaEstimate:
        """The least-squares inertia of each series (batched, see :func:`estimate_inertia`)."""
        self._check_fitted()
        return estimate_inertia(
            self.scenario_,
            self.sequence_,
            _check_series(X),
            window_s=self.window_s,
            lowpass=self.lowpass,
            start_at_rest=self.start_at_rest,
        )

    def _distances(self, estimate: InertiaEstimate) -> np.ndarray:
        candidates = self.candidate_parameters_kg_m2_
        if self.distance == "frobenius":
            tensors = tensor_from_parameters(candidates)
            gap = estimate.inertia_kg_m2[:, None] - tensors[None]
            return np.asarray(
                np.linalg.norm(gap, axis=(-2, -1)) / np.linalg.norm(tensors, axis=(-2, -1))
            )
        gap = candidates[None, :, :] - estimate.parameters_kg_m2[:, None, :]
        quadratic = np.einsum("nki,nij,nkj->nk", gap, estimate.normal_matrix, gap)
        return np.asarray(np.sqrt(np.maximum(quadratic, 0.0) / estimate.n_equations))

    def transform(self, X: Any) -> np.ndarray:
        """Distance of each series' estimate to each candidate, (n_series, K).

        N m s for "equation-error", dimensionless for "frobenius".
        """
        return self._distances(self.estimate(X))

    def predict(self, X: Any) -> np.ndarray:
        """Candidate index of each series: the nearest candidate tensor."""
        return np.asarray(self.transform(X).argmin(axis=1))

    def fit_predict(self, X: Any, y: Any, **kwargs: Any) -> np.ndarray:
        return self.fit(X, y, **kwargs).predict(X)

    def novelty_thresholds(self) -> np.ndarray:
        """Per-candidate distance beyond which a series "matches none", (K,)."""
        self._check_fitted()
        return np.asarray(self.novelty_factor * self.max_training_distance_)

    # Storage as data.

    def to_dict(self) -> dict[str, Any]:
        self._check_fitted()
        return {
            "params": self.get_params(),
            "candidate_names": self.candidate_names_,
            "max_training_distance": self.max_training_distance_.tolist(),
            "f1": self.f1_,
            "accuracy": self.accuracy_,
            "confusion": self.confusion_.tolist(),
            "scenario": self.scenario_.model_dump(mode="json"),
            "sequence": np.asarray(self.sequence_).tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LeastSquaresClassifier:
        try:
            model = cls(**data["params"])
            model._check_params()
            model.scenario_ = Scenario.model_validate(data["scenario"])
            model.sequence_ = model.scenario_.check_sequence(data["sequence"])
            model.n_candidates_ = model.scenario_.n_candidates
            model.candidate_names_ = [str(n) for n in data["candidate_names"]]
            model.candidate_parameters_kg_m2_ = parameters_from_tensor(
                model.scenario_.inertia_array
            )
            model.max_training_distance_ = np.asarray(data["max_training_distance"], float)
            model.f1_ = float(data["f1"])
            model.accuracy_ = float(data["accuracy"])
            model.confusion_ = np.asarray(data["confusion"], dtype=int)
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"not a valid least-squares classifier document: {exc}") from None
        k = model.n_candidates_
        if len(model.candidate_names_) != k or model.max_training_distance_.shape != (k,):
            raise ValueError(
                f"not a valid least-squares classifier document: {k} candidates, "
                f"{len(model.candidate_names_)} names, "
                f"{model.max_training_distance_.shape} thresholds"
            )
        return model


def train_least_squares(
    scenario: Scenario,
    sequence: Any,
    n_realisations: int,
    rng: np.random.Generator,
    **classifier_params: Any,
) -> LeastSquaresClassifier:
    """Simulate every candidate under ``sequence`` at 1x noise and fit the classifier.

    Like :func:`~inertia_id.classify.train`; only the novelty thresholds depend on the
    simulated series.

    :param n_realisations: series per candidate for the novelty thresholds.
    :param rng: source of the simulated noise; the same state gives the same model.
    """
    sequence = scenario.check_sequence(sequence)
    X, y = simulate(scenario, sequence, n_realisations, rng).dataset()
    model = LeastSquaresClassifier(**classifier_params)
    return model.fit(X, y, scenario=scenario, sequence=sequence)
