"""inertia-id: which configuration is the spacecraft in, from how it rotates.

The science core, usable from a notebook::

    import numpy as np
    from inertia_id import Scenario, simulate, train, run_sweep, identify

    scenario = Scenario.paper()
    sequence = [[4, 4, 4, 0, 0, 0]] * 4
    result = simulate(scenario, sequence, 20, np.random.default_rng(0))
    classifier = train(scenario, sequence, 20, np.random.default_rng(1), metric="dtw")

Importing the package is quick: each public name below is imported from its module
(:mod:`inertia_id.physics`, :mod:`inertia_id.classifiers`, :mod:`inertia_id.evaluation`)
when first used, so ``import inertia_id`` loads neither torch, tslearn nor scikit-learn.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import InputError

if TYPE_CHECKING:
    from .classifiers.clustering import METRICS, InertiaClassifier, MatchScores, match_clusters
    from .classifiers.leastsquares import LeastSquaresClassifier
    from .classifiers.likelihood import LikelihoodClassifier
    from .classifiers.marginal import MarginalLikelihoodClassifier, train_marginal
    from .classifiers.minirocket import MiniRocketClassifier
    from .classifiers.nearest import NearestCentroidClassifier, NearestNeighbourClassifier
    from .classifiers.registry import (
        CLASSIFIER_KINDS,
        classifier_from_json,
        load_classifier,
        make_classifier,
        train,
        train_classifier,
        warm_up,
    )
    from .evaluation.identify import Identification, identify
    from .evaluation.sweep import (
        InertiaSweepResult,
        SweepPoint,
        SweepResult,
        run_inertia_sweep,
        run_sweep,
        wilson_interval,
    )
    from .evaluation.telemetry import Telemetry, load_telemetry, parse_telemetry
    from .physics.estimate import InertiaEstimate, estimate_inertia
    from .physics.presets import PRESETS, preset
    from .physics.scenario import (
        CandidateGenerator,
        InertiaCandidate,
        Scenario,
        Thrusters,
        Timing,
        Uncertainty,
        check_inertia_tensor,
    )
    from .physics.simulate import SimulationResult, Simulator, simulate

__version__ = "0.1.0"

#: Where each public name lives: imported on first use (PEP 562).
_LAZY = {
    **dict.fromkeys(
        ("METRICS", "InertiaClassifier", "MatchScores", "match_clusters"),
        ".classifiers.clustering",
    ),
    "LeastSquaresClassifier": ".classifiers.leastsquares",
    "LikelihoodClassifier": ".classifiers.likelihood",
    "MarginalLikelihoodClassifier": ".classifiers.marginal",
    "train_marginal": ".classifiers.marginal",
    "MiniRocketClassifier": ".classifiers.minirocket",
    "NearestCentroidClassifier": ".classifiers.nearest",
    "NearestNeighbourClassifier": ".classifiers.nearest",
    **dict.fromkeys(
        (
            "CLASSIFIER_KINDS",
            "classifier_from_json",
            "load_classifier",
            "make_classifier",
            "train",
            "train_classifier",
            "warm_up",
        ),
        ".classifiers.registry",
    ),
    "Identification": ".evaluation.identify",
    "identify": ".evaluation.identify",
    **dict.fromkeys(
        (
            "InertiaSweepResult",
            "SweepPoint",
            "SweepResult",
            "run_inertia_sweep",
            "run_sweep",
            "wilson_interval",
        ),
        ".evaluation.sweep",
    ),
    **dict.fromkeys(("Telemetry", "load_telemetry", "parse_telemetry"), ".evaluation.telemetry"),
    "InertiaEstimate": ".physics.estimate",
    "estimate_inertia": ".physics.estimate",
    "PRESETS": ".physics.presets",
    "preset": ".physics.presets",
    **dict.fromkeys(
        (
            "CandidateGenerator",
            "InertiaCandidate",
            "Scenario",
            "Thrusters",
            "Timing",
            "Uncertainty",
            "check_inertia_tensor",
        ),
        ".physics.scenario",
    ),
    **dict.fromkeys(("SimulationResult", "Simulator", "simulate"), ".physics.simulate"),
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "CLASSIFIER_KINDS",
    "METRICS",
    "PRESETS",
    "CandidateGenerator",
    "Identification",
    "InertiaCandidate",
    "InertiaClassifier",
    "InertiaEstimate",
    "InertiaSweepResult",
    "InputError",
    "LeastSquaresClassifier",
    "LikelihoodClassifier",
    "MarginalLikelihoodClassifier",
    "MatchScores",
    "MiniRocketClassifier",
    "NearestCentroidClassifier",
    "NearestNeighbourClassifier",
    "Scenario",
    "SimulationResult",
    "Simulator",
    "SweepPoint",
    "SweepResult",
    "Telemetry",
    "Thrusters",
    "Timing",
    "Uncertainty",
    "check_inertia_tensor",
    "classifier_from_json",
    "estimate_inertia",
    "identify",
    "load_classifier",
    "load_telemetry",
    "make_classifier",
    "match_clusters",
    "parse_telemetry",
    "preset",
    "run_inertia_sweep",
    "run_sweep",
    "simulate",
    "train",
    "train_classifier",
    "train_marginal",
    "warm_up",
    "wilson_interval",
]
