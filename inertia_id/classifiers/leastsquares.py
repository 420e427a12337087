"""The physics baseline as a classifier: the candidate whose tensor fits Euler's equations.

:func:`~inertia_id.physics.estimate.estimate_inertia` solves the integral form of Euler's
equations for the inertia tensor by least squares; :class:`LeastSquaresClassifier` ranks
the candidates by how much worse their tensors fit the same equations. A sequence that
fires one fixed torque direction identifies the full tensor poorly but still separates
the candidates this way (see the class docstring).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..errors import InputError
from ..physics.estimate import (
    InertiaEstimate,
    estimate_inertia,
    parameters_from_tensor,
    tensor_from_parameters,
)
from .base import BaseClassifier, is_number

__all__ = ["DISTANCES", "LeastSquaresClassifier"]

DISTANCES = ("equation-error", "frobenius")


class LeastSquaresClassifier(BaseClassifier):
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
    :param window_s: window length passed to
        :func:`~inertia_id.physics.estimate.estimate_inertia`; None: cumulative windows
        from the sequence start.
    :param lowpass: apply the scenario's known low-pass to the commanded torque.
    :param start_at_rest: rate known to be zero at t = 0; None: from the scenario.
    :param novelty_factor: multiple of the largest training distance beyond which a
        series matches no candidate.
    """

    kind: ClassVar[str] = "least-squares"
    REMOVES_OFFSET = False
    FORMAT = "inertia-id/least-squares-classifier"
    NEEDS_SCENARIO = True
    LISTING_ORDER = 60
    LABEL = "least squares (physics baseline: the inertia estimated, nearest candidate)"
    metric = "least-squares"

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

    def _check_params(self) -> None:
        super()._check_params()
        if self.distance not in DISTANCES:
            raise InputError(f"distance must be one of {list(DISTANCES)}, got {self.distance!r}")
        if self.window_s is not None and not is_number(self.window_s, minimum=0, exclusive=True):
            raise InputError(f"window_s must be None or a time > 0 s, got {self.window_s!r}")

    # Fitting.

    def _fit(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Take the candidates from the scenario; the training distances (unbiased here:
        nothing was fitted to them) calibrate the novelty thresholds."""
        assert self.scenario_ is not None  # NEEDS_SCENARIO: _prepare refused a fit without
        self.candidate_parameters_kg_m2_ = parameters_from_tensor(self.scenario_.inertia_array)
        return self._distances(self._estimate(X))

    # Prediction.

    def estimate(self, X: Any) -> InertiaEstimate:
        """The least-squares inertia of each series (batched, see
        :func:`~inertia_id.physics.estimate.estimate_inertia`)."""
        return self._estimate(self._check_input(X), standard_errors=True)

    def _estimate(self, X: np.ndarray, *, standard_errors: bool = False) -> InertiaEstimate:
        """The estimates of checked series; the fit and the distances read no standard
        error, so theirs are skipped unless asked for (see
        :func:`~inertia_id.physics.estimate.estimate_inertia`)."""
        assert self.scenario_ is not None and self.sequence_ is not None
        return estimate_inertia(
            self.scenario_,
            self.sequence_,
            X,
            window_s=self.window_s,
            lowpass=self.lowpass,
            start_at_rest=self.start_at_rest,
            standard_errors=standard_errors,
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

    def _candidate_distances(self, X: np.ndarray) -> np.ndarray:
        """Distance of each series' estimate to each candidate, (n_series, K).

        N m s for "equation-error", dimensionless for "frobenius".
        """
        return self._distances(self._estimate(X))

    # Storage as data: the common fields hold the whole model (scenario and sequence).

    @classmethod
    def stored_numbers(cls, n_candidates: int, values: int, n_realisations: int) -> int:
        """None: the scenario and sequence, among the common fields, are the model."""
        return 0

    def _state(self) -> dict[str, Any]:
        return {}

    def _load_state(self, data: dict[str, Any]) -> None:
        if self.scenario_ is None or self.sequence_ is None:
            raise InputError("the document holds no scenario and sequence, the model itself")
        scenario = self.scenario_
        self.sequence_ = scenario.check_sequence(self.sequence_)
        if self.n_candidates_ != scenario.n_candidates:
            raise InputError(
                f"{self.n_candidates_} candidate names for the scenario's "
                f"{scenario.n_candidates} candidates"
            )
        self.length_ = len(self.sequence_) * scenario.timing.samples_per_step
        self.candidate_parameters_kg_m2_ = parameters_from_tensor(scenario.inertia_array)
