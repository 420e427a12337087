"""Which candidate is this spacecraft? Classify measured telemetry.

Telemetry is the gyro's ω samples, with time stamps measured from the start of the
actuation sequence the classifier was trained for. It is resampled (linear
interpolation) onto the classifier's sample grid and compared with every candidate's
centroid. A series farther from its nearest centroid than any training response was
(times the classifier's novelty factor) "matches none": a spacecraft in an unexpected
state is not forced into a class.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

from ..errors import InputError
from ..physics.estimate import estimate_inertia
from .telemetry import Telemetry, resample

if TYPE_CHECKING:
    from ..classifiers.registry import CandidateClassifier


__all__ = ["Identification", "identify"]


class Identification(BaseModel):
    """The verdict on one telemetry series.

    ``candidate`` is the nearest candidate even when ``matches_none`` is true, so an
    operator can see what it was closest to; ``matches_none`` says it should not be
    believed.
    """

    candidate_index: int
    candidate: str
    inertia_kg_m2: list[list[float]] | None
    distances: dict[str, float]
    margin: float
    relative_margin: float
    threshold: float
    matches_none: bool
    verdict: str
    estimated_inertia_kg_m2: list[list[float]] | None = None
    estimated_principal_moments_kg_m2: list[float] | None = None
    estimate_condition_number: float | None = None
    poorly_excited: list[str] = []


def identify(
    classifier: CandidateClassifier, telemetry: Telemetry | dict[str, Any]
) -> Identification:
    """Classify one telemetry series to a candidate, or say it matches none.

    :param classifier: fitted classifier that carries its scenario and sequence.
    :param telemetry: the response to the classifier's sequence.
    """
    if not isinstance(telemetry, Telemetry):
        telemetry = Telemetry.model_validate(telemetry)
    scenario, sequence = classifier.scenario_, classifier.sequence_
    if scenario is None or sequence is None:
        raise InputError("the classifier does not carry its scenario and sequence")
    grid = scenario.sample_times(len(sequence))
    series = resample(telemetry, grid)
    distances = classifier.transform(series[None])[0]
    order = np.argsort(distances)
    best = int(order[0])
    runner_up = float(distances[order[1]])
    margin = runner_up - float(distances[best])
    threshold = float(classifier.novelty_thresholds()[best])
    matches_none = bool(distances[best] > threshold)
    name = classifier.candidate_names_[best]
    verdict = (
        f"matches none of the candidates: nearest is {name!r} at distance "
        f"{distances[best]:.4g}, beyond {threshold:.4g} seen in training"
        if matches_none
        else f"{name}"
    )
    # The physics baseline's view of the same telemetry: the inertia tensor the
    # integral-form least squares estimates from it, whatever the classifier's kind.
    estimate = estimate_inertia(scenario, sequence, series)
    tensor = np.asarray(estimate.inertia_kg_m2)
    finite = bool(np.all(np.isfinite(tensor)))
    condition = float(estimate.condition_number)
    return Identification(
        candidate_index=best,
        candidate=name,
        inertia_kg_m2=scenario.inertia_candidates[best].inertia_kg_m2,
        distances={
            n: float(d) for n, d in zip(classifier.candidate_names_, distances, strict=True)
        },
        margin=margin,
        relative_margin=margin / runner_up if runner_up > 0 else 0.0,
        threshold=threshold,
        matches_none=matches_none,
        verdict=verdict,
        estimated_inertia_kg_m2=tensor.tolist() if finite else None,
        estimated_principal_moments_kg_m2=np.linalg.eigvalsh(tensor).tolist() if finite else None,
        estimate_condition_number=condition if np.isfinite(condition) else None,
        poorly_excited=estimate.poorly_excited(),
    )
